"""relight_rt.color: the sRGB transfer functions (IEC 61966-2-1)."""

import numpy as np
import pytest

from relight_rt import RelightError
from relight_rt.image.color import linear_to_srgb, srgb_to_linear

# Reference points of the sRGB curve (IEC 61966-2-1 formulas evaluated in float64):
# 0.5 → 0.214041140, 0.04045 → 0.0031308 (the knee), 1 → 1, 0 → 0.
GOLDEN = [(0.0, 0.0), (0.04045, 0.04045 / 12.92), (0.5, 0.21404114048223255), (1.0, 1.0)]


@pytest.mark.parametrize(("srgb", "linear"), GOLDEN)
def test_golden_points(srgb, linear):
    assert srgb_to_linear(np.float64(srgb)) == pytest.approx(linear, rel=1e-12, abs=1e-15)
    assert linear_to_srgb(np.float64(linear)) == pytest.approx(srgb, rel=1e-6, abs=1e-12)


@pytest.mark.parametrize("shape", [(), (7,), (4, 5, 3)])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_round_trip_shape_dtype(shape, dtype):
    x = np.random.default_rng(0).random(shape).astype(dtype)
    lin = srgb_to_linear(x)
    assert lin.shape == np.shape(x) and lin.dtype == dtype
    back = linear_to_srgb(lin)
    assert back.dtype == dtype
    np.testing.assert_allclose(back, x, atol=1e-6 if dtype == np.float32 else 1e-12)


def test_monotone_and_continuous_at_knee():
    x = np.linspace(-0.1, 1.5, 20001)
    y = srgb_to_linear(x)
    assert (np.diff(y) > 0).all()
    z = linear_to_srgb(np.linspace(-0.1, 1.5, 20001))
    assert (np.diff(z) > 0).all()
    eps = 1e-9
    assert srgb_to_linear(0.04045 + eps) == pytest.approx(srgb_to_linear(0.04045 - eps), abs=1e-7)
    assert linear_to_srgb(0.0031308 + eps) == pytest.approx(linear_to_srgb(0.0031308 - eps), abs=1e-6)


def test_integer_images():
    u8 = np.array([0, 128, 255], np.uint8)
    out = srgb_to_linear(u8)
    assert out.dtype == np.float32
    np.testing.assert_allclose(out, srgb_to_linear(u8 / 255.0), rtol=1e-6)
    np.testing.assert_allclose(srgb_to_linear(np.array([65535], np.uint16)), [1.0], rtol=1e-6)


def test_inputs_not_modified():
    x = np.array([0.2, 0.5, 0.9], np.float32)
    before = x.copy()
    for fn in (srgb_to_linear, linear_to_srgb):
        out = fn(x)
        assert out is not x
        np.testing.assert_array_equal(x, before)


@pytest.mark.parametrize("bad", [np.array([True]), np.array(["a"]), np.array([1 + 2j]), np.array([1], np.int64)])
def test_rejects_non_float(bad):
    for fn in (srgb_to_linear, linear_to_srgb):
        with pytest.raises(RelightError, match="expected a float array"):
            fn(bad)
