"""relight_rt.image.guided_filter: the one guided filter (matting's coarse matte, the edge refinement and detail
transfer use it).

Properties from the model p ≈ a·I + b fitted by least squares in each window (He, Sun & Tang 2013)."""

import cv2
import numpy as np
import pytest

from relight_rt.image import guided_filter

EPS = 1e-3


def _guide(h: int = 60, w: int = 80, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return cv2.GaussianBlur(rng.random((h, w)).astype(np.float32), (0, 0), 1.5)


@pytest.mark.parametrize("radius", [1, 2, 4])
def test_a_constant_input_is_kept(radius):
    """p constant: a = 0, b = p in every window, so the output is p whatever the guide."""
    g = _guide()
    p = np.full(g.shape, 0.3, np.float32)
    np.testing.assert_allclose(guided_filter.fast_guided_filter(p, g, g, radius, EPS), 0.3, atol=1e-5)
    rgb = np.stack([g, g[::-1], g[:, ::-1]], -1)
    np.testing.assert_allclose(guided_filter.fast_guided_filter(p, rgb, rgb, radius, EPS), 0.3, atol=1e-5)


def test_an_affine_function_of_the_guide_is_kept_as_eps_vanishes():
    """p = 0.6 I + 0.1 is fitted exactly (a = 0.6 / (1 + eps / var)); with a tiny eps the output is p."""
    g = _guide()
    p = (0.6 * g + 0.1).astype(np.float32)
    out = guided_filter.fast_guided_filter(p, g, g, 2, 1e-8)
    np.testing.assert_allclose(out[3:-3, 3:-3], p[3:-3, 3:-3], atol=2e-3)


def test_a_gray_colour_guide_is_the_gray_filter_with_a_third_of_eps():
    """A colour guide (I, I, I): the 3x3 system gives sum_c a_c = cov / (var + eps / 3)."""
    g = _guide(seed=1)
    p = np.clip(_guide(seed=2) * 1.3, 0, 1).astype(np.float32)
    rgb = np.repeat(g[..., None], 3, axis=2)
    colour = guided_filter.fast_guided_filter(p, rgb, rgb, 2, 3e-3)
    gray = guided_filter.fast_guided_filter(p, g, g, 2, 1e-3)
    np.testing.assert_allclose(colour, gray, atol=1e-4)


def test_channels_are_filtered_one_by_one():
    """gray_coefficients on (H, W, C) (detail transfer's maps) equals C single-channel fits."""
    g = _guide()
    rng = np.random.default_rng(3)
    p = rng.random(g.shape + (5,)).astype(np.float32)
    a, b = guided_filter.gray_coefficients(p, g, 2, EPS)
    for c in range(5):
        ac, bc = guided_filter.gray_coefficients(np.ascontiguousarray(p[..., c]), g, 2, EPS)
        np.testing.assert_allclose(a[..., c], ac, rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose(b[..., c], bc, rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("colour", [False, True])
def test_fast_filter_output_size_and_range(colour):
    small = _guide(30, 40)
    full = cv2.resize(small, (160, 120), interpolation=cv2.INTER_LINEAR)
    if colour:
        small, full = (np.stack([x, 1 - x, 0.5 * x], -1) for x in (small, full))
    p = (_guide(30, 40, seed=4) > 0.5).astype(np.float32)
    out = guided_filter.fast_guided_filter(p, small, full, 2, EPS)
    assert out.shape == (120, 160) and out.dtype == np.float32
    assert out.min() >= 0.0 and out.max() <= 1.0
    # the upsampled result agrees with the small-grid filter where the two grids meet (block means)
    same = guided_filter.fast_guided_filter(p, small, small, 2, EPS)
    np.testing.assert_allclose(cv2.resize(out, (40, 30), interpolation=cv2.INTER_AREA), same, atol=0.1)
