"""comfyui/_convert.py: ComfyUI's IMAGE (B, H, W, C) and MASK (B, H, W) tensors to relight_rt's arrays and back."""

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from comfyui._convert import (  # noqa: E402
    arrays_to_image,
    arrays_to_mask,
    batch_pairs,
    images_to_arrays,
    masks_to_arrays,
)
from relight_rt import RelightError  # noqa: E402


@pytest.mark.parametrize("shape", [(1, 5, 7, 3), (3, 4, 6, 3), (2, 5, 5, 4)])
def test_images_to_arrays_takes_rgb_channels_last(shape):
    image = torch.rand(shape, dtype=torch.float32)
    arrays = images_to_arrays(image)
    assert len(arrays) == shape[0]
    for i, a in enumerate(arrays):
        assert a.shape == (shape[1], shape[2], 3) and a.dtype == np.float32
        np.testing.assert_array_equal(a, image[i, ..., :3].numpy())  # RGB as is, alpha dropped


def test_images_to_arrays_copies():
    image = torch.full((1, 4, 4, 3), 0.5)
    a = images_to_arrays(image)[0]
    a[:] = 0
    assert float(image.min()) == 0.5


def test_images_to_arrays_accepts_float16_and_other_devices_as_float32():
    arrays = images_to_arrays(torch.full((1, 3, 3, 3), 0.25, dtype=torch.float16))
    assert arrays[0].dtype == np.float32 and np.all(arrays[0] == 0.25)


@pytest.mark.parametrize(
    ("value", "match"),
    [
        (torch.rand(4, 6, 3), r"\(B, H, W, 3\)"),  # no batch axis
        (torch.rand(1, 3, 4, 6), r"\(B, H, W, 3\)"),  # channels first
        (np.zeros((1, 4, 4, 3), np.float32), r"\(B, H, W, 3\)"),  # not a tensor
        (torch.rand(0, 4, 4, 3), "at least one image"),
        (torch.full((1, 2, 2, 3), 2.0), r"values in \[0, 1\]"),
        (torch.full((1, 2, 2, 3), float("nan")), "NaN or Inf"),
    ],
)
def test_images_to_arrays_refuses(value, match):
    with pytest.raises(RelightError, match=match):
        images_to_arrays(value)


def test_masks_to_arrays_broadcasts_one_mask():
    mask = torch.rand(4, 5)
    out = masks_to_arrays(mask, 3, (4, 5))
    assert len(out) == 3 and all(np.array_equal(m, mask.numpy()) for m in out)
    out = masks_to_arrays(mask[None], 2, (4, 5))
    assert len(out) == 2 and out[0].dtype == np.float32


def test_masks_to_arrays_one_per_image_and_none():
    mask = torch.rand(2, 4, 5)
    out = masks_to_arrays(mask, 2, (4, 5))
    np.testing.assert_array_equal(out[1], mask[1].numpy())
    assert masks_to_arrays(None, 3, (4, 5)) == [None, None, None]


@pytest.mark.parametrize(
    ("mask", "match"),
    [
        (torch.zeros(64, 64), "64x64"),  # LoadImage's mask of a photo without alpha
        (torch.zeros(3, 4, 5), "1 or 2 masks"),
        (torch.zeros(1, 1, 4, 5), r"\(B, H, W\)"),
        (torch.full((4, 5), 1.5), r"\[0, 1\]"),
    ],
)
def test_masks_to_arrays_refuses(mask, match):
    with pytest.raises(RelightError, match=match):
        masks_to_arrays(mask, 2, (4, 5))


def test_arrays_to_image_and_mask_follow_comfyui():
    image = arrays_to_image([np.full((3, 4, 3), 1.2), np.full((3, 4, 4), -0.1)])  # clipped, alpha dropped
    assert isinstance(image, torch.Tensor) and image.dtype == torch.float32 and tuple(image.shape) == (2, 3, 4, 3)
    assert float(image[0].min()) == 1.0 and float(image[1].max()) == 0.0
    mask = arrays_to_mask([np.full((3, 4), 0.5, np.float64)])
    assert mask.dtype == torch.float32 and tuple(mask.shape) == (1, 3, 4)


def test_batch_pairs_broadcasts_a_batch_of_one():
    assert batch_pairs([1, 2, 3], ["a"], ("x", "y")) == [(1, "a"), (2, "a"), (3, "a")]
    assert batch_pairs([1], ["a", "b"], ("x", "y")) == [(1, "a"), (1, "b")]
    assert batch_pairs([1, 2], ["a", "b"], ("x", "y")) == [(1, "a"), (2, "b")]
    with pytest.raises(RelightError, match=r"x \(2\) and y \(3\)"):
        batch_pairs([1, 2], ["a", "b", "c"], ("x", "y"))
