"""The body the photo's bottom border cuts: what the selfie graph is sure of under the matte, down to that border.

A person whose matte runs into the photo's bottom border is cut by the frame: the ground they stand or sit on lies
outside the photo. Under their matte, down to that border, lies more of them. The pose graph, framed on what it sees,
can miss a part there (a trouser leg, the bottom of a white top: probability < 0.1 over it) that the selfie graph is
sure of both on the whole photo and framed on the person (each pixel >= OWN_SURE on the whole photo and >= 0.5 framed
on the people: the own colours' candidates). The own colours' step (relight_rt.person.matting._colours) refuses such
a part where its colours lie near the backdrop's (grey trousers before a grey wall: 11 % of their pixels pass its
test); here the ground the own colours' test is made to refuse is out of the frame, so the part is taken unless its
colours are clearly the backdrop's (median CUT_BACKDROP x nearer the backdrop's colours than the person's), and of it
only the pixels whose own colour passes that test (light between two legs that run off the frame, joined to a leg).

The candidates are told apart away from the matte (CUT_NEAR canvas pixels: the selfie graph's outline lies a pixel or
two outside the pose graph's, a ring that would join a bench beside the person to their missed leg) and above the
photo's bottom rows (where the matte, read back on this canvas, stops a row short of the border, a row of candidates
would join them all). A part is the person's when it reaches those rows, lies under the matte (CUT_UNDER of its pixels
have the matte above them in their column: not beside the person), holds at least OWN_MIN x the matte's pixels (not
its rim), and lies beside a piece of the matte that itself reaches the bottom rows: a person standing in the photo
keeps the own colours' test for what lies under their feet, also where someone beside them is cut by the border.
It gets back its share of the ring (the candidates within CUT_NEAR + 1 pixels of it) and is carried on down to the
border.

Measured (benchmarks/people_masks_eval.py --methods ours,selfie; no graph run more, the own colours' canvas and colour
model): half A 0.92087 and the clip 0.93254 unchanged (no part on them), half B 0.89581 -> 0.89695 (p126 +0.049: a grey
trouser leg before a grey wall, the pose graph 0.04 over it; p259 +0.069: the bottom of a white top). On that first
version, without the test of being under the matte: half A -0.0001 (p101 -0.011: the grass beside a woman lying in
it, which relight_rt.person.matting._layout.unconfirmed_cut drops, came back; p094 +0.003), B 0.89727 (p098 +0.034, not
taken here); without the colour test: B 0.89687 (p150 -0.008: the light between a man's legs); translucent interiors
(benchmarks/matte_translucent.py) B 1.92 % -> 1.89 %. The ring, the per-pixel colour test and the piece of the matte
reaching the bottom rows, added later (main of the day A 0.92339, B 0.90116, clip 0.93254): A and the clip unchanged,
B 0.90117 (p259 0.8990 -> 0.9001: 80 canvas pixels of the backdrop's colour off the top; p126 0.9725 -> 0.9724: 8
pixels of the ring beside the leg not given back).

Its candidates are the own colours' and, where the matte reaches the bottom rows, the pixels joined to it that the
graph framed on the people alone is sure of (>= OWN_SURE; relight_rt.person.matting._colours.candidates): the whole
photo's answer is asked to keep out the ground under a person's feet, which here lies out of the frame, and on the whole
photo the graph, seeing people small, is unsure of their own clothes at the border (p093, an embracing couple before the
sea: the man's brown trousers 0.9+ framed on the couple, 0.3-0.6 on the whole photo, the pose graph < 0.1). The colour
model's backdrop ring leaves those pixels out. Measured (benchmarks/people_masks_eval.py --methods ours; main of the
day A 0.92340, B 0.90164, clip 0.93254): A and the clip unchanged (p094 +0.00001), B 0.90164 -> 0.90222 (p093 0.842 ->
0.902, p126 +0.0003, p259 -0.0002); a second backdrop model (~2 ms, benchmarks/own_colours_speed.py) on 39 of the
208 photos, none on the reference photo.
Tried (IoU on the canvas, a scratch estimate): the framed answer >= 0.5 (clip frame 84 -0.03), the ring drawn round all
the candidates (measured: p259 -0.002, a white top's bottom whose colour then lies near the new ring's), the thresholds
swapped for the own colours' step (framed >= OWN_SURE, whole photo >= 0.5: A -0.0001, p239 and p259 -0.02); for that
step both >= 0.5 and either >= OWN_SURE (measured: B -0.0001, p246 +0.014 a child's dark trousers but p259 -0.019,
the clip 0.93254 -> 0.93243, frame 92 -0.024).
Tests: tests/runtime/person/matting/test_cut_body.py.
"""

from __future__ import annotations

import cv2
import numpy as np

from ...image.regions import SIZE, Region, grid_of_region
from ._colours import OWN_MIN, Colours, joined, nearest
from ._layout import JOIN_GAP

CUT_UNDER = 0.9  # a part lies under the matte: this share of its pixels has the matte above them in their column
CUT_BACKDROP = 2.0  # ... refused when its colours' median distance to the person's is this x that to the backdrop's
CUT_NEAR = 2  # canvas pixels: candidates this near the matte are its rim (the selfie graph's outline past the matte)


def photo_bottom(region: Region, shape: tuple[int, int], size: int = SIZE) -> np.ndarray:
    """(size, size) bool: the pixels of ``region``'s canvas on the last row of a photo of ``shape`` (H, W) or within
    JOIN_GAP canvas rows above it (a matte read back on another region's canvas can stop a row short of the border).
    A canvas row lies on the photo's last row when its centre lies inside the photo and the next row's does not,
    the canvas's own last row included."""
    h, w = shape
    k, bx, by = grid_of_region(region, size)
    c = np.arange(size, dtype=np.float64)
    y, x = (c - by) / k, (c - bx) / k  # image coordinates of the canvas pixels' centres (as canvas_points)
    rows = (y >= 0) & (y < h) & ((c + JOIN_GAP + 1 - by) / k >= h)
    return rows[:, None] & ((x >= 0) & (x < w))[None, :]


def cut_part(mine: np.ndarray, cand: np.ndarray, model: Colours, bottom: np.ndarray) -> np.ndarray | None:
    """The parts of a canvas that are the person's because the photo's bottom border cuts them (module docstring), or
    None.

    Args:
        mine: (S, S) bool, the matte (the people found).
        cand: (S, S) bool, the own colours' candidates (relight_rt.person.matting._colours.candidates).
        model: their colour model (the canvas's L*a*b*, the person's centres, the backdrop's: the same call).
        bottom: (S, S) bool, the photo's bottom rows on the canvas (:func:`photo_bottom`).

    Returns:
        (S, S) bool, the pixels added, or None when none is.
    """
    if not (mine & bottom).any() or not (cand & bottom).any():
        return None  # no one is cut by the bottom border: what lies under them may be their ground
    _, piece = cv2.connectedComponents(mine.astype(np.uint8), connectivity=8)
    cut = np.unique(piece[mine & bottom])  # the pieces of the matte that run into the bottom border
    near = cv2.dilate(mine.astype(np.uint8), np.ones((2 * CUT_NEAR + 1,) * 2, np.uint8)).astype(bool)
    n, labels, stats, _ = cv2.connectedComponentsWithStats((cand & ~near & ~bottom).astype(np.uint8), connectivity=8)
    above = np.maximum.accumulate(mine, axis=0)  # the matte somewhere above in the same column
    least = max(1.0, OWN_MIN * int(mine.sum()))
    reach = cv2.dilate(bottom.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    beside = np.ones((2 * CUT_NEAR + 3,) * 2, np.uint8)  # a part's share of the ring, and the matte it lies beside
    lab, person, backdrop = model
    ratio = np.full(mine.shape, np.inf, np.float32)  # each candidate's distance to the person's / the backdrop's
    x = lab[cand]
    ratio[cand] = nearest(x, person)[0] / np.maximum(nearest(x, backdrop)[0], 1e-3)
    keep = np.zeros(mine.shape, bool)
    for k in range(1, n):
        size = int(stats[k, cv2.CC_STAT_AREA])
        if size < least:
            continue  # (the canvas-wide tests below only for parts large enough)
        part = labels == k
        if not (part & reach).any() or (part & above).sum() < CUT_UNDER * size:
            continue
        around = cv2.dilate(part.astype(np.uint8), beside).astype(bool)
        if np.isin(piece[around & mine], cut).any() and np.median(ratio[part]) < CUT_BACKDROP:
            keep |= part | (around & cand & near)
    if not keep.any():
        return None
    # carried on down to the border over the candidates in the bottom rows beside them; of it, the pixels whose own
    # colour is not clearly the backdrop's, joined to the matte
    rows = np.ones((2 * JOIN_GAP + 3, 3), np.uint8)
    keep |= cv2.dilate(keep.astype(np.uint8), rows).astype(bool) & cand & bottom
    keep = joined(keep & (ratio < CUT_BACKDROP), mine)
    return keep if keep.any() else None
