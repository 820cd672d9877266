"""The selfie graph's segmentation of a square region as a person, and the regions it is run on again when its first
answer does not fit its region: framed tighter on that answer (:func:`reframed`), raised where the answer runs into
the region's top (:func:`uncut`), carried on past a cut side (:func:`widened`, and by the whole photo's answer:
:func:`carried_past`). The person matter (relight_rt.person.matting._matter) asks for them on close portraits and
faces, where the pose graph sees no body; every answer comes through :func:`roi_prob` (kept per region inside
``reductions_shared``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace

import cv2
import numpy as np

from ...engine.session import Model
from ...image.regions import Region, grid_of_region
from ..face_detector import Face
from ._detect import roi_prob
from ._layout import continued, grow_where_cut, held, parts_going_on, resampled, unconfirmed, unconfirmed_cut
from ._models import SIZE
from ._segmentation import (
    LOGIT_CLIP,
    Person,
    as_logits,
    canvas_index,
    canvas_points,
    contains,
    face_middle,
    logits_on_grid,
    person_box,
    prob_at,
)

_REFRAME = 0.9  # the selfie graph is run again on its own segmentation's region when that is this much smaller
_MAX_GROW = 2  # selfie-graph runs on a higher region while its segmentation is cut by the region's top (uncut)
PAST_SURE = 0.75  # carried_past: the whole photo's mean probability over a part past a region's cut side
PAST_INSIDE = 3.0  # ... its logit inside (0.95; the graph's own at its outline): the part is the person's, not a veil
_SEAM = 3  # carried_past: canvas pixels inside the cut side over which the part overlaps the person (no seam)


def roi_person(roi: Model, rgb: np.ndarray, region: Region, presence: float) -> Person:
    """The selfie graph's segmentation of ``region`` as a Person (its probability kept as logits)."""
    return Person(region, as_logits(roi_prob(roi, rgb, region)), presence, "roi")


def seen_on(roi: Model, rgb: np.ndarray, region: Region) -> np.ndarray:
    """The selfie graph's answer on the whole photo (asked by the region finder already) on ``region``'s canvas."""
    h, w = rgb.shape[:2]
    return prob_at(roi_person(roi, rgb, Region(w / 2, h / 2, float(max(h, w))), 0.0), *canvas_points(region))


def reframed(roi: Model, rgb: np.ndarray, person: Person) -> Person:
    """The selfie graph's segmentation ``person`` again on a region framed on its first answer (ROI_SCALE x its
    box), when that region is smaller: the regions it is first run on are framed for a whole body (the pose
    graph's) or guessed from a face, and in them a portrait's head spans half the canvas or less. Grace
    Hopper's white cap before the white flag stripes: alpha over the crown 0.59 -> 0.96."""
    box = person_box(person, rgb.shape[:2])
    if box is None:
        return person
    tight = Region.around(*box)
    if tight.side >= _REFRAME * person.region.side:
        return person
    return roi_person(roi, rgb, tight, person.presence)


def face_person(roi: Model, rgb: np.ndarray, face: Face, presence: float) -> Person:
    """The selfie graph's segmentation of ``face``'s person: its body box (:meth:`Face.body_box`), framed again on
    the first answer (:func:`reframed`)."""
    region = Region.around(*face.body_box(rgb.shape[:2]))
    return reframed(roi, rgb, roi_person(roi, rgb, region, presence))


def confirmed(
    roi: Model, rgb: np.ndarray, person: Person, find_faces: Callable[[np.ndarray], list[Face]]
) -> Person:  # fmt: skip
    """The selfie graph's segmentation ``person`` (a portrait's, :func:`reframed`) less what it is unsure of that the
    graph framed on a face's body does not see (:func:`unconfirmed`), when its region is the whole photo: framed
    there, the graph sees the photo's background small, as it does on the whole photo, and takes in textured ground
    joined to the person. The face: the first of ``find_faces(rgb)`` (best first) whose middle ``person`` holds
    (:func:`contains`), its person framed as for person="all" (:func:`face_person`). ``person`` itself elsewhere, or
    without such a face; the faces are asked for only on the whole photo's framing (a video's portrait frames
    framed tighter run no face graph for it).

    Measured (benchmarks/people_masks_eval.py, matte17; DOUBTED_PART chosen on photos half A among 0.7, 0.8, 0.9 and
    SURE_PART 0.95: A +0.0010, +0.0010, -0.0029, -0.0030): half A 0.92087 -> 0.92191 (p016 +0.055: a blurred hedge
    beside a portrait; p043 +0.042, p111 +0.018; p186 -0.014: part of the lit star a man stands beside, which the
    service's mask holds), half B 0.89581 -> 0.89725 (p063 0.782 -> 0.909: the pale rocks left of a woman's shoulder;
    p193 +0.018; the worst p223 -0.001), the clip unchanged (0.93254); photos below the selfie graph alone 48 -> 46.
    At 0.9 and over, p186 lost that star whole (-0.41) and p272 a group's second person where the face frames the
    first (-0.012). Confirmed on every portrait, not only the whole photo's (a scratch run): A about as much, but more
    photos worse (p274 -0.024, p086 -0.013, p109 -0.010). Outside the face's framing nothing is unseen, only unknown
    (mend17, on main's 0.92339 / 0.90116 / 0.93254): p016 0.956 -> 0.927 (two blurred-background blobs at the photo's
    left edge, apart from her, lie wholly left of it and stay; 0.901 without the rule), A 0.92311, B and the clip
    unchanged, every other photo within 0.001 (person="all": p025 -0.008, pieces of a blurred shape likewise)."""
    h, w = rgb.shape[:2]
    if person.region.side < max(h, w):
        return person
    for f in find_faces(rgb):
        if contains(person, f, (h, w)):
            return unconfirmed(person, face_person(roi, rgb, f, person.presence))
    return person


def uncut(roi: Model, rgb: np.ndarray, person: Person) -> tuple[Person, Person | None]:
    """The selfie graph's segmentation ``person`` again on a region reaching higher while it runs into its region's
    top inside the image (:func:`grow_where_cut`, upwards only), and the segmentation it started from (None:
    not run again). The region is the pose graph's (or a face's guess), and on a close portrait the pose
    graph misses the top of the head, so its region, centred on what it saw, can start below the crown;
    alpha outside the region is 0, so the head was cut off flat (DPR's portrait: at row 188 of 909, the
    forehead and hair missing). The higher region's answer is kept to the first one's columns
    (:func:`held`): the selfie graph segments everyone in its region, and a larger region takes in more
    of the people beside. Not sideways, for the same reason."""
    first = None
    for _ in range(_MAX_GROW):
        box = person_box(person, rgb.shape[:2])
        if box is None:
            break
        top = grow_where_cut(box, person.region, rgb.shape[:2])[1]
        if top >= box[1]:
            break
        first = person if first is None else first
        raised = roi_person(roi, rgb, Region.around(box[0], top, box[2], box[3]), person.presence)
        person = held(raised, first, rgb.shape[:2])
    return person, first


def widened(roi: Model, rgb: np.ndarray, person: Person) -> Person:
    """The selfie graph's segmentation ``person`` carried on past its region's left or right side where it runs into
    it inside the image: whole or not at all. Cut there, the matte ended in a straight line through whoever stood
    beside (an old man's friend in profile halved down his coat; a man holding hands with the woman found, whom
    :func:`uncut` then kept to her columns). The graph is run again on a region reaching past every cut side
    (:func:`grow_where_cut`, at most _MAX_GROW runs), and of its answer only what goes on from the cut and is
    sure is added (:func:`continued`): framed larger, the graph answers worse elsewhere. Before that, what runs into
    a cut side that the wider run does not see and the first is not sure of is dropped, whole
    (:func:`unconfirmed_cut`: ground the tight frame took in).

    Measured (benchmarks/people_masks_eval.py, photos; the selfie graph's mean over the added part >= SURE_PART
    chosen on half A): half A +0.005 (two photos +0.21, +0.31), half B +0.001 (two photos +0.04, +0.06), no photo
    worse; the whole new answer instead: A +0.003, B -0.006 (a bright-sky portrait's face half lost, -0.56);
    the continuation without the sureness test: A +0.0035 (a red wall's glow and a blurred shoulder behind, -0.09
    each)."""
    shape = rgb.shape[:2]
    for _ in range(_MAX_GROW):
        box = person_box(person, shape)
        if box is None:
            break
        grown = grow_where_cut(box, person.region, shape)
        if grown[0] >= box[0] and grown[2] <= box[2]:
            break
        wide = roi_person(roi, rgb, Region.around(*grown), person.presence)
        cut = (grown[0] < box[0], grown[1] < box[1], grown[2] > box[2], grown[3] > box[3])
        person = unconfirmed_cut(wide, person, cut)  # what runs into a cut side: whole or not at all
        more = continued(wide, person, cut)
        if more is person:
            break
        person = more
    return person


def carried_past(roi: Model, rgb: np.ndarray, person: Person, faces: Sequence[Face] = ()) -> list[Person]:
    """What the selfie graph on the whole photo sees past a side of ``person``'s region that cuts them inside the
    photo (:func:`grow_where_cut`), going on from the cut: [a Person of source "own" holding it, ``of`` ``person``'s
    region: part of the matte, and in :meth:`relight_rt.person.matting.PersonMatter.parts` that person's share, as
    :func:`owning` merges it] or []. A portrait's region, framed on a face or on what the pose graph saw, can stop
    short of a shoulder that runs on to the photo's corner, and alpha outside a region is 0: the matte ended in the
    region's straight side. :func:`widened` runs the graph on a region reaching past that side, but framed larger
    than the photo it loses the shoulder too or is not sure of it (< SURE_PART); the whole photo's answer (asked by
    the region finder already: no graph run) is kept where it goes on from the person's pixels at the cut
    (:func:`relight_rt.person.matting._layout.parts_going_on`, as :func:`relight_rt.person.matting._layout.continued`:
    8-connected to a canvas pixel next to them) and is sure enough (mean probability >= PAST_SURE), whole, and never a
    part that holds the middle of one of ``faces`` (two of the three points
    :func:`relight_rt.person.matting._segmentation.contains` reads; the part lies past the region, so it is not the
    person's own face): someone else joined to them in the whole photo's answer, a passer-by cut by the photo's
    border touching the shoulder, whom person="largest" takes only when seen whole. The matter passes the faces that
    no one it found holds: a part joined to a peer it took whole stays. The part is the person's: PAST_INSIDE inside,
    the graph's own answer at its outline (where the photo then draws it), and it overlaps the person over _SEAM
    canvas pixels inside the cut side so that the two alphas meet without a seam. Carried onto a region around the
    part (bilinearly): the matte is filtered over each person's region, and over the whole photo that cost ~0.1 s on
    a 2.5-MP photo.

    Measured (benchmarks/people_masks_eval.py --methods ours,selfie; PAST_SURE chosen on photos half A among 0.5 and
    0.75: the parts the rule finds there have means 0.56 and 0.78-0.83, and at 0.5 the 0.56 one, a red wall's glow
    beside a bare-chested man, p064 -0.001): half A 0.92236 -> 0.92254 (p177 +0.012: a shoulder at the bottom right
    corner; p047 +0.004: a hand holding a stick; p094 +0.003: a woman's shoulder at the right border), half B 0.89971
    -> 0.89979 (p024 +0.007, p265 +0.001), no photo worse, the clip unchanged (0.93254: its people are the pose
    graph's); photos under the selfie graph alone 47 -> 45; translucent interiors (benchmarks/matte_translucent.py) A
    1.43 -> 1.42 %, B 1.89 -> 1.87 %. Asked for the selfie graph's people only: past the region of a pose-graph person
    (none cut in half A) the whole photo's answer ran on into a shop counter and its floor (B p181 0.84 -> 0.26).
    The faces' rule, the shares and the one run per split segmentation (mend19) move no photo nor clip frame (half A
    0.92329, B 0.90124, the clip 0.93254, each photo as at the branch's head: on these sets no carried part holds a
    face no one found holds; p265's holds two children's faces, both found: it stays)."""
    h, w = rgb.shape[:2]
    box = person_box(person, (h, w))
    if box is None:
        return []
    grown = grow_where_cut(box, person.region, (h, w))
    cut = (grown[0] < box[0], grown[1] < box[1], grown[2] > box[2], grown[3] > box[3])
    if not any(cut):
        return []
    whole = roi_person(roi, rgb, Region(w / 2, h / 2, float(max(h, w))), person.presence)
    before, x, y = resampled(person, whole.region)
    x0, y0, x1, y1 = person.region.box()
    xs, ys = x[None, :], y[:, None]
    own = (xs >= x0) & (xs <= x1) & (ys >= y0) & (ys <= y1)
    d = _SEAM * whole.region.side / before.shape[0]  # _SEAM canvas pixels of the whole photo, in image px
    past = np.zeros(before.shape, bool)
    seam = np.zeros(before.shape, bool)
    for side, beyond, near in zip(
        cut, (xs < x0, ys < y0, xs > x1, ys > y1), (xs < x0 + d, ys < y0 + d, xs > x1 - d, ys > y1 - d), strict=True
    ):  # fmt: skip
        if side:
            past |= beyond & ~own
            seam |= near & own
    labels = parts_going_on(whole.logits, before, own, past, PAST_SURE)
    part = (labels > 0) & ~np.isin(labels, [k for f in faces for k in _middle_holders(labels, whole.region, f)])
    if not part.any():
        return []
    window = np.ones((2 * _SEAM + 1,) * 2, np.uint8)
    part |= seam & (whole.logits > 0) & cv2.dilate(part.astype(np.uint8), window).astype(bool)
    ring = np.ones((3, 3), np.uint8)
    rim = cv2.dilate(part.astype(np.uint8), ring).astype(bool) & (past | seam)
    inner = cv2.erode(part.astype(np.uint8), ring).astype(bool)  # decided: sure inside, the graph's own at the outline
    logits = np.where(inner, np.maximum(whole.logits, np.float32(PAST_INSIDE)), whole.logits)
    found = Person(whole.region, np.where(rim, logits, np.float32(-LOGIT_CLIP)).astype(np.float32), person.presence,
                   "own", of=person.region)  # fmt: skip
    box = person_box(found, (h, w))
    if box is None:  # (a part of fewer than COARSE_MIN_AREA canvas pixels)
        return []
    tight = Region.around(*box)
    k, bx, by = grid_of_region(tight)
    return [replace(found, region=tight, logits=logits_on_grid(found, (SIZE, SIZE, k, k, bx, by)))]


def _middle_holders(labels: np.ndarray, region: Region, face: Face) -> list[int]:
    """The labels (> 0) of ``labels`` (components on ``region``'s canvas) that hold two or more of the three points
    of ``face``'s middle that :func:`relight_rt.person.matting._segmentation.contains` reads (:func:`face_middle`)."""
    if not np.all(np.isfinite(face.box)):
        return []  # a box the detector could not place holds nothing
    i, j = canvas_index(region, *face_middle(face))
    inside = (i >= 0) & (i < labels.shape[0]) & (j >= 0) & (j < labels.shape[1])
    held = labels[i[inside], j[inside]]
    values, counts = np.unique(held[held > 0], return_counts=True)
    return [int(v) for v, c in zip(values, counts, strict=True) if c >= 2]


def owning(person: Person, parts: Sequence[Person]) -> Person:
    """``person`` with the logits of ``parts`` (what :func:`carried_past` carried on from them, ``of`` their region)
    merged in (the larger at each pixel), on the canvas of a region around all of theirs: the person as
    :func:`relight_rt.person.matting._parts.shares` weighs them, so that a part outside their own region (where
    their logits do not reach) is theirs and not the share of whoever else's region reaches it. ``person`` itself
    when ``parts`` is empty. The canvas is coarser than the person's own: only the shares read it, on a working grid
    of the photo, blurred over a percent of its side."""
    if not parts:
        return person
    boxes = np.array([p.region.box() for p in (person, *parts)])
    region = Region.around(*boxes[:, :2].min(axis=0), *boxes[:, 2:].max(axis=0), scale=1.0)
    k, bx, by = grid_of_region(region)
    grid = (SIZE, SIZE, k, k, bx, by)
    logits = np.max([logits_on_grid(p, grid) for p in (person, *parts)], axis=0)
    return replace(person, region=region, logits=logits.astype(np.float32), whole=None)
