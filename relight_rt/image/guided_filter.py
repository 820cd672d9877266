"""The guided filter (He, Sun & Tang, "Guided Image Filtering", 2013) and its fast form (He & Sun, "Fast
Guided Filter", 2015): the one implementation the runtime uses.

In every (2r+1)² window the input p is fitted as a linear function of the guide I, ``p ≈ a·I + b``
(least squares with a regulariser ``eps`` on a); a and b are averaged over the windows that cover each
pixel and applied to the guide, so the result follows the guide's edges. The fast form fits a and b on
a small grid and applies them, upsampled, with the full-resolution guide.

Users: the person matte's refinement (relight_rt.person.matting: gray or colour guide, working grid -> photo),
the colour-line edge estimate's denoising (relight_rt.image.matte_edges: gray guide at full resolution) and the
detail transfer's upsampling of the relighting factor (relight_rt.relight.detail: network frame -> crop box,
mapped by the crop geometry).

Guides are float32 in [0, 1]; box means use reflected borders (OpenCV's BORDER_REFLECT).
"""

from __future__ import annotations

import cv2
import numpy as np

_ONES_1x3 = np.ones((1, 3), np.float32)


def box_mean(x: np.ndarray, radius: int) -> np.ndarray:
    """Mean of ``x`` ((H, W) or (H, W, C) float32) over (2r+1)² windows, borders reflected."""
    k = 2 * radius + 1
    return cv2.boxFilter(x, -1, (k, k), borderType=cv2.BORDER_REFLECT)


def gray_coefficients(p: np.ndarray, guide: np.ndarray, radius: int, eps: float) -> tuple[np.ndarray, np.ndarray]:
    """Window-averaged coefficients (a, b) of ``p ≈ a·I + b`` for a gray guide.

    Args:
        p: (H, W) or (H, W, C) float32 input.
        guide: (H, W) float32 gray guide I.
        radius: window radius r in pixels.
        eps: regulariser on a (guide values in [0, 1]).

    Returns:
        (a, b), each of ``p``'s shape, float32, already averaged over the windows covering each pixel:
        the filtered input is ``a * I + b``.
    """
    g = guide if p.ndim == 2 else guide[..., None]
    mean_i = box_mean(guide, radius)
    var_i = box_mean(guide * guide, radius) - mean_i * mean_i
    mean_p = box_mean(p, radius)
    if p.ndim == 3:
        mean_i, var_i = mean_i[..., None], var_i[..., None]
    cov = box_mean(p * g, radius) - mean_i * mean_p
    a = cov / (var_i + eps)
    b = mean_p - a * mean_i
    return box_mean(a, radius), box_mean(b, radius)


def color_coefficients(p: np.ndarray, guide: np.ndarray, radius: int, eps: float) -> tuple[np.ndarray, np.ndarray]:
    """Window-averaged coefficients (a, b) of ``p ≈ a·I + b`` for a colour guide (He et al. 2013, eq. 14).

    Args:
        p: (H, W) float32 input.
        guide: (H, W, 3) float32 RGB guide I.
        radius: window radius r in pixels.
        eps: regulariser, added to the diagonal of the guide's 3x3 covariance in each window.

    Returns:
        a (H, W, 3) and b (H, W) float32, averaged over the windows covering each pixel: the filtered input
        is ``sum_c a_c I_c + b``.
    """
    i = guide
    mean_i = box_mean(i, radius)  # (h, w, 3)
    mean_p = box_mean(p, radius)
    cov_ip = box_mean(i * p[..., None], radius) - mean_i * mean_p[..., None]
    # covariance of the guide: six distinct entries, + eps on the diagonal
    rr = box_mean(i[..., 0] * i[..., 0], radius) - mean_i[..., 0] ** 2 + eps
    rg = box_mean(i[..., 0] * i[..., 1], radius) - mean_i[..., 0] * mean_i[..., 1]
    rb = box_mean(i[..., 0] * i[..., 2], radius) - mean_i[..., 0] * mean_i[..., 2]
    gg = box_mean(i[..., 1] * i[..., 1], radius) - mean_i[..., 1] ** 2 + eps
    gb = box_mean(i[..., 1] * i[..., 2], radius) - mean_i[..., 1] * mean_i[..., 2]
    bb = box_mean(i[..., 2] * i[..., 2], radius) - mean_i[..., 2] ** 2 + eps
    # inverse of the symmetric 3x3 by cofactors
    c00, c01, c02 = gg * bb - gb * gb, gb * rb - rg * bb, rg * gb - gg * rb
    c11, c12, c22 = rr * bb - rb * rb, rg * rb - rr * gb, rr * gg - rg * rg
    det = rr * c00 + rg * c01 + rb * c02
    x, y, z = cov_ip[..., 0], cov_ip[..., 1], cov_ip[..., 2]
    a = np.stack([c00 * x + c01 * y + c02 * z, c01 * x + c11 * y + c12 * z, c02 * x + c12 * y + c22 * z], -1)
    a /= det[..., None]
    b = mean_p - (a * mean_i).sum(-1)
    return box_mean(a, radius), box_mean(b, radius)


def fast_guided_filter(p: np.ndarray, guide_small: np.ndarray, guide_full: np.ndarray, radius: int,
                       eps: float) -> np.ndarray:  # fmt: skip
    """The fast guided filter of a probability map: fit on the small grid, apply with the full-size guide.

    Args:
        p: (h, w) float32 map in [0, 1] on the small grid.
        guide_small: the guide on the small grid: (h, w) gray or (h, w, 3) RGB, float32 in [0, 1].
        guide_full: the same guide at full size, (H, W) or (H, W, 3) (the small one when no upsampling).
        radius: window radius in small-grid pixels.
        eps: regulariser.

    Returns:
        New (H, W) float32 in [0, 1].
    """
    color = guide_small.ndim == 3
    a, b = (color_coefficients if color else gray_coefficients)(p, guide_small, radius, eps)
    size = (guide_full.shape[1], guide_full.shape[0])
    if size != (p.shape[1], p.shape[0]):
        a = cv2.resize(a, size, interpolation=cv2.INTER_LINEAR)
        b = cv2.resize(b, size, interpolation=cv2.INTER_LINEAR)
    if color:
        # sum_c a_c I_c + b with OpenCV's vectorised kernels (numpy's strided channel slices cost 5x more)
        out = cv2.add(cv2.transform(cv2.multiply(a, guide_full), _ONES_1x3), b)
    else:
        out = a * guide_full
        out += b
    return np.clip(out, 0.0, 1.0, out=out)
