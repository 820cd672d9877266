"""Procedural textures, skin tones and the UV rasteriser (numpy + OpenCV only)."""

from __future__ import annotations

import numpy as np
import pytest

from export.render import textures
from relight_rt import RelightError


def _luminance(rgb: np.ndarray) -> float:
    return float(rgb @ np.array([0.2126, 0.7152, 0.0722]))


def test_skin_tones_run_light_to_deep_within_range():
    tones = np.stack([textures.skin_tone(t) for t in np.linspace(0, 1, 11)])
    assert tones.dtype == np.float32 and tones.shape == (11, 3)
    assert (tones >= 0).all() and (tones <= 1).all()
    lum = [_luminance(t) for t in tones]
    assert all(a > b for a, b in zip(lum, lum[1:], strict=False))
    assert lum[0] > 3 * lum[-1]  # light to deep, not a narrow band
    assert (tones[:, 0] >= tones[:, 1]).all() and (tones[:, 1] >= tones[:, 2]).all()  # warm hues


def test_skin_tone_rejects_nan():
    with pytest.raises(RelightError, match="finite skin tone"):
        textures.skin_tone(float("nan"))


def test_value_noise_is_bounded_deterministic_and_smooth():
    rng = np.random.default_rng(0)
    pts = rng.uniform(-1, 1, (2000, 3))
    a = textures.value_noise(pts, 7.0, seed=3)
    assert a.shape == (2000,) and (a >= 0).all() and (a <= 1).all()
    np.testing.assert_array_equal(a, textures.value_noise(pts, 7.0, seed=3))
    assert not np.allclose(a, textures.value_noise(pts, 7.0, seed=4))
    # continuity: a step of 1e-4 lattice units changes the value by little
    b = textures.value_noise(pts + 1e-5, 7.0, seed=3)
    assert np.abs(a - b).max() < 1e-2
    assert a.std() > 0.05  # not constant


def test_fbm_is_centred():
    pts = np.random.default_rng(1).uniform(-2, 2, (20000, 3))
    f = textures.fbm(pts, 5.0, octaves=3, seed=2)
    assert abs(f.mean()) < 0.05 and np.abs(f).max() <= 0.5


@pytest.mark.parametrize("kind", textures.PATTERNS)
def test_patterns_are_colours_in_range(kind):
    rng = np.random.default_rng(5)
    pattern = textures.random_pattern(rng, (kind,))
    assert pattern.kind == kind
    pts = rng.uniform(-0.5, 0.5, (3000, 3))
    out = textures.evaluate_pattern(pattern, pts)
    assert out.shape == (3000, 3) and out.dtype == np.float32
    assert (out >= 0).all() and (out <= 1).all()
    np.testing.assert_array_equal(out, textures.evaluate_pattern(pattern, pts))
    if kind != "solid":
        assert out.std(axis=0).max() > 0.01  # a pattern, not a flat colour


def test_unknown_pattern_raises():
    with pytest.raises(RelightError, match="unknown pattern 'plaid'"):
        textures.evaluate_pattern(textures.Pattern("plaid", np.zeros((3, 3))), np.zeros((1, 3)))


def test_random_colours_in_range():
    rng = np.random.default_rng(0)
    cols = np.stack([textures.random_color(rng) for _ in range(200)])
    assert (cols >= 0).all() and (cols <= 1).all() and cols.std() > 0.1


def test_rasterize_uv_covers_a_triangle_and_interpolates_linearly():
    # the lower-left half of the texture: corners (0,0), (1,0), (0,1) in uv (v up)
    uv = np.array([[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]])
    raster = textures.rasterize_uv(uv, 64, dilate=0)
    assert 0.45 < len(raster.rows) / 64**2 < 0.56
    np.testing.assert_allclose(raster.bary.sum(axis=1), 1.0, atol=1e-5)
    # interpolating the corners' u coordinate gives each texel's own u (to within a texel)
    u = raster.interpolate(np.array([[0, 1, 2]]), np.array([0.0, 1.0, 0.0]))
    np.testing.assert_allclose(u, (raster.cols + 0.5) / 64, atol=1.5 / 64)
    # v up: covered texels are in the lower rows' left part (row 63 is v≈0)
    img = raster.image(np.ones(len(raster.rows), np.float32))
    assert img[60, 2] == 1 and img[2, 60] == 0


def test_rasterize_uv_dilation_grows_coverage():
    uv = np.array([[[0.25, 0.25], [0.75, 0.25], [0.5, 0.75]]])
    small = textures.rasterize_uv(uv, 32, dilate=0)
    grown = textures.rasterize_uv(uv, 32, dilate=2)
    assert len(grown.rows) > len(small.rows)
    assert (grown.bary >= 0).all()


def test_rasterize_uv_bad_shape():
    with pytest.raises(RelightError, match=r"expected \(F, 3, 2\) uv"):
        textures.rasterize_uv(np.zeros((4, 2)), 16)


def _hue(rgb: np.ndarray) -> float:
    import colorsys

    return 360.0 * colorsys.rgb_to_hsv(*rgb)[0]


def test_lab_to_srgb_matches_the_standard_white_and_grey():
    np.testing.assert_allclose(textures.lab_to_srgb([100.0, 0.0, 0.0]), 1.0, atol=2e-3)
    np.testing.assert_allclose(textures.lab_to_srgb([50.0, 0.0, 0.0]), 119 / 255, atol=2e-3)  # sRGB 119 grey
    np.testing.assert_allclose(textures.lab_to_srgb([0.0, 0.0, 0.0]), 0.0, atol=1e-6)


def test_skin_tones_have_the_hue_and_chroma_of_measured_skin():
    # colorimetric surveys: skin in photos sits at HSV hue ~15-30 deg with visible chroma; the first table
    # (about 24-27 deg, B/R up to 0.73) was too yellow and grey.
    for t in np.linspace(0, 1, 7):
        tone = textures.skin_tone(t)
        assert 17.0 < _hue(tone) < 25.0
        assert tone[2] / tone[0] < 0.8


def test_undertone_moves_hue_from_pink_to_olive():
    pink, neutral, olive = (textures.skin_tone(0.4, u) for u in ((1, -1), (0, 0), (-1, 1)))
    assert _hue(pink) < _hue(neutral) - 5 < _hue(olive) - 10
    assert abs(_luminance(pink) - _luminance(olive)) < 0.05  # the undertone leaves depth alone
    np.testing.assert_array_equal(textures.skin_tone(0.4, (5, -5)), pink)  # clipped to [-1, 1]
    with pytest.raises(RelightError, match="finite"):
        textures.skin_tone(0.4, (float("nan"), 0.0))
