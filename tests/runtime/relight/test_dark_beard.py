"""relight_rt.relight.dark_beard: a black beard taken as a dark material, only in the beard's place on a face mesh
(beard40), and look.with_material: its chroma kept as a near-neutral dark's whatever its warm cast."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from _graphs import diffuse_models_dir

from relight_rt.relight import dark_beard, look
from relight_rt.relight.dark_beard import CHIN, JAW, NOSE, TOP, beard_region, beard_weight, dark_material, turn

__all__ = ["diffuse_models_dir"]  # fixture

H, W, CX = 160, 121, 60.0
SKIN = np.array([0.75, 0.55, 0.45], np.float32)


def _face() -> np.ndarray:
    """(468, 3) a mesh symmetric about x = 60 (every pair of the symmetry map), its forehead at y = 10, its chin at
    y = 110 (a face 100 px tall), the nose's base at y = 70, the jaw's contour from x = 25 to 95 between y = 75 and
    110."""
    from relight_rt.person.face_mesh import read_partners

    partner = read_partners()
    assert partner is not None
    first, own = partner > np.arange(468), partner == np.arange(468)
    points = np.zeros((468, 3))
    left = np.random.default_rng(3).uniform([CX - 40, 10], [CX, 100], (468, 2))
    points[first, :2] = left[first]
    points[partner[first], :2] = np.stack([2 * CX - left[first, 0], left[first, 1]], axis=1)
    points[own, 0], points[own, 1] = CX, np.linspace(10, 110, int(own.sum()))
    points[TOP, :2], points[CHIN, :2], points[NOSE, :2] = (CX, 10), (CX, 110), (CX, 70)
    half = [i for i in JAW if partner[i] > i]  # one of each pair along the jaw, from the ear down to the chin
    for k, i in enumerate(half):
        x, y = CX - 35 + 33 * k / max(len(half) - 1, 1), 75 + 33 * k / max(len(half) - 1, 1)
        points[i, :2], points[partner[i], :2] = (x, y), (2 * CX - x, y)
    return points


def _turned(far: float) -> np.ndarray:
    """``_face`` turned: its far half (x > 60) foreshortened to ``far`` of its width about the midline, as a face
    turned to its side shows it; the nose's base, chin and forehead stay on the midline."""
    points = _face()
    right = points[:, 0] > CX
    points[right, 0] = CX + far * (points[right, 0] - CX)
    return points


def _photo(patches: list[tuple[slice, slice, bool]], seed: int = 0, skin: np.ndarray = SKIN) -> np.ndarray:
    """(H, W, 3) ``skin`` with near-black patches (rows, cols, textured: grey 0.06 with +-0.04 noise, else flat)."""
    rng = np.random.default_rng(seed)
    rgb = np.broadcast_to(skin, (H, W, 3)).copy()
    for rows, cols, textured in patches:
        shape = rgb[rows, cols, 0].shape
        grey = 0.06 + (rng.uniform(-0.04, 0.04, shape) if textured else 0)
        rgb[rows, cols] = np.float32(grey)[..., None]
    return rgb


def _inputs(rgb: np.ndarray):
    """What ``Factor.own`` hands the rule: stage 1's albedo reading every pixel as skin (0.5), a frontal transport
    the same everywhere, the photo's light white, the whole window solid."""
    albedo = np.full((H, W), 0.5, np.float32)
    transport = np.zeros((H, W, 9), np.float32)
    transport[..., 0], transport[..., 3] = np.pi * 0.282095, 2 * np.pi / 3 * 0.488603
    white = np.zeros(9, np.float32)
    white[0], white[3] = 1.0, 0.5
    return rgb, albedo, transport, white, np.ones((H, W), bool), (_face(),)


def test_the_region_is_the_lower_face_within_the_jaws_width_and_soft_edged():
    """On the face of ``_face``: all of it over the chin and below the mouth, none above the nose's base, none beside
    the jaw (hair), none past ``BEARD_BELOW`` of the face's height under the chin; no step of its own at its edges."""
    region = beard_region(_face(), (H, W))
    assert region[80:125, 35:86].min() > 0.99  # the lower face and the neck just under the chin
    assert region[:66, :].max() == 0  # above the nose's base: cheeks, eyes, hair
    assert region[:, :20].max() == 0 and region[:, 101:].max() == 0  # beside the jaw
    assert region[146:, :].max() == 0  # past 0.3 of the face's height under the chin
    assert np.abs(np.diff(region, axis=0)).max() < 0.3 and np.abs(np.diff(region, axis=1)).max() < 0.3


def test_a_textured_near_black_beard_on_both_halves_is_taken_as_a_dark_material():
    """A near-black, near-neutral patch with a hair's fine detail on both halves of the chin, stage 1 reading it as
    skin (albedo 0.5): d ~1 over it; ``dark_material`` gives it the surroundings' transport and an albedo whose
    product with their shading is the photo (the photo's own light gives it back)."""
    rgb = _photo([(slice(92, 118), slice(38, 83), True)])
    args = _inputs(rgb)
    d, around, shading = beard_weight(*args)
    assert d[98:112, 45:76].min() > 0.9
    assert d[:60].max() == 0 and d[92:118, 5:20].max() == 0  # nothing off the beard
    albedo, transport, weight = dark_material(*args)
    np.testing.assert_array_equal(weight, d)
    photo = rgb @ look.REC709
    np.testing.assert_allclose((albedo * (transport @ args[3]))[100:110, 50:70], photo[100:110, 50:70], rtol=1e-3)
    assert albedo[100:110, 50:70].max() < 0.15  # a dark material, not skin in a shade


@pytest.mark.parametrize("case", ["flat", "one half", "beside the jaw", "grey photo", "small face", "off"])
def test_what_is_not_a_beard_is_left_alone(case, monkeypatch):
    """A shade on smooth skin (no fine detail: the held-out renders' shaded chins), a near-black patch on one half
    only (a shadow darkens one side), a textured one beside the jaw (hair), the beard of a grey photo (every pixel
    is neutral there: Extended Yale B's shaded jaws), of a face under ``BEARD_MIN_FACE`` and any with the rule off
    (``BEARD``): no weight, and ``dark_material`` returns its inputs."""
    patches = {"flat": [(slice(92, 118), slice(38, 83), False)],
               "one half": [(slice(92, 118), slice(30, 55), True)],
               "beside the jaw": [(slice(60, 110), slice(103, 118), True)],
               "off": [(slice(92, 118), slice(38, 83), True)]}.get(case, [(slice(92, 118), slice(38, 83), True)])
    if case == "off":
        monkeypatch.setattr(dark_beard, "BEARD", False)
    if case == "small face":
        monkeypatch.setattr(dark_beard, "BEARD_MIN_FACE", 101)  # the face is 100 px tall
    args = _inputs(_photo(patches, skin=np.full(3, 0.6, np.float32) if case == "grey photo" else SKIN))
    found = beard_weight(*args)
    assert found is None or found[0].max() < 0.05
    if found is None:
        albedo, transport, weight = dark_material(*args)
        assert weight is None and albedo is args[1] and transport is args[2]


def test_hair_beside_the_jaw_on_each_side_apart_is_not_taken_a_beard_joining_them_is(monkeypatch):
    """Long dark hair hanging beside the jaw inside the region, one strand on each side (each the other's mirror, so
    the both-halves cue holds; beard40 took them): no piece reaches across the chin's midline, no weight. Joined by
    a beard over the chin they are one piece, and all of it is taken."""
    strands = [(slice(80, 118), slice(30, 45), True), (slice(80, 118), slice(76, 91), True)]
    args = _inputs(_photo(strands))
    monkeypatch.setattr(dark_beard, "BEARD_ACROSS", None)  # beard40: the gate off
    ungated = beard_weight(*args)
    assert ungated is not None and ungated[0][95:110, 33:42].min() > 0.9 and ungated[0][95:110, 79:88].min() > 0.9
    monkeypatch.undo()
    found = beard_weight(*args)
    assert found is None or found[0].max() < 0.05
    args = _inputs(_photo(strands + [(slice(100, 118), slice(45, 76), True)]))
    d = beard_weight(*args)[0]
    assert d[95:110, 33:42].min() > 0.9 and d[95:110, 79:88].min() > 0.9 and d[104:114, 50:70].min() > 0.9


@pytest.mark.parametrize("far", [1.0, 0.8, 0.6, 0.3, 0.0])
def test_a_faces_turn_is_the_nose_off_the_jaws_middle_in_halves_of_its_width(far):
    """``turn``: 0 on the symmetric face, (1 - far) / (1 + far) with its far half foreshortened to ``far`` (the jaw
    from 35 px on the near side to 35 far px on the far one), 1 in profile; the same turned either way and after
    any rotation and scale in the picture."""
    points = _turned(far)
    assert turn(points) == pytest.approx((1 - far) / (1 + far), abs=1e-9)
    flipped = points.copy()
    flipped[:, 0] = 2 * CX - flipped[:, 0]
    assert turn(flipped) == pytest.approx(turn(points), abs=1e-9)
    angle = np.deg2rad(30)
    rot = 1.7 * np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    moved = points.copy()
    moved[:, :2] = points[:, :2] @ rot.T + (40, -7)
    assert turn(moved) == pytest.approx(turn(points), abs=1e-9)


def test_the_beard_of_a_turned_face_is_left_alone(monkeypatch):
    """A face turned past ``BEARD_TURN`` (its far half foreshortened to 0.3: turn 0.54; p092 0.51, p085 1.05) shows one
    half: a textured near-black patch across its chin meets the other cues (taken with the gate off) but gets no
    weight; turned less than ``BEARD_TURN[0]`` (0.8: turn 0.11, the bettered photos' 0.03-0.24) all of it."""
    beard = [(slice(92, 118), slice(38, 70), True)]
    rgb, albedo, transport, white, solid, _ = _inputs(_photo(beard))
    args = (rgb, albedo, transport, white, solid, (_turned(0.3),))
    monkeypatch.setattr(dark_beard, "BEARD_TURN", None)
    ungated = beard_weight(*args)
    assert ungated is not None and ungated[0][100:112, 42:66].min() > 0.9
    monkeypatch.undo()
    assert beard_weight(*args) is None
    albedo_out, transport_out, weight = dark_material(*args)
    assert weight is None and albedo_out is albedo and transport_out is transport
    d = beard_weight(rgb, albedo, transport, white, solid, (_turned(0.8),))[0]
    assert d[100:112, 48:66].min() > 0.9  # (the patch whose mirror image lies on the patch)


def test_a_warm_near_black_material_keeps_its_chroma_under_a_brightening_light():
    """``look.with_material``: a near-black pixel with a warm cast (a* +5, b* +2: ``neutral_darks`` leaves it alone,
    brown hair) brightened 3x grows in C*; counted as a material (a beard) it keeps the photo's C*, and the union
    keeps ``neutral_darks``' own pixels at their weights."""
    rgb = np.broadcast_to(np.float32([0.1, 0.06, 0.05]), (16, 64, 3)).copy()  # L* 5, a* +4, b* +3: warm
    rgb[:, 32:] = np.float32([0.06, 0.06, 0.075])  # a cool near-black beside it: neutral_darks' own
    own = look.neutral_darks(rgb)
    assert own is not None and (own.index[0] // 3 % 64 >= 16).all()  # (its weight smoothed over a reduced pixel)
    gain = np.full(rgb.shape, 3.0, np.float32)
    material = np.zeros(rgb.shape[:2], np.float32)
    material[:, :32] = 1
    merged = look.with_material(own, rgb, material)

    def chroma(c: np.ndarray) -> float:
        lab = cv2.cvtColor(np.clip(c, 0, 1).astype(np.float32), cv2.COLOR_RGB2Lab)[8, 8]
        return float(np.hypot(lab[1], lab[2]))

    before = chroma(rgb)
    plain, kept = (chroma(look.keep_neutral(rgb * gain, gain, n)) for n in (own, merged))
    assert plain > before + 10 and kept < before + 3  # (keep_neutral holds C* about the photo's: 4.9 -> 7.3)
    np.testing.assert_allclose(look.keep_neutral(rgb * gain, gain, merged)[:, 32:],
                               look.keep_neutral(rgb * gain, gain, own)[:, 32:], atol=1e-6)
    assert look.with_material(own, rgb, None) is own and look.with_material(own, rgb, material * 0) is own


def test_the_beard_takes_its_lit_surroundings_transport_not_its_own():
    """Stage 1 reading the beard as a shadow (its transport half its surroundings'): over the beard ``dark_material``
    hands back the surroundings' transport, and the albedo that with it gives the photo back (were its own transport
    kept, a new light would still lift it as a shadow)."""
    rgb = _photo([(slice(92, 118), slice(38, 83), True)])
    rgb_, albedo, transport, white, solid, points = _inputs(rgb)
    transport[92:118, 38:83] *= 0.5
    new_albedo, new_transport, weight = dark_material(rgb, albedo, transport, white, solid, points)
    assert weight is not None and weight[100:110, 50:70].min() > 0.9
    np.testing.assert_allclose(new_transport[100:110, 50:70], transport[20, 60][None, None].repeat(10, 0).repeat(20, 1),
                               rtol=0.05, atol=1e-3)
    photo = rgb @ look.REC709
    np.testing.assert_allclose((new_albedo * (new_transport @ white))[100:110, 50:70], photo[100:110, 50:70], rtol=1e-3)
    assert transport[100, 60, 0] == np.float32(np.pi * 0.282095 * 0.5)  # the input itself untouched


def test_the_relighter_keeps_a_beards_chroma_where_the_factor_finds_one(diffuse_models_dir, monkeypatch):
    """The wiring: ``Composer.neutral`` hands ``Factor.beard``'s weight to ``look.with_material``, so a warm
    near-black the factor calls a beard keeps the photo's C* through ``Relighter.relight``; without one it is
    brightened into brown as any warm colour (analytic graphs: a light k times the photo's own brightens k times)."""
    from _graphs import OWN_LIGHT

    import relight_rt
    from relight_rt.engine.config import RuntimeConfig
    from relight_rt.relight import compose, factor

    image = np.zeros((96, 80, 3), np.float32)
    image[:] = (0.1, 0.06, 0.05)  # L* ~5, a* +4, b* +3: the warm near-black neutral_darks leaves alone
    mask = np.zeros((96, 80), np.float32)
    mask[8:88, 8:72] = 1
    part = (slice(30, 66), slice(24, 56))

    def chroma(rgb: np.ndarray) -> float:
        lab = cv2.cvtColor(np.clip(rgb, 0, 1).astype(np.float32), cv2.COLOR_RGB2Lab).reshape(-1, 3)
        return float(np.hypot(lab[:, 1], lab[:, 2]).mean())

    def relit(beard: bool) -> np.ndarray:
        whole = (lambda self, dec: np.ones(compose.photo_crop(dec).shape[:2], np.float32)) if beard else \
            (lambda self, dec: None)
        monkeypatch.setattr(factor.Factor, "beard", whole)
        r = relight_rt.open(RuntimeConfig(models=diffuse_models_dir, device="cpu"))
        return r.relight(r.decompose(image, mask), 3 * OWN_LIGHT, exposure="physical")[part]

    before = chroma(image[part])
    assert chroma(relit(beard=False)) > before + 6
    assert chroma(relit(beard=True)) < before + 3
