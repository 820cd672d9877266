"""A second look at a face that stage 1 saw small.

Stage 1 sees the whole person in one R x R square, so in a full-body photo the face is 10-20 network pixels
tall and its transport is a blur: a new light barely changes the face and a light from below paints blotches
where the blur is wrong. When the face is small, the Relighter runs stage 1 a second time on a square around
the head (the bundled stage 1 is trained on head-and-shoulders and face framings too) and takes the change of
shading on the head from that pass, blended into the body's over a feathered border.

The face is found from stage 1's own skin map: the largest skin blob in the upper part of the person. No
extra model is needed; when no such blob exists (a person seen from behind, a face hidden), nothing changes.
"""

from __future__ import annotations

import cv2
import numpy as np

from ..image.crop import CropGeometry

SMALL_FACE = 0.2  # a face taller or wider than this fraction of the network square is seen well enough
MIN_FACE_PX = 6  # a skin blob smaller than this (network pixels) is not trusted as a face
HEAD_SIDE = 3.0  # side of the head square, in face sizes (hair, ears, neck and a little shoulder)
MIN_HEAD_INPUT = 64  # the head square must hold at least this many input pixels a side
UPPER_PART = 0.45  # the face's centre lies in this upper fraction of the person's height
FEATHER = 0.3  # the head pass fades out over this fraction of the head square at each side


def head_box(skin: np.ndarray, network_mask: np.ndarray, geometry: CropGeometry) -> tuple[int, int, int, int] | None:
    """The square around a small face, in input pixels (y0, y1, x0, x1, end exclusive), or None.

    Args:
        skin: (R, R) stage 1's skin probability, masked.
        network_mask: (R, R) the person's mask in the network frame.
        geometry: the crop geometry of the decomposition.

    Returns:
        None when no face is found, when it is already large in the network square, or when the photo has
        too few pixels there for a second pass to see more.
    """
    inner = network_mask > 0.5
    rows = np.flatnonzero(inner.any(axis=1))
    if rows.size == 0:
        return None
    top, height = int(rows[0]), int(rows[-1] - rows[0] + 1)
    blobs = ((skin > 0.5) & inner).astype(np.uint8)
    n, _, stats, centres = cv2.connectedComponentsWithStats(blobs, connectivity=8)
    r = geometry.resolution
    best, best_area = None, 0
    for i in range(1, n):
        x, y, bw, bh, area = (int(v) for v in stats[i])
        if y <= top + UPPER_PART * height and min(bw, bh) > SMALL_FACE * r:
            # a large skin blob from the upper part down: a face seen well whose centre lies lower (a portrait
            # framed from the chest up); a small blob beside it is a temple or an ear, not a small face (DPR's
            # portrait got a second pass on a 96-px square of its temple, and a red patch there under neon)
            return None
        if centres[i][1] <= top + UPPER_PART * height and area > best_area:
            best, best_area = i, area
    if best is None:
        return None
    face = max(int(stats[best, cv2.CC_STAT_WIDTH]), int(stats[best, cv2.CC_STAT_HEIGHT]))
    if face < MIN_FACE_PX or face > SMALL_FACE * r:
        return None
    # network pixel u is at square pixel (u + 0.5) S/R - 0.5; the square's origin is the crop box minus offset
    k = geometry.scale
    cx, cy = centres[best]
    y0b, _, x0b, _ = geometry.box
    oy, ox = geometry.offset
    cx_in = (cx + 0.5) * k - 0.5 - ox + x0b
    cy_in = (cy + 0.5) * k - 0.5 - oy + y0b
    side = HEAD_SIDE * face * k
    if side < MIN_HEAD_INPUT:
        return None
    h, w = geometry.frame
    y0, x0 = max(int(round(cy_in - side / 2)), 0), max(int(round(cx_in - side / 2)), 0)
    y1, x1 = min(int(round(cy_in + side / 2)), h), min(int(round(cx_in + side / 2)), w)
    if y1 - y0 < MIN_HEAD_INPUT or x1 - x0 < MIN_HEAD_INPUT:
        return None
    return y0, y1, x0, x1


def feather(h: int, w: int, cut: tuple[bool, bool, bool, bool] = (False, False, False, False)) -> np.ndarray:
    """(h, w) float32 weight: 1 in the middle of a box, falling smoothly to 0 at its sides.

    ``cut`` (top, bottom, left, right): sides where the box ends at the photo's border keep weight 1 there
    (nothing lies beyond to blend with).
    """

    def ramp(n: int, cut_start: bool, cut_end: bool) -> np.ndarray:
        t = (np.arange(n, dtype=np.float32) + 0.5) / n
        up = np.ones(n, np.float32) if cut_start else np.clip(t / FEATHER, 0, 1)
        down = np.ones(n, np.float32) if cut_end else np.clip((1 - t) / FEATHER, 0, 1)
        r = np.minimum(up, down)
        return r * r * (3 - 2 * r)  # smoothstep

    return ramp(h, cut[0], cut[1])[:, None] * ramp(w, cut[2], cut[3])[None, :]
