"""What a background photo's camera did to it, to do the same to a person put into it (relight_rt.apps.scene, step 5):
its blur (``camera_blur``: of its sharpest part; ``blur_sigma``: of an image's strongest edges) and its noise
(``noise_sigma``)."""

from __future__ import annotations

import math

import cv2
import numpy as np

_NOISE_KERNEL = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], np.float32)


def noise_sigma(image: np.ndarray, where: np.ndarray | None = None) -> float:
    """Per-channel noise standard deviation of an (H, W, 3) float image, averaged over the channels (Immerkær's
    Laplacian-difference operator, with the median absolute response instead of the mean, so that edges and
    texture sway it less). Units of ``image``."""
    r = np.abs(cv2.filter2D(image, -1, _NOISE_KERNEL, borderType=cv2.BORDER_REFLECT))[1:-1, 1:-1]
    if where is not None:
        r = r[where[1:-1, 1:-1]]
    if r.size < 48:
        return 0.0
    return float(np.median(r.reshape(-1, 3), axis=0).mean()) / (0.6745 * 6)  # the operator's gain on white noise


def _gradients(gray: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Gradient magnitude (Sobel) of a grey image, and of the same image blurred by 1 px (Gaussian)."""
    g0 = np.hypot(cv2.Sobel(gray, cv2.CV_32F, 1, 0), cv2.Sobel(gray, cv2.CV_32F, 0, 1))
    blurred = cv2.GaussianBlur(gray, (0, 0), 1.0)
    return g0, np.hypot(cv2.Sobel(blurred, cv2.CV_32F, 1, 0), cv2.Sobel(blurred, cv2.CV_32F, 0, 1))


def _blur_from(g0: np.ndarray, g1: np.ndarray) -> float | None:
    """The blur (px) of the strongest edges among these gradients (``blur_sigma``); None with too few."""
    if g0.size < 64:
        return None
    strong = g0 >= np.percentile(g0, 98)
    total = float(g0[strong].sum())
    if total <= 1e-6:
        return None
    r = min(float(g1[strong].sum()) / total, 0.995)
    return r / math.sqrt(1 - r * r)


def blur_sigma(gray: np.ndarray, where: np.ndarray | None = None) -> float:
    """Effective Gaussian blur (pixels) of a grey image's strongest edges: blurring a step edge of blur s by 1 px
    more lowers its peak gradient by s / sqrt(s² + 1); that ratio, measured on the top 2 % of gradients, gives s."""
    g0, g1 = _gradients(gray)
    if where is not None:
        g0, g1 = g0[where], g1[where]
    s = _blur_from(g0, g1)
    return 0.0 if s is None else s


_BLUR_TILE = 48  #: px: the background's blur is measured in tiles this size ...
_EDGE_FLOOR = 0.1  #: ... that hold an edge (Sobel magnitude of a grey in [0, 1]: a sharp step of about 0.03)
_BLUR_TILES = 10  #: at most this many tiles a side
_BLUR_QUANTILE = 25  #: the camera's blur: this percentile of the tiles' blurs (its sharpest part, robustly)


def camera_blur(gray: np.ndarray) -> float:
    """The background camera's own blur (px): the blur of the sharpest part of the photo.

    A photographer focuses on the person, so what is soft only in part of the background (defocus: depth) is not
    the person's; what softens the whole photo (the lens, a small sensor, resampling) is. So the blur is
    measured in tiles (``_BLUR_TILE``; at most ``_BLUR_TILES`` a side, spread evenly over a large photo) that hold
    a real edge (a strongest gradient above ``_EDGE_FLOOR``: a smooth sky or wall has none, and its ramps would
    read as an endless blur) and the low quantile ``_BLUR_QUANTILE`` of those is the camera's. 0 when no tile
    holds an edge (nothing to match)."""
    h, w = gray.shape
    ny, nx = max(1, h // _BLUR_TILE), max(1, w // _BLUR_TILE)
    found = []
    pad = 4  # the filters' reach: each tile is filtered with its surroundings
    for y in np.linspace(0, h - min(h, _BLUR_TILE), min(ny, _BLUR_TILES)).round().astype(int):
        for x in np.linspace(0, w - min(w, _BLUR_TILE), min(nx, _BLUR_TILES)).round().astype(int):
            y0, x0 = max(0, y - pad), max(0, x - pad)
            g0, g1 = _gradients(gray[y0 : y + _BLUR_TILE + pad, x0 : x + _BLUR_TILE + pad])
            t = np.s_[y - y0 : y - y0 + _BLUR_TILE, x - x0 : x - x0 + _BLUR_TILE]
            a, b = g0[t], g1[t]
            if float(a.max()) < _EDGE_FLOOR:
                continue
            s = _blur_from(a, b)
            if s is not None:
                found.append(s)
    return float(np.percentile(found, _BLUR_QUANTILE)) if found else 0.0


def grey(image: np.ndarray) -> np.ndarray:
    """(H, W) float32 luma of an RGB image, in [0, 1] (uint8 or float input)."""
    if image.dtype == np.uint8:
        return cv2.cvtColor(np.ascontiguousarray(image), cv2.COLOR_RGB2GRAY).astype(np.float32) * np.float32(1 / 255)
    return cv2.cvtColor(np.ascontiguousarray(image, dtype=np.float32), cv2.COLOR_RGB2GRAY)
