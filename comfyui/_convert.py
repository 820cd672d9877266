"""ComfyUI's tensors to relight_rt's arrays and back: the one place where torch meets the runtime.

ComfyUI's conventions (its ``nodes.py``: LoadImage, SaveImage, the mask nodes):

- IMAGE: a torch float32 tensor (B, H, W, C), RGB, values in [0, 1], channels last; C is 3 (an RGBA image
  from some nodes has 4: the alpha is dropped here, a mask travels as a MASK).
- MASK: a torch float32 tensor (B, H, W) in [0, 1] (a single (H, W) mask is also met); here 1 = the person,
  as segmentation nodes output it (LoadImage's mask is 1 - alpha: invert it first).

relight_rt takes and returns numpy float32 (H, W, 3) RGB in [0, 1] and (H, W) masks; torch stays on this side.
"""

from __future__ import annotations

import numpy as np
import torch

from relight_rt import RelightError
from relight_rt.image.io import read_mask


def _describe(t) -> str:
    shape = tuple(t.shape) if hasattr(t, "shape") else type(t).__name__
    return f"{shape} {getattr(t, 'dtype', '')}".strip()


def images_to_arrays(image, name: str = "image") -> list[np.ndarray]:
    """A ComfyUI IMAGE (B, H, W, 3|4) → B float32 (H, W, 3) RGB arrays in [0, 1] (new arrays, on the CPU).

    Raises:
        RelightError: not a tensor of that shape, an empty batch, values outside [0, 1] or not finite.
    """
    if not isinstance(image, torch.Tensor) or image.ndim != 4 or image.shape[-1] not in (3, 4):
        raise RelightError(f"{name}: expected a ComfyUI IMAGE tensor (B, H, W, 3), got {_describe(image)}")
    if image.shape[0] == 0:
        raise RelightError(f"{name}: expected at least one image in the batch, got {_describe(image)}")
    rgb = image[..., :3].detach().to("cpu", torch.float32)
    if not bool(torch.isfinite(rgb).all()):
        raise RelightError(f"{name}: expected finite values in [0, 1], got NaN or Inf")
    lo, hi = float(rgb.min()), float(rgb.max())
    if lo < -1e-6 or hi > 1 + 1e-6:
        raise RelightError(f"{name}: expected values in [0, 1], got [{lo:.4g}, {hi:.4g}]")
    arr = rgb.numpy()
    return [np.clip(a, 0.0, 1.0) for a in arr]  # clip copies: never alias the tensor's memory


def masks_to_arrays(mask, count: int, size: tuple[int, int], name: str = "mask") -> list[np.ndarray | None]:
    """A ComfyUI MASK (B, H, W) or (H, W) → ``count`` float32 (H, W) arrays in [0, 1]; None → ``count`` Nones.

    A batch of one is used for every image (ComfyUI's broadcasting of a single mask).

    Raises:
        RelightError: another shape, a batch size that is neither 1 nor ``count``, a size other than ``size``,
            values that relight_rt.image.io.read_mask refuses (not finite, outside [0, 1]).
    """
    if mask is None:
        return [None] * count
    if not isinstance(mask, torch.Tensor) or mask.ndim not in (2, 3):
        raise RelightError(f"{name}: expected a ComfyUI MASK tensor (B, H, W), got {_describe(mask)}")
    m = mask[None] if mask.ndim == 2 else mask
    if m.shape[0] not in (1, count):
        raise RelightError(f"{name}: expected 1 or {count} masks (one per image), got {m.shape[0]}")
    if tuple(m.shape[1:]) != tuple(size):
        raise RelightError(f"{name}: expected the image's size {size[0]}x{size[1]}, got {m.shape[1]}x{m.shape[2]} "
                           "(LoadImage gives a 64x64 mask for a photo without alpha: leave the mask unconnected)")
    arr = m.detach().to("cpu", torch.float32).numpy()
    # values, dtype and size as every mask of relight_rt is checked (a new float32 array: never the tensor's memory);
    # empty masks pass, as a video frame's do (the Decompose node says what an empty one means)
    out = [read_mask(a, size, name if len(arr) == 1 else f"{name} {i}", allow_empty=True) for i, a in enumerate(arr)]
    return out * count if len(out) == 1 else out


def arrays_to_image(arrays) -> torch.Tensor:
    """(H, W, 3) float arrays of one size → a ComfyUI IMAGE (B, H, W, 3) float32 tensor, clipped to [0, 1]."""
    stack = np.stack([np.asarray(a, np.float32)[..., :3] for a in arrays])
    return torch.from_numpy(np.clip(stack, 0.0, 1.0))


def arrays_to_mask(arrays) -> torch.Tensor:
    """(H, W) float arrays of one size → a ComfyUI MASK (B, H, W) float32 tensor, clipped to [0, 1]."""
    stack = np.stack([np.asarray(a, np.float32) for a in arrays])
    return torch.from_numpy(np.clip(stack, 0.0, 1.0))


def batch_pairs(first: list, second: list, names: tuple[str, str]) -> list[tuple]:
    """Pair two batches as ComfyUI broadcasts them: equal sizes item by item, a batch of one with every item.

    Raises:
        RelightError: two batches of different sizes, neither of them 1.
    """
    a, b = len(first), len(second)
    if a != b and 1 not in (a, b):
        raise RelightError(f"{names[0]} ({a}) and {names[1]} ({b}): expected batches of equal size, or one of 1")
    n = max(a, b)
    return [(first[i if a > 1 else 0], second[i if b > 1 else 0]) for i in range(n)]
