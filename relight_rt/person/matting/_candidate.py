"""One candidate's person: the pose graph on a square region re-centred until it settles, the portrait check that hands
a close portrait to the selfie graph, and whether a person is there at all (the pose graph's presence flag, a face,
or the selfie graph seeing the same shape: :func:`vouched`).

The searches (relight_rt.person.matting._largest, ._everyone) ask :func:`person_at` for each candidate box; it goes
through the matter's own ``segment`` and ``vouched`` (relight_rt.person.matting._matter.PersonMatter), which hand the
pose graph in as ``PersonMatter._pose``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Protocol

import numpy as np

from ...engine.session import Model
from ...image.regions import Region
from ..face_detector import Face
from ._detect import roi_prob
from ._layout import box_area, box_past_border, grow_where_cut, is_portrait, within_photo
from ._segmentation import Person, contains, person_box
from ._selfie import confirmed, face_person, reframed, roi_person

Pose = Callable[[np.ndarray, Region], Person]  # the pose graph on one region of the photo (PersonMatter._pose)
Faces = Callable[[np.ndarray], list[Face]]  # the face graph on the whole photo (PersonMatter.find_faces)


class Segmenter(Protocol):
    """What the searches ask of the person matter (relight_rt.person.matting._matter.PersonMatter is the one): its
    selfie and face graphs, where people are, faces, one region segmented, and whether a segmentation is a person."""

    roi: Model
    face: Model | None

    def find_people(self, rgb: np.ndarray) -> list[tuple[float, tuple[float, float, float, float]]]: ...

    def find_faces(self, rgb: np.ndarray, *, every: bool = False) -> list[Face]: ...

    def segment(
        self, rgb: np.ndarray, region: Region, give_up: float = 0.0, past_border: bool = False,
        passes: int | None = None,
    ) -> Person: ...  # fmt: skip

    def vouched(self, rgb: np.ndarray, person: Person) -> bool: ...


PRESENCE_MIN = 0.5  # pose-presence probability below which a region holds no person (unless a face vouches)
_AGREE = 0.75  # ... or where the selfie graph's segmentation of its region overlaps the pose graph's this much
_NOBODY = 0.05  # a face under which the pose graph's presence is below this ...
_SETTLED_IOU = 0.9  # the region has settled when the next one overlaps it this much
_PORTRAIT_REACH = 0.3  # a pose-graph person ending this close to the bottom (x the height) may be a portrait
_PORTRAIT_FACE = 0.3  # ... and holding a face this x its width wide
PORTRAIT_ANYWHERE = True  # last, the portrait check wherever the settled person ends, if it holds such a face (gate44)
# a blob's answer that does not hang on where the pose graph's re-centring wandered (matte39; RESULTS, broad sets):
START_PORTRAIT = True  # the portrait check (:func:`portrait_region`) on the region first given too
_WALKED_PART = 0.7  # ... where the re-centred person's box is less than this x the first region's person's


def part_of(person: Person, first: Person, shape: tuple[int, int]) -> bool:
    """Whether ``person``'s box is less than _WALKED_PART x the area of ``first``'s (both the pose graph's)."""
    box, start = person_box(person, shape), person_box(first, shape)
    return box is not None and start is not None and box_area(box) < _WALKED_PART * box_area(start)


def segment(
    pose: Pose, roi: Model, find_faces: Faces, rgb: np.ndarray, region: Region, passes: int, give_up: float = 0.0,
    past_border: bool = False,
) -> Person:  # fmt: skip
    """Run the pose graph (``pose``) on one square region; re-centre on its segmentation until it settles (or, with
    ``give_up``, stop when the presence flag is below it: nobody there), at most ``passes`` runs (1: the region as
    given, not re-centred). With ``past_border``, a region whose presence stays low while the segmentation runs into
    the image border is tried once more, reaching past that border (:func:`box_past_border`). The pose graph's answer
    keeps its first pass's presence (``start``: relight_rt.person.matting._largest.is_walked); where the re-centring
    walked onto a part of what the first pass saw (:func:`part_of`) and the settled person calls for no portrait check,
    the first region is looked at for one. A portrait (:func:`portrait_region`, :func:`is_portrait`) is the selfie
    graph's (``roi``) person, confirmed against the faces ``find_faces`` gives (:func:`confirmed`).

    Measured (benchmarks/people_masks_eval.py, with is_walked; matte39): the photos as they come unchanged
    (0.91399), mirrored 0.88691 -> 0.89694 (p193 0.19 -> 0.91, p085 0.50 -> 0.95, p170 0.00 -> 0.92), clip 0.93254
    -> 0.93277 / 0.93000 -> 0.93001. Checked wherever the first region reached past the bottom it took a runner
    crouching at the frame's bottom for a portrait (clip 0.915)."""
    person = first = None
    for _ in range(passes):
        person = pose(rgb, region)
        first = person if first is None else first
        if person.presence < give_up:
            break
        box = person_box(person, rgb.shape[:2])
        if box is None or box[2] <= box[0] or box[3] <= box[1]:
            break
        nxt = Region.around(*grow_where_cut(box, region, rgb.shape[:2]))
        if nxt.iou(region) > _SETTLED_IOU:
            break
        region = nxt
    if past_border and person is not None and person.presence < PRESENCE_MIN:
        wider = box_past_border(person_box(person, rgb.shape[:2]), rgb.shape[:2])
        if wider is not None:
            retry = pose(rgb, Region.around(*wider))
            person = retry if retry.presence > person.presence else person
    if person is None or first is None:
        return person
    moved = first is not person  # re-centred (asked before ``replace`` makes ``person`` a new object)
    person = replace(person, start=first.presence)
    region = portrait_region(rgb, person, find_faces)
    if region is None and START_PORTRAIT and moved and part_of(person, first, rgb.shape[:2]):
        # the re-centring walked off the region first given onto a part of what the pose graph saw there (a child
        # in front, a head and shoulders) and no longer reaches the bottom: the portrait check looks at that
        # first region too (portrait_region)
        region = portrait_region(rgb, first, find_faces)
    if region is None and PORTRAIT_ANYWHERE:
        # the pose graph, seeing part of a close portrait, can stop anywhere above the bottom: a large face decides
        region = portrait_region(rgb, person, find_faces, anywhere=True)
    if region is None:
        return person
    framed = roi_person(roi, rgb, region, person.presence)
    if not is_portrait(framed, rgb.shape[:2]):
        return person
    return confirmed(roi, rgb, reframed(roi, rgb, framed), find_faces)


def portrait_region(rgb: np.ndarray, person: Person, find_faces: Faces, anywhere: bool = False) -> Region | None:
    """Where the selfie graph checks for a portrait (:func:`is_portrait`): the pose graph's region when it
    reaches past the image's bottom; else, when the pose graph's person ends within _PORTRAIT_REACH x the
    image's height above the bottom, a region around that person reaching down to the bottom (the pose graph
    loses the shoulders and chest of a close portrait, and its region, framed on what it saw, then stops
    above the bottom: a portrait before an orange wall was matted down to the collar) and a face at least
    _PORTRAIT_FACE x that person's width wide lies inside it (a portrait's face is half the width the pose
    graph sees; a whole body crouching at the bottom of a frame, whose face is a tenth of it, is no
    portrait: the selfie graph would take the bushes around the runner's legs); None: no check. Either region
    is at most the photo's own square (:func:`within_photo`). ``find_faces``: the face graph on the whole photo.

    ``anywhere``: however far above the bottom the person ends (:func:`segment` asks last, when neither the
    settled region nor the one first given called for a check). The pose graph, seeing part of a close portrait,
    can stop anywhere: on one photo's mirror image its person ended 0.33 of the height above the bottom, the check
    was left out and the matte kept a head and shoulders cut at the chest (IoU 0.43 against 0.90 as it comes;
    RESULTS, broad sets, gate44). Asked first instead (the bar gone), it framed a walked-off head on another
    photo's mirror where the region first given held the whole portrait (``--person all`` 0.95 -> 0.81)."""
    h = rgb.shape[0]
    if person.region.box()[3] > h:
        return within_photo(person.region, rgb.shape[:2])
    box = person_box(person, rgb.shape[:2])
    if box is None or (not anywhere and box[3] < h * (1.0 - _PORTRAIT_REACH)):
        return None
    if big_face_in(rgb, person, find_faces):
        return within_photo(Region.around(box[0], box[1], box[2], float(h)), rgb.shape[:2])
    return None


def big_face_in(rgb: np.ndarray, person: Person, find_faces: Faces) -> bool:
    """Whether a face (``find_faces``: the face graph's on the whole photo) at least _PORTRAIT_FACE x the width of
    ``person``'s box wide has its middle inside that box: a portrait's face (:func:`portrait_region`)."""
    box = person_box(person, rgb.shape[:2])
    if box is None:
        return False
    for f in find_faces(rgb):
        cx, cy = (f.box[0] + f.box[2]) / 2, (f.box[1] + f.box[3]) / 2
        inside = box[0] <= cx <= box[2] and box[1] <= cy <= box[3]
        if inside and f.box[2] - f.box[0] >= _PORTRAIT_FACE * (box[2] - box[0]):
            return True
    return False


def person_at(
    matter: Segmenter, rgb: np.ndarray, box, face: Face | None, give_up: float = 0.0, passes: int | None = None,
    sure_face: float = 0.0, vouch: bool = True,
) -> Person | None:  # fmt: skip
    """The person in ``box`` (a blob's or a face's body box, image pixels (x0, y0, x1, y1)), or None when the pose
    graph says nobody is there and no face vouches for one (``give_up``, ``passes``: see :func:`segment`; run by
    ``matter.segment``, and ``matter.vouched`` asked). A face vouches when the pose graph sees at least a trace of a
    body under it (presence >= _NOBODY) or its score is at least ``sure_face`` (person="all" asks for _SURE_FACE
    (relight_rt.person.matting._everyone) once someone is found: its faces come from tiles, where the face graph
    also finds faces in things, 0.66-0.73 on a red bench and a treadmill's console beside the person, with
    presence 0.00-0.01 under them, while the faces of other people under which the pose graph sees nobody
    scored 0.87-0.90 on the photos of benchmarks/people_masks_eval.py; a close portrait's face, the only
    person in the photo, can score 0.71). With ``vouch`` False only the pose graph's flag says whether a blob
    holds a person (person="all" once someone is found: a pile of clothes on a chair beside a man at a desk,
    which both graphs segment alike, was a second person)."""
    p = matter.segment(
        rgb, Region.around(*box), give_up if face is None else 0.0, past_border=face is None, passes=passes
    )
    # the pose graph segments something in any region; its presence output says whether a person is there
    # (0.0000 on a colour gradient the region finder took for one, >= 0.87 on people in full view), or the
    # selfie graph sees the same shape there (:func:`vouched`)
    if face is None and (p.presence >= PRESENCE_MIN or (vouch and matter.vouched(rgb, p))):
        return p
    if p.presence >= PRESENCE_MIN and face is not None and contains(p, face, rgb.shape[:2]):
        return p
    if face is None or (p.presence < _NOBODY and face.score < sure_face):
        return None
    # a face, but the pose graph sees no body here (a close portrait) or another person: the selfie graph
    # segments the face's region instead (made for head-and-shoulders framing)
    roi = face_person(matter.roi, rgb, face, max(p.presence, face.score))
    return roi if contains(roi, face, rgb.shape[:2]) else None


def vouched(pose: Pose, roi: Model, rgb: np.ndarray, person: Person) -> bool:
    """Whether ``person`` (the pose graph's segmentation of a region) is a person: the pose graph's presence
    flag says so, or the selfie graph (``roi``) on the same region segments the same shape (IoU >= _AGREE of their
    two masks on the canvas). The presence flag is made for upright bodies: it says nobody for a runner in
    mid-air over a railing (0.00-0.09 on 10 of the 100 frames of the parkour clip), a man lying on a floor,
    a woman seen from behind reaching out (0.003), while both graphs segment the same body there (IoU
    0.78-0.95); on a region holding nobody the two disagree or see nothing. A selfie-graph person (a portrait's)
    is asked of the pose graph (``pose``) instead."""
    if person.presence >= PRESENCE_MIN:
        return True
    if person.source == "pose":
        mine, other = person.logits > 0, roi_prob(roi, rgb, person.region) > 0.5
    else:  # the selfie graph's (a portrait's): the pose graph on the same region must see the same shape
        mine, other = person.logits > 0, pose(rgb, person.region).logits > 0
    return bool(mine.any() and (mine & other).sum() >= _AGREE * (mine | other).sum())
