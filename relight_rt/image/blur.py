"""A wide Gaussian blur at a quarter of the work: the relighting's and the compositing's smooth reads of a photo."""

from __future__ import annotations

import math

import cv2
import numpy as np


def wide_blur(img: np.ndarray, sigma: float) -> np.ndarray:
    """``img`` (h, w[, c]) float32 blurred by a Gaussian of ``sigma`` pixels (reflected border); from ``sigma`` >= 4
    on a half-size copy (area halving, the rest of the blur there, resized back up): the same to ~1e-3 of its range,
    a quarter of the work. Any number of channels (OpenCV's resize takes four at a time); a new array of ``img``'s
    shape."""
    img = np.ascontiguousarray(img, np.float32)
    if sigma < 4 or min(img.shape[:2]) < 16:
        return cv2.GaussianBlur(img, (0, 0), sigma, borderType=cv2.BORDER_REFLECT).reshape(img.shape)
    if img.ndim == 3 and img.shape[2] > 4:
        return np.concatenate([wide_blur(img[..., i : i + 4], sigma) for i in range(0, img.shape[2], 4)], axis=2)
    h, w = img.shape[:2]
    small = cv2.resize(img, ((w + 1) // 2, (h + 1) // 2), interpolation=cv2.INTER_AREA)
    small = cv2.GaussianBlur(small, (0, 0), math.sqrt((sigma / 2) ** 2 - 0.25), borderType=cv2.BORDER_REFLECT)
    return cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR).reshape(img.shape)
