"""``relight.compose.shown_edge``: over the photo's own background, a matte softer than the photo's edge gives way to
the edge the photo's colours show (look24: a relit person's change had spread past a sharp outline as a halo)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from _graphs import models_dir

from relight_rt import Relighter, RuntimeConfig, lights
from relight_rt.image.compositing import Background
from relight_rt.relight import compose
from relight_rt.relight.compose import colours_of, shown_edge

__all__ = ["models_dir"]  # fixture

H, W, EDGE = 64, 96, 48  # the photo's edge: the columns left of EDGE are the person


def _feathered(sigma: float) -> np.ndarray:
    """A matte whose outline lies on the photo's edge, blurred across it by ``sigma`` px."""
    hard = np.zeros((H, W), np.float32)
    hard[:, :EDGE] = 1
    return cv2.GaussianBlur(hard, (0, 0), sigma)


def _two_colours(person=(0.25, 0.15, 0.1), background=(0.9, 0.92, 0.95), blur: float = 0.0) -> np.ndarray:
    img = np.empty((H, W, 3), np.float32)
    img[:, :EDGE], img[:, EDGE:] = person, background
    return cv2.GaussianBlur(img, (0, 0), blur) if blur else img


def _soft(alpha: np.ndarray) -> np.ndarray:
    return (alpha > 1 / 255) & (alpha < 254 / 255)


def test_a_feathered_matte_over_a_sharp_edge_follows_the_photo():
    image, alpha = _two_colours(), _feathered(3.0)
    shown, behind = shown_edge(image, alpha, image)
    outside = _soft(alpha) & (np.arange(W) >= EDGE + 1)[None, :]
    inside = _soft(alpha) & (np.arange(W) < EDGE - 1)[None, :]
    assert alpha[outside].mean() > 0.1 and alpha[inside].mean() < 0.9  # the matte's feather, both sides
    assert shown[outside].max() < 0.05 and shown[inside].min() > 0.95


def test_the_photo_is_given_back_under_its_own_light():
    rng = np.random.default_rng(3)
    image = np.clip(_two_colours() + 0.01 * rng.standard_normal((H, W, 3)), 0, 1).astype(np.float32)
    alpha = _feathered(3.0)
    fg, _ = colours_of(image, alpha, multilevel=True)  # the person's own colour as a photo's relighting takes it
    shown, behind = shown_edge(image, alpha, fg)
    assert np.abs(shown - alpha).max() > 0.2  # the edge did move
    again = shown[..., None] * fg + (1 - shown[..., None]) * behind
    # within a level: a pixel the rule leaves at alpha <= 1/255 keeps the photo behind it (as ``consistent`` does)
    np.testing.assert_allclose(again, image, atol=1 / 255)


def test_a_real_blur_keeps_its_matte():
    """Where the photo's edge is as soft as the matte (defocus), colour agrees with the matte and nothing moves."""
    alpha = _feathered(3.0)
    shown, _ = shown_edge(_two_colours(blur=3.0), alpha, _two_colours())
    soft = _soft(alpha)
    assert np.abs(shown - alpha)[soft].max() < 0.06


@pytest.mark.parametrize("noise", [0.05, 0.1])
def test_colour_that_cannot_tell_the_sides_apart_moves_nothing_much(noise):
    """The same texture on both sides (noise about one mean): colour has no word, the matte stays."""
    rng = np.random.default_rng(7)
    image = np.clip(0.5 + noise * rng.standard_normal((H, W, 3)), 0, 1).astype(np.float32)
    alpha = _feathered(3.0)
    shown, _ = shown_edge(image, alpha, image)
    soft = _soft(alpha)
    assert np.abs(shown - alpha)[soft].mean() < 0.02
    assert np.abs(shown - alpha)[soft].max() < 0.15


def test_alike_colours_move_nothing():
    """A dark coat before a dark doorway: |F - B| too small for colour to say where the edge is."""
    alpha = _feathered(3.0)
    image = _two_colours(person=(0.1, 0.1, 0.1), background=(0.12, 0.11, 0.1))
    shown, _ = shown_edge(image, alpha, image)
    assert np.abs(shown - alpha).max() < 0.01


def test_a_hard_matte_is_left_alone():
    alpha = np.zeros((H, W), np.float32)
    alpha[:, :EDGE] = 1
    image = _two_colours()
    shown, behind = shown_edge(image, alpha, image)
    assert shown is alpha and behind is None


def _portrait() -> tuple[np.ndarray, np.ndarray]:
    """A dark rectangle "person" before a plain pale wall with a sharp outline, and a matte feathered 4 px past it."""
    h, w, box = 150, 100, (20, 140, 30, 70)
    img = np.empty((h, w, 3), np.float32)
    img[...] = (0.85, 0.85, 0.8)
    hard = np.zeros((h, w), np.float32)
    y0, y1, x0, x1 = box
    img[y0:y1, x0:x1] = (0.35, 0.25, 0.2)
    hard[y0:y1, x0:x1] = 1
    return img, np.clip(cv2.GaussianBlur(hard, (0, 0), 4.0), 0, 1)


def test_only_the_automatic_matte_takes_the_shown_edge(models_dir):
    """Photos matted automatically composite over the edge the photo shows; a given mask (the user's word) is kept,
    and the wall beside a sharp outline is left as it was by a light that darkens the person."""
    img, soft = _portrait()
    relighter = Relighter(RuntimeConfig(models=str(models_dir), device="cpu"), matter=lambda rgb, name="image": soft)
    auto, given = relighter.decompose(img), relighter.decompose(img, soft)
    assert auto.edge is not None and given.edge is None
    np.testing.assert_array_equal(auto.mask, given.mask)  # the matte itself is not changed
    y0, _, x0, _ = auto.geometry.box  # the edge lies in the crop box
    row = auto.edge[80 - y0, 60 - x0 : 80 - x0]  # x 60-69 person, 70-79 wall
    assert row[12:16].max() < 0.01 < 0.05 < soft[80, 72:76].min()  # the wall is wall, where the matte feathers onto it
    assert (row[:10] >= soft[80, 60:70] - 1e-6).all()  # and the person no less the person
    light = lights.directional((0.3, 1.0, 0.2), (1, 1, 1), 1.0) + lights.ambient(0.02)
    wall = np.zeros(img.shape[:2], bool)
    wall[20:140, 72:80] = True  # the wall beside the outline the matte feathers onto (x 70 is the outline)
    change = {k: np.abs(np.asarray(relighter.relight(d, light)) - img).max(axis=2)[wall].max()
              for k, d in (("auto", auto), ("given", given))}
    assert change["given"] > 0.005  # the feathered matte carries the person's change onto the wall ...
    assert change["auto"] < 0.3 * change["given"]  # ... which the shown edge leaves (mostly) as the photo has it


def test_a_graded_background_under_the_photos_own_light_is_the_photo(models_dir):
    """The background's grade compares the relit person with their own colour over one matte (``own_light``'s):
    measured over the shown edge on one side and the matte on the other, the photo's own light had moved the whole
    background by about a level."""
    img, soft = _portrait()
    relighter = Relighter(RuntimeConfig(models=str(models_dir), device="cpu"), matter=lambda rgb, name="image": soft)
    dec = relighter.decompose(img)
    assert dec.edge is not None
    out = np.asarray(relighter.relight(dec, dec, background=Background.original(grade=True)))
    np.testing.assert_allclose(out, img, atol=0.5 / 255)


def _shoe_on_a_glossy_floor() -> tuple[np.ndarray, np.ndarray]:
    """A pale shoe (the columns left of EDGE) with a dark sole line on a white glossy floor whose reflection fades
    from the shoe's colour over 6 px (colours on the line between floor and shoe: colour alone reads them as a
    partly covered floor), and a matte whose soft rim runs 8 px either side of the sole (issue 48's clip)."""
    shoe, floor = np.array((0.9, 0.76, 0.68), np.float32), np.array((0.98, 0.94, 0.92), np.float32)
    img = np.empty((H, W, 3), np.float32)
    img[:, :EDGE], img[:, EDGE:] = shoe, floor
    img[:, EDGE - 1 : EDGE + 1] = (0.3, 0.23, 0.2)  # the sole: the photo's edge, two pixels wide
    for i, t in enumerate(np.linspace(0.3, 0.0, 6)):
        img[:, EDGE + 1 + i] = floor + t * (shoe - floor)
    x = np.arange(W, dtype=np.float32)
    alpha = np.broadcast_to(np.clip((EDGE + 8 - x) / 16, 0, 1), (H, W)).astype(np.float32)
    return img, alpha


def test_a_wide_rim_past_a_sharp_edge_steepens_where_colour_cannot_tell(monkeypatch):
    """The reflection's colours lie between the floor's and the shoe's, so colour keeps the matte's rim there; the
    photo's sharp sole says the rim is 8 x too wide, and its outer half gives way beyond the sole."""
    image, alpha = _shoe_on_a_glossy_floor()
    fg, _ = colours_of(image, alpha, multilevel=True)
    shown, _ = shown_edge(image, alpha, fg)
    beyond = slice(EDGE + 2, EDGE + 8)  # the floor and its reflection, past the sole
    assert alpha[:, beyond].min() > 0.05 and shown[:, beyond].max() < 0.01
    assert (shown[:, :EDGE - 1] >= alpha[:, :EDGE - 1] - 1e-6).all()  # the shoe keeps (at least) its matte
    monkeypatch.setattr(compose, "_steepened", lambda image, alpha, outer, r, b_sums: alpha[outer])
    colour_only, _ = shown_edge(image, alpha, fg)
    assert colour_only[:, beyond].mean() > 0.05  # colour alone leaves the rim on the reflection


def test_steepening_follows_the_ratio_of_the_photos_edge_to_the_rims():
    """A 3-px feather over a photo blurred as much keeps its rim; over a hard step, the rim's outer half goes; with
    the step only half the rim's slope wider, partly."""
    alpha = _feathered(3.0)
    soft = _soft(alpha)
    outer = soft & (alpha < 0.5)
    r = 3 * 3

    def steepened(image: np.ndarray) -> np.ndarray:
        b_sums = compose._side_sums(image, alpha <= 1 / 255, r)
        out = np.array(alpha)
        out[outer] = compose._steepened(image, alpha, outer, r, b_sums)
        return out

    blurred, sharp = steepened(_two_colours(blur=3.0)), steepened(_two_colours())
    half = steepened(_two_colours(blur=1.5))
    assert np.abs(blurred - alpha).max() < 0.02
    assert sharp[:, EDGE + 2 :].max() < 0.01 < alpha[:, EDGE + 2].min()
    moved = lambda a: (alpha - a)[outer].sum()  # noqa: E731
    assert 0.1 * moved(sharp) < moved(half) < 0.9 * moved(sharp)
    for a in (blurred, sharp, half):  # never above the matte, never below 0
        assert (a <= alpha + 1e-7).all() and (a >= 0).all()


def test_a_plateau_of_low_alpha_far_from_the_outline_is_left_as_it_was():
    """A matte that stays at 0.3 for 40 px past a sharp outline instead of ramping down (a matte already poor there,
    people_masks' p272 and p289): the rule steepens the rim by its 0.5 line and fades out with the distance from it
    (by the reach r), so the plateau beyond is kept and what it lowers joins it gradually, not with a straight,
    box-shaped border where the window's square reach ends (edge25r: 0 within r, 0.3 beyond)."""
    r = 9
    alpha = _feathered(3.0)
    rows, plateau = slice(24, 40), slice(EDGE + 2, W - 4)
    alpha[rows, plateau] = np.maximum(alpha[rows, plateau], 0.3)
    image = _two_colours()
    outer = _soft(alpha) & (alpha < 0.5)
    out = np.array(alpha)
    out[outer] = compose._steepened(image, alpha, outer, r, compose._side_sums(image, alpha <= 1 / 255, r))
    assert (out[rows, EDGE + 2] < alpha[rows, EDGE + 2] - 0.2).all()  # the rim by the outline still gives way
    far = (slice(24, 40), slice(EDGE + r, W - 4))  # r px and more from the 0.5 line (column EDGE - 1)
    np.testing.assert_allclose(out[far], alpha[far], atol=1e-6)
    assert np.abs(np.diff(out[rows, EDGE + 2 : W - 4], axis=1)).max() < 0.12  # a ramp, not a step of 0.3
    assert (out <= alpha + 1e-7).all() and (out >= 0).all()


def _without_steepening(image: np.ndarray, alpha: np.ndarray, monkeypatch) -> tuple[np.ndarray, np.ndarray]:
    """``shown_edge``'s alpha' with the rim rule and with colour alone (``_steepened`` switched off)."""
    fg, _ = colours_of(image, alpha, multilevel=True)
    with_rule, _ = shown_edge(image, alpha, fg)
    with monkeypatch.context() as m:
        m.setattr(compose, "_steepened", lambda image, alpha, outer, r, b_sums: alpha[outer])
        colour_only, _ = shown_edge(image, alpha, fg)
    return with_rule, colour_only


@pytest.mark.parametrize("column, colour", [(EDGE + 7, (0.2, 0.2, 0.2)), (EDGE - 6, (0.95, 0.95, 0.95))])
def test_a_sharp_line_beside_a_blurred_edge_is_not_the_persons_edge(column, colour, monkeypatch):
    """A defocused or moving limb (the photo's edge as soft as the matte's feather) with a sharp line a few pixels
    off the outline, a door frame behind it or a seam on the person: the photo's edge at the outline is soft, so
    the rim stays (the steepest step anywhere within reach had cut the whole outer half)."""
    image, alpha = _two_colours(blur=3.0), _feathered(3.0)
    image[:, column] = colour
    with_rule, colour_only = _without_steepening(image, alpha, monkeypatch)
    assert np.abs(with_rule - colour_only).max() < 0.05


def test_a_matte_inside_a_sharp_edge_keeps_the_persons_own_pixels(monkeypatch):
    """The matte's 0.5 contour 2 px inside the photo's sharp edge (a matte too tight): the pixels between are the
    person's, and the rule, which steepens about the matte's contour, does not take them out."""
    hard = np.zeros((H, W), np.float32)
    hard[:, : EDGE - 2] = 1
    alpha = cv2.GaussianBlur(hard, (0, 0), 3.0)
    with_rule, colour_only = _without_steepening(_two_colours(), alpha, monkeypatch)
    person = slice(EDGE - 2, EDGE)
    assert alpha[:, person].min() > 0.15  # the person's own pixels, which the matte holds partly
    assert (with_rule[:, person] >= colour_only[:, person] - 0.02).all()


def test_the_relit_change_stays_off_the_floor_past_a_sharp_edge(models_dir):
    """End to end: the automatic matte's wide rim over the glossy floor; a light that darkens the shoe leaves the
    floor past the sole within a level of the photo (the given mask, the user's word, keeps its rim)."""
    img, soft = _shoe_on_a_glossy_floor()
    relighter = Relighter(RuntimeConfig(models=str(models_dir), device="cpu"), matter=lambda rgb, name="image": soft)
    auto, given = relighter.decompose(img), relighter.decompose(img, soft)
    light = lights.directional((0.8, 0.3, 0.5), (0.2, 0.4, 1.0), 1.0) + lights.ambient(0.02)
    floor = np.zeros(img.shape[:2], bool)
    floor[4:-4, EDGE + 2 : EDGE + 8] = True
    change = {k: 255 * np.abs(np.asarray(relighter.relight(d, light)) - img).max(axis=2)[floor].max()
              for k, d in (("auto", auto), ("given", given))}
    assert change["given"] > 5  # the rim carries the shoe's new light onto the floor ...
    assert change["auto"] < 1  # ... which the shown edge, steepened by the photo's sharp sole, does not


@pytest.mark.parametrize("pixels", [97 * 6, 97 * 16, 97 * 200])
def test_bands_give_the_whole_boxs_values(pixels):
    """A group's box is worked on a band of rows at a time (``shown_edge_bands``): the same alpha' and colour behind
    as the whole box at once, bit for bit, whatever the band's height (odd sizes: the half-resolution rows)."""
    rng = np.random.default_rng(5)
    h, w = 121, 97
    hard = np.zeros((h, w), np.float32)
    for cy, cx, rad in ((30, 25, 18), (80, 60, 25), (110, 15, 12)):  # three people, one cut by the box's edge
        hard[(np.arange(h)[:, None] - cy) ** 2 + (np.arange(w)[None, :] - cx) ** 2 < rad * rad] = 1
    alpha = cv2.GaussianBlur(hard, (0, 0), 2.5)
    image = np.where(hard[..., None] > 0, np.float32([0.3, 0.2, 0.1]), np.float32([0.85, 0.9, 0.95]))
    image = np.clip(image + 0.03 * rng.standard_normal((h, w, 3)), 0, 1).astype(np.float32)
    fg, _ = colours_of(image, alpha, multilevel=True)
    shown, behind = shown_edge(image, alpha, fg)
    assert behind is not None and np.abs(shown - alpha).max() > 0.05  # the rule moved the edge
    bands = list(compose.shown_edge_bands(image, alpha, lambda a, b: fg[a:b], pixels))
    assert len(bands) == -(-h // max(2, pixels // w // 2 * 2)) and bands[-1][1] == h
    np.testing.assert_array_equal(np.concatenate([b[2] for b in bands]), shown)
    np.testing.assert_array_equal(np.concatenate([b[3] for b in bands]), behind)


def test_bands_see_the_solid_pixels_the_whole_box_sees_past_the_reach():
    """A wide soft person far above sets a reach r > 42 px, where cv2.distanceTransform's 3 x 3 chamfer (0.955 px a
    step along an axis) puts a hard-edged solid patch r + 2 px left of a poor matte's plateau within r of it: the
    band of rows holding the plateau crops its distances to as many solid pixels as the whole box does (it cropped
    at r + 1 px from its own rim, leaving the patch out: 0.0076 apart)."""
    h, w, yp, xp = 800, 560, 480, 300
    yy, xx = np.mgrid[:h, :w]
    hard = ((yy - 120) ** 2 + (xx - 120) ** 2 < 70 ** 2).astype(np.float32)
    alpha = cv2.GaussianBlur(hard, (0, 0), 14)
    alpha[yp : yp + 24, xp : xp + 24] = 0.2  # a plateau, no solid pixel of its own
    r = 59
    for rows, cols in (((yp - 10, yp + 40), (xp - r - 42, xp - r - 1)),  # the patch, r + 2 px left of the plateau
                       ((yp - r - 29, yp - r + 2), (xp + r - 1, xp + r + 29))):  # a solid corner in its window
        alpha[slice(*rows), slice(*cols)] = hard[slice(*rows), slice(*cols)] = 1
    assert compose.edge_reach(alpha) == r
    image = np.where(hard[..., None] > 0, np.float32([0.2, 0.15, 0.1]), np.float32([0.9, 0.9, 0.95]))
    image[(alpha > 0.1) & (alpha < 0.3)] = (0.75, 0.72, 0.74)
    image = np.clip(image + 0.01 * np.random.default_rng(0).standard_normal((h, w, 3)), 0, 1).astype(np.float32)
    fg = np.full_like(image, 0.2)
    shown, _ = shown_edge(image, alpha, fg)
    assert np.abs(shown - alpha)[yp : yp + 24, xp : xp + 24].max() > 0.005  # the patch's reach steepens the plateau
    bands = np.concatenate([b[2] for b in compose.shown_edge_bands(image, alpha, lambda a, b: fg[a:b], 60 * w)])
    np.testing.assert_allclose(bands, shown, rtol=0, atol=1e-6)  # the distances' float sums: to the last bits
