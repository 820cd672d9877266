"""The person seen turned: limbs the graphs miss because the body is not upright, found by the selfie graph on the
person's region turned a quarter each way.

Both graphs were made for upright people. A runner lying along a wall, a trailing leg stretched out behind, a knee
raised across the body: the pose graph does not see the legs (probability < 0.1 over them on the parkour clip's
worst frames) and the selfie graph half-sees them upright (0.2-0.6). Turned a quarter to the left and to the right,
the same canvas shows the legs standing, and the selfie graph sees them (0.9 and more in both turns). It also sees
the backdrop between an arm and the body in a turned view, so a part is taken only where three tests agree: both
turns see it (their smaller probability, :data:`TURNED_SURE` on average over the part), an upright view sees it too
(the selfie graph on the region or on the whole photo, :data:`UPRIGHT_SEEN` on average: a turned view alone also
sees sky and lawn as a body) and its colours are not clearly the backdrop's (the median over its pixels of the
distance to the person's nearest k-means centre over that to the background ring's, below :data:`TURNED_COLOUR`: a
pale wall between arm and body). Only parts outside the matte that reach more than :data:`TURNED_OPEN` canvas pixels
past it and touch it are looked at: the turned views' outline differs from the matte's by a pixel or two all round,
which is no limb. The turned views are asked only where the upright view has such a part to offer (most photos of
one person have none: one selfie-graph run, shared with the own colours' test on the same region).

Measured (benchmarks/people_masks_eval.py --methods ours; the form chosen on the clip and an offline replay of both
halves of the photos, TURNED_COLOUR on the clip and half A among 0.8, 1.0, 1.3, 2.0, none: clip 0.9257, 0.9288, 0.9296,
0.9298, 0.9288; half A 0.9186 at 0.8-1.0, 0.9186 (+0.005 on one photo) at 1.3): clip 0.9248 -> 0.9296 (frame 31, the
runner lying on the wall, 0.54 -> 0.86; frame 19 +0.16, frame 50 +0.14; frame 96 -0.06: a dark car behind his arm,
the trousers' colour), photos half A 0.9178 -> 0.9186 (p184 +0.08; p194 -0.02), half B 0.8902 -> 0.8929 (checked: p227
+0.22, p158 +0.04; p098 -0.04). Tests: tests/runtime/person/matting/test_turned.py.
"""

from __future__ import annotations

import cv2
import numpy as np

from ...engine.session import Model
from ...image.regions import crop_region
from ._colours import OWN_MIN, colour_model, nearest
from ._detect import Around, around_people, roi_prob
from ._segmentation import Person, own_person

TURNED_SURE = 0.75  # the turned views' smaller probability, averaged over a part
UPRIGHT_SEEN = 0.5  # ... the upright selfie graph's (on the region or on the whole photo), averaged over it
TURNED_COLOUR = 1.3  # ... the median of its colours' distance to the person's over that to the background's
TURNED_OPEN = 7  # canvas pixels: a part must hold a disc this wide outside the matte


def turned_views(roi: Model, canvas: np.ndarray) -> np.ndarray:
    """The selfie graph's person probability on a (S, S, 3) float32 ``canvas`` turned a quarter to the left and a
    quarter to the right, each turned back: the smaller of the two, (S, S) float32."""
    out = []
    for k in (1, 3):
        turned = np.ascontiguousarray(np.rot90(canvas, k))
        prob = roi.run({"image": turned.transpose(2, 0, 1)[None]})["segmentation"][0, 0]
        out.append(np.rot90(prob, -k))
    return np.minimum(out[0], out[1]).astype(np.float32)


def reaching_past(cand: np.ndarray, mine: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """The parts of ``cand`` (bool canvas) that reach past the matte ``mine``: ``cand`` opened by a disc TURNED_OPEN
    canvas pixels wide (its core), the core's 8-connected labels, and the labels of the components within
    TURNED_OPEN + 1 pixels of ``mine`` and at least OWN_MIN x its size (smaller ones are its rim, as for the own
    colours)."""
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (TURNED_OPEN, TURNED_OPEN))
    core = cv2.morphologyEx(cand.astype(np.uint8), cv2.MORPH_OPEN, disc)
    if not core.any():
        return core.astype(bool), core.astype(np.int32), []
    near = cv2.dilate(mine.astype(np.uint8), np.ones((TURNED_OPEN + 2,) * 2, np.uint8)).astype(bool)
    n, labels = cv2.connectedComponents(core, connectivity=8)
    size = np.bincount(labels.ravel(), minlength=n)
    least = OWN_MIN * int(mine.sum())
    return core.astype(bool), labels, [int(i) for i in np.unique(labels[near]) if i > 0 and size[i] >= least]


def turned_part(
    canvas: np.ndarray, inside: np.ndarray, mine: np.ndarray, upright: np.ndarray, turned: np.ndarray
) -> np.ndarray | None:
    """The parts of a canvas that the turned views add to the matte (module docstring), or None.

    Args:
        canvas: (S, S, 3) float32 RGB in [0, 1].
        inside: (S, S) bool, the canvas pixels inside the photo.
        mine: (S, S) bool, the matte (the people found).
        upright: (S, S) float, the upright selfie graph's person probability (the larger of its answers).
        turned: (S, S) float, the turned views' person probability (:func:`turned_views`).

    Returns:
        (S, S) bool, the pixels added (each part as the turned views see it at >= 0.5), or None when none is.
    """
    cand = (turned >= 0.5) & ~mine & inside
    core, labels, parts = reaching_past(cand, mine)
    if not parts:
        return None
    model = colour_model(canvas, inside, mine, mine, apart=core)
    if model is None:
        return None
    lab, person, backdrop = model
    keep = np.zeros(mine.shape, bool)
    for i in parts:
        part = labels == i
        x = lab[part]
        ratio = nearest(x, person)[0] / np.maximum(nearest(x, backdrop)[0], 1e-3)
        if (turned[part].mean() >= TURNED_SURE and upright[part].mean() >= UPRIGHT_SEEN
                and np.median(ratio) < TURNED_COLOUR):  # fmt: skip
            keep |= part
    if not keep.any():
        return None
    # the part as the turned views see it: the opening's core grown back over their answer (its neck to the matte)
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (TURNED_OPEN, TURNED_OPEN))
    grown = cv2.dilate(keep.astype(np.uint8), disc).astype(bool) & cand
    _, labels = cv2.connectedComponents(grown.astype(np.uint8), connectivity=8)
    held = np.unique(labels[keep & grown])
    return np.isin(labels, held[held > 0]) | keep


def turned_people(roi: Model, rgb: np.ndarray, people: list[Person], start: Around | None = None) -> list[Person]:
    """What the selfie graph sees of ``people`` only turned (module docstring): [one Person holding it, source "own":
    part of the matte, no one's share of it] or []. On the canvas of a region around ``people`` (ROI_SCALE x their
    box; ``start``: :func:`around_people`'s answer for ``people`` when the caller has it); three selfie-graph runs
    (upright, and turned either way), the upright one shared with the other rules asking for that region."""
    start = around_people(roi, rgb, people) if start is None else start
    if start is None:
        return []
    region, seen, inside, mine = start
    upright = np.maximum(roi_prob(roi, rgb, region), seen)
    if not reaching_past((upright >= 0.5) & ~mine & inside, mine)[2]:
        return []  # nothing upright reaches past the matte: no part could pass (a photo of one person, mostly)
    canvas = crop_region(rgb, region)
    turned = turned_views(roi, canvas)
    part = turned_part(canvas, inside, mine, upright, turned)
    if part is None:
        return []
    return [own_person(region, part, mine, turned, people[0].presence)]
