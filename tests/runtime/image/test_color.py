"""relight_rt.image.color: the sRGB transfer functions (IEC 61966-2-1) and the brightest channel."""

import numpy as np
import pytest

from relight_rt import RelightError
from relight_rt.image.color import channel_max, linear_to_srgb, srgb_to_linear

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


def _old_peak(rgb):
    """The brightest channel as light.exposure's ``_peak`` and relight.look's ``channel_max`` each wrote it before the
    two became image.color's one function."""
    return np.maximum(np.maximum(rgb[..., 0], rgb[..., 1]), rgb[..., 2])


@pytest.mark.parametrize("shape", [(0, 3), (11, 3), (5, 7, 3)])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_channel_max_is_the_brightest_channel_to_the_last_bit(shape, dtype):
    x = (np.random.default_rng(1).standard_normal(shape) * 2).astype(dtype)  # negative and past 1 too
    got = channel_max(x)
    assert got.dtype == dtype and got.shape == shape[:-1]
    assert np.array_equal(got, x.max(axis=-1)) and np.array_equal(got, _old_peak(x))
    before = x.copy()
    channel_max(x)
    assert np.array_equal(x, before)  # the input is only read


def test_the_shoulder_and_the_exposure_rule_share_the_one_brightest_channel(monkeypatch):
    from relight_rt.light import exposure
    from relight_rt.relight import look

    assert look.channel_max is channel_max and exposure.channel_max is channel_max
    rng = np.random.default_rng(2)
    n = 4000
    lit, steady = rng.random((n, 3), np.float32), 0.1 * rng.random((n, 3), np.float32)
    transport = rng.standard_normal((n, 9)).astype(np.float32)
    transport[:, 0] = 2.0 + rng.random(n, np.float32)
    light = np.zeros((9, 3), np.float32)
    light[0], light[1] = 1.2, 0.6
    white = light[:, 0]
    knee = exposure.own_light_knee(lit, steady, transport, white)
    gain = exposure.shoulder_gain(lit, steady, transport, 1.5 * light, knee)
    assert gain > 1.0  # the shoulder takes something back: the peak is used
    monkeypatch.setattr(exposure, "channel_max", _old_peak)  # the rule as it was written before: the same bits
    assert np.array_equal(exposure.own_light_knee(lit, steady, transport, white), knee)
    assert exposure.shoulder_gain(lit, steady, transport, 1.5 * light, knee) == gain
