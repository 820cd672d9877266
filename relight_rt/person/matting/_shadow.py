"""A person's own cast shadow on the ground at their feet, taken out of the matte.

In sun the segmentation graphs take the dark patch on the ground beside the feet for part of the person (the parkour
clip's runner on paving). A cast shadow is the ground with less light on it: it keeps the ground's chromaticity and
only lowers its luminance, and outdoors it turns a little bluer (lit by the sky alone: log B/G up, log R/G down); a shoe
or a trouser hem need not. On grey paving, grey or black cloth has the ground's chromaticity too, so the sky's shift is
the test that tells them apart. :func:`without_cast_shadow` reads the matte's lowest part only, for a matte that
stands (taller than wide, _UPRIGHT) and ends above the photo's bottom border (feet on a ground that shows):

1. the lit ground: the brighter half of a ring (_RING_GAP px to _RING x the matte's height past the outline) beside
   the matte's lowest _GROUND share and below it: its median log-luminance and log-chromaticity (log R/G, log B/G);
2. shadow-like pixels: luminance _DIM[0] to _DIM[1] x the lit ground's, log-chromaticity within _CHROMA of it (log B/G
   may be up to _BLUE higher), and lit by the sky alone: log B/G at least _BLUER above the lit ground's, log R/G not
   above it (after a _BLUR-px blur: the ground's grain);
3. candidates: the matte's shadow-like pixels in its lowest _LOW share, except where the selfie graph is sure of the
   person (``sure``);
4. dropped: a part of the candidates (8-connected) that reaches the matte's outline and holds a pixel _THICK x the
   matte's height inside it (a patch, not a shoe's mixed rim); never more than _MAX_SHARE of the lowest part.

Measured (benchmarks/people_masks_eval.py; thresholds on the clip and photos half A): the clip 0.9318 -> 0.9325
(frames 5, 9-12, 51 +0.007-0.019, none worse), photos unchanged (A 0.9197, B 0.8950; p182 -0.002, a shoe's lower edge).
The pose graph's segmentation cannot be the guard: it is as sure of the shadow as of the legs (0.95-1.0).
"""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np

from ...engine.session import Model
from ...image.color import REC709
from ...image.regions import Region, grid_of_region
from ._detect import roi_prob

_UPRIGHT = 1.3  # only a matte at least this x taller than wide (someone standing; not lying or leaping)
_BORDER = 0.02  # ... and ending more than this x its height above the bottom border (feet and ground in the photo)
_LOW = 0.12  # the matte's lowest part examined, x its height (the feet and what lies around them)
_RING = 0.08  # the ground's ring reaches this x the matte's height past the outline ...
_RING_GAP = 2  # ... from this many pixels past it (the soft rim left out) ...
_GROUND = 0.05  # ... beside the matte's lowest this x its height, and below it
_MIN_RING = 20  # ... at least this many pixels of it, or nothing is dropped
_BLUR = 1.0  # Gaussian sigma (px) taken off the photo first: the ground's grain, not its colour
_DIM = (0.35, 0.8)  # a cast shadow's luminance, x the lit ground's
_CHROMA = 0.12  # ... its log-chromaticity within this of the lit ground's ...
_BLUE = 0.15  # ... log B/G allowed this much higher (the sky's fill in a shadow outdoors)
_BLUER = 0.05  # ... and log B/G at least this above the lit ground's (log R/G not above it)
_THICK = 0.01  # a dropped part holds a pixel this x the matte's height (>= 2 px) inside it
_MAX_SHARE = 0.5  # never more than this share of the lowest part's matte is dropped (else nothing is)
_SURE = 0.7  # the selfie graph on the matte's region (:func:`selfie_sure`) this sure of a pixel: never dropped

Box = tuple[int, int, int, int]  # (x0, y0, x1, y1), image pixels, x1 and y1 past the end
Sure = Callable[[Box, Box], np.ndarray]  # (box, the matte's box) -> bool (y1 - y0, x1 - x0): where the person is sure


def _log_colour(img: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(log-luminance (H, W), log-chromaticity (H, W, 2): log R/G, log B/G) of float RGB in [0, 1]."""
    eps = 0.02
    lum = img @ REC709
    chroma = np.log(img[..., (0, 2)] + eps) - np.log(img[..., 1:2] + eps)
    return np.log(lum + eps), chroma


def _chroma_off(chroma: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Distance of each log-chromaticity from ``ref``, log B/G up to _BLUE above it counting as none."""
    d = chroma - ref
    blue = d[..., 1] - np.clip(d[..., 1], 0.0, _BLUE)
    return np.hypot(d[..., 0], blue)


def without_cast_shadow(rgb: np.ndarray, alpha: np.ndarray, sure: Sure | None = None) -> np.ndarray:
    """``alpha`` without the person's cast shadow on the ground at their feet (module docstring).

    Args:
        rgb: (H, W, 3) float32 RGB in [0, 1], the photo.
        alpha: (H, W) float32 matte in [0, 1].
        sure: optional: given an image box (x0, y0, x1, y1) and the matte's (alpha >= 0.5) bounding box, where in the
            first the person is sure (bool (y1 - y0, x1 - x0)): no such pixel is dropped. Asked once, and only when
            there are candidates (:func:`selfie_sure`).

    Returns:
        (H, W) float32 alpha: ``alpha`` itself when nothing is dropped, else a copy with the shadow's pixels at 0.
    """
    inside = alpha >= 0.5
    rows = np.flatnonzero(inside.any(axis=1))
    if rows.size < 8:
        return alpha
    h, w = alpha.shape
    top, bot = int(rows[0]), int(rows[-1])
    tall = bot - top + 1
    if bot >= h - 1 - _BORDER * tall:  # the photo's border cuts the body: no feet on the ground in it
        return alpha
    cols_all = np.flatnonzero(inside.any(axis=0))
    if tall < _UPRIGHT * (cols_all[-1] - cols_all[0] + 1):  # a body lying or leaping: no feet on the ground
        return alpha
    y0 = bot - int(round(_LOW * tall))
    reach = max(int(round(_RING * tall)), _RING_GAP + 2)
    cols = np.flatnonzero(inside[y0 : bot + 1].any(axis=0))
    x0, x1 = max(int(cols[0]) - reach, 0), min(int(cols[-1]) + reach + 1, w)
    y1 = min(bot + reach + 1, h)
    m = inside[y0:y1, x0:x1].astype(np.uint8)
    img = cv2.GaussianBlur(np.ascontiguousarray(rgb[y0:y1, x0:x1]), (0, 0), _BLUR)
    lum, chroma = _log_colour(img)

    def grown(r: int) -> np.ndarray:
        return cv2.dilate(m, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))) > 0

    ring = grown(reach) & ~grown(_RING_GAP)
    ring[: max(bot - y0 - int(round(_GROUND * tall)), 0)] = False
    if ring.sum() < _MIN_RING:
        return alpha
    lit = ring & (lum >= np.median(lum[ring]))
    ground_lum, ground_chroma = float(np.median(lum[lit])), np.median(chroma[lit], axis=0)
    ratio = np.exp(lum - ground_lum)  # ~ luminance ratio (the eps shifts it a little: dark ground only)
    like = (ratio >= _DIM[0]) & (ratio <= _DIM[1]) & (_chroma_off(chroma, ground_chroma) <= _CHROMA)
    # lit by the sky's fill alone: bluer than the sunlit ground and not redder (grey cloth on grey paving is neither)
    off = chroma - ground_chroma
    cand = like & m.astype(bool) & (off[..., 1] >= _BLUER) & (off[..., 0] <= 0.0)
    if sure is not None and cand.any():
        cand &= ~sure((x0, y0, x1, y1), (int(cols_all[0]), top, int(cols_all[-1]) + 1, bot + 1))
    if not cand.any():
        return alpha
    # attached: a part of the candidates that reaches the matte's outline (the ground goes on past it) ...
    rim = m.astype(bool) & ~(cv2.erode(m, np.ones((3, 3), np.uint8)) > 0)
    _, labels = cv2.connectedComponents(cand.astype(np.uint8), connectivity=8)
    hit = np.unique(labels[rim & cand])
    # ... and is a patch, not a rim (a shoe's or a hem's mixed edge against the ground is shadow-like too)
    core = cv2.distanceTransform(cand.astype(np.uint8), cv2.DIST_L2, 3) >= max(_THICK * tall, 2.0)
    hit = np.intersect1d(hit[hit > 0], np.unique(labels[core]))
    drop = np.isin(labels, hit)
    if not drop.any() or drop.sum() > _MAX_SHARE * m.sum():
        return alpha
    out = alpha.copy()
    out[y0:y1, x0:x1][drop] = 0.0
    return out


def selfie_sure(roi: Model, rgb: np.ndarray) -> Sure:
    """Where the selfie graph, run on the square around the matte (ROI_SCALE x its box, which
    :func:`without_cast_shadow` has found already), is at least _SURE sure of a person: one selfie-graph run (~5 ms),
    made when first asked. On the parkour clip the graph framed on the runner is sure of his grey trousers (>= 0.7) and
    unsure of his shadow (0.2-0.6 at the pixels the hand mask leaves out)."""

    def sure(box: Box, matte_box: Box) -> np.ndarray:
        region = Region.around(*(float(v) for v in matte_box))
        k, bx, by = grid_of_region(region)
        x0, y0, x1, y1 = box
        to_canvas = np.array([[k, 0.0, bx + k * x0], [0.0, k, by + k * y0]], np.float64)
        prob = cv2.warpAffine(roi_prob(roi, rgb, region).astype(np.float32), to_canvas, (x1 - x0, y1 - y0),
                              flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_CONSTANT,
                              borderValue=0.0)  # fmt: skip
        return prob >= _SURE

    return sure
