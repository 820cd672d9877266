"""matting.as_rgb and metrics.as_float_image convert through the one image intake (relight_rt.image.io.read_image)."""

import numpy as np
import pytest

from relight_rt import RelightError
from relight_rt.image.io import read_image
from relight_rt.person.matting import as_rgb
from relight_rt.video import metrics


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32, np.float64])
def test_as_rgb_converts_as_the_intake_does(dtype):
    rng = np.random.default_rng(0)
    top = 1.0 if np.dtype(dtype).kind == "f" else np.iinfo(dtype).max
    img = (rng.random((20, 24, 4)) * top).astype(dtype)
    got = as_rgb(img)
    assert got.shape == (20, 24, 3) and got.dtype == np.float32 and got.flags.c_contiguous
    np.testing.assert_array_equal(got, read_image(img)[..., :3])


def test_as_rgb_returns_a_new_array():
    img = np.full((20, 20, 3), 0.5, np.float32)
    out = as_rgb(img)
    out[0, 0] = 0.0
    assert img[0, 0, 0] == 0.5


def test_as_rgb_keeps_its_own_checks():
    with pytest.raises(RelightError, match="array"):
        as_rgb("photo.png")
    with pytest.raises(RelightError, match="too small"):
        as_rgb(np.zeros((15, 40, 3), np.uint8))
    with pytest.raises(RelightError, match="shape"):
        as_rgb(np.zeros((20, 20, 2), np.uint8))


def test_as_float_image_converts_as_the_intake_does():
    rng = np.random.default_rng(1)
    img = (rng.random((10, 12, 3)) * 255).astype(np.uint8)
    np.testing.assert_array_equal(metrics.as_float_image(img), read_image(img))
    f = np.full((4, 4, 3), 1.0005, np.float32)  # a rounding above 1 is clipped
    assert metrics.as_float_image(f).max() == 1.0


@pytest.mark.parametrize("bad, words", [
    (np.full((4, 4, 3), 1.5, np.float32), r"\[0, 1\]"),
    (np.full((4, 4, 3), np.inf, np.float32), "NaN or Inf"),
    (np.zeros((4, 4, 4), np.float32), r"expected \(H, W, 3\) image"),
    (np.zeros((4, 4, 3), np.int32), "uint8, uint16 or float"),
])
def test_as_float_image_refuses(bad, words):
    with pytest.raises(RelightError, match=words):
        metrics.as_float_image(bad, "frame")


def test_read_image_without_copy_hands_back_a_float32_photo_in_range():
    img = np.random.default_rng(2).random((20, 24, 3), dtype=np.float32)
    assert read_image(img, copy=False) is img  # the matters only read it: no 12-megapixel copy
    assert as_rgb(img, copy=False) is img
    assert read_image(img) is not img  # the default stays a new array


@pytest.mark.parametrize("img", [
    np.full((8, 8, 3), 0.5, np.float64),  # another dtype
    np.full((8, 8, 3), 1.0005, np.float32),  # a rounding above 1: clipped, so converted
    np.asfortranarray(np.full((8, 8, 3), 0.5, np.float32)),  # not C-contiguous
    np.full((8, 8, 4), 0.5, np.float32)[..., :3],  # a view with strides
])
def test_read_image_without_copy_converts_anything_else(img):
    out = read_image(img, copy=False)
    assert out is not img and out.dtype == np.float32 and out.flags.c_contiguous and out.max() <= 1.0
    np.testing.assert_array_equal(out, read_image(img))


@pytest.mark.parametrize("bad, words", [
    (np.full((4, 4, 3), np.nan, np.float32), "NaN or Inf"),
    (np.full((4, 4, 3), -np.inf, np.float32), "NaN or Inf"),
    (np.full((4, 4, 3), 1.5, np.float32), r"\[0, 1\]"),
])
def test_read_image_without_copy_checks_all_the_same(bad, words):
    bad = bad.copy()
    bad[1, 2, 0] = 0.5  # mixed values: the check is not only of the first pixel
    with pytest.raises(RelightError, match=words):
        read_image(bad, "frame", copy=False)
