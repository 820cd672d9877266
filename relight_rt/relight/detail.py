"""Full-resolution detail transfer: carry the input's own detail into a result computed at low resolution.

The Relighter computes, in the network frame, the ratio relit / reconstruction (the reconstruction is
the pipeline's output under the photo's own light). These helpers unpremultiply it by the network mask,
extend it a few pixels past the outline (so upsampling does not blend in meaningless values from
outside the person), and upsample it edge-aware with a fast guided filter steered by the
full-resolution input; the result multiplies the input. ``masked_blur`` is the same normalised convolution for a
map that only the person's pixels may move (the deep shadow's fill, relight_rt.relight.factor).
"""

from __future__ import annotations

import cv2
import numpy as np

from ..image.crop import CropGeometry
from ..image.guided_filter import gray_coefficients

GUIDE_EPS = 1e-3  # guided-filter regulariser (guide values in [0, 1])
GUIDE_RADIUS = 2  # guided-filter window radius, in network pixels


def window(network_mask: np.ndarray, margin: int = 8) -> tuple[int, int, int, int]:
    """(y0, y1, x0, x1): the box of ``network_mask > 0`` widened by ``margin`` (the whole frame if empty)."""
    m = network_mask > 0
    rows, cols = np.flatnonzero(m.any(axis=1)), np.flatnonzero(m.any(axis=0))
    h, w = m.shape
    if rows.size == 0:
        return 0, h, 0, w
    y0, y1 = max(int(rows[0]) - margin, 0), min(int(rows[-1]) + 1 + margin, h)
    x0, x1 = max(int(cols[0]) - margin, 0), min(int(cols[-1]) + 1 + margin, w)
    return y0, y1, x0, x1


def unpremultiply(premult: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """(R, R, 3) colour ⊙ alpha → colour where alpha > 0.5 (stable), 0 elsewhere."""
    a = alpha[..., None]
    return np.divide(premult, a, out=np.zeros(premult.shape, np.float32), where=a > 0.5)


def extend_outward(values: np.ndarray, inner: np.ndarray, sigma: float = 2.0, *, far_own: bool = False) -> np.ndarray:
    """Keep (R, R, C) ``values`` where ``inner``; outside, fill with a Gaussian-weighted average of nearby inner
    values (normalised convolution), so that upsampling near the outline does not mix in meaningless values.
    Far from the person (no inner pixel near) the fill is 1 (a factor's neutral), or with ``far_own`` the values
    themselves (a change added to the photo, whose neutral is not 1)."""
    w = inner.astype(np.float32)
    num = cv2.GaussianBlur(values * w[..., None], (0, 0), sigma).reshape(values.shape)  # cv2 drops a C=1 axis
    den = cv2.GaussianBlur(w, (0, 0), sigma)[..., None]
    out = values.astype(num.dtype, copy=True) if far_own else np.ones_like(num)
    filled = np.divide(num, den, out=out, where=den > 1e-3)
    return np.where(inner[..., None], values, filled)


def masked_blur(values: np.ndarray, keep: np.ndarray, sigma: float) -> np.ndarray:
    """(r, r') float32: ``values`` blurred over ``sigma`` pixels with only the ``keep`` pixels (in [0, 1]) counting
    (a normalised convolution): the background beside the person moves nothing."""
    keep = keep.astype(np.float32)
    return (cv2.GaussianBlur((values * keep).astype(np.float32), (0, 0), sigma)
            / np.maximum(cv2.GaussianBlur(keep, (0, 0), sigma), 1e-3)).astype(np.float32)


def guided_upsample(
    geom: CropGeometry, src: np.ndarray, guide_net: np.ndarray, guide: np.ndarray, origin: tuple[int, int]
) -> np.ndarray:
    """Edge-aware upsampling of a network-frame (R, R, C) map to the crop box, by the fast guided filter.

    The local linear model src ≈ a·I + b (I: gray guide) is fitted in (2r+1)² windows at network resolution
    (relight_rt.image.guided_filter), the window-averaged a and b are mapped to the crop box, and applied there with the
    full-resolution gray guide, so edges of the full-resolution input carry into the result (He & Sun, "Fast Guided
    Filter", 2015; He, Sun & Tang, "Guided Image Filtering", 2013).

    Args:
        geom: the crop geometry.
        src: (r, r', C) float32 map: a window of the network frame starting at ``origin``.
        guide_net: (r, r', 3) RGB input, the same window.
        guide: (h, w, 3) RGB input in the crop box, full resolution, or its (h, w) gray (cv2's RGB2GRAY)
            when the caller keeps it for several calls.
        origin: (y, x) of the window in the network frame.

    Returns:
        (h, w, C) float32.
    """
    a, b = gray_coefficients(src, cv2.cvtColor(guide_net, cv2.COLOR_RGB2GRAY), GUIDE_RADIUS, GUIDE_EPS)
    # a and b mapped separately: each has <= 4 channels, which OpenCV resamples in one call (a 6-channel
    # stack would be resampled in slices and concatenated: a full-size copy, ~40 % of this function's time)
    out = geom.to_crop(a, origin).reshape(guide.shape[:2] + (-1,))
    out *= (guide if guide.ndim == 2 else cv2.cvtColor(guide, cv2.COLOR_RGB2GRAY))[..., None]
    out += geom.to_crop(b, origin).reshape(out.shape)
    return out


def shadow_texture(gray: np.ndarray, reference: np.ndarray, scales: tuple[float, float], block: float,
                   share: float, skin: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray | None:
    """The photo's own fine detail as a factor, for what is added where its shading is too dark to multiply.

    The detail is the log of ``gray`` (+ one 8-bit level) blurred over ``scales[0]`` pixels less its blur over
    ``scales[1]`` (a band: the single-pixel noise and quantisation of a deep shadow left out, the skin's texture
    kept). Where its local power (over ``block`` pixels) passes the ``share`` quantile of that power over the
    ``reference`` pixels (the lit person: the texture shown where the light is enough), it is scaled down to it; on
    ``skin`` to the quantile over the lit skin's own pixels instead. In a shadow at levels 2-10 the detail is mostly
    noise, many times the material's own texture: held to the lit side's amplitude it reads as skin, not speckle; a
    clean shadow's own detail is kept as it is.

    Args:
        gray: (h, w) float32 in [0, 1], the photo's grey in the crop box.
        reference: (h, w) bool, the lit pixels whose detail is the person's own (at least 64 of them).
        scales: (fine, coarse) Gaussian sigmas of the band, in input pixels.
        block: the window of the detail's local power (Gaussian sigma), in input pixels.
        share: the quantile of the reference's power the detail is held to, in (0, 1).
        skin: (weight, reference): (h, w) float32 in [0, 1], where the lit skin's amplitude holds instead (a soft
            edge blends the two), and (h, w) bool its lit pixels; None (or fewer than 64 lit skin pixels): the
            person's everywhere.

    Returns:
        (h, w) float32 exp(detail) (1: none), a new array; None when ``reference`` has too few pixels.
    """
    if int(np.count_nonzero(reference)) < 64:
        return None
    y = np.log(gray.astype(np.float32) + np.float32(1 / 255))
    detail = cv2.GaussianBlur(y, (0, 0), scales[0]) - cv2.GaussianBlur(y, (0, 0), scales[1])
    power = cv2.GaussianBlur(detail * detail, (0, 0), block)
    allowed = np.float32(max(float(np.quantile(power[reference], share)), 1e-12))
    if skin is not None and int(np.count_nonzero(skin[1])) >= 64:
        on_skin = max(float(np.quantile(power[skin[1]], share)), 1e-12)
        allowed = allowed + skin[0].astype(np.float32) * np.float32(on_skin - allowed)
    return np.exp(detail * np.sqrt(allowed / np.maximum(power, allowed))).astype(np.float32)
