"""Where the matter's people stand: boxes against the image's border and each other, a person less another, who
straddles two, who stands beside (the geometric rules of the person matter's choices:
relight_rt.person.matting._candidate, ._largest, ._everyone, ._company)."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np

from ...image.regions import Region, grid_of_region
from ..face_detector import Face
from ._models import SIZE
from ._parts import faces_side_by_side, split_by_faces
from ._segmentation import LOGIT_CLIP, Person, as_logits, contains, logits_on_grid, person_box, prob_at, sigmoid

COVERED = 0.5  # a candidate (blob) this much inside people already matted is one of them
STRADDLE = 0.75  # person="all": a pose-graph person this much inside the others together straddles two
CUT_WIDTH = 0.125  # a portrait's body is cut by the bottom border over at least this x its box's width
PEER_HEIGHT = 0.75  # person="largest": someone beside the person, as tall within this factor, stands with them
BESIDE = 0.1  # ... looked for where a blob of the selfie graph reaches this x the person's width past their box
SURE_PART = 0.95  # a part carried on past a region's cut side needs the selfie graph's mean probability this high
JOIN_GAP = 2  # canvas pixels: a part of the selfie graph's segmentation this close to the matte is joined to it
DOUBTED_PART = 0.8  # a part of a portrait framed on the whole photo that framed on its face is unseen: kept this sure
LOST_SHARE = 0.5  # a drop holding this share of the first answer's person or more: the other answer lost them


def person_outside(person: Person, other: Person) -> Person:
    """``person`` less what ``other`` holds: at each pixel of its canvas the smaller of its logit and the negated
    logit of ``other`` there (a soft cut along ``other``'s outline)."""
    k, bx, by = grid_of_region(person.region)
    c = (np.arange(SIZE, dtype=np.float64) - np.array([[bx], [by]])) / k  # image x of the columns, y of the rows
    xs, ys = np.meshgrid(c[0], c[1])
    p = np.clip(prob_at(other, xs.ravel(), ys.ravel()).reshape(SIZE, SIZE), 1e-6, 1 - 1e-6)
    theirs = np.log(p) - np.log1p(-p)
    return replace(person, logits=np.minimum(person.logits, -theirs).astype(np.float32), whole=None)


def someone_beside(box, blobs: list, faces: list[Face]) -> bool:
    """Whether anyone may stand beside the person in ``box``: a face outside them, or a blob of the selfie graph
    (:func:`relight_rt.person.matting._detect.find_people`) at least PEER_HEIGHT x their height tall that reaches
    BESIDE x their width or more past their box's sides."""
    if faces:
        return True
    x0, y0, x1, y1 = box
    for _, (bx0, by0, bx1, by1) in blobs:
        past = max(x0 - bx0, 0.0) + max(bx1 - x1, 0.0) if by1 > y0 and by0 < y1 else bx1 - bx0
        if by1 - by0 >= PEER_HEIGHT * (y1 - y0) and past >= BESIDE * (x1 - x0):
            return True
    return False


def grow_where_cut(
    box: tuple[float, float, float, float], region: Region, shape: tuple[int, int]
) -> tuple[float, float, float, float]:
    """Extend ``box`` by half its size past each side where the segmentation runs into the region's edge
    inside the image: the person goes on beyond the region (the region finder saw only part of them,
    e.g. the head of a small person), so the next region must reach further."""
    h, w = shape
    x0, y0, x1, y1 = box
    rx0, ry0, rx1, ry1 = region.box()
    m = 0.03 * region.side
    bw, bh = x1 - x0, y1 - y0
    grow = 0.5 * max(bw, bh)
    nx0 = x0 - grow if x0 <= rx0 + m and rx0 > 0 else x0
    ny0 = y0 - grow if y0 <= ry0 + m and ry0 > 0 else y0
    nx1 = x1 + grow if x1 >= rx1 - m and rx1 < w else x1
    ny1 = y1 + grow if y1 >= ry1 - m and ry1 < h else y1
    return max(nx0, 0.0), max(ny0, 0.0), min(nx1, float(w)), min(ny1, float(h))


def box_past_border(box, shape: tuple[int, int]) -> tuple[float, float, float, float] | None:
    """A segmentation ``box`` that runs into the image border, extended by half its size past each border it
    touches (not clipped), or None when it touches none. The pose graph sees a person by their whole body:
    framed on the visible part of someone cut by the border (a fighter cut at the thighs) it can say nobody
    is there (presence 0.006), framed as if the body went on it sees them (0.99)."""
    if box is None:
        return None
    h, w = shape
    x0, y0, x1, y1 = box
    grow = 0.5 * max(x1 - x0, y1 - y0)
    cut = (x0 <= 1, y0 <= 1, x1 >= w - 1, y1 >= h - 1)
    if not any(cut):
        return None
    return x0 - grow * cut[0], y0 - grow * cut[1], x1 + grow * cut[2], y1 + grow * cut[3]


def is_portrait(roi: Person, shape: tuple[int, int]) -> bool:
    """Head-and-shoulders (or chest-up) framing: the person as the selfie graph sees them in the region runs
    off the bottom of the image across at least CUT_WIDTH of their box's width (the torso is cut there), and
    their visible box is less than 1.8x as tall as wide. The pose graph was trained on bodies and loses the
    shoulders of such crops (IoU 0.71-0.85 on crops of the reference video); the selfie graph, made for them,
    keeps them (0.97-0.99). Full bodies and knee-up crops stay with the pose graph (0.97-0.99 there, the selfie
    graph 0.92-0.97), and so does a body across the frame that only a foot or skate cuts at the bottom (a
    skater in a spin: 0.07 of the width, where portraits measure 0.5-0.99 and a waist-up photo 0.18): wide
    and touching the bottom, it looked like a portrait."""
    h, w = shape
    box = person_box(roi, shape)
    if box is None:
        return False
    x0, y0, x1, y1 = box
    if y1 < h - 2 or (y1 - y0) >= 1.8 * (x1 - x0):
        return False
    xs = np.linspace(x0, x1, 256)
    return bool((prob_at(roi, xs, np.full(xs.shape, h - 1.0)) > 0.5).mean() >= CUT_WIDTH)


def without_straddlers(
    people: list[Person], grid, faces: list[Face] = (), shape: tuple[int, int] | None = None
) -> list[Person]:
    """``people`` less each pose-graph person whose segmentation lies at least STRADDLE inside the other people
    together: a region framed between two people side by side, on which the pose graph (which segments one
    person) answers with a body across both (two men crouching face to face came out as 3: the straddling one
    lies 0.81 inside the two, 0.46 at most inside either; between distinct people found by the pose graph on the
    13 photos of benchmarks/people_photos.py with several people, each at 3 framings shifted by 0-1 px, at most
    0.47). The one lying most inside the others goes first. The others are the pose-graph people and the parts of
    selfie-graph segmentations split by faces (:func:`split_by_faces`: each is one person's share of the
    canvas; group_t1's pose-graph box across Rachel's head and Ross's body lay 0.19 inside Rachel and 0.68
    inside Ross's part). A person who alone holds one of ``faces`` (image ``shape``) stays: on group_t1 shifted
    by a pixel that box was the only one holding Rachel's face. Only pose-graph people are dropped, and an
    unsplit selfie-graph person is not one of the others: it segments everyone in its region, so it overlaps its
    neighbours by nature (up to 0.99 in a group seen face by face)."""
    ones = [i for i, p in enumerate(people) if p.source == "pose" or p.whole is not None]
    if len(ones) < 3 or not any(people[i].source == "pose" for i in ones):
        return people
    masks = {i: logits_on_grid(people[i], grid) > 0 for i in ones}
    holds = {i: {j for j, f in enumerate(faces) if shape is not None and contains(people[i], f, shape)} for i in ones}
    kept = set(ones)
    while len(kept) >= 3:
        inside = {}
        for i in kept:
            if people[i].source != "pose":
                continue
            others = np.zeros_like(masks[i])
            held = set()
            for j in kept - {i}:
                others |= masks[j]
                held |= holds[j]
            if holds[i] <= held:
                inside[i] = float(others[masks[i]].mean()) if masks[i].any() else 0.0
        if not inside:
            break
        worst = max(inside, key=inside.get)
        if inside[worst] < STRADDLE:
            break
        kept.discard(worst)
    return [p for i, p in enumerate(people) if i in kept or i not in masks]


def resampled(person: Person, region: Region) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``person``'s logits on ``region``'s canvas (nearest canvas pixel; -LOGIT_CLIP outside ``person``'s region),
    and the image x of that canvas's columns' centres and y of its rows'."""
    k, bx, by = grid_of_region(region)
    c = np.arange(SIZE, dtype=np.float64)
    x, y = (c - bx) / k, (c - by) / k
    kf, bxf, byf = grid_of_region(person.region)
    i = np.floor(kf * y + byf + 0.5).astype(int)  # nearest canvas pixel of person's region
    j = np.floor(kf * x + bxf + 0.5).astype(int)
    rows, cols = (i >= 0) & (i < SIZE), (j >= 0) & (j < SIZE)
    out = np.full((SIZE, SIZE), -LOGIT_CLIP, np.float32)
    out[np.ix_(rows, cols)] = person.logits[np.ix_(i[rows], j[cols])]
    return out, x, y


def continued(wide: Person, first: Person, cut: tuple[bool, bool, bool, bool]) -> Person:
    """``first`` (a selfie-graph segmentation that runs into its region's sides ``cut`` = (left, top, right, bottom)
    inside the image) carried on past those sides by ``wide`` (the same graph's segmentation of a region reaching
    further), on ``wide``'s canvas: ``first``'s logits over its own region, and past each cut side only the parts of
    ``wide``'s segmentation that go on from where ``first`` was cut (8-connected to a canvas pixel next to one of
    ``first``'s person pixels on its region's edge) and that the graph is sure of (mean probability >= SURE_PART: a
    red wall's glow and a blurred shoulder behind were taken at 0.9), with one canvas pixel around them. Nothing of
    ``wide`` elsewhere: framed larger, the graph can answer worse over ``first``'s region (half a face lost against
    a bright sky)."""
    before, x, y = resampled(first, wide.region)
    x0, y0, x1, y1 = first.region.box()
    xs, ys = x[None, :], y[:, None]
    own = (xs >= x0) & (xs <= x1) & (ys >= y0) & (ys <= y1)
    sides = (xs < x0, ys < y0, xs > x1, ys > y1)
    past = np.zeros((SIZE, SIZE), bool)
    for side, beyond in zip(cut, sides, strict=True):
        if side:
            past |= beyond & ~own
    part = parts_going_on(wide.logits, before, own, past, SURE_PART) > 0
    if not part.any():
        return first
    rim = cv2.dilate(part.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool) & past
    return Person(wide.region, np.where(rim, wide.logits, before).astype(np.float32), first.presence, first.source)


def parts_going_on(
    wide: np.ndarray, before: np.ndarray, own: np.ndarray, past: np.ndarray, sure: float
) -> np.ndarray:  # fmt: skip
    """The parts of a wider answer that go on past a region's cut sides from the person cut there, all on one canvas
    ((256, 256) each): ``wide`` the wider answer's logits, ``before`` the person's logits, ``own`` the pixels of the
    person's region, ``past`` those beyond its cut sides. Returns the 8-connected components' labels (int32, 0 none)
    of ``wide``'s person pixels past the cut that hold a pixel next to one of the person's pixels inside the region
    and whose mean probability under ``wide`` is ``sure`` or more; every other component's label is 0
    (:func:`continued`; relight_rt.person.matting._selfie.carried_past)."""
    seeds = past & cv2.dilate(((before > 0) & own).astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    mask = (wide > 0) & past
    _, labels = cv2.connectedComponents(mask.astype(np.uint8), connectivity=8)
    keep = [k for k in np.unique(labels[seeds & mask]) if k > 0]
    keep = [k for k in keep if sigmoid(wide[labels == k]).mean() >= sure]
    return np.where(np.isin(labels, keep), labels, 0).astype(np.int32)


def unconfirmed_cut(wide: Person, first: Person, cut: tuple[bool, bool, bool, bool]) -> Person:
    """``first`` (a selfie-graph segmentation that runs into its region's sides ``cut`` = (left, top, right, bottom)
    inside the image) less what runs into a cut side that ``wide`` (the same graph on a region reaching past it)
    does not see (< 0.5) and ``first`` is not sure of (mean probability < SURE_PART): the parts of ``first``'s person
    pixels outside ``wide``'s person, 8-connected to a cut side's edge column or row of its canvas. Whole or not at
    all, as :func:`continued` carries on only what goes on past the side: the graph takes in whatever its frame cuts
    at the bottom (grass around a woman lying in it matted in two blocks ending in the region's straight sides),
    framed wider it does not. Nothing is dropped where it would take most of the person (the wider run lost them: it
    can lose half a face against a bright sky, :func:`relight_rt.person.matting._selfie.widened`). Measured
    (benchmarks/people_masks_eval.py, matte14; no new threshold): half A 0.91967 -> 0.92047 (p101 +0.083: that
    grass; p083 +0.002; the worst p177 -0.001), half B 0.89509 -> 0.89602 (p265 +0.076: the grass under sitting
    children beside a region's side; p225 +0.018), the clip unchanged."""
    after, _, _ = resampled(wide, first.region)
    cand = (first.logits > 0) & (after <= 0)
    edge = np.zeros((SIZE, SIZE), bool)
    for side, line in zip(cut, (np.s_[:, 0], np.s_[0, :], np.s_[:, -1], np.s_[-1, :]), strict=True):
        if side:
            edge[line] = True
    return _less_unsure(first, cand, edge, SURE_PART)


def unconfirmed(first: Person, second: Person) -> Person:
    """``first`` (the selfie graph's segmentation of a region) less the parts that ``second`` (the same graph framed
    otherwise) does not see (< 0.5) where it looks and ``first`` is unsure of (mean probability < DOUBTED_PART): the
    8-connected components of ``first``'s person pixels outside ``second``'s person that reach, inside ``second``'s
    region, further than JOIN_GAP canvas pixels from it (nearer, the two answers only draw one outline a little
    apart: the photo decides there at full resolution), whole. Outside ``second``'s region nothing is known: a part
    lying all there stays (someone beside the person the face's framing does not reach). Nothing is dropped where it
    would take LOST_SHARE or more of the person (:func:`_less_unsure`). Framed on the whole photo, the graph sees its
    background small and takes in textured ground joined to the person at 0.5-0.7 (the pale rocks beside a woman's
    shoulder, a blurred hedge beside a portrait), which framed on the person it leaves out; what it is sure of stays
    (a lit star decoration a man stands beside, 0.83, which the service's mask holds)."""
    after, x, y = resampled(second, first.region)
    x0, y0, x1, y1 = second.region.box()
    looked = ((y >= y0) & (y < y1))[:, None] & ((x >= x0) & (x < x1))[None, :]
    cand = (first.logits > 0) & (after <= 0)
    return _less_unsure(first, cand, cand & looked & ~_near(after > 0), DOUBTED_PART)


def _less_unsure(first: Person, cand: np.ndarray, seeds: np.ndarray, sure: float) -> Person:
    """``first`` less the 8-connected components of ``cand`` (bool canvas) holding a pixel of ``seeds`` whose mean
    probability under ``first`` is below ``sure``, whole; ``first`` itself where none is, or where they hold
    LOST_SHARE or more of its person pixels: the other answer lost the person (half a face against a bright sky, a
    body seen only at the face), it did not find ground beside them."""
    _, labels = cv2.connectedComponents(cand.astype(np.uint8), connectivity=8)
    drop = [k for k in np.unique(labels[seeds & cand]) if k > 0]
    drop = [k for k in drop if sigmoid(first.logits[labels == k]).mean() < sure]
    gone = np.isin(labels, drop)
    mine = first.logits > 0
    if not drop or (gone & mine).sum() >= LOST_SHARE * mine.sum():
        return first
    logits = np.where(gone, np.float32(-LOGIT_CLIP), first.logits).astype(np.float32)
    return replace(first, logits=logits)


def held(raised: Person, first: Person, shape: tuple[int, int]) -> Person:
    """The selfie graph's segmentation ``raised`` (of a region reaching higher than ``first``'s) joined with
    ``first`` (the larger logit where both regions reach) and kept to ``first``'s columns (its box, widened by
    3 % of its width each side). Joined: framed on the whole head, the selfie graph is less sure of the body
    at the bottom corners (DPR's portrait: the checked shirt 0.96 / 0.50 -> 0.59 / 0.41 at the bottom left /
    right). The larger logit, not the smaller: ``first``'s answer is weakest right below the top its region cut
    (held to it, the hair had a notch at the temple)."""
    box = person_box(first, shape)
    if box is None:
        return raised
    margin = 0.03 * (box[2] - box[0])
    before, x, _ = resampled(first, raised.region)
    within = ((x >= box[0] - margin) & (x <= box[2] + margin))[None, :]
    logits = np.where(within, np.maximum(raised.logits, before), np.float32(-LOGIT_CLIP)).astype(np.float32)
    return Person(raised.region, logits, raised.presence, raised.source)


def as_people(
    p: Person, k: int | None, faces: list[Face], owned: set[int], shape: tuple[int, int]
) -> tuple[list[Person], list[int]]:
    """A segmentation newly kept by person="all" as people, and the faces it takes (indices into ``faces``;
    ``k``: the face it was found from, None for a blob). The selfie graph segments everyone in its region, so
    people side by side come as one segmentation holding several faces: one person per face not taken yet
    (:func:`split_by_faces`; the matte stays their union). The faces of people matted already take their share
    of the canvas too, so that a new person's part holds none of them (group_t1: Monica's face gave a part
    holding Rachel, Ross and half of Chandler, and a straddling box across Rachel and Ross lay inside it). A
    pose-graph person found from a blob holding several faces side by side takes none of them: the pose graph
    segments one person, and framed between two in a group it answers with a body across both, holding little
    of the second (group_t1 less its bottom row: such a box across Rachel and Ross took Ross's face, Ross's own
    search was skipped, and the box was dropped as a straddler: 5 people); the faces' own searches find them
    (:func:`without_straddlers` then drops the box)."""
    held = [j for j, f in enumerate(faces) if contains(p, f, shape)]
    mine = [j for j in held if j not in owned]
    side_by_side = faces_side_by_side([faces[j] for j in held])
    taken = {id(faces[j]) for j in owned}  # side_by_side holds the same Face objects
    new = [i for i, f in enumerate(side_by_side) if id(f) not in taken]
    if p.source == "roi" and len(side_by_side) >= 2 and new:
        parts = split_by_faces(p, side_by_side)
        return [parts[i] for i in new], mine
    if p.source == "pose" and k is None and len(side_by_side) >= 2:
        return [p], []  # a box across people side by side: each face's own search decides who they are
    return [p], ([k] if k is not None else mine[:1])


def face_share(p: Person, k: int | None, faces: list[Face], shape: tuple[int, int]) -> Person:
    """The part of ``p`` that stands for face ``k`` (``faces[k]``): its share when ``p`` is a selfie-graph
    segmentation holding that face among several side by side (:func:`split_by_faces`, as :func:`as_people`
    splits it), else ``p`` itself. A face's person is judged on this share: the selfie graph's region of one face
    in a group shows the neighbours too, and whether they were matted already says nothing of that face's
    person (group_t1 less its top row: Joey's segmentation, three faces wide, lay 0.80 inside the people matted
    before, his own share 0.44, and he was taken for one of them: 5 people)."""
    if k is None or p.source != "roi" or not contains(p, faces[k], shape):
        return p
    side_by_side = faces_side_by_side([f for f in faces if contains(p, f, shape)])
    if len(side_by_side) < 2:
        return p
    mine = [i for i, f in enumerate(side_by_side) if f is faces[k]]
    return split_by_faces(p, side_by_side)[mine[0]] if mine else p


def within_photo(region: Region, shape: tuple[int, int]) -> Region:
    """``region``, or the whole photo's square (centred, as wide as its longer side) when ``region`` is wider: a
    portrait's region framed on a box as wide as the photo shows the selfie graph the photo smaller than the
    photo itself does, with empty margins around it, and it then took the halo and the print of a red poster
    behind a man's head (p183 of people_masks: IoU 0.67 framed 800 px wide, 0.86 on the photo's square).
    Keeping the region's centre at the photo's width instead gained half as much (default matte photos
    +0.001, not +0.002)."""
    h, w = shape
    if region.side <= max(h, w):
        return region
    return Region(w / 2, h / 2, float(max(h, w)))


def box_beside(box, other) -> tuple[float, float, float, float] | None:
    """The part of ``box`` left of or right of the box ``other`` (the wider part), kept to the rows ``other``
    spans where the two share rows, or None when less than a quarter of ``box``'s width remains.

    Kept to ``other``'s rows: someone standing beside a person spans about their rows, while a blob of the selfie
    graph over tiles often reaches further (the road below a couple walking side by side: a blob 440 px tall
    around two people 180 px tall), and the square region framed on such a part beside is then mostly road, where
    the pose graph sees nobody. Measured (benchmarks/people_masks_eval.py, photos, --inset 1; only where the pose
    graph re-centred onto the neighbour matted already): half A 0.9237 -> 0.9238 (a passer-by found, +0.012),
    half B 0.8976 -> 0.9011 (the woman walking beside her partner, 0.54 -> 0.91; a group -0.005)."""
    if other is None:
        return None
    x0, y0, x1, y1 = box
    left, right = (x0, min(x1, other[0])), (max(x0, other[2]), x1)
    a, b = max(left, right, key=lambda t: t[1] - t[0])
    if b - a < 0.25 * (x1 - x0):
        return None
    top, bottom = max(y0, other[1]), min(y1, other[3])
    return (a, top, b, bottom) if bottom > top else (a, y0, b, y1)


def mostly_in(mask: np.ndarray, occupied: np.ndarray) -> bool:
    """Whether a person's mask (working grid) lies mostly (COVERED) inside the people matted already."""
    return bool(mask.any() and occupied[mask].mean() >= COVERED)


def box_area(box) -> float:
    return max(box[2] - box[0], 0.0) * max(box[3] - box[1], 0.0)


def box_height(box) -> float:
    return 0.0 if box is None else box[3] - box[1]


def joined_part(prob: np.ndarray, mine: np.ndarray, seeds: list[tuple[int, int]]) -> np.ndarray | None:
    """Where the selfie graph sees someone joined to the people matted: the 8-connected components of its person
    pixels outside them (``prob`` >= 0.5 and not ``mine``, both on one canvas) that hold a ``seeds`` point (row,
    column: a face the matte does not hold) and touch ``mine`` (within JOIN_GAP canvas pixels); None when none does.
    A face alone says someone is there; joined in the selfie graph's view, they stand with the person (a couple
    embracing, a child leaning on a mother); a face apart from them is a passer-by."""
    found = _seeded_parts((prob >= 0.5) & ~mine, mine, seeds)
    if found is None:
        return None
    labels, _, touching = found
    part = np.isin(labels, list(touching))
    return part if part.any() else None


def _near(mine: np.ndarray) -> np.ndarray:
    """(H, W) bool: within JOIN_GAP canvas pixels of ``mine`` (a part there is joined to it)."""
    return cv2.dilate(mine.astype(np.uint8), np.ones((2 * JOIN_GAP + 1,) * 2, np.uint8)).astype(bool)


def _seeded_parts(person: np.ndarray, mine: np.ndarray, seeds: list[tuple[int, int]]):
    """The 8-connected components of ``person`` (bool canvas): (labels, the label under each seed that lies on the
    canvas (0: none), the set of those components that touch ``mine`` within JOIN_GAP); None without a component."""
    n, labels = cv2.connectedComponents(person.astype(np.uint8), connectivity=8)
    if n <= 1:
        return None
    near = _near(mine)
    held = [int(labels[i, j]) for i, j in seeds if 0 <= i < labels.shape[0] and 0 <= j < labels.shape[1]]
    touching = {label for label in set(held) - {0} if (near & (labels == label)).any()}
    return labels, held, touching


WHOLE_SURE = 0.95  # people_whole: the selfie graph's probability over what completes a second person


def people_whole(prob: np.ndarray, mine: np.ndarray, seeds: list[tuple[int, int]]) -> np.ndarray | None:
    """The selfie graph's people at the matte, each whole: when its person pixels (``prob`` >= 0.5, one canvas with
    ``mine``) that touch ``mine`` (within JOIN_GAP canvas pixels) hold two or more ``seeds`` (faces), the components
    holding them, less ``mine``; else None. Two faces in the matte or joined to it are two people, and the matte
    held the second in part: the pose graph's segmentation of a region holding two (a couple embracing, two women
    posing arm in arm) takes the other's head or legs or not, and the part outside it that :func:`joined_part` finds
    from their face stops where the matte cuts them. Completed as the selfie graph sees them, where it is sure (>=
    WHOLE_SURE): on the whole photo's 256² canvas it fills the gaps between people standing close (foliage, a wall) at
    0.5-0.9. Measured (benchmarks/people_masks_eval.py; WHOLE_SURE chosen on photos half A among 0.5, 0.8, 0.95, on the
    photos the rule moves at 0.5: their half-A sum -0.019, -0.001, +0.0005): half A 0.9167 -> 0.9168 (a trio +0.016; a
    couple holding hands -0.010 and three men -0.005, the gaps between them), half B 0.8881 -> 0.8900 (the couple
    embracing 0.63 -> 0.84, the women arm in arm 0.854 -> 0.879; the wall between two girls on a bench -0.016, a group
    -0.017), the clip unchanged. No graph run more (the whole photo's answer is the region finder's)."""
    found = _seeded_parts(prob >= 0.5, mine, seeds)
    if found is None:
        return None
    labels, held, touching = found
    if sum(label in touching for label in held) < 2:
        return None
    part = np.isin(labels, list(touching)) & ~mine & (prob >= WHOLE_SURE)
    return part if part.any() else None


WHOLE_IN = 0.9  # seen_whole: this share of the pose graph's person lies inside the selfie graph's view of the photo
WHOLE_IOU = 0.6  # ... and the two overlap this much (IoU)


def seen_whole(mine: np.ndarray, seen: np.ndarray) -> bool:
    """Whether the pose graph's person ``mine`` (bool, its canvas) is the shape the selfie graph sees on the whole
    photo (``seen``, on the same canvas): at least WHOLE_IN of it inside, overlapping at least WHOLE_IOU."""
    both = int((mine & seen).sum())
    return both > 0 and both >= WHOLE_IN * int(mine.sum()) and both >= WHOLE_IOU * int((mine | seen).sum())


BLEND_IOU = 0.6  # blended: the selfie graph's two answers agree this much (IoU) where they are averaged
BLEND_TAKE = 0.9  # ... except where the region's answer leaves out what the whole photo's sees this surely: taken


def blended(person: Person, seen: np.ndarray, seen_side: float) -> Person:
    """A selfie-graph person (its region's answer) averaged with the selfie graph's answer on the whole photo
    (``seen``, its probability on the same canvas; ``seen_side``, the side in photo pixels of the square that
    answer's canvas spans) where the two agree (IoU of their masks >= BLEND_IOU); else
    as it is. Framed on the person, the graph takes in more of what stands behind them (grass either side of a
    woman lying in it, a blurred guitar behind a girl, a tap beside a boy); framed on the photo it loses half a
    woman or takes a passer-by (averaged whatever they say, two photos 0.08-0.10 worse), which the agreement
    test leaves out. Measured (benchmarks/people_masks_eval.py; BLEND_IOU chosen on photos half A among 0.5-0.9:
    0.913 at 0.5-0.6, 0.912 at 0.7, 0.911 at 0.75-0.85, 0.910 at 0.9; the clip's people are the pose graph's):
    half A 0.910 -> 0.913 (mannequins +0.10, the worst -0.02), half B 0.8835 -> 0.8851 (the worst -0.015).

    The average only takes from the region's answer (matte15): where that answer leaves a pixel out and the whole
    photo's sees more, the mean of a 0 and a 0.9 is a veil at alpha 0.3-0.45, pasted into every composite (p101: over a
    grass block :func:`unconfirmed_cut` had dropped whole and over her arm beside it; p285: a jacket's shoulder the
    framed run missed). There the pixel is decided, not mixed: the whole photo's answer where it is sure (>= BLEND_TAKE)
    in a part joined to the person (within JOIN_GAP canvas pixels: a sure blob apart is someone else), the region's
    answer elsewhere (a rule's drop stays dropped). Measured (people_masks_eval.py; BLEND_TAKE among 0.8, 0.9, 0.95 on
    half A: 0.92085, 0.92087, 0.92087): half A 0.92047 -> 0.92087 (p285 +0.028: the shoulder whole; p083 +0.021; p101
    -0.005: the grass veil gone, a strip of her arm with it; the worst p270 -0.004), half B 0.89602 -> 0.89581 (p190
    -0.026: a patch above a seated man's head that the whole photo sees at 0.97 and the service's mask leaves out, now
    opaque, before a veil at 0.68; p246 -0.014: a group's far side the whole photo half-sees, 0.34 -> 0.30; p282
    +0.009), the clip unchanged (0.93254); translucent interiors (benchmarks/matte_translucent.py) A 1.45 -> 1.42 %, B
    2.03 -> 1.92 %, clip 0.80 % unchanged. Averaged everywhere but never lifting (the region's answer kept wherever the
    whole photo's is higher): A unchanged at 0.92047 (p101 -0.023, p285 -0.010: the arm and shoulder lost with the
    veil).

    The mean is of the two answers' logits, each weighted by its resolution (:func:`_weighted_odds`; matte20): the whole
    photo's canvas is ``seen_side`` / the region's side times coarser (0.8-2.9 for the people it averages on
    people_masks' photos, over 1 for 45 %), and the mean of probabilities took away what the region's answer saw and the
    coarser one saw faintly: p109's raised arms, a sleeve the region's answer held at 0.55-0.65 and the whole photo's at
    0.15-0.4, came out under 0.5 (0.884; 0.921 without the average). In logits, an answer sure of a pixel outweighs one
    unsure of it, and the coarser answer counts less: a thin part the region's answer sees at 0.9 and the whole photo's
    blurs to 0.05 stays (at 0.62, canvas twice as coarse), a rim the whole photo sees as background (0.02) still goes,
    and inside the person a pixel one answer is sure of stays nearly opaque where the other half-sees it (0.99 and 0.6:
    0.92; the mean of probabilities 0.80). Measured (people_masks_eval.py; matte_translucent.py): half A 0.92339 ->
    0.92350 (p047 +0.008; p104, p089, p101 -0.004: a little more of the ground between hands or grass beside a face
    kept), half B 0.90116 -> 0.90156 (p109 +0.020, p246 +0.017: a group's far side; p265 -0.008), the clip unchanged
    (0.93254: its people are the pose graph's); translucent interiors A 1.41 -> 1.29 %, B 1.87 -> 1.68 %. BLEND_SURE
    among 0.98 and 0.99 on half A: within 0.00002."""
    mine, whole = person.logits > 0, seen > 0.5
    if (mine & whole).sum() < BLEND_IOU * (mine | whole).sum():
        return person
    own = sigmoid(person.logits)  # a pixel left out is the whole photo's answer where sure and joined, else own
    take = _touching(~mine & (seen >= BLEND_TAKE), mine)
    mean = _weighted_odds(person, seen, seen_side)
    out = np.where(~mine & (seen > own), np.where(take, as_logits(seen), person.logits), mean)
    return replace(person, logits=out.astype(np.float32))


BLEND_SURE = 0.99  # _weighted_odds: the whole photo's answer counts as at most this sure either way


def _weighted_odds(person: Person, seen: np.ndarray, seen_side: float) -> np.ndarray:
    """The mean of ``person``'s logits and ``seen``'s (clipped to BLEND_SURE either way), each weighted by the
    canvas pixels its answer spends on a photo pixel: 1 / ``person.region.side`` and 1 / ``seen_side`` (the side in
    photo pixels of the square the whole photo's canvas spans). (256, 256) float32 logits."""
    ratio = float(seen_side) / person.region.side
    other = as_logits(np.clip(seen, 1.0 - BLEND_SURE, BLEND_SURE))
    return ((ratio * person.logits + other) / (1.0 + ratio)).astype(np.float32)


def _touching(part: np.ndarray, mine: np.ndarray) -> np.ndarray:
    """The 8-connected components of ``part`` (bool canvas) within JOIN_GAP canvas pixels of ``mine``."""
    n, labels = cv2.connectedComponents(part.astype(np.uint8), connectivity=8)
    if n <= 1:
        return part
    near = _near(mine)
    return np.isin(labels, [k for k in np.unique(labels[near & part]) if k > 0])


BACKED_EDGE = 1.0  # backed_logits: the logit of a pixel both graphs see at the person's outline ...
BACKED_INSIDE = 3.0  # ... and further than BACKED_DEPTH canvas pixels inside it
BACKED_DEPTH = 2
BACKED_GAP = 0.2  # ... except a lifted pixel this far under the closing of the pose graph's probability there ...
BACKED_DOUBT = 0.25  # ... (a gap the canvas cannot draw): this logit (0.56); the photo decides at full resolution
BACKED_SURE = 1.0  # ... between pixels of this logit (0.73: more than _backed lifts) across, down or diagonally


def backed_logits(logits: np.ndarray, lift: np.ndarray) -> np.ndarray:
    """A pose-graph person's canvas ``logits`` with the pixels of ``lift`` (those it half-sees that the selfie graph
    sees as a person) made theirs: BACKED_EDGE (0.73) within BACKED_DEPTH canvas pixels of the outline of what they
    then hold, where the guided filter is to follow the photo's edges, and BACKED_INSIDE (0.95) further in. At 0.73
    everywhere, a body the pose graph half-sees as a whole stayed translucent inside (an embracing couple's shirts
    and faces at alpha 0.6-0.75 over a third of them): relit, the old photo showed through. Measured (IoU:
    benchmarks/people_masks_eval.py --inset 1; translucent: benchmarks/matte_translucent.py, the share of the mask's
    interior at alpha 0.05-0.95; BACKED_INSIDE and BACKED_DEPTH chosen on photos half A among 3, 5 and 2, 3, 5 px, IoU
    within 0.0002 of each other): half A IoU 0.9238 -> 0.9240, translucent 2.24 % -> 1.56 % (images over 5 %: 15 -> 9);
    half B 0.9011 -> 0.9014, 3.63 % -> 2.22 % (17 -> 12); the clip 0.9248 -> 0.9247, 2.18 % -> 1.17 % (13 -> 6).
    BACKED_INSIDE everywhere (no edge): the clip 0.9234 (the legs' outline).

    A gap the pose graph sees narrower than that window (a lifted pixel whose probability lies at least BACKED_GAP
    under the window's closing of it: higher on both sides, and between body the pose graph is sure of, logit >=
    BACKED_SURE, across, down or diagonally: :func:`_between`) gets BACKED_DOUBT instead. The canvas cannot draw a gap
    of 3-5 photo px, so the photo decides at full resolution (relight_rt.image.matte_edges: a pocket the matte
    half-holds opens where it shows the backdrop's colour and is the person's where it shows another; colour alone
    decides nothing where the pose graph sees no gap). Made sure, the white backdrop in the gaps between the reference
    clip's arms and dress (pose probability 0.35-0.68 between sure arm and dress, the selfie graph sure there) was
    matted opaque and relit as the person (campfire: up to 149 levels). BACKED_DOUBT is a little over even odds: what
    asks whether a canvas pixel is the person's (logits > 0) still counts the gap (at 0, a frame of the parkour
    clip whose trousers the pose graph half-sees lost a leg: IoU 0.94 -> 0.89), and the guided filter leaves a gap
    one canvas pixel wide under matte_edges' pocket threshold (0.9; at BACKED_EDGE it gave 0.92-0.94: closed).
    Chosen on the reference clip's frames 1-6 among 0.25, 0.5 and 1.0 (band pixels the matte holds opaque, frames
    1 / 2: 25 / 45, 35 / 55, 51 / 76; -1 gives 10 / 19 there, but at 0 and under the leg above is lost). Measured
    with matte_edges' pockets (benchmarks/photo_faults.py --skip-photos, people_masks_eval.py, matte_translucent.py):
    the reference clip's opaque band pixels, frames 1-6, 555-577 / 419-426 -> 25-45 / 11-23, the relit band's worst
    p99 over 12 lights 5.1-148.7 -> 0.9-11.5 levels; IoU half A 0.91967 -> 0.91969, B 0.89496 -> 0.89493 (p227
    -0.005: pavement seen in a 4-px gap between two people's legs, which the service's mask fills), the clip 0.93246
    -> 0.93252; translucent interior A 1.56 -> 1.43 %, B 2.22 -> 2.00 %, the clip 1.17 -> 0.80 %.

    The sure ends (matte14): with the closing's test alone any local dip was a gap, and a body the pose graph half-sees
    with noisy probability (0.4 +- 0.1) had 27 % of its interior left in doubt (a reviewer's finding). A real gap
    lies between body the pose graph is sure of, its two ends at most 4 * BACKED_DEPTH + 1 pixels apart, as far as the
    closing reaches (at BACKED_DEPTH it missed the 5-canvas-px top of a gap between the parkour runner's arm and
    body: frame 3 -0.001). Measured: the sets, the translucent interiors and the reference clip's relit band as
    before (clip 0.93254, A 0.91967, B 0.89508 -> 0.89509; 0.798 / 1.448 / 2.032 -> 2.030 %; band within 2e-5
    levels)."""
    out = np.where(lift, np.float32(BACKED_EDGE), logits).astype(np.float32)
    k = 2 * BACKED_DEPTH + 1
    window = np.ones((k, k), np.uint8)
    inner = cv2.erode((out > 0).astype(np.uint8), window).astype(bool)
    prob = sigmoid(logits).astype(np.float32)
    valley = lift & (cv2.morphologyEx(prob, cv2.MORPH_CLOSE, window) - prob > BACKED_GAP)
    out = np.where(lift & inner, np.float32(BACKED_INSIDE), out)
    between = _between(logits >= BACKED_SURE, 2 * k - 1)  # the window's closing reaches k - 1 pixels either way
    return np.where(valley & between, np.float32(BACKED_DOUBT), out).astype(np.float32)


def _between(sure: np.ndarray, k: int) -> np.ndarray:
    """Where a pixel is ``sure`` or lies between two ``sure`` pixels at most ``k`` apart on its row, its column or
    a diagonal: the union of ``sure``'s closings by the four lines of ``k`` pixels. (H, W) bool."""
    lines = (np.ones((1, k), np.uint8), np.ones((k, 1), np.uint8), np.eye(k, dtype=np.uint8),
             np.eye(k, dtype=np.uint8)[::-1].copy())  # fmt: skip
    src = sure.astype(np.uint8)
    out = np.zeros(sure.shape, bool)
    for line in lines:
        # past the canvas nothing is sure (OpenCV's default border would count it as sure body in the erosion)
        out |= cv2.morphologyEx(src, cv2.MORPH_CLOSE, line, borderType=cv2.BORDER_CONSTANT, borderValue=0).astype(bool)
    return out
