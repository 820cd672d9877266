"""image.blur.wide_blur: a wide Gaussian on a half-size copy stays a Gaussian, on any number of channels."""

import cv2
import numpy as np
import pytest

from relight_rt.image.blur import wide_blur


@pytest.mark.parametrize("sigma", [2.0, 6.0, 12.0])
def test_a_wide_blur_is_the_full_size_gaussian_within_a_thousandth(sigma):
    rng = np.random.default_rng(0)
    img = cv2.GaussianBlur(rng.random((120, 90, 3), np.float32), (0, 0), 1.5)  # smooth at the half-size scale
    exact = cv2.GaussianBlur(img, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)
    out = wide_blur(img, sigma)
    assert out.shape == img.shape and out.dtype == np.float32
    assert np.abs(out - exact)[20:-20, 20:-20].max() < 1e-3 * np.ptp(img)


@pytest.mark.parametrize("shape", [(64, 48), (64, 48, 1), (64, 48, 9)])
def test_any_number_of_channels_each_blurred_alone(shape):
    rng = np.random.default_rng(1)
    img = rng.random(shape, np.float32)
    out = wide_blur(img, 8.0)
    assert out.shape == img.shape
    if img.ndim == 3:
        for c in range(img.shape[2]):
            np.testing.assert_array_equal(out[..., c], wide_blur(img[..., c], 8.0).reshape(out.shape[:2]))


def test_the_input_is_left_as_it_came():
    img = np.linspace(0, 1, 40 * 40, dtype=np.float32).reshape(40, 40)
    before = img.copy()
    wide_blur(img, 5.0)
    np.testing.assert_array_equal(img, before)
