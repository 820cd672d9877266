"""Image metrics of the evaluation tables: RMSE inside a mask, SSIM inside the mask's bounding box.

numpy + OpenCV, float64 internally; images are (H, W, C) float (any range; C ≥ 1).

- ``masked_rmse``: sqrt(Σ m·(x − y)² / (C · Σ m)) with a soft or binary mask m (H, W).
- ``masked_ssim``: the SSIM of Wang et al. (2004) — Gaussian window σ = 1.5 (11 × 11), K1 = 0.01,
  K2 = 0.03, data range 1 by default — computed per channel on the crop to the bounding box of
  ``mask > 0.5`` (both images multiplied by the mask first, so the background is zero in both), and
  averaged over the crop's pixels and channels. Borders of the crop are reflected (OpenCV's default).
"""

from __future__ import annotations

import cv2
import numpy as np

from relight_rt import RelightError

_K1, _K2, _SIGMA = 0.01, 0.03, 1.5


def _check_pair(pred: np.ndarray, true: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    pred, true, mask = (np.asarray(a, dtype=np.float64) for a in (pred, true, mask))
    if pred.ndim == 2:
        pred, true = pred[..., None], true[..., None]
    if pred.shape != true.shape or pred.ndim != 3:
        raise RelightError(f"metrics: expected two (H, W, C) images of one shape, got {pred.shape} and {true.shape}")
    if mask.shape != pred.shape[:2]:
        raise RelightError(f"metrics: expected an (H, W) = {pred.shape[:2]} mask, got {mask.shape}")
    return pred, true, mask


def masked_rmse(pred: np.ndarray, true: np.ndarray, mask: np.ndarray) -> float:
    """Root mean squared error inside the mask.

    Args:
        pred, true: (H, W, C) or (H, W) float.
        mask: (H, W) in [0, 1].

    Returns:
        RMSE (float); NaN for an empty mask.
    """
    pred, true, mask = _check_pair(pred, true, mask)
    weight = mask.sum() * pred.shape[2]
    if weight <= 0:
        return float("nan")
    return float(np.sqrt((mask[..., None] * (pred - true) ** 2).sum() / weight))


def mask_bbox(mask: np.ndarray) -> tuple[slice, slice]:
    """(rows, cols) slices of the bounding box of ``mask > 0.5``.

    Raises:
        RelightError: the mask is empty.
    """
    rows = np.flatnonzero(np.asarray(mask).max(axis=1) > 0.5)
    cols = np.flatnonzero(np.asarray(mask).max(axis=0) > 0.5)
    if rows.size == 0:
        raise RelightError("metrics: the mask is empty (no pixel > 0.5)")
    return slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1)


def ssim(pred: np.ndarray, true: np.ndarray, data_range: float = 1.0) -> float:
    """Mean SSIM of two (H, W, C) images (window, constants: module docstring)."""
    pred, true, _ = _check_pair(pred, true, np.ones(np.shape(pred)[:2]))
    c1, c2 = (_K1 * data_range) ** 2, (_K2 * data_range) ** 2

    def blur(x: np.ndarray) -> np.ndarray:
        out = cv2.GaussianBlur(x, (11, 11), _SIGMA)
        return out.reshape(x.shape)

    mu_x, mu_y = blur(pred), blur(true)
    sxx = blur(pred * pred) - mu_x**2
    syy = blur(true * true) - mu_y**2
    sxy = blur(pred * true) - mu_x * mu_y
    num = (2 * mu_x * mu_y + c1) * (2 * sxy + c2)
    den = (mu_x**2 + mu_y**2 + c1) * (sxx + syy + c2)
    return float((num / den).mean())


def masked_ssim(pred: np.ndarray, true: np.ndarray, mask: np.ndarray, data_range: float = 1.0) -> float:
    """SSIM inside the bounding box of the mask (both images masked first).

    Args:
        pred, true: (H, W, C) or (H, W) float.
        mask: (H, W) in [0, 1].
        data_range: the dynamic range used in SSIM's stabilising constants.

    Returns:
        Mean SSIM over the box (1.0 for identical images).
    """
    pred, true, mask = _check_pair(pred, true, mask)
    rows, cols = mask_bbox(mask)
    m = mask[..., None]
    return ssim((pred * m)[rows, cols], (true * m)[rows, cols], data_range)
