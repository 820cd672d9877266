"""The body the photo's bottom border cuts: what the selfie graph is sure of under the matte, down to that border.

A person whose matte runs into the photo's bottom border is cut by the frame: under their matte, down to that border,
lies more of them. The pose graph, framed on what it sees, can miss a part there (a trouser leg, the bottom of a white
top: probability < 0.1 over it) that the selfie graph is sure of both on the whole photo and framed on the person
(each pixel >= OWN_SURE on the whole photo and >= 0.5 framed on the people: the own colours' candidates). The own
colours' step (relight_rt.person.matting._colours) refuses such a part where its colours lie near the backdrop's (grey
trousers before a grey wall: 11 % of their pixels pass its test); here the part is taken unless its colours are
clearly the backdrop's (median CUT_BACKDROP x nearer the backdrop's colours than the person's), and of it only the
pixels whose own colour passes that test (light between two legs that run off the frame, joined to a leg). The ground
can be in the frame here too (a woman seated on grass, p265; one lying in it, p101): what keeps it out is the colour
test, and that a part must lie under the matte and reach the bottom rows (below).

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
graph framed on the people alone is sure of (>= OWN_SURE): on the whole photo the graph, seeing people small, is unsure
of their own clothes at the border (p093, an embracing couple before the sea: the man's brown trousers 0.9+ framed on
the couple, 0.3-0.6 on the whole photo, the pose graph < 0.1). What that graph alone sees may as well be a chair or
someone behind, seen between the legs, or the ground a seated person is on. Of it only the shades of the person's
colours count (a*b* within CUT_SHADE of a colour of the matte's brought to the pixel's lightness: a lit crease of their
trousers, not a brown chair nor someone in red, who may touch a leg that graph alone sees and make one part with it:
judged by that part's median, the leg decided for the chair, 99 % of it taken). A part is judged, over those pixels, on
the own colours' model, whose backdrop ring round the matte and the own colours' candidates holds the framed graph's
pixels (a thing in a shade of the person's that is also the backdrop's stays out), and once it holds up, its pixels
on that ring's backdrop drawn again without them (the creases of a trouser leg, a shade the matte lacks, would
otherwise be their own backdrop: p093's trousers, judged on the first model alone, keep 894 of their 1262 canvas
pixels); where under 20 of that ring's pixels are left, the framed graph's pixels are kept as judged (testing them on
the first model, the creases joining the leg to the matte failed: the leg was lost whole). Measured
(benchmarks/people_masks_eval.py --methods ours; main of the day A 0.92340, B 0.90164, clip 0.93254), with the
backdrop without them for both: A and the clip unchanged (p094 +0.00001), B 0.90164 -> 0.90222 (p093 0.842 -> 0.902,
p126 +0.0003, p259 -0.0002); judging the part on the first model changed no photo's canvas (p093's part: median ratio
1.67 on it, 0.64 without them; p265's grass 2.8-3.3, refused; p101's and p234's fail where they lie). The shades'
test changed no photo's canvas either (p093's trousers lie within 4.3 of the matte's colours, p126's 19 such pixels
within 9.9; a dark-wood chair's 16 from black trousers).
The colours are looked at only where a part can be kept (the own colours' candidates at least OWN_MIN x the matte, or
a part of the bottom border's that passes the tests of where it lies); the second backdrop only once a part holds up
(~2 ms: benchmarks/own_colours_speed.py).
Tried (IoU on the canvas, a scratch estimate): a stricter colour test for what the framed graph alone sees instead of
the ring that holds it (a dark-wood chair between the legs has a median ratio of 0.34 without it, p093's trousers 0.64);
each connected piece of what the framed graph alone sees judged on its own on the first model (the creases' median ratio
1.4-2.2 on it, a dark-wood chair's 2.15: no bound keeps one and refuses the other, and they touch); the framed answer >=
0.5 (clip frame 84 -0.03), the ring drawn round all the candidates (measured: p259 -0.002, a white top's bottom whose
colour then lies near the new ring's), the thresholds swapped for the own colours' step (framed >= OWN_SURE, whole photo
>= 0.5: A -0.0001, p239 and p259 -0.02); for that step both >= 0.5 and either >= OWN_SURE (measured: B -0.0001, p246
+0.014 a child's dark trousers but p259 -0.019, the clip 0.93254 -> 0.93243, frame 92 -0.024).
Tests: tests/runtime/person/matting/test_cut_body.py.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ...image.regions import SIZE, Region, grid_of_region
from ._colours import OWN_MIN, OWN_SURE, Colours, backdrop_less, joined, nearest
from ._layout import JOIN_GAP

CUT_UNDER = 0.9  # a part lies under the matte: this share of its pixels has the matte above them in their column
CUT_BACKDROP = 2.0  # ... refused when its colours' median distance to the person's is this x that to the backdrop's
CUT_SHADE = 12.0  # a*b*: what the framed graph alone sees is a shade of the person's colour within this of it
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


@dataclass(frozen=True)
class CutBody:
    """A body the photo's bottom border cuts, on a canvas (:func:`cut_body`): the matte ``mine``, the own colours'
    candidates ``cand``, the bottom border's ``below`` (``cand`` and what the framed graph alone is sure of), the
    pixels inside the photo (``inside``) and its bottom rows (``bottom``), all (S, S) bool; and the ``parts`` of
    ``below`` that lie where that body goes on, each (part, its share of the ring beside the matte)."""

    mine: np.ndarray
    cand: np.ndarray
    below: np.ndarray
    inside: np.ndarray
    bottom: np.ndarray
    parts: tuple[tuple[np.ndarray, np.ndarray], ...]

    def part(self, model: Colours) -> np.ndarray | None:
        """The pixels added (module docstring), or None when none is. (S, S) bool.

        Args:
            model: the own colours' model (relight_rt.person.matting._colours.colour_model: the canvas's L*a*b*, the
                person's centres, those of the backdrop's ring round the matte and ``cand``, the pixels the framed
                graph alone is sure of kept in it). Of those pixels only the shades of the person's colours
                (:func:`shade_distances` < CUT_SHADE) may be added; a part is judged on the model over the pixels
                that may be; they are kept where their colour passes on it with that ring's backdrop drawn again
                without the framed graph's pixels (where no 20 pixels would be left: as judged, the own colours'
                candidates on the model).
        """
        alone = self.below & ~self.cand  # what the framed graph alone is sure of
        lab, person, _ = model
        may = self.cand.copy()  # of it, the shades of the person's colours (not a chair nor someone behind)
        may[alone] = shade_distances(lab[alone], person) < CUT_SHADE
        to_person = nearest(lab[may], person)[0]  # the same for both backdrops: measured once
        judged = ratios(may, model, to_person)
        held = [p | share for p, share in self.parts if (p & may).any() and np.median(judged[p & may]) < CUT_BACKDROP]
        if not held:
            return None
        beside = backdrop_less(model, self.inside, self.mine, self.mine | self.cand, alone) if alone.any() else None
        ratio = np.where(alone, 0.0, judged) if beside is None else ratios(may, beside, to_person)
        # carried on down to the border over the candidates in the bottom rows beside them; of it, the pixels whose own
        # colour is not clearly the backdrop's, joined to the matte
        keep = np.any(held, axis=0)
        rows = np.ones((2 * JOIN_GAP + 3, 3), np.uint8)
        keep |= cv2.dilate(keep.astype(np.uint8), rows).astype(bool) & self.below & self.bottom
        keep = joined(keep & may & (ratio < CUT_BACKDROP), self.mine)
        return keep if keep.any() else None


def shade_distances(x: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """(N,) float: each of (N, 3) L*a*b* ``x``'s a*b* distance to the nearest of (k, 3) ``centres`` brought to its
    lightness (a*, b* times (L* + 16) over the centre's: the same surface in more or less light, where L*a*b*'s cube
    root holds, L* > 8): small for a lit crease of the person's trousers, large for a thing of another hue."""
    s = (x[:, :1] + 16.0) / (centres[:, 0] + 16.0)[None, :]
    da = x[:, 1:2] - s * centres[None, :, 1]
    db = x[:, 2:3] - s * centres[None, :, 2]
    return np.sqrt(da * da + db * db).min(axis=1)


def ratios(cand: np.ndarray, model: Colours, to_person: np.ndarray | None = None) -> np.ndarray:
    """(S, S) float32: each of ``cand``'s pixels' distance to the person's nearest centre over that to the backdrop's
    (``model``), inf elsewhere. ``to_person``: the (N,) first distances (``cand``'s pixels in row-major order) when
    already measured on the same L*a*b* and person's centres (None: measured here)."""
    lab, person, backdrop = model
    ratio = np.full(cand.shape, np.inf, np.float32)
    x = lab[cand]
    near = nearest(x, person)[0] if to_person is None else to_person
    ratio[cand] = near / np.maximum(nearest(x, backdrop)[0], 1e-3)
    return ratio


def cut_body(inside: np.ndarray, mine: np.ndarray, cand: np.ndarray, framed: np.ndarray,
             bottom: np.ndarray) -> CutBody | None:  # fmt: skip
    """Where the bottom border cuts the people on a canvas, the parts that may be theirs by where they lie (module
    docstring: away from the matte and the bottom rows, reaching those rows, under the matte, at least OWN_MIN x its
    pixels, beside a piece of it that reaches the bottom rows); None when there is none (no colours need be looked
    at).

    Args:
        inside: (S, S) bool, the canvas pixels inside the photo.
        mine: (S, S) bool, the matte (the people found).
        cand: (S, S) bool, the own colours' candidates (relight_rt.person.matting._colours.candidates).
        framed: (S, S) float, the selfie graph's person probability framed on the canvas's region.
        bottom: (S, S) bool, the photo's bottom rows on the canvas (:func:`photo_bottom`).
    """
    if not (mine & bottom).any():
        return None  # no one is cut by the bottom border: what lies under them may be their ground
    below = cand | joined((framed >= OWN_SURE) & ~mine & inside, mine)
    if not (below & bottom).any():
        return None
    _, piece = cv2.connectedComponents(mine.astype(np.uint8), connectivity=8)
    cut = np.unique(piece[mine & bottom])  # the pieces of the matte that run into the bottom border
    near = cv2.dilate(mine.astype(np.uint8), np.ones((2 * CUT_NEAR + 1,) * 2, np.uint8)).astype(bool)
    n, labels, stats, _ = cv2.connectedComponentsWithStats((below & ~near & ~bottom).astype(np.uint8), connectivity=8)
    above = np.maximum.accumulate(mine, axis=0)  # the matte somewhere above in the same column
    least = max(1.0, OWN_MIN * int(mine.sum()))
    reach = cv2.dilate(bottom.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    beside = np.ones((2 * CUT_NEAR + 3,) * 2, np.uint8)  # a part's share of the ring, and the matte it lies beside
    parts = []
    for k in range(1, n):
        size = int(stats[k, cv2.CC_STAT_AREA])
        if size < least:
            continue  # (the canvas-wide tests below only for parts large enough)
        part = labels == k
        if not (part & reach).any() or (part & above).sum() < CUT_UNDER * size:
            continue
        around = cv2.dilate(part.astype(np.uint8), beside).astype(bool)
        if np.isin(piece[around & mine], cut).any():
            parts.append((part, around & below & near))
    return CutBody(mine, cand, below, inside, bottom, tuple(parts)) if parts else None
