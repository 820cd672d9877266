"""The deep shadow's fill at the photo's own resolution: its edge is the photo's shadow edge, not the network's grid.

Where the photo's own shading is near zero the relighting factor adds the new light's change instead of multiplying the
photo (relight_rt.relight.shadow_fill ``ShadowFill.shadow_weight``, relight_rt.relight.factor ``Factor.gain_and_fill``).
The weight w of that fill is found on the network's grid. It used to be blended into the factor there
((1 - w) x ratio + w) before the edge-aware upsampling, and the fill itself was mapped on its own. Where the photo is
larger than the network's square (one network pixel 2-8 input pixels), the last black network pixel then carried the
fill and the factor's 1 onto the lit side of the photo's own edge, through the guided filter's windows and the linear
mapping: up to 0.06 on the lit pixel beside a hard shadow, still 0.018 four input pixels away
(tests/runtime/relight/test_shadow_fill.py). Now the ratio is upsampled as it is (high in a black shadow, lower in its
penumbra, 1-2 on the lit side: a slope the guided filter's local linear model follows, not the ridge the blend made),
the weight is mapped to the crop box and decided at the photo's resolution (``edge_weight``), and the two meet per input
pixel.

``edge_weight``: along a shadow's border (where the network's weight steps from one network pixel to the next) each
input pixel's own shading (its luminance over the albedo, against the same median the network's weight is measured on)
decides, held between the least and the greatest network weight around it: a lit input pixel is multiplied, a black
one filled, whichever network pixel it falls in (the fill had also stopped short of the edge inside the black, the
last network pixel straddling it reading lit: 0.10 instead of 0.32 two input pixels inside). Only there: stage 1
often takes part of a shadow for a dark albedo, so an input pixel's own shading inside a wide shadow can read lit (a
mole, a brow) where the network's smoothed weight rightly says shadow, and a textured shadow's own weight follows
its texture (the fill's texture then no longer the photo's: correlation 0.67 -> 0.57 in test_shadow_fill).

Both reach a hard edge from inside (faces17): on the network's grid the weight grows into the near-black pixels
beside a shadow (``grid_weight``: its blurs had held it to 0.27-0.64 over the last three network pixels), and at the
photo's resolution a pixel's own luminance is read through a 3-pixel median, which keeps a hard edge where it is (a
blur over 0.7 px took the lit side into the last black pixel). On a synthetic hard edge the weight over the last four
input pixels inside was 0.10 / 0.78 / 0.84 / 0.91, now 0.98 / 1.00 / 1.00 / 1.00; on Extended Yale B's side-lit faces
the last pixel 0.81 -> 0.89 from 50 degrees, 0.89 -> 0.93 from 70 (benchmarks/fill_edge_profile.py).
"""

from __future__ import annotations

import cv2
import numpy as np

from ..image.crop import CropGeometry
from .detail import masked_blur

OWN_MEDIAN = 3  # edge_weight: each input pixel's own luminance read through a median of this many pixels a side
# grid_weight: the weight grows from a shadow into the near-black pixels beside it (their own weight from the first
# to the second) for this many network pixels (the blurs' reach inside a hard edge: about three)
GROW_DEEP, GROW_STEPS = (0.9, 1.0), 3
EDGE_SPAN = (0.3, 0.7)  # edge_weight: deciding where the network's weights around differ by more than this (a border)
# crop_part: the box reaches this many network pixels past ``where``: the weight's 3 x 3 greatest (``edge_weight``'s
# ``most``) reaches one past it, and the box's first pixels must see it fall to nothing (with 1 the box began where
# the greatest was still a neighbour's: a step in the weight at the box's border)
BOX_MARGIN = 2


def fill_share(shown: np.ndarray, level: float, low: float, high: float) -> np.ndarray:
    """The fill's share from the shading shown (photo over albedo, any shape): all of it from ``low`` x ``level``
    down, none from ``high`` x ``level`` up, a smoothstep between (the dtype of ``shown``)."""
    q = np.clip((shown / max(level, 1e-6) - low) / (high - low), 0, 1)
    return 1 - q * q * (3 - 2 * q)


def soften(area: np.ndarray, sigma: float, inner: np.ndarray | None = None) -> np.ndarray:
    """(r, r') float32 in [0, 1]: ``area`` (bool or [0, 1]) with its edge softened over ``sigma`` pixels, all of it
    from half-way into the blur on (twice the blurred area, at most 1), times ``inner`` (the person) when given."""
    out = np.minimum(2 * cv2.GaussianBlur(area.astype(np.float32), (0, 0), sigma), 1)
    return (out if inner is None else out * inner).astype(np.float32)


def grid_weight(shown: np.ndarray, solid: np.ndarray, inner: np.ndarray, level: float, low: float, high: float,
                sigma: float, edge_sigma: float) -> np.ndarray | None:
    """(r, r') float32 in [0, 1]: the fill's weight on the network's grid (relight_rt.relight.shadow_fill
    ``ShadowFill.shadow_weight``), None where no pixel is in a deep shadow (the smoothed weight nowhere past 0.05).

    A shadow is wide, a black stripe the albedo blurred away is not: the shading shown smoothed over ``sigma`` pixels
    (masked to the ``solid`` person: the background, in a soft edge's pixels too, moves no weight) gives the weight
    of its core; near a core each pixel's own shading (smoothed over ``edge_sigma``, that spread over a pixel) places
    the weight's edge (smoothed alone it ended inside the black: a dark line, multiplied), held to its own unblurred
    weight (the lit side beside it keeps its texture). Those blurs still take the lit side into the last network
    pixels inside a hard edge (there the weight fell to 0.27-0.64 over three network pixels: a band just inside the
    shadow multiplied, not filled, darker than the fill); so the weight then grows from the shadow into the pixels
    beside it that are themselves near black (their own weight within ``GROW_DEEP``), one pixel a step for
    ``GROW_STEPS`` steps: it reaches a hard edge from inside and never crosses it (the lit side is not black), nor
    spreads over a penumbra or a textured lit side (not black either).

    Args:
        shown: (r, r') the shading the photo shows (its luminance over the albedo's, floored).
        solid, inner: (r, r') bool, the person's pixels with no background mixed in, and the person's (alpha > 0.5).
        level: the shading shown the thresholds are shares of (its median over the person).
        low, high: ``fill_share``'s thresholds.
        sigma, edge_sigma: the core's smoothing and each pixel's own (network pixels).
    """
    keep = solid.astype(np.float32)
    each = masked_blur(shown, keep, edge_sigma)
    both = np.stack([masked_blur(shown, keep, sigma), each, np.where(solid, shown, each)])  # a soft edge's own pixel
    w, each, bare = np.where(inner, fill_share(both, level, low, high), 0).astype(np.float32)  # mixes the background
    if w.max() <= 0.05:
        return None
    core = (w > 0.5).astype(np.float32)  # a shadow's (a stripe's smoothed weight stays low)
    near = cv2.GaussianBlur(each * soften(core, sigma), (0, 0), 1.0)
    w = np.maximum(cv2.GaussianBlur(w, (0, 0), 1.0), np.minimum(near, bare))
    deep = np.clip((bare - GROW_DEEP[0]) / (GROW_DEEP[1] - GROW_DEEP[0]), 0, 1)
    around = np.ones((3, 3), np.uint8)
    for _ in range(GROW_STEPS):
        w = np.maximum(w, np.minimum(cv2.dilate(w, around), deep))
    return (w * inner).astype(np.float32)


def crop_part(geom: CropGeometry, maps: np.ndarray, where: np.ndarray, origin: tuple[int, int]) -> tuple | None:
    """``maps`` (r, r', C), a window of the network frame starting at ``origin``, mapped to the crop box as
    ``CropGeometry.to_crop`` maps it: (box, part), ``part`` (h', w', C) over ``box`` (a pair of slices of the crop
    box), the whole box unless enlarging, else only the part ``where`` (r, r') bool covers; None when that is empty.
    """
    h, wd = geom.crop_shape
    if geom.side <= geom.resolution:
        return (slice(0, h), slice(0, wd)), geom.to_crop(maps, origin)
    ys, xs = np.nonzero(where)
    if ys.size == 0:
        return None
    (oy, ox), k = geom.offset, geom.resolution / geom.side

    def span(lo: int, hi: int, start: int, offset: int, size: int) -> tuple[int, int]:
        a = int(np.floor((lo - BOX_MARGIN + start + 0.5) / k - 0.5 - offset))
        b = int(np.ceil((hi + BOX_MARGIN + start + 0.5) / k - 0.5 - offset)) + 1
        return max(a, 0), min(b, size)

    cy0, cy1 = span(int(ys.min()), int(ys.max()), origin[0], oy, h)
    cx0, cx1 = span(int(xs.min()), int(xs.max()), origin[1], ox, wd)
    if cy1 <= cy0 or cx1 <= cx0:
        return None
    m = geom.net_affine(origin, (cy0, cx0))
    maps = np.ascontiguousarray(maps, np.float32)
    size = (cx1 - cx0, cy1 - cy0)
    parts = [cv2.warpAffine(np.ascontiguousarray(maps[..., i : i + 4]), m, size,  # OpenCV: <= 4 channels a call
                            flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_REPLICATE)
             for i in range(0, maps.shape[2], 4)]
    parts = [p.reshape(size[1], size[0], -1) for p in parts]
    return (slice(cy0, cy1), slice(cx0, cx1)), parts[0] if len(parts) == 1 else np.dstack(parts)


def edge_weight(w: np.ndarray, least: np.ndarray, most: np.ndarray, luma: np.ndarray, albedo: np.ndarray,
                level: float, low: float, high: float) -> np.ndarray:
    """(h', w') float32 in [0, 1]: the fill's weight at the photo's resolution (module docstring): along a shadow's
    border each input pixel's own weight, held between the least and the greatest of the network's weights around
    it; elsewhere the network's. A pixel's own luminance is read through a ``OWN_MEDIAN``-pixel median (noise; a
    Gaussian over 0.7 px took the lit side into the last black pixel beside a hard edge: its weight 0.07, a dark
    line one pixel wide).

    Args:
        w, least, most: (h', w') the network's weight mapped to the input pixels, and the least and the greatest of
            it over each network pixel's 3 x 3 neighbours, mapped the same way. Where they differ by more than
            ``EDGE_SPAN`` (a border: the weight steps within a network pixel) the pixel's own weight takes over, in
            full from ``EDGE_SPAN[1]`` on; inside a shadow, away from one and along a smooth ramp the network's stays.
        luma: (h', w') the person's Rec. 709 luminance there (the foreground estimate's: the photo's inside the
            person, at a soft edge the background taken out), in [0, 1] (the weight on the network's grid is a
            Rec. 709 luminance over the albedo's too: a BT.601 grey moved the threshold by 10-15 % on saturated
            colours); albedo: (h', w') stage 1's albedo luminance mapped there (floored by the caller).
        level: the shading shown (photo over albedo) that the network's weight is measured against (its median).
        low, high: from ``high`` x level of the shading shown down to ``low`` x level the pixel's own weight goes
            from none to all (the network weight's own thresholds).
    """
    span = np.clip((most - least - EDGE_SPAN[0]) / (EDGE_SPAN[1] - EDGE_SPAN[0]), 0, 1)
    if not span.any():
        return w.astype(np.float32)
    shown = cv2.medianBlur(luma.astype(np.float32), OWN_MEDIAN) / albedo
    own = np.clip(fill_share(shown, level, low, high), least, most)
    return (w + span * (own - w)).astype(np.float32)
