"""relight_rt.relight.fill_colour: the deep shadow's fill takes the colour of the lit pixels around of its own
material (stage 1's albedo chromaticity), not of whatever is lit nearby (a real photo's black hair shadow above a lit
green shirt took the shirt's green under ``front``).

The relighter's tests use the analytic stage 1 (tests/_graphs.py), which reads the photo as its albedo; the
Decomposition is given the albedo of the scene without its shadow, as in test_shadow_fill.py."""


import cv2
import numpy as np
import pytest
from _graphs import OWN_LIGHT, models_dir

import relight_rt
from relight_rt.engine.config import RuntimeConfig
from relight_rt.image.color import REC709
from relight_rt.relight import fill_colour, shadow_fill
from relight_rt.relight.fill_colour import material_colour

__all__ = ["models_dir"]  # fixtures

GREEN = np.array([0.25, 0.60, 0.30], np.float32)
SKIN = np.array([0.62, 0.47, 0.40], np.float32)
GREY = np.array([0.30, 0.30, 0.30], np.float32)


def plain_colour(rgb, trust, sigma):
    """The rule before fill31: the lit pixels' colour around, every material alike."""
    luma = rgb @ REC709
    num = cv2.GaussianBlur(rgb * trust[..., None], (0, 0), sigma)
    den = cv2.GaussianBlur(luma * trust, (0, 0), sigma)[..., None]
    return num / np.maximum(den, 1e-6)


def strips(*parts: tuple[np.ndarray, np.ndarray, float], width: int = 20, h: int = 40):
    """(rgb, albedo, trust): vertical strips side by side, each (photo colour, albedo colour, trust)."""
    rgb = np.concatenate([np.broadcast_to(c, (h, width, 3)) for c, _, _ in parts], axis=1).astype(np.float32)
    albedo = np.concatenate([np.broadcast_to(a, (h, width, 3)) for _, a, _ in parts], axis=1).astype(np.float32)
    trust = np.concatenate([np.full((h, width), t, np.float32) for _, _, t in parts], axis=1)
    return rgb, albedo, trust


@pytest.mark.parametrize("sigma", [3.0, 12.0])  # the blur at full size and at a quarter of it
def test_a_black_shadow_beside_a_lit_green_takes_its_own_materials_grey(sigma):
    rgb, albedo, trust = strips((GREEN, GREEN, 1), (0.01 * GREY, GREY, 0), (GREY, GREY, 1), width=3 * int(sigma))
    w = 3 * int(sigma)
    near = np.s_[:, w : w + 3]  # the shadow's pixels next to the green
    before = plain_colour(rgb, trust, sigma)[near].mean(axis=(0, 1))
    assert before[1] > 1.2 * before[0], before  # the plain mean: green there (the fault)
    colour = material_colour(rgb, rgb @ REC709, trust, albedo, sigma)[near].mean(axis=(0, 1))
    np.testing.assert_allclose(colour, 1, atol=0.02)  # the lit grey's colour: neutral


@pytest.mark.parametrize("sigma", [6.0, 12.0])  # the cells filled at a third and a quarter of the size
def test_a_black_shadow_between_lit_green_and_skin_stays_grey_wherever_the_reduced_grid_falls(sigma):
    """Lit green, a black shadow of grey albedo 30 px wide, lit skin: no lit grey anywhere, so the shadow's own
    material is white, whatever the reduced grid's phase. A reduced pixel straddling the shadow's edge on the skin's
    side averaged the skin's and the shadow's albedos (mostly grey's cell) but its lit colour was the skin's alone:
    0.19-0.24 off at 3 of 4 phases before fill32."""
    for offset in range(4):
        edge = 40 + offset
        rgb, albedo, trust = strips((GREEN, GREEN, 1), (0.01 * GREY, GREY, 0), (SKIN, SKIN, 1), width=30)
        rgb, albedo, trust = (np.concatenate([np.repeat(a[:, :1], offset + 10, axis=1), a], axis=1)
                              for a in (rgb, albedo, trust))  # the green wider by 10 + offset px
        colour = material_colour(rgb, rgb @ REC709, trust, albedo, sigma)[:, edge : edge + 30]
        np.testing.assert_allclose(colour, 1, atol=0.02, err_msg=f"offset {offset}")  # measured 0.000


def test_a_skin_shadow_takes_the_lit_skins_colour_not_the_shirts_beside():
    rgb, albedo, trust = strips((GREEN, GREEN, 1), (0.01 * SKIN, 0.4 * SKIN, 0), (SKIN, SKIN, 1))
    colour = material_colour(rgb, rgb @ REC709, trust, albedo, 6.0)[:, 20:40]
    np.testing.assert_allclose(colour, np.broadcast_to(SKIN / float(SKIN @ REC709), colour.shape), atol=0.02)


# at full size; at a quarter of it (the image's border, where the reduced blur's edge differs, left out)
@pytest.mark.parametrize("sigma, atol", [(3.0, 2e-3), (12.0, 0.01)])
def test_one_material_gives_the_plain_mean_where_lit_pixels_are_near(sigma, atol):
    rng = np.random.default_rng(3)
    rgb = (0.2 + 0.6 * rng.random((90, 100, 3))).astype(np.float32)
    trust = (rng.random((90, 100)) > 0.4).astype(np.float32)
    albedo = np.broadcast_to(SKIN, rgb.shape)  # one material (tents in two cells a side: their shares sum to 1)
    got = material_colour(rgb, rgb @ REC709, trust, albedo, sigma)
    inside = np.s_[16:-16, 16:-16]
    np.testing.assert_allclose(got[inside], plain_colour(rgb, trust, sigma)[inside], atol=atol)


def test_a_material_lit_nowhere_is_white_and_nothing_lit_gives_white():
    rgb, albedo, trust = strips((GREEN, GREEN, 1), (0.01 * GREY, GREY, 0), width=12)
    colour = material_colour(rgb, rgb @ REC709, trust, albedo, 3.0)[:, 18:]
    np.testing.assert_allclose(colour, 1, atol=0.02)
    dark = material_colour(rgb, rgb @ REC709, np.zeros_like(trust), albedo, 3.0)
    np.testing.assert_array_equal(dark, 1)


@pytest.mark.parametrize("sigma", [3.0, 12.0])
def test_a_material_lit_only_on_a_border_is_white_not_a_neighbours_colour(sigma):
    """A red lit only as a stripe 1 px wide between lit green and lit skin (every one of its pixels on a border, so
    no vote of it survives ``_pure``), its own shadow 10 px past the skin: white (the light's colour alone), as a
    material lit nowhere, never the green's or the skin's colour (measured 0.000). The price of the purity rule: a
    material seen lit only that thin loses its own colour too (main's rule gave a pale red at sigma 3, 0.32 off white;
    at sigma 12 white as well, leaning white by ``MATERIAL_KNOWN``)."""
    red = np.array([0.60, 0.15, 0.12], np.float32)
    rgb, albedo, trust = (np.concatenate(parts, axis=1) for parts in zip(
        strips((GREEN, GREEN, 1), width=30), strips((red, red, 1), width=1), strips((SKIN, SKIN, 1), width=10),
        strips((0.01 * red, red, 0), width=20), strips((SKIN, SKIN, 1), width=30), strict=True))
    colour = material_colour(rgb, rgb @ REC709, trust, albedo, sigma)[:, 44:58]
    np.testing.assert_allclose(colour, 1, atol=0.02)


@pytest.fixture(scope="module")
def relighter(models_dir):
    return relight_rt.open(RuntimeConfig(models=models_dir, device="cpu"))


@pytest.fixture(scope="module")
def relit_strips(load_benchmark):
    """benchmarks/fill_colour_layouts.py's scene: a person (rows ``top``-139, x 20-79) lit green on its left
    (x < ``edge``), a deep shadow of albedo ``shadowed[1]`` 20 px wide (photo ``shadowed[0]``), lit skin on its right;
    relit under twice the photo's own light (white). The top row sets the crop's size, so the network grid's scale and
    phase; the edge, where the green's border falls on that grid."""
    scene = load_benchmark("fill_colour_layouts").relit_strips
    return lambda relighter, shadowed, top=20, edge=40: scene(relighter, shadowed, OWN_LIGHT, top, edge)


def chroma(pixels: np.ndarray) -> np.ndarray:
    mean = pixels.reshape(-1, 3).mean(axis=0)
    return mean / float(mean @ REC709)


@pytest.mark.parametrize("top", range(17, 25))
@pytest.mark.parametrize("material", ["black", "skin"])
def test_the_relit_fill_takes_its_own_materials_colour_wherever_the_grid_falls(relighter, relit_strips, monkeypatch,
                                                                               material, top):
    """A black shadow beside the lit green stays grey under a white light (the plain mean made it green); a skin
    shadow between the green and the lit skin takes the lit skin's colour. For every top row 17-24 and green edge
    36-44 (benchmarks/fill_colour_layouts.py): a network pixel straddling the shadow's edge, its albedo mostly the
    shadow's but its photo the lit neighbour's, gave the shadow's own material that neighbour's colour at about half
    of these layouts (up to 0.34 off for black, 0.42 for skin, before fill32)."""
    albedo = GREY if material == "black" else 0.5 * SKIN
    want = np.ones(3) if material == "black" else SKIN / float(SKIN @ REC709)
    for edge in range(36, 45):
        out = relit_strips(relighter, (0.01 * albedo, albedo), top, edge)
        near = np.s_[40:120, edge + 3 : edge + 9]  # the shadow's side next to the green (its first 3 px: the edge)
        got = chroma(out[near])
        assert float(out[near].mean()) > 0.05, edge  # the fill lit it
        # measured: black 0.000, skin at most 0.017 (before fill32: 0.338 and 0.415)
        np.testing.assert_allclose(got, want, atol=0.03, err_msg=f"edge {edge}")
    monkeypatch.setattr(shadow_fill, "FILL_BY_MATERIAL", False)  # the plain mean: the green taken
    before = chroma(relit_strips(relighter, (0.01 * albedo, albedo), top, edge)[near])  # the last edge's layout
    assert before[1] - before[0] > 0.15 + got[1] - got[0], (before, got)


def test_many_materials_stay_within_the_lit_colours():
    """Every cell of the span in use (more than one blur's batch): each pixel's colour is a mean of lit colours. The
    materials come in 4 x 4 blocks, so each block's inner pixels are pure and vote (a material per pixel is all
    border: no vote survives ``_pure`` and the colour is white everywhere, the batches never run)."""
    rng = np.random.default_rng(5)
    rgb = (0.1 + 0.8 * rng.random((64, 80, 3))).astype(np.float32)
    blocks = np.exp(rng.uniform(-2, 2, (16, 20, 3))).astype(np.float32) * 0.1
    albedo = np.repeat(np.repeat(blocks, 4, axis=0), 4, axis=1)
    trust = (rng.random((64, 80)) > 0.5).astype(np.float32)
    uv = np.floor(fill_colour._chroma(albedo)).reshape(-1, 2)
    assert len(np.unique(uv, axis=0)) > fill_colour._BATCH
    for sigma in (3.0, 10.0):
        got = material_colour(rgb, rgb @ REC709, trust, albedo, sigma)
        lit = (rgb / (rgb @ REC709)[..., None])[trust > 0]
        assert np.isfinite(got).all()
        assert np.abs(got - 1).max() > 0.1  # the lit colours read, not white alone
        assert (got >= np.minimum(lit.min(axis=0), 1) - 1e-4).all() and (got <= lit.max(axis=0) + 1e-4).all()


@pytest.mark.parametrize("sigma", [3.0, 12.0])
def test_a_material_drifting_across_cells_takes_a_colour_without_a_seam(sigma):
    """Skin whose albedo chromaticity drifts across two cell boundaries on each axis (log R / G 0.15 -> 0.65, log
    B / G -0.05 -> -0.45 over the width), lit above and below a shadow band: the shadow's colour follows the lit
    colour above it column by column, its step between neighbouring columns no larger than the lit colour's own (a
    pixel read from its nearest cell alone jumps where the drift crosses a cell's edge)."""
    h, w = 60, 400
    x = np.linspace(0, 1, w, dtype=np.float32)
    lit = np.stack([0.3 * np.exp(0.15 + 0.5 * x), np.full_like(x, 0.3), 0.3 * np.exp(-0.05 - 0.4 * x)], axis=-1)
    albedo = np.broadcast_to(lit, (h, w, 3)).astype(np.float32)
    rgb, trust = albedo.copy(), np.ones((h, w), np.float32)
    rgb[26:34] *= 0.01
    trust[26:34] = 0
    got = material_colour(rgb, rgb @ REC709, trust, albedo, sigma)[30, 20:-20]
    want = (lit / (lit @ REC709)[:, None])[20:-20]
    np.testing.assert_allclose(got, want, atol=0.01)
    steps, own_steps = np.abs(np.diff(got, axis=0)).max(), np.abs(np.diff(want, axis=0)).max()
    assert steps < 1.5 * own_steps, (steps, own_steps)
