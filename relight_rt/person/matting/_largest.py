"""The largest person (person="largest", the default): the selfie graph's blobs (largest first) segmented until one
holds a person, then the faces, then a frame that is mostly one face, then the selfie graph's own answer on the
largest blob when nobody vouches. A person the pose graph's re-centring reached from nobody, holding no face, is set
aside while the other candidates are tried (:func:`is_walked`, WALKED_LAST; matte39).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ...image.regions import Region
from ._candidate import Faces, Segmenter, person_at
from ._detect import find_close_faces
from ._everyone import GIVE_UP, everyone
from ._layout import box_area, seen_whole
from ._segmentation import COARSE_MIN_AREA, Person, contains, person_box, sigmoid
from ._selfie import reframed, roi_person, seen_on

_SURE_BLOB = 0.9  # nobody else found: the selfie graph's blob is a person when this sure of it
_TRACE = 0.1  # nobody else found: the pose graph's presence over a blob the whole photo vouches for
WALKED_LAST = True  # a person reached from nobody, holding no face, tried after the other candidates (is_walked)


def largest(matter: Segmenter, rgb: np.ndarray) -> tuple[list[Person], list]:
    """The largest person in ``rgb`` (H, W, 3) float32 [0, 1] ([] or [one]) and the selfie graph's blobs
    (``matter.find_people``) they were looked for in (the peers' search reads them again:
    relight_rt.person.matting._company.peers). Each candidate is segmented by ``matter``
    (relight_rt.person.matting._candidate.person_at)."""
    h, w = rgb.shape[:2]
    found = matter.find_people(rgb)  # the selfie graph over the photo and its tiles: once, for every use below
    walked = None  # a person the re-centring reached from nobody, holding no face: kept unless a larger is found
    for _, box in found:
        p = person_at(matter, rgb, box, None)
        if p is not None and WALKED_LAST and walked is None and is_walked(rgb, p, matter.find_faces):
            walked = p
            continue
        if p is not None:
            return [over_walked(rgb, walked, p)], found
    faces = matter.find_faces(rgb)  # no body found: a face is the second way in
    for face in sorted(faces, key=lambda f: -box_area(f.body_box((h, w)))):
        p = person_at(matter, rgb, face.body_box((h, w)), face)
        if p is not None:
            return [over_walked(rgb, walked, p)], found
    if walked is not None:
        return [larger_than_walked(matter, rgb, walked)], found
    # a frame that is mostly one face (a crop through the forehead or the eyes): the face graph finds it
    # zoomed out only, and the pose graph sees no body in it
    for face in find_close_faces(matter.face, rgb):
        p = person_at(matter, rgb, face.body_box((h, w)), face)
        if p is not None:
            return [p], found
    # neither the pose graph nor a face vouches for anyone: the selfie graph's own segmentation of its largest
    # blob, when it is sure of it (a man lying on a shop floor, a couple taking a selfie, a woman seen from
    # behind: the pose graph's presence 0.003-0.27 there, and no face found; the selfie graph alone 0.69-0.84
    # IoU where the matte was empty)
    for _, box in found[:1]:
        roi = reframed(matter.roi, rgb, roi_person(matter.roi, rgb, Region.around(*box), 0.0))
        mine = roi.logits > 0
        if mine.sum() >= COARSE_MIN_AREA and float(sigmoid(roi.logits[mine]).mean()) >= _SURE_BLOB:
            return [roi], found
        # ... else the pose graph's, when it sees a trace of a person there and the selfie graph on the whole photo
        # sees the same shape (:func:`seen_whole`; a man in dark clothes in a dim arcade, the selfie graph on his
        # region seeing nothing of him)
        p = matter.segment(rgb, Region.around(*box), past_border=True)
        if p.presence >= _TRACE and seen_whole(p.logits > 0, seen_on(matter.roi, rgb, p.region) > 0.5):
            return [p], found
    return [], found


def is_walked(rgb: np.ndarray, person: Person, find_faces: Faces) -> bool:
    """Whether ``person`` (a blob's, person="largest") was reached by re-centring from a region where the pose
    graph saw nobody (its first pass's presence below GIVE_UP) and holds no face of the face graph's on the whole
    photo (``find_faces``): the walk may have settled on anything person-like near the blob (a shop sign beside a
    woman the selfie graph joined to her blob: presence 0.007 on the blob, 0.907 on the sign), so the other
    candidates (the other blobs, the faces) come first."""
    if person.start is None or person.start >= GIVE_UP or person.presence <= person.start:
        return False
    return not any(contains(person, f, rgb.shape[:2]) for f in find_faces(rgb))


def over_walked(rgb: np.ndarray, walked: Person | None, other: Person) -> Person:
    """``other`` (a later blob's or a face's person) unless a set-aside ``walked`` person (:func:`is_walked`) is at
    least as large (box area): being reached from nobody with no face is no evidence against a person seen from
    behind, so a smaller passer-by does not displace them (the choice before matte39's rule)."""
    if walked is None:
        return other
    shape = rgb.shape[:2]
    size = box_area(person_box(walked, shape) or (0, 0, 0, 0))
    return other if box_area(person_box(other, shape) or (0, 0, 0, 0)) > size else walked


def larger_than_walked(matter: Segmenter, rgb: np.ndarray, walked: Person) -> Person:
    """The largest person that person="all" finds (relight_rt.person.matting._everyone.everyone, which does not
    re-centre from a region where the pose graph sees nobody, and tries a blob holding nobody strip by strip) when
    their box is larger than ``walked``'s (:func:`is_walked`), else ``walked``."""
    shape = rgb.shape[:2]
    size = box_area(person_box(walked, shape) or (0, 0, 0, 0))
    best = max(everyone(matter, rgb), key=lambda p: box_area(person_box(p, shape) or (0, 0, 0, 0)), default=None)
    if best is None or box_area(person_box(best, shape) or (0, 0, 0, 0)) <= size:
        return walked
    return best if best.whole is None else replace(best, whole=None)
