"""``relight.kept_rim``: over the photo's own background, the light its scene sends through the person's edge stays
when a new lamp misses that side (issue 48: the edge had gone black against a bright background)."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest
from _graphs import models_dir

from relight_rt import Relighter, RuntimeConfig, lights
from relight_rt.image.color import REC709, srgb_to_linear
from relight_rt.relight import compose
from relight_rt.relight import kept_rim as kr
from relight_rt.relight.kept_rim import KeptRim, SkinMap, kept_rim, skin_share, with_kept_rim

__all__ = ["models_dir"]  # fixture

H, W = 120, 100


def _person(sigma: float) -> np.ndarray:
    """A matte: a box 30-90 wide, 10-110 high, its edge blurred by ``sigma`` px (0: binary)."""
    hard = np.zeros((H, W), np.float32)
    hard[10:110, 30:70] = 1
    return np.clip(cv2.GaussianBlur(hard, (0, 0), sigma), 0, 1) if sigma else hard


def _photo(background=(0.9, 0.85, 0.6), person=(0.5, 0.4, 0.35)) -> np.ndarray:
    img = np.empty((H, W, 3), np.float32)
    img[:] = background
    img[10:110, 30:70] = person
    return img


def _behind(background=(0.9, 0.85, 0.6)) -> np.ndarray:
    """The colour behind the person: the background everywhere."""
    return np.broadcast_to(np.asarray(background, np.float32), (H, W, 3)).copy()


def _depth(alpha: np.ndarray) -> np.ndarray:
    """Each pixel's distance (px) inside the matte's 0.5 outline."""
    inside = (alpha >= 0.5).astype(np.uint8)
    return cv2.distanceTransform(np.pad(inside, 1), cv2.DIST_L2, 3)[1:-1, 1:-1]


def test_a_black_background_or_no_outline_gives_no_rim():
    alpha = _person(3.0)
    assert kept_rim(_behind((0, 0, 0)), alpha, _photo()) is None
    assert kept_rim(_behind(), np.zeros((H, W), np.float32), _photo()) is None


def test_fibres_take_the_rim_deeper_than_a_binary_edge():
    """A soft, wide matte (strands) takes the rim some pixels in; a binary mask only a thin line at its outline."""
    img = _photo()
    soft, hard = _person(3.0), _person(0)
    # the soft matte's outline is wider than a box's hard edge only where it is judged against its own: a matte
    # blurred all round is one width everywhere, so a sharper side is made for the comparison
    soft[:, 50:] = hard[:, 50:]
    rims = {k: kept_rim(_behind(), a, img) for k, a in (("soft", soft), ("hard", hard))}
    depth = {k: _depth(a).reshape(-1)[rims[k].index] for k, a in (("soft", soft), ("hard", hard))}
    assert depth["hard"].max() <= 2.0  # a thin grazing line
    left = (rims["soft"].index % W) < 50
    assert depth["soft"][left].max() > 3.0  # the strands' glow reaches further in


def test_the_photos_sharp_edge_overrules_a_soft_mattes_fibres():
    """A soft matte along an edge the photo shows sharp (a cheek against a wall, issue 48's p071) takes only the thin
    grazing line when the photo is given; where the photo's own edge is as soft as the matte, the strands' depth."""
    soft, hard = _person(3.0), _person(0)
    soft[:, 50:] = hard[:, 50:]  # as above: the left side is the matte's soft one
    sharp = _photo()
    blurred = cv2.GaussianBlur(sharp, (0, 0), 3.0)  # the photo's transition as wide as the matte's
    depth = _depth(soft).reshape(-1)
    deep = {}  # the rim's luminance more than 2 px inside the soft side's outline
    for name, img in (("matte alone", None), ("sharp", sharp), ("blurred", blurred)):
        rim = kept_rim(_behind(), soft, sharp, image=img)
        at = ((rim.index % W) < 50) & (depth[rim.index] > 2)
        deep[name] = float((rim.rim[at] @ REC709).sum())
    assert deep["matte alone"] > 0
    assert deep["sharp"] < 0.2 * deep["matte alone"]  # a thin line (and what the matte's own softness lets through)
    assert deep["blurred"] == pytest.approx(deep["matte alone"], rel=0.05)


def test_the_rim_goes_no_deeper_than_the_photos_own_edge():
    """Dark hair against a bright sky (issue 48's p071 under RIGHT): a soft matte, a tall person (the rim's reach
    ~8 px) and a photo whose own step is ~2.5 px wide: the rim stays within the photo's transition instead of a
    smooth veil of the sky's light ~15-20 px into the hair; where the photo's edge is as soft as the wide read
    sees, the rim goes as deep as the reach."""
    h, w = 900, 240
    hard = np.zeros((h, w), np.float32)
    hard[50:850, 60:180] = 1
    soft = np.clip(cv2.GaussianBlur(hard, (0, 0), 4.0), 0, 1)
    soft[:, 120:] = hard[:, 120:]  # the left side soft (fibres against the box's hard right side)
    sky = np.empty((h, w, 3), np.float32)
    sky[:] = (0.95, 0.95, 0.9)
    sky[50:850, 60:180] = (0.12, 0.1, 0.09)
    behind = np.broadcast_to(np.float32([0.95, 0.95, 0.9]), (h, w, 3)).copy()
    inside = (soft >= 0.5).astype(np.uint8)
    depth = cv2.distanceTransform(np.pad(inside, 1), cv2.DIST_L2, 3)[1:-1, 1:-1].reshape(-1)
    deep = {}  # the rim's luminance more than 8 px inside the soft side's outline
    for name, sigma in (("crisp", 1.0), ("soft", 6.0)):
        img = cv2.GaussianBlur(sky, (0, 0), sigma)
        rim = kept_rim(behind, soft, img, image=img)
        at = ((rim.index % w) < 120) & (depth[rim.index] > 8)
        deep[name] = float((rim.rim[at] @ REC709).sum())
    assert deep["soft"] > 0
    assert deep["crisp"] < 0.05 * deep["soft"]


def _skin(share: float, left_only: bool = False) -> SkinMap:
    """A skin map over the crop box at half its resolution (a network frame smaller than the photo): ``share``
    everywhere (or on the box's left half only)."""
    net = np.zeros((H // 2, W // 2), np.float32)
    net[:, : (W // 4 if left_only else W // 2)] = share
    k = 0.5
    return SkinMap(net, np.array([[k, 0.0, 0.5 * k - 0.5], [0.0, k, 0.5 * k - 0.5]]))


def test_skin_takes_no_rim_whatever_the_matte_and_the_photo_say():
    """Skin is smooth and opaque: a soft matte over a soft photo edge (strands by both words) takes no rim where the
    skin map says skin, and the full rim beside it where it does not (issue 48: p071's olive fringe on the jaw)."""
    soft = _person(3.0)
    img = cv2.GaussianBlur(_photo(), (0, 0), 3.0)
    none = kept_rim(_behind(), soft, _photo(), image=img)
    half = kept_rim(_behind(), soft, _photo(), image=img, skin=_skin(1.0, left_only=True))
    x = lambda r: r.index % W  # noqa: E731
    lum = lambda r, left: float((r.rim[x(r) < 45 if left else x(r) >= 55] @ REC709).sum())  # noqa: E731  (the
    # skin map's own edge, bilinear, lies between)
    assert lum(none, True) > 0 and lum(none, False) > 0
    assert lum(half, True) == 0  # the skin side: nothing (not even the grazing line)
    np.testing.assert_allclose(lum(half, False), lum(none, False), rtol=1e-5)
    assert kept_rim(_behind(), soft, _photo(), image=img, skin=_skin(1.0)) is None


def test_skin_share_is_the_straight_probability_ramped():
    """The network's skin map is times the matte: read straight (over the matte) it is the person's own, so a cheek
    whose map falls to 0.4 at a soft outline (0.8 x alpha 0.5) is skin there; below ``SKIN_FROM`` nothing."""
    alpha = np.zeros((40, 40), np.float32)
    alpha[:, :20] = 1
    alpha[:, 20] = 0.6
    for p, want in ((0.8, 1.0), (0.3, 0.0), ((kr.SKIN_FROM + kr.SKIN_SURE) / 2, 0.5)):
        share = skin_share(alpha * p, alpha)
        np.testing.assert_allclose(share[:, :21], want, atol=1e-5)


def test_the_rim_has_the_backgrounds_colour_and_no_more_than_the_photo_holds():
    img = _photo(background=(0.2, 0.4, 0.95))
    rim = kept_rim(_behind((0.2, 0.4, 0.95)), _person(3.0), img)
    assert (rim.rim[:, 2] > rim.rim[:, 0]).all()  # blue behind: a blue rim
    assert (rim.rim @ REC709 <= rim.own * (1 + 1e-5)).all()
    dark = kept_rim(_behind((0.2, 0.4, 0.95)), _person(3.0), img * 0.1)  # a near-black person: the photo holds
    # little rim
    assert (dark.rim @ REC709 <= dark.own * (1 + 1e-5)).all()


def test_the_photos_own_light_and_a_brighter_light_add_nothing():
    img = _photo()
    rim = kept_rim(_behind(), _person(3.0), img)
    np.testing.assert_array_equal(with_kept_rim(img, rim), img)  # g = 1: the photo back
    brighter = np.clip(img * 1.3, 0, 1)
    np.testing.assert_array_equal(with_kept_rim(brighter, rim), brighter)
    assert with_kept_rim(img, None) is img


def test_a_darkened_edge_keeps_the_rim_and_stays_below_the_photo():
    img = _photo()
    rim = kept_rim(_behind(), _person(3.0), img)
    dark = img * 0.05
    out = with_kept_rim(dark, rim)
    assert out is not dark and not np.shares_memory(out, dark)
    y = lambda a: srgb_to_linear(np.clip(a, 0, 1)).reshape(-1, 3)[rim.index] @ REC709  # noqa: E731
    assert (y(out) >= y(dark) - 1e-7).all() and (y(out) > y(dark) + 1e-3).any()
    assert (y(out) <= y(img) * 1.002 + 1e-5).all()  # never brighter than the photo there (to the tables' steps)
    untouched = np.ones(H * W, bool)
    untouched[rim.index] = False
    np.testing.assert_array_equal(out.reshape(-1, 3)[untouched], dark.reshape(-1, 3)[untouched])


def test_written_in_place_only_into_a_callers_own_float32_array():
    img = _photo()
    rim = kept_rim(_behind(), _person(3.0), img)
    dark = np.ascontiguousarray(img * 0.05, np.float32)
    want = with_kept_rim(dark, rim)
    mine = dark.copy()
    assert with_kept_rim(mine, rim, copy=False) is mine
    np.testing.assert_array_equal(mine, want)
    frozen = dark.copy()
    frozen.flags.writeable = False  # not the caller's to write: a new array, the input as it was
    out = with_kept_rim(frozen, rim, copy=False)
    assert out is not frozen and (frozen == dark).all()
    np.testing.assert_array_equal(out, want)


def test_kept_rim_is_a_named_tuple_of_arrays():
    rim = kept_rim(_behind(), _person(3.0), _photo())
    assert isinstance(rim, KeptRim)
    assert rim.index.ndim == 1 and rim.rim.shape == (rim.index.size, 3) and rim.own.shape == rim.index.shape
    assert rim.rim.dtype == np.float32 and (np.diff(rim.index) > 0).all()


@pytest.mark.parametrize("background", ["original", "transparent", "black"])
def test_only_the_photos_own_background_keeps_a_rim(models_dir, background, monkeypatch):
    """End to end: a lamp from the side over the photo's own background lightens the dark side's outline against a
    bright background; a new backdrop or the RGBA output are the same as without the rule."""
    img, soft = _photo(), _person(3.0)
    relighter = Relighter(RuntimeConfig(models=str(models_dir), device="cpu"), matter=lambda rgb, name="image": soft)
    dec = relighter.decompose(img)
    light = lights.directional((0.3, 1.0, 0.2), (1, 1, 1), 1.0) + lights.ambient(0.01)
    on = np.asarray(relighter.relight(dec, light, background=background))
    monkeypatch.setattr(kr, "KEPT_SCATTER", 0.0)
    relighter._memo(dec).clear()
    off = np.asarray(relighter.relight(dec, light, background=background))
    if background != "original":
        np.testing.assert_array_equal(on, off)
        return
    assert (on >= off - 1 / 255).all()
    assert on.sum() > off.sum()
    far = _depth(soft) > 12  # deep inside the person, and the background away from it, unchanged
    np.testing.assert_array_equal(on[far], off[far])
    np.testing.assert_array_equal(on[soft <= 0], off[soft <= 0])


def test_a_person_all_skin_keeps_no_rim_end_to_end(models_dir, monkeypatch):
    """The composite reads the person's skin (``compose.skin_map``): where stage 1 calls everything skin the rule
    adds nothing, and a face mesh's hull is skin whatever stage 1's map says."""
    img, soft = _photo(), _person(3.0)
    relighter = Relighter(RuntimeConfig(models=str(models_dir), device="cpu"), matter=lambda rgb, name="image": soft)
    dec = relighter.decompose(img)
    light = lights.directional((0.3, 1.0, 0.2), (1, 1, 1), 1.0) + lights.ambient(0.01)
    monkeypatch.setattr(kr, "KEPT_SCATTER", 0.0)
    off = np.asarray(relighter.relight(dec, light))
    monkeypatch.setattr(kr, "KEPT_SCATTER", 0.7)
    monkeypatch.setattr(kr, "SKIN_FROM", 2.0)
    monkeypatch.setattr(kr, "SKIN_SURE", 3.0)  # no probability is skin
    relighter._memo(dec).clear()
    assert np.asarray(relighter.relight(dec, light)).sum() > off.sum()
    monkeypatch.setattr(kr, "SKIN_FROM", -2.0)
    monkeypatch.setattr(kr, "SKIN_SURE", -1.0)  # every probability is sure skin
    relighter._memo(dec).clear()
    np.testing.assert_array_equal(np.asarray(relighter.relight(dec, light)), off)
    monkeypatch.setattr(kr, "SKIN_FROM", 2.0)
    monkeypatch.setattr(kr, "SKIN_SURE", 3.0)  # the face mesh's hull alone
    y0, _, x0, _ = dec.geometry.box
    face = np.array([[40.0, 30.0, 0.0], [60.0, 30.0, 0.0], [60.0, 60.0, 0.0], [40.0, 60.0, 0.0]])
    skin = compose.skin_map(dataclasses.replace(dec, face_meshes=(face,)))
    ys, xs = np.mgrid[32:58, 42:58]
    np.testing.assert_allclose(skin.at(ys.ravel() - y0, xs.ravel() - x0), 1.0, atol=1e-3)
    assert skin.at(np.array([100 - y0]), np.array([35 - x0]))[0] == 0


def test_where_two_people_meet_there_is_no_rim():
    """A group's person: the background is what no one covers (``cover``), so the side a neighbour touches gets no
    rim, the side against the wall does."""
    img = _photo()
    hard_a, hard_b = np.zeros((H, W), np.float32), np.zeros((H, W), np.float32)
    hard_a[10:110, 20:50], hard_b[10:110, 50:80] = 1, 1
    group = np.clip(cv2.GaussianBlur(hard_a + hard_b, (0, 0), 3.0), 0, 1)
    near_a, near_b = (cv2.GaussianBlur(h, (0, 0), 3.0) for h in (hard_a, hard_b))
    share = group * near_a / np.maximum(near_a + near_b, 1e-6)
    alone, among = kept_rim(_behind(), share, img), kept_rim(_behind(), share, img, cover=group)
    middle = lambda rim: rim.index[(rim.index // W > 30) & (rim.index // W < 90)] % W  # noqa: E731  (columns)
    assert (middle(alone) > 44).any()  # taken alone, the neighbour's side would be outline
    assert not (middle(among) > 44).any() and (middle(among) < 26).any()  # among the group, only the wall's side


def test_a_given_mask_is_kept_as_it_is(models_dir, monkeypatch):
    """A mask or alpha given is the user's word (as for the shown edge): no rim over the photo's own background."""
    img, soft = _photo(), _person(3.0)
    relighter = Relighter(RuntimeConfig(models=str(models_dir), device="cpu"), matter=lambda rgb, name="image": soft)
    dec = relighter.decompose(img, soft)
    light = lights.directional((0.3, 1.0, 0.2), (1, 1, 1), 1.0) + lights.ambient(0.01)
    on = np.asarray(relighter.relight(dec, light))
    monkeypatch.setattr(kr, "KEPT_SCATTER", 0.0)
    relighter._memo(dec).clear()
    np.testing.assert_array_equal(on, np.asarray(relighter.relight(dec, light)))
