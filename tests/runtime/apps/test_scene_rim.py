"""relight_rt.apps.scene_rim: a small bright source behind the person becomes a rim, its strength from the source's
radiance along grazing directions, not the map's mean."""

import math

import cv2
import numpy as np
import pytest

from relight_rt import envmap
from relight_rt.apps.panorama import panorama_view, view_rotation
from relight_rt.apps.scene_rim import (
    LOBE_SR,
    RIM_MAX,
    RIM_PHOTO,
    body,
    fibre_patch,
    fibre_share,
    fibres_in,
    key_rim,
    panorama_rim,
    photo_rim,
    rim_colour,
    rim_facing,
)
from relight_rt.image.color import REC709
from relight_rt.light.from_background import FRONT_WEIGHTS


def sunset_map(sky: float, share: float = 0.01, h: int = 64, right_deg: float = 16.0):
    """A uniform sky of radiance ``sky`` and a one-pixel sun holding ``share`` of a uniform sky of radiance 1's
    power, ``right_deg`` right of the map's centre, on the horizon (the centre column is the view at azimuth 0)."""
    env = np.full((h, 2 * h, 3), sky, np.float32)
    dirs, d_omega = envmap.directions_envmap(h), envmap.solid_angles_envmap(h)
    target = view_rotation(0, 0) @ np.array([-math.cos(math.radians(right_deg)), math.sin(math.radians(right_deg)), 0])
    r, c = np.unravel_index(np.argmax(dirs @ target), dirs.shape[:2])
    env[r, c] += share * 4 * math.pi / d_omega[r, c]
    return env


def test_a_sun_with_a_hundredth_of_the_light_still_gives_a_visible_rim():
    """The sunset map's case: the sun holds 1 % of the light; its rim is at least 0.4 of the person's front shading
    (the old rule, the sun's irradiance over the front's, gave 0.04), on the image's right."""
    pv = panorama_view(sunset_map(1.0), (160, 120), (0, 0))
    direction, rgb = pv.rim
    front = float(FRONT_WEIGHTS @ (pv.light @ REC709))
    assert direction[0] < -0.9 and direction[1] > 0.2
    assert float(rgb @ REC709) > 0.4 * front
    assert float(pv.source_shading @ REC709) < 0.1 * front  # what the old gain was


def test_the_rim_follows_the_sources_power_not_the_maps_mean():
    """The same sun under a sky 8 times as bright: the rim (in the map's units) is the same (within the sky's own
    radiance in the sun's pixel, 1.3 %); the sun twice as strong: twice the rim."""
    rot = view_rotation(0, 0)
    (_, dim), (_, bright) = panorama_rim(sunset_map(0.1), rot, 1.0), panorama_rim(sunset_map(0.8), rot, 1.0)
    np.testing.assert_allclose(dim, bright, rtol=0.03)
    _, double = panorama_rim(sunset_map(0.1, share=0.02), rot, 1.0)
    np.testing.assert_allclose(double, 2 * dim, rtol=0.03)


def test_no_rim_from_a_source_in_front_or_beside_and_the_rim_clips_at_white():
    assert not rim_colour([1.0, 1.0, 1.0], 0.001, [0.5, 0.0, 0.87]).any()  # in front of the person
    assert not rim_colour([1.0, 1.0, 1.0], 0.001, [0.0, 1.0, 0.0]).any()  # straight beside: the SH light's
    huge = rim_colour([1e6, 5e5, 1e5], 0.001, [-1.0, 0.0, 0.0])
    assert float(huge @ REC709) == pytest.approx(RIM_MAX) and huge[0] > huge[1] > huge[2]  # the source's colour
    p = [0.01, 0.01, 0.01]
    wide = rim_colour(p, 100 * LOBE_SR, [-1.0, 0.0, 0.0])  # wider than the lobe: its mean radiance
    np.testing.assert_allclose(wide, rim_colour(p, LOBE_SR, [-1.0, 0.0, 0.0]) / 100)
    np.testing.assert_allclose(rim_colour(p, LOBE_SR / 10, [-1.0, 0.0, 0.0]), rim_colour(p, LOBE_SR, [-1.0, 0.0, 0.0]))


def test_a_clipped_sun_in_a_photo_is_a_source_on_its_side_and_an_overcast_sky_is_not():
    photo = np.full((120, 160, 3), 90, np.uint8)
    photo[30:36, 120:126] = 255  # upper right
    direction, rgb = photo_rim(photo, 60.0)
    assert direction[0] < -0.8 and direction[1] > 0.2 and direction[2] > 0.1 and float(rgb @ REC709) > 0
    overcast = np.full((120, 160, 3), 90, np.uint8)
    overcast[:50] = 255  # a blown-out sky: no compact source
    assert photo_rim(overcast, 60.0) is None
    assert photo_rim(np.full((120, 160, 3), 90, np.uint8), 60.0) is None


def test_a_photos_clipped_source_gives_a_visible_rim_whatever_its_size_in_its_colour():
    """The clip hides a source's power (scene_rim's docstring): the rim of a clipped source is ``RIM_PHOTO`` times
    how far behind the person it stands, however few pixels clipped (read as the plate's white over its pixels, a
    36-pixel sun gave a rim of ~0.002, nothing to see), in the clipped pixels' colour."""
    photo = np.full((120, 160, 3), 90, np.uint8)
    photo[57:63, 77:83] = 255  # straight behind
    direction, rgb = photo_rim(photo, 60.0)
    assert float(rgb @ REC709) == pytest.approx(RIM_PHOTO * -direction[0], rel=1e-6) and -direction[0] > 0.99
    bigger = photo.copy()
    bigger[52:68, 72:88] = 255
    np.testing.assert_allclose(photo_rim(bigger, 60.0)[1], rgb, rtol=1e-3)
    warm = photo.copy()
    warm[57:63, 77:83] = (255, 252, 236)  # clipped in red only (>= 250 in its brightest channel)
    _, w = photo_rim(warm, 60.0)
    assert float(w @ REC709) == pytest.approx(float(rgb @ REC709), rel=1e-6) and w[0] > w[1] > w[2]
    aside = np.full((120, 160, 3), 90, np.uint8)
    aside[57:63, 150:156] = 255  # near the right border: less behind, a weaker rim
    d, a = photo_rim(aside, 60.0)
    assert float(a @ REC709) == pytest.approx(RIM_PHOTO * -d[0], rel=1e-6) and -d[0] < 0.9


def test_the_rim_is_added_so_a_dark_coat_gets_it_too():
    """The rim adds the source's radiance: the same absolute rim on a dark and a light body, on the source's side."""
    alpha = np.zeros((120, 120), np.float32)
    alpha[20:100, 40:80] = 1.0
    d = np.array([-0.96, 0.27, 0.09])
    d /= np.linalg.norm(d)
    rgb = np.array([0.3, 0.2, 0.1], np.float32)
    for level in (0.01, 0.3):
        out = key_rim(np.full((120, 120, 3), level, np.float32), alpha, d, rgb, 2.0, fibres=1.0)  # strands
        added = out[60, 79] - level
        assert added[0] > 0.5 * rgb[0] and added[0] > added[1] > added[2]
        far = out[60, 40] - level  # the left side: the body hides most of a source 16 degrees to the right
        assert (far >= 0).all() and far[0] < 0.15 * added[0] and out[60, 60] == pytest.approx(level)  # middle: none


def _box_rim(d, size=160):
    """The rim a unit grey source in ``d`` adds to a hard-edged box, at the middle of its four sides."""
    alpha = np.zeros((size, size), np.float32)
    alpha[30:130, 50:110] = 1.0
    out = key_rim(np.zeros((size, size, 3), np.float32), alpha, np.asarray(d) / np.linalg.norm(d), 1.0, 2.0)
    return {"top": out[30, 80, 0], "bottom": out[129, 80, 0], "left": out[80, 50, 0], "right": out[80, 109, 0]}


def test_a_source_straight_behind_lights_the_outline_all_round():
    """bl-sunrise_toward's sun (x = -0.99, its projection up a little): a rim on every side, most on the top. The old
    weight, max(0, n . p) with p the projection's unit vector, gave the top and nothing at the bottom, and jumped to
    the bottom as the sun crossed to a little below straight behind."""
    exact = _box_rim([-1.0, 0.0, 0.0])
    assert min(exact.values()) > 0.9 * max(exact.values()) > 0
    up = _box_rim([-0.99, 0.014, 0.139])
    assert up["top"] == max(up.values()) and min(up["left"], up["right"]) > 0.3 * up["top"] and up["bottom"] > 0
    down = _box_rim([-0.99, 0.014, -0.139])
    np.testing.assert_allclose([down["top"], down["bottom"]], [up["bottom"], up["top"]], rtol=0.02)  # continuous


def test_a_source_to_one_side_lights_that_side_at_todays_strength():
    """A sun 45 degrees right of straight behind: the right side gets the rim's full radiance (as the old weight
    gave it, times the band's weight), the top and bottom a little, the left none; the peak over the outline's
    directions is 1."""
    side, full = _box_rim([-0.707, 0.707, 0.0]), _box_rim([-1.0, 0.0, 0.0])["right"]  # the band's own weight
    assert side["right"] == pytest.approx(full, rel=0.01) and side["left"] < 0.01
    assert side["top"] < 0.2 * side["right"] and side["bottom"] == pytest.approx(side["top"], rel=0.05)
    round_ = np.linspace(0, 2 * math.pi, 720, endpoint=False)
    for d in ([-1.0, 0.0, 0.0], [-0.9, 0.3, 0.3], [-0.2, -0.5, 0.84]):
        d = np.asarray(d) / np.linalg.norm(d)
        assert float(rim_facing(np.cos(round_), np.sin(round_), d).max()) == pytest.approx(1.0, abs=1e-3)
    assert not rim_facing(np.cos(round_), np.sin(round_), [0.3, 0.95, 0.0]).any()  # in front: none


def test_straight_behind_is_along_each_points_own_ray():
    """A low sun straight behind a standing person's head (on the camera's axis, the head at the frame's centre): the
    head's sides glow as the source is straight behind them, the feet's sides far less (the sun is ~25 degrees above
    their rays) and the top of the head most; without the rays (every point on the axis) head and feet alike."""
    alpha = np.zeros((400, 120), np.float32)
    alpha[190:390, 40:80] = 1.0  # the head's top at the frame's centre (row 200), the feet 190 rows below
    focal = 400.0  # the window is the frame: its corner 200 rows, 60 columns before the centre
    zero = np.zeros((400, 120, 3), np.float32)
    on = key_rim(zero, alpha, np.array([-1.0, 0.0, 0.0]), 1.0, 2.0, view=(focal, -200.0, -60.0))[..., 0]
    flat = key_rim(zero, alpha, np.array([-1.0, 0.0, 0.0]), 1.0, 2.0)[..., 0]
    head, feet = on[200, 79], on[380, 79]
    assert head > 0.7 * flat[200, 79] and feet < 0.6 * head and on[190, 60] >= head
    assert flat[380, 79] == pytest.approx(flat[200, 79], rel=1e-3)


def _hair_on_top(size=160, ramp=10):
    """A box whose top edge is a wide soft ramp of alpha (strands) and whose other edges are hard."""
    alpha = np.zeros((size, size), np.float32)
    alpha[30:130, 50:110] = 1.0
    alpha[30 - ramp : 30, 50:110] = (np.arange(1, ramp + 1, dtype=np.float32) / (ramp + 1))[:, None]
    return alpha


def test_the_matte_tells_strands_from_a_smooth_edge():
    """fibre_share: a binary matte has no fibres; a matte soft on top (a ramp of 10 px) and hard elsewhere has them
    on top only; a matte soft everywhere alike has none (its own hard edge is that soft)."""
    hard = _hair_on_top(ramp=0)
    assert not fibre_share(hard).any()
    hair = fibre_share(_hair_on_top())
    assert hair[25, 80] == pytest.approx(1.0) and hair[80, 50] == 0 and hair[80, 109] == 0 and hair[129, 80] == 0
    even = cv2.GaussianBlur(hard, (0, 0), 3)
    assert fibre_share(even)[80, 50] < 0.2 and fibre_share(even)[30, 80] < 0.2


def test_a_back_light_glows_through_strands_and_only_grazes_a_smooth_edge():
    """A source straight behind: the strands on top take the full rim over their width; the hard sides keep a thin
    line (their outermost pixel lit, a third of the strands' light or less, nothing two pixels in). Without the
    rule every edge took the same wide band (sunset_toward: an orange outline down both legs)."""
    alpha = _hair_on_top()
    out = key_rim(np.zeros((160, 160, 3), np.float32), alpha, np.array([-1.0, 0.0, 0.0]), 1.0, 3.0)[..., 0]
    top = out[16:40, 80].sum()  # across the strands and the body's top
    side = out[80, 50:70].sum()  # across the left side
    assert side > 0.05 and side < 0.35 * top
    assert out[80, 50] > 0.1 and out[80, 53] < 0.01  # a line, not a band
    wide = key_rim(np.zeros((160, 160, 3), np.float32), alpha, np.array([-1.0, 0.0, 0.0]), 1.0, 3.0, fibres=1.0)
    assert wide[..., 0][80, 50:70].sum() > 2.5 * side  # the same edge taken as strands: the old wide band


def test_the_rim_follows_the_body_not_the_mattes_specks_and_holes():
    """A crumb of matte beside the body and a pinhole in it get no rim of their own (each took the rim's full
    radiance before: the rim drew the matte's fringes); the body's outline keeps its rim."""
    alpha = np.zeros((120, 120), np.float32)
    alpha[20:100, 40:80] = 1.0
    alpha[50:52, 90:92] = 1.0  # a crumb 10 px right of the body
    alpha[60:62, 70:72] = 0.0  # a pinhole 8 px inside its right edge
    out = key_rim(np.zeros((120, 120, 3), np.float32), alpha, np.array([-1.0, 0.0, 0.0]), 1.0, 3.0, fibres=1.0)
    edge = out[30, 79, 0]
    assert edge > 0.3
    assert out[50:52, 90:92, 0].max() < 0.05 * edge
    assert out[58:64, 68:74, 0].max() < 0.05 * edge and out[60:62, 70:72].max() == 0
    kept = body(alpha, 3.0)
    assert kept[50, 90] == 0 and kept[60, 70] == 1 and kept[30, 60] == 1
    blurred = cv2.GaussianBlur(alpha, (0, 0), 1.0)  # the pinhole a dip to ~0.6 after a camera's blur: still no rim
    assert blurred[60:62, 70:72].min() > 0.5
    soft = key_rim(np.zeros((120, 120, 3), np.float32), blurred, np.array([-1.0, 0.0, 0.0]), 1.0, 3.0, fibres=1.0)
    assert soft[58:64, 66:72, 0].max() <= soft[40:46, 66:72, 0].max() + 0.01  # what the body's edge gives anyway


def _disc(img, cy, cx, r, value):
    yy, xx = np.mgrid[: img.shape[0], : img.shape[1]]
    img[(yy - cy) ** 2 + (xx - cx) ** 2 <= r * r] = value


def test_a_clipped_sun_takes_its_colour_from_its_halo():
    """bl-sunrise_toward's case: the sun clipped white inside an orange glow. The clip carries no colour (its rim was
    white: R/B 1.0); the glow just outside it does: the rim is orange (R/B > 2), its luminance RIM_PHOTO as before.
    A white window in a dim wall (no bright glow round it) stays white."""
    photo = np.full((120, 160, 3), 60, np.uint8)
    _disc(photo, 50, 80, 9, (240, 150, 60))  # the glow, unclipped (brightest channel < 250)
    _disc(photo, 50, 80, 4, 255)  # the clipped disc
    direction, rgb = photo_rim(photo, 60.0)
    assert rgb[0] / rgb[2] > 2 and float(rgb @ REC709) == pytest.approx(RIM_PHOTO * -direction[0], rel=1e-6)
    window = np.full((120, 160, 3), 60, np.uint8)
    _disc(window, 50, 80, 9, (120, 80, 40))  # a dim orange wall round it
    _disc(window, 50, 80, 4, 255)
    _, white = photo_rim(window, 60.0)
    np.testing.assert_allclose(white / white.max(), 1.0, atol=1e-6)


def test_a_map_that_clips_gives_its_source_its_halos_colour():
    """A panorama whose sun clipped at a ceiling (a flat 3 x 3 of equal white values) in an orange halo: the rim takes
    the halo's colour at the sun's luminance; an unclipped sun (one peak pixel) keeps its own colour."""
    rot = view_rotation(0, 0)
    env = np.full((64, 128, 3), 0.2, np.float32)
    env[30:35, 62:67] = (400.0, 200.0, 60.0)  # the halo
    env[31:34, 63:66] = 1000.0  # the clipped sun, straight ahead of the camera: behind the person
    _, rgb = panorama_rim(env, rot, 1.0)
    assert rgb[0] / rgb[2] > 4
    env_white = env.copy()
    env_white[31:34, 63:66] = 0.0
    env_white[32, 64] = (9000.0, 8000.0, 7000.0)  # one bright pixel, not a ceiling: its own colour
    _, own = panorama_rim(env_white, rot, 1.0)
    assert own[0] / own[2] < 1.6


def test_the_fibres_are_read_on_the_photo_and_placed_with_the_person():
    """composite reads the fibres on the person's own matte and puts them where ``place`` puts the person: the soft
    top of the matte (at half size here) is strands, its hard sides are not, and ``fibres_in`` cuts the placed map to
    a window of the frame."""
    from relight_rt.apps.scene_place import place

    alpha = _hair_on_top()
    rgba = np.dstack([np.full(alpha.shape + (3,), 0.3, np.float32), alpha])
    placed = place(rgba, (400, 400, 3), position=(0.5, 0.9), height=0.3)
    patch = fibre_patch(alpha, placed)
    assert patch.shape == (placed.height, placed.width)
    assert patch[:4, placed.width // 2].max() > 0.9  # the strands on top, at the box's top
    assert patch[placed.height // 2, :3].max() < 0.1 and patch[placed.height // 2, -3:].max() < 0.1  # hard sides
    window = (placed.top - 5, placed.top + 20, placed.left - 7, placed.left + placed.width + 7)
    cut = fibres_in(patch, (placed.top, placed.left), window)
    assert cut.shape == (25, placed.width + 14)
    np.testing.assert_array_equal(cut[5:, 7:-7], patch[:20])
    assert not cut[:5].any() and not cut[:, :7].any()
