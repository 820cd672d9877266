"""How much of a person's outline is fibres (hair, fuzz, a thin fabric's edge) rather than a smooth opaque edge, read
from the matte.

A light behind the person glows through fine translucent strands and only grazes smooth cloth, and strands are what
makes a matte's alpha go from 0 to 1 over a wide band. Two rims read this: a back key's in a new scene
(relight_rt.apps.scene_rim ``key_rim``) and the kept background's light on the outline of a photo relit in place
(relight_rt.relight.kept_rim). (Moved here from relight_rt.apps.scene_rim, which re-exports the names: the relighting
core does not import the apps.)
"""

from __future__ import annotations

import cv2
import numpy as np

from .blur import wide_blur

__all__ = ["FIBRE_RATIO", "GRAZE_WIDTH", "HARD_PX", "WIDTH_REACH", "fibre_share", "outline"]

HARD_PX = 2.0  #: a matte's edge whose alpha goes from 0 to 1 within this many of its photo's pixels is hard, whatever
# the matte (anti-aliasing, a lens's softness)
FIBRE_RATIO = 2.0  #: an edge this many times as wide as the matte's own hard edges (their lower quartile) is strands:
# the full rim (chosen: a wider transition than the matte gives a smooth outline is what fibres add)
GRAZE_WIDTH = 0.25  #: a hard edge's grazing line: its reach, this share of the rim's (chosen: a pixel or so)
WIDTH_REACH = 0.02  #: an edge's width is read over this share of the person's height along the outline


_CROSS = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], np.uint8)


def outline(inside: np.ndarray) -> np.ndarray:
    """(h, w) uint8 in {0, 1}: the matte's 0.5 line, the pixels of ``inside`` ((h, w) uint8 in {0, 1}, alpha >= 1/2)
    beside one outside it (4-neighbours; the image's border is not an outside)."""
    return inside - cv2.erode(inside, _CROSS, borderType=cv2.BORDER_REPLICATE)


def fibre_share(alpha: np.ndarray, pixel: float = 1.0) -> np.ndarray:
    """How much of the outline near each pixel is fibres (1: hair, fuzz, a thin fabric's edge) rather than a smooth
    opaque edge (0), read from the matte: a back light glows through fine translucent strands and only grazes smooth
    cloth, and strands are what makes a matte's alpha go from 0 to 1 over a wide band.

    The edge's width w: the pixels of fractional alpha (0.02-0.98) per pixel of outline (alpha >= 1/2 beside one
    below), both averaged along the outline over ``WIDTH_REACH`` of the person's height. A matte has hard edges of
    its own width (a binary mask none, an automatic one its grid's smear): the lower quartile of w over the outline,
    at least ``HARD_PX``. The share is 0 up to that width and 1 from ``FIBRE_RATIO`` times it on, linear between: a
    binary mask has no fibres anywhere, a soft one fibres where it is softer than its own hard edges.

    Args:
        alpha: (h, w) float matte in [0, 1] at its photo's resolution (or as seen in a frame).
        pixel: the size of one of ``alpha``'s pixels in the photo's (2: a half-size copy; ``HARD_PX`` is the
            photo's pixels).

    Returns:
        (h, w) float32 in [0, 1]; 0 far from the outline and everywhere when the matte has none.
    """
    a = np.clip(np.asarray(alpha, np.float32), 0, 1)
    inside = (a >= 0.5).astype(np.uint8)
    line = outline(inside)
    rows = np.flatnonzero(inside.any(1))
    out = np.zeros(a.shape, np.float32)
    if not line.any():
        return out
    sigma = max(2.0, WIDTH_REACH * float(rows[-1] + 1 - rows[0]))
    frac = ((a > 0.02) & (a < 0.98)).astype(np.float32)
    along = wide_blur(line.astype(np.float32), sigma)
    near = along > 1e-3 * float(along.max())
    width = np.zeros(a.shape, np.float32)
    width[near] = wide_blur(frac, sigma)[near] / along[near]
    hard = max(HARD_PX / pixel, float(np.percentile(width[line > 0], 25)))
    out[near] = np.clip((width[near] / hard - 1) / (FIBRE_RATIO - 1), 0, 1)
    return out
