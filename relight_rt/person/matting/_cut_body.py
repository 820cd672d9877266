"""The body the photo's bottom border cuts: what the selfie graph is sure of under the matte, down to that border.

A person whose matte runs into the photo's bottom border is cut by the frame: the ground they stand or sit on lies
outside the photo. Under their matte, down to that border, lies more of them. The pose graph, framed on what it sees,
can miss a part there (a trouser leg, the bottom of a white top: probability < 0.1 over it) that the selfie graph is
sure of both on the whole photo and framed on the person (>= 0.85 on average). The own colours' step
(relight_rt.person.matting._colours) refuses such a part where its colours lie near the backdrop's (grey trousers before
a grey wall: 11 % of their pixels pass its test); here the ground the own colours' test is made to refuse is out of
the frame, so the part is taken whole, unless its colours are clearly the backdrop's (light seen between two legs
that run off the frame, median CUT_BACKDROP x nearer the backdrop's colours than the person's).

A part of the own colours' candidates (the selfie graph >= OWN_SURE on the whole photo and >= 0.5 on the people's
region, joined to the matte), told apart above the photo's bottom rows, is the person's when it reaches those rows, lies
under the matte (CUT_UNDER of its pixels have the matte above them in their column: not beside the person) and holds
at least OWN_MIN x the matte's pixels (not its rim); it is carried on down to the border. Only where the matte itself
reaches the bottom rows: a person standing in the photo keeps the own colours' test for what lies under their feet.

Measured (benchmarks/people_masks_eval.py --methods ours,selfie; no graph run more, the own colours' canvas): half A
0.92087 and the clip 0.93254 unchanged (no part on them), half B 0.89581 -> 0.89695 (p126 +0.049: a grey trouser leg
before a grey wall, the pose graph 0.04 over it; p259 +0.069: the bottom of a white top). Without the test of being
under the matte: half A -0.0001 (p101 -0.011: the grass beside a woman lying in it, which
relight_rt.person.matting._layout.unconfirmed_cut drops, came back; p094 +0.003), B 0.89727 (p098 +0.034, not taken
here). Without the colour test: B 0.89687 (p150 -0.008: the light between a man's legs). Translucent interiors
(benchmarks/matte_translucent.py) B 1.92 % -> 1.89 %. Tests: tests/runtime/person/matting/test_cut_body.py.
"""

from __future__ import annotations

import cv2
import numpy as np

from ._colours import OWN_MIN, OWN_SURE, colour_model, joined, nearest
from ._layout import JOIN_GAP

CUT_UNDER = 0.9  # a part lies under the matte: this share of its pixels has the matte above them in their column
CUT_BACKDROP = 2.0  # ... refused when its colours' median distance to the person's is this x that to the backdrop's


def photo_bottom(inside: np.ndarray) -> np.ndarray:
    """(S, S) bool: the canvas pixels on the photo's last row or within JOIN_GAP rows above it (a matte read back on
    another region's canvas can stop a row short of the border). The photo's last row: inside it, the pixel below
    outside; the canvas's own last row only where the photo ends there too, which ``inside`` cannot say: never."""
    below = np.empty_like(inside)
    below[:-1] = inside[1:]
    below[-1] = inside[-1]
    last = (inside & ~below).astype(np.uint8)
    up = np.zeros((2 * JOIN_GAP + 1, 1), np.uint8)
    up[JOIN_GAP:] = 1  # the row itself and JOIN_GAP below it: a pixel within JOIN_GAP rows above the last row
    return cv2.dilate(last, up, anchor=(0, JOIN_GAP)).astype(bool) & inside


def cut_part(canvas: np.ndarray, inside: np.ndarray, mine: np.ndarray, prob: np.ndarray) -> np.ndarray | None:
    """The parts of a canvas that are the person's because the photo's bottom border cuts them (module docstring), or
    None.

    Args:
        canvas: (S, S, 3) float32 RGB in [0, 1].
        inside: (S, S) bool, the canvas pixels inside the photo.
        mine: (S, S) bool, the matte (the people found).
        prob: (S, S) float, the selfie graph's person probability (the own colours' ``prob``: 0 where the graph framed
            on the people does not see a person).

    Returns:
        (S, S) bool, the pixels added, or None when none is.
    """
    bottom = photo_bottom(inside)
    if not (mine & bottom).any():
        return None  # the person is not cut by the bottom border: what lies under them may be their ground
    cand = joined((prob >= OWN_SURE) & ~mine & inside, mine)
    if not (cand & bottom).any():
        return None
    # the parts are told apart above the bottom rows: a row of candidates along the border (where the matte, read
    # back on this canvas, stops a row short of it) would join them all
    n, labels = cv2.connectedComponents((cand & ~bottom).astype(np.uint8), connectivity=8)
    above = np.maximum.accumulate(mine, axis=0)  # the matte somewhere above in the same column
    least = max(1.0, OWN_MIN * int(mine.sum()))
    reach = cv2.dilate(bottom.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    keep = np.zeros(mine.shape, bool)
    model = None
    for k in range(1, n):
        part = labels == k
        size = int(part.sum())
        if size < least or not (part & reach).any() or (part & above).sum() < CUT_UNDER * size:
            continue
        model = colour_model(canvas, inside, mine, mine | cand) if model is None else model
        if model is None:
            return None
        lab, person, backdrop = model
        x = lab[part]
        if np.median(nearest(x, person)[0] / np.maximum(nearest(x, backdrop)[0], 1e-3)) < CUT_BACKDROP:
            keep |= part
    if not keep.any():
        return None
    # ... and carried on down to the border over the candidates in the bottom rows beside them
    rows = np.ones((2 * JOIN_GAP + 3, 3), np.uint8)
    return keep | (cv2.dilate(keep.astype(np.uint8), rows).astype(bool) & cand & bottom)
