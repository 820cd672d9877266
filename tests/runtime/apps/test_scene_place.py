"""relight_rt.apps.scene_place: how a photo framed its person and where they go in another scene (synthetic mattes)."""

import cv2
import numpy as np
import pytest
from _graphs import diffuse_models_dir

from relight_rt import RelightError
from relight_rt.apps.scene_place import (
    CAMERA_M,
    DEFAULT_FEET,
    PERSON_M,
    check_camera_height,
    framing,
    place,
)

__all__ = ["diffuse_models_dir"]  # fixtures


def figure(h=200, w=120, top=20, bottom=180, arm=False):
    """A straight-alpha RGBA stick figure: a body at columns 50-70, legs 48-56 and 64-72 below row 120 (feet
    centred at column 60); ``arm``: a long arm out to the right, columns 70-118, rows 60-70."""
    rgba = np.zeros((h, w, 4), np.float32)
    rgba[..., :3] = (0.5, 0.4, 0.3)
    rgba[top:min(bottom, 120), 50:70, 3] = 1
    rgba[120:bottom, 48:56, 3] = 1
    rgba[120:bottom, 64:72, 3] = 1
    if arm:
        rgba[60:70, 70:118, 3] = 1
    return rgba


def legs_x(placed):
    """The frame column of the centre of the placed person's bottom rows (their feet), from their pixels."""
    sole = placed.premult[-3:, :, 3].sum(axis=0)
    return placed.left + float(sole @ (np.arange(sole.size) + 0.5) / sole.sum())


def test_framing_finds_the_borders_that_cut_the_person():
    a = figure()[..., 3]
    assert framing(a).cut == frozenset() and framing(a).full_body
    half = figure(bottom=200)[..., 3]  # the legs run off the bottom
    assert framing(half).cut == {"bottom"} and not framing(half).full_body
    side = half.copy()
    side[60:200, 0:60] = 1  # and off the left border
    assert framing(side).cut == {"bottom", "left"}
    wisp = a.copy()
    wisp[199, 30] = 1  # one stray pixel on the bottom row, and a faint haze along it
    wisp[199, :] = np.maximum(wisp[199, :], 0.3)
    assert framing(wisp).full_body


def test_the_feet_are_under_the_legs_not_the_box():
    fr = framing(figure(arm=True)[..., 3])
    y0, y1, x0, x1 = fr.box
    assert (x0 + x1) / 2 == pytest.approx(83)  # the arm pulls the box's centre to the right
    assert fr.feet_x == pytest.approx(60, abs=0.5) and fr.feet_width == pytest.approx(24, abs=1)


def test_a_full_body_stands_its_feet_where_asked_and_scales_with_the_camera_height():
    rgba = figure(arm=True)
    placed = place(rgba, (300, 400, 3), (0.25, 0.9), None, 0.5)
    assert placed.full_body and placed.feet_y == 270
    assert legs_x(placed) == pytest.approx(100, abs=1)  # the legs, not the box's centre, stand at x = 0.25
    assert placed.feet_x == pytest.approx(100, abs=0.5)
    assert placed.height == round((0.9 - 0.5) * 300 * PERSON_M / CAMERA_M)
    low = place(rgba, (300, 400, 3), (0.25, 0.9), None, 0.5, camera_height=2 * CAMERA_M)
    assert low.height == pytest.approx(placed.height / 2, abs=1)  # twice as high a camera: the feet twice as far
    default = place(figure(), (300, 400, 3), None, None, 0.5)
    assert default.feet_y == round(DEFAULT_FEET * 300) and default.feet_x == pytest.approx(60 / 120 * 400, abs=0.5)


@pytest.mark.parametrize("bg", [(300, 400), (400, 300), (200, 600)])
def test_a_half_body_is_cut_by_the_same_borders(bg):
    hb, wb = bg
    rgba = figure(bottom=200)
    rgba[60:200, 0:60, 3] = 1  # cut by the bottom and the left border of its 200 x 120 photo
    placed = place(rgba, (hb, wb, 3))
    assert not placed.full_body
    assert placed.top + placed.height == hb and placed.left == 0  # the cut edges on the same borders
    assert placed.height == round(180 * hb / 200)  # its relative height kept
    right = place(rgba[:, ::-1], (hb, wb, 3))
    assert right.left + right.width == wb and right.top + right.height == hb


@pytest.mark.parametrize("bg, reach", [((300, 400), True), ((400, 300), True), ((150, 600), False)])
def test_a_portrait_cut_at_both_sides_reaches_both_borders_if_its_face_stays(bg, reach):
    from relight_rt.apps.scene_place import HEAD_ROOM

    hb, wb = bg
    rgba = np.zeros((200, 200, 4), np.float32)
    rgba[40:, :, 3] = 1  # shoulders through both side borders and the bottom: a portrait
    rgba[10:40, 75:125, 3] = 1  # the head, whole, 10 rows below the top
    placed = place(rgba, (hb, wb, 3))
    assert placed.top + placed.height == hb  # on the bottom border
    assert (placed.left <= 0 and placed.left + placed.width >= wb) == reach  # the cut sides on both borders
    assert placed.top >= -HEAD_ROOM * placed.height - 1  # the face kept
    assert abs(placed.left + placed.width / 2 - wb / 2) <= 1  # centred, as its photo framed it
    if not reach:  # a tall portrait in a wide strip: its photo's framing, the head whole
        assert placed.top >= 0 and placed.height == round(190 * hb / 200)


def test_a_person_not_cut_at_a_side_stays_whole_in_the_picture():
    rgba = figure(bottom=200)  # cut by the bottom only, near its photo's right
    rgba = np.roll(rgba, 45, axis=1)
    placed = place(rgba, (300, 200, 3))
    assert placed.left >= 0 and placed.left + placed.width <= 200


def test_bad_camera_heights():
    assert check_camera_height("1.2") == 1.2
    for bad in ("low", "nan", 0, -1, 1e4):
        with pytest.raises(RelightError, match="camera height"):
            check_camera_height(bad)


def test_the_contact_shadow_lies_under_the_feet_and_is_foreshortened():
    from relight_rt.apps.scene import SceneLighting, shade, shadows

    placed = place(figure(arm=True), (300, 400, 3), (0.5, 0.9), 0.5, 0.5)
    none = SceneLighting(np.zeros((9, 3), np.float32), np.zeros((9, 3), np.float32), None, 0.0)
    cast = shadows(placed, (300, 400, 3), 0.5, 60.0, none)
    assert cast.foot[0] == pytest.approx(legs_x(placed), abs=1) == 200  # under the legs, not the arm-wide box
    lin = np.ones((300, 400, 3), np.float32)
    shade(lin, (0, 0), cast)
    row = lin[int(cast.foot[1]), :, 0]
    dark = np.flatnonzero(row < 0.9)
    assert abs((dark[0] + dark[-1]) / 2 - 200) <= 2  # centred under the feet
    cols = np.flatnonzero(lin[:, 200, 0] < 0.9)
    assert cols.size < dark.size / 2  # flatter than wide: ground seen at a slant
    near = place(figure(), (300, 400, 3), (0.5, 0.98), 0.5, 0.5)
    far = place(figure(), (300, 400, 3), (0.5, 0.7), 0.5, 0.5)
    (w0, h0), (w1, h1) = (shadows(p, (300, 400, 3), 0.5, 60.0, none).size for p in (near, far))
    assert h0 / w0 == pytest.approx(2.4 * h1 / w1, rel=0.05)  # the ground 2.4x as far below the horizon


def poles(tilt_deg: float, size=(640, 480), fov=60.0, seed=0) -> np.ndarray:
    """A street of vertical poles (and a few slanted distractors) seen by a camera 1.5 m up, tilted by tilt_deg
    (up positive), no roll: 8-bit RGB. Its horizon lies at (h/2 + f tan t) / h."""
    w, h = size
    f = (w / 2) / np.tan(np.radians(fov) / 2)
    t = np.radians(tilt_deg)
    img = np.full((h, w, 3), 70, np.uint8)
    rng = np.random.default_rng(seed)

    def project(x, y_up, z):  # world: x right, y up (from the camera's height), z ahead
        yc = -(y_up * np.cos(t) - z * np.sin(t))
        zc = y_up * np.sin(t) + z * np.cos(t)
        return int(round(w / 2 + f * x / zc)), int(round(h / 2 + f * yc / zc))

    for _ in range(14):
        x, z = rng.uniform(-8, 8), rng.uniform(6, 30)
        cv2.line(img, project(x, -1.5, z), project(x, rng.uniform(1, 6), z), (230, 220, 200), 3, cv2.LINE_AA)
    for _ in range(4):  # not verticals of the world
        a = rng.uniform(0, w, 2).astype(int)
        cv2.line(img, (int(a[0]), 20), (int(a[1]), h - 20), (20, 20, 20), 2, cv2.LINE_AA)
    return img


@pytest.mark.parametrize("tilt", [-12.0, 0.0, 8.0, 15.0])
def test_the_horizon_is_found_from_the_verticals(tilt):
    from relight_rt.apps.scene_place import estimate_horizon

    w, h = 640, 480
    f = (w / 2) / np.tan(np.radians(30))
    truth = (h / 2 + f * np.tan(np.radians(tilt))) / h
    assert estimate_horizon(poles(tilt), 60.0) == pytest.approx(truth, abs=0.03)


def test_no_verticals_no_horizon():
    from relight_rt.apps.scene_place import estimate_horizon

    flat = np.full((240, 320, 3), 120, np.uint8)
    flat[:100] = 200  # a skyline is not a vertical
    assert estimate_horizon(flat) is None


def test_composite_stands_the_person_on_the_estimated_horizons_ground(diffuse_models_dir):
    """A camera turned up (verticals converging upward) sees the horizon low: the person's height follows it."""
    from relight_rt import Relighter, RuntimeConfig
    from relight_rt.apps.scene import composite
    from relight_rt.apps.scene_place import estimate_horizon

    r = Relighter(RuntimeConfig(models=diffuse_models_dir, device="cpu", detail=False))
    img = np.full((150, 100, 3), (150, 110, 90), np.uint8)
    mask = np.zeros((150, 100), np.float32)
    mask[20:140, 30:70] = 1.0
    bg = poles(10.0, size=(320, 240))
    found = estimate_horizon(bg)
    assert found is not None and found > 0.6
    kw = {"mask": mask, "meter": "background", "shadow": False, "match_camera": False, "light_wrap": False}
    np.testing.assert_array_equal(composite(r, img, bg, **kw), composite(r, img, bg, horizon=found, **kw))
    assert not np.array_equal(composite(r, img, bg, **kw), composite(r, img, bg, horizon=0.5, **kw))


def launch_pad(tilt=8.0, fov=35.0, size=(640, 480), sky_to=None, backdrop=False, towers=True):
    """``poles`` (a camera turned up ``tilt`` degrees, its horizontal field of view ``fov``) without the slanted
    distractors, over a twilight sky, dark blue and smooth, down to the horizon (or the row fraction ``sky_to``)
    and dark, textured ground with a few bright lamps below it, as a launch pad at dusk is photographed;
    ``backdrop``: the blue runs down to the bottom edge (no ground); ``towers=False``: no poles, nothing vertical.
    Returns the picture and its true horizon."""
    w, h = size
    f = (w / 2) / np.tan(np.radians(fov) / 2)
    truth = (h / 2 + f * np.tan(np.radians(tilt))) / h
    edge = truth if sky_to is None else sky_to
    img = poles(tilt, size=size, fov=fov) if towers else np.zeros((h, w, 3), np.uint8)
    rows = np.arange(h, dtype=np.float32)[:, None] / h
    sky = np.array([25, 40, 95], np.float32) + rows[..., None] * np.array([30, 45, 60], np.float32)
    ground = np.random.default_rng(1).uniform(10, 45, (h, w, 1)).astype(np.float32).repeat(3, axis=2)
    back = np.broadcast_to(sky, (h, w, 3)) if backdrop else np.where(rows[..., None] < edge, sky, ground)
    out = np.where(img.mean(axis=2, keepdims=True) > 110, img, back).astype(np.uint8)  # the poles, nothing else
    if not backdrop:
        for x in range(40, w, 90):  # lamps on the ground line
            cv2.circle(out, (x, int(edge * h) + 8), 4, (255, 240, 200), -1)
    return out, truth


def test_no_sky_below_the_horizon():
    """A camera turned up with a longer lens than the 60° guessed: the verticals read its horizon too high (how
    far scales with the focal length squared); the sky line (no sky is seen below the horizon) puts it lower,
    near the true one."""
    from relight_rt.apps.scene_place import HORIZON_ESTIMATE_MAX, estimate_horizon, find_horizon, sky_line

    bg, truth = launch_pad(8.0, 35.0)
    assert truth == pytest.approx(0.797, abs=0.001)
    assert estimate_horizon(bg, 60.0) < truth - 0.15
    line = sky_line(bg)
    assert truth - 0.03 < line <= truth + 0.01  # a bound: at most the sky's lowest row
    assert find_horizon(bg, 60.0) == line
    assert find_horizon(launch_pad(8.0, 35.0, sky_to=0.96)[0], 60.0) == HORIZON_ESTIMATE_MAX  # ground below it
    # no ground under it: a backdrop, not a sky; a grey wall over a floor as bright: not a sky either
    assert sky_line(launch_pad(8.0, 35.0, backdrop=True)[0]) is None
    wall = np.full((240, 320, 3), 180, np.uint8)
    wall[170:] = np.random.default_rng(2).uniform(120, 200, (70, 320, 1)).astype(np.uint8)
    assert sky_line(wall) is None
    # the verticals see the camera turned down: sky below their horizon contradicts them, and they stand
    down, _ = launch_pad(-10.0, 60.0, sky_to=0.6)
    assert 0.55 < sky_line(down) <= 0.61
    assert find_horizon(down, 60.0) == pytest.approx(estimate_horizon(down, 60.0))
    # no verticals: the sky line alone is not trusted (walls, curtains and seas read as sky), a level camera's 0.5
    open_sky, truth = launch_pad(8.0, 35.0, towers=False)
    assert estimate_horizon(open_sky, 60.0) is None and sky_line(open_sky) > 0.75
    assert find_horizon(open_sky, 60.0) == 0.5


def test_sky_line_inputs():
    from relight_rt.apps.scene_place import sky_line

    bg, _ = launch_pad(8.0, 35.0, size=(320, 240))
    assert sky_line(bg.astype(np.float32) / 255) == pytest.approx(sky_line(bg), abs=0.01)
    assert sky_line(bg[:2, :2]) is None  # tiny: no room for a run
    for bad in (bg[..., 0], bg[..., :2], np.zeros((1, 5, 3), np.uint8)):
        with pytest.raises(RelightError, match="sky line: expected an"):
            sky_line(bad)


def test_composite_keeps_the_feet_out_of_the_sky(diffuse_models_dir):
    """composite's default horizon is find_horizon's: on the launch pad the person is as small as the ground's
    distance makes them, not a giant standing in the sky above the lamps."""
    from relight_rt import Relighter, RuntimeConfig
    from relight_rt.apps.scene import composite
    from relight_rt.apps.scene_place import estimate_horizon, find_horizon

    r = Relighter(RuntimeConfig(models=diffuse_models_dir, device="cpu", detail=False))
    img = np.full((150, 100, 3), (150, 110, 90), np.uint8)
    mask = np.zeros((150, 100), np.float32)
    mask[20:140, 30:70] = 1.0
    bg, truth = launch_pad(8.0, 35.0, size=(320, 240))
    hz = find_horizon(bg)
    assert hz > estimate_horizon(bg) + 0.1
    kw = {"mask": mask, "meter": "background", "shadow": False, "match_camera": False, "light_wrap": False}
    out = composite(r, img, bg, **kw)
    np.testing.assert_array_equal(out, composite(r, img, bg, horizon=hz, **kw))
    person = np.flatnonzero((np.abs(out - bg / 255).max(axis=2) > 0.05).any(axis=1))
    assert person[0] > (truth - 0.1) * 240  # the head near the horizon (a standing camera), none of them in the sky
