"""The people with the largest person (person="largest"): those who stand with them, as tall and seen whole
(:func:`peers`: a group posing together is the photo's subject, a passer-by further back is not), and those joined to
them in the selfie graph's view of the whole photo who show a face of their own (:func:`joined`: a man embracing the
woman found, a child sitting against his mother).
"""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np

from ...engine.session import Model
from ...image.regions import Region, grid_of_region
from ..face_detector import Face
from ._candidate import Segmenter
from ._detect import roi_prob
from ._everyone import everyone
from ._layout import COVERED, PEER_HEIGHT, joined_part, people_whole, person_outside, someone_beside
from ._segmentation import (
    LOGIT_CLIP,
    Person,
    as_logits,
    canvas_points,
    contains,
    logits_on_grid,
    person_box,
    prob_at,
    working_grid,
)

_JOINED_FACE = 0.75  # a face outside the matte at least this sure, joined to it, is someone with them


def peers(matter: Segmenter, rgb: np.ndarray, main: Person, blobs: list, faces: list[Face]) -> list[Person]:
    """The people who stand with the largest person ``main`` (person="largest") in ``rgb`` (H, W, 3) float32
    [0, 1]: a group posing together is the photo's subject, a passer-by further back is not. A peer is a person that
    person="all" finds (relight_rt.person.matting._everyone.everyone, run by ``matter``) who is as tall as ``main``
    within a factor PEER_HEIGHT (seen at the same distance), seen whole (their box touches no border of the photo but
    the bottom, and that only where ``main``'s does too), not mostly ``main`` again (at most COVERED of them inside
    ``main``'s segmentation), and a body the pose graph sees or holding a face outside ``main`` (the selfie graph's
    segmentation of a treadmill beside a runner is neither; ``faces``: the face graph's on the whole photo). Looked
    for only where the selfie graph's ``blobs`` (``matter.find_people``'s) or ``faces`` show someone beside ``main``
    (:func:`someone_beside`): a photo of one person costs nothing more.

    Measured (benchmarks/people_masks_eval.py, photos half A; the service masks everyone in a group): mean IoU
    0.848 -> 0.903, share under 0.8 20 % -> 7.7 %, 15 photos better, none worse, at PEER_HEIGHT 0.7-0.85 (0.5:
    a man cut by the frame's side and a passer-by further back taken, 2 photos worse); looked for on 35 of the
    104 photos at BESIDE 0.1 (everywhere: the same figures; 0.25: 25 photos, two couples one behind the other
    missed)."""
    h, w = rgb.shape[:2]
    box = person_box(main, (h, w))
    if box is None:
        return []
    outside = [f for f in faces if not contains(main, f, (h, w))]
    if not someone_beside(box, blobs, outside):
        return []
    grid = working_grid((0, 0, w, h))
    mine = logits_on_grid(main, grid) > 0
    tall = box[3] - box[1]
    found = everyone(matter, rgb, PEER_HEIGHT * tall)
    out = []
    for p in found:
        mask = logits_on_grid(p, grid) > 0
        if mask.any() and (mask & mine).sum() >= COVERED * mask.sum():
            # mostly ``main`` again: the pose graph segments everyone in its region, so the segmentation of a
            # couple side by side holds both; what lies outside ``main`` may be the other one, whole
            p = person_outside(p, main)
            mask = logits_on_grid(p, grid) > 0
        b = person_box(p, (h, w))
        if b is None or not mask.any() or not PEER_HEIGHT * tall <= b[3] - b[1] <= tall / PEER_HEIGHT:
            continue
        if b[0] <= 1 or b[1] <= 1 or b[2] >= w - 1 or (b[3] >= h - 1 and box[3] < h - 1):
            continue  # cut by the frame: whole or not at all
        if p.source != "pose" and not any(contains(p, f, (h, w)) for f in outside):
            continue
        out.append(p)
    # a part split from a selfie-graph segmentation holding several people is matted from the whole of it
    # (rejoin): only where every part of that whole is taken, else from its own part
    taken = {id(p.whole) for p in out if p.whole is not None}
    split = {key: sum(id(q.whole) == key for q in found) for key in taken}
    return [p if p.whole is None or sum(id(q.whole) == id(p.whole) for q in out) == split[id(p.whole)]
            else replace(p, whole=None) for p in out]  # fmt: skip


def joined(roi: Model, rgb: np.ndarray, people: list[Person], faces: list[Face]) -> list[Person]:
    """The people joined to ``people`` in the selfie graph's (``roi``) view of the whole photo who show a face of their
    own (person="largest"): [one "roi" Person holding them] or []. A face at least _JOINED_FACE sure whose
    middle no one in ``people`` covers, lying in a part of the selfie graph's segmentation (>= 0.5, outside
    ``people``) that touches them (:func:`joined_part`), is someone standing with them: a man embracing the
    woman found, a boy sitting against his mother, a monk beside another (the pose graph segments one of them;
    :func:`peers` asks for a person seen whole and as tall, which a couple's overlapping bodies and a seated
    child are not). The part is taken as the selfie graph sees it, softly (its probability as logits, one
    canvas pixel around it). One selfie-graph run, only where such a face is.

    Measured (benchmarks/people_masks_eval.py, photos; ``faces`` from the whole photo, PersonMatter.find_faces): half
    B 0.863 -> 0.869 (three photos 0.06-0.40 better), half A unchanged at a face score of 0.75 (at 0.5: two
    photos 0.18-0.20 worse, a shop's mannequin and a child's face beside the person in a street), the clip
    unchanged (no face joined)."""
    h, w = rgb.shape[:2]
    sure = [f for f in faces if f.score >= _JOINED_FACE]
    outside = [f for f in sure if not any(contains(p, f, (h, w)) for p in people)]
    if not outside and len(sure) < 2:
        return []
    region = Region(w / 2, h / 2, float(max(h, w)))
    prob = roi_prob(roi, rgb, region)
    k, bx, by = grid_of_region(region)
    xs, ys = canvas_points(region)
    mine = np.any([prob_at(p, xs, ys) > 0.5 for p in people], axis=0)
    seeds = [(int(np.floor(k * (f.box[1] + f.box[3]) / 2 + by + 0.5)),
              int(np.floor(k * (f.box[0] + f.box[2]) / 2 + bx + 0.5))) for f in sure]  # fmt: skip
    part = people_whole(prob, mine, seeds)  # two people at the matte: both whole
    if part is None:  # else a face outside the matte brings the part of its own that touches the matte
        part = joined_part(prob, mine, [s for s, f in zip(seeds, sure, strict=True) if f in outside])
    if part is None:
        return []
    rim = cv2.dilate(part.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool) & ~mine
    logits = np.where(rim, as_logits(prob), -LOGIT_CLIP).astype(np.float32)
    return [Person(region, logits, max(f.score for f in outside or sure), "roi")]
