"""Everyone in a photo (person="all", relight --person all): the selfie graph's blobs over every tile scale and the
faces found in tiles, largest first, each segmented (relight_rt.person.matting._candidate.person_at) unless it lies
inside the people matted already; a blob holding several people searched again for the rest, strip by strip where it
held nobody as a whole; last the places the selfie graph sees only faintly. The largest person's search asks it too,
for the people who stand with them (relight_rt.person.matting._company.peers) and for a larger one than a person the
re-centring reached from nobody (relight_rt.person.matting._largest.larger_than_walked).
"""

from __future__ import annotations

import cv2
import numpy as np

from ._candidate import Segmenter, person_at
from ._detect import MIN_TILE, faint_places, grid_pixels, roi_prob, strips
from ._layout import (
    COVERED,
    as_people,
    box_area,
    box_beside,
    box_height,
    box_past_border,
    face_share,
    mostly_in,
    without_straddlers,
)
from ._segmentation import Person, logits_on_grid, person_box, tile_levels, warp_to_grid, working_grid

MIN_PERSON_FRACTION = 0.06  # people whose box is shorter than this x the image's height are left out
PRESENCE_FAINT = 0.9  # a person the selfie graph hardly sees (faint_places): the pose graph must be this sure
_SURE_FACE = 0.8  # a face under which the pose graph sees nobody (_candidate._NOBODY) is a person only this sure
_COVERED_FACE = 0.8  # a face's person this much inside the people matted already is one of them
_MAX_REQUEUE = 16  # leftovers of blobs searched again (several people in one blob)
_MAX_TRIES = 32  # candidates segmented at most (each costs 1-4 pose-graph runs)
_MAX_FAINT = 16  # ... and faint places (:func:`faint_places`) tried at most after them
_FAINT_FRAME = 2.0  # ... each framed at least this x the smallest person kept (a faint blob is often part of one)
GIVE_UP = 0.02  # a blob whose first pose-graph pass says this little is nobody (no re-centring)


def everyone(matter: Segmenter, rgb: np.ndarray, tall: float = 0.0) -> list[Person]:
    """Everyone (person="all", :meth:`PersonMatter.people`) in ``rgb`` (H, W, 3) float32 [0, 1], each segmented by
    ``matter`` (its selfie graph ``roi``, its ``find_faces`` and ``segment``); with ``tall`` (image pixels), only those
    who may be that tall: blobs shorter than half of it are not tried, nor the faint places (the peers' search,
    relight_rt.person.matting._company.peers)."""
    h, w = rgb.shape[:2]
    grid = working_grid((0, 0, w, h))
    gw, gh, kx, ky, bx, by = grid
    prob = np.zeros((gh, gw), np.float32)
    for windows in tile_levels(h, w, MIN_TILE):
        for win in windows:
            np.maximum(prob, warp_to_grid(roi_prob(matter.roi, rgb, win), win, grid, 0.0), out=prob)
    min_rows = max(MIN_PERSON_FRACTION * h, tall) * ky * 0.5  # (a blob may be part of a person)

    def blobs(mask: np.ndarray) -> list[tuple[float, tuple, None, np.ndarray]]:
        n, labels, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
        out = []
        for i in range(1, n):
            x, y, bw, bh, area = (int(v) for v in stats[i])
            if bh >= min_rows:
                box = ((x - bx) / kx, (y - by) / ky, (x + bw - bx) / kx, (y + bh - by) / ky)
                out.append((area / kx / ky, box, None, np.flatnonzero(labels == i)))
        return out

    faces = matter.find_faces(rgb, every=True)
    cands: list = blobs(prob > 0.5)
    cands += [(box_area(f.body_box((h, w))) * 0.5, f.body_box((h, w)), k, None) for k, f in enumerate(faces)]
    cands.sort(key=lambda t: -t[0])
    occupied = np.zeros((gh, gw), bool)
    owned: set[int] = set()  # faces whose person is matted
    found: list[Person] = []
    requeued = tries = 0
    while cands and tries < _MAX_TRIES:
        _, box, k, pix = cands.pop(0)
        face = faces[k] if k is not None else None
        if (k is not None and k in owned) or (pix is not None and occupied.flat[pix].mean() >= COVERED):
            continue
        tries += 1
        p = person_at(matter, rgb, box, face, GIVE_UP, sure_face=_SURE_FACE if found else 0.0, vouch=not found)
        if p is not None and face is None and mostly_in(logits_on_grid(p, grid) > 0, occupied):
            # it slid onto a neighbour matted already (two passers-by side by side, one blob): the pose graph
            # framed on the blob's part beside that neighbour, not re-centred, may see the other one
            beside = box_beside(box, person_box(p, (h, w)))
            p = None if beside is None else person_at(matter, rgb, beside, None, GIVE_UP, passes=1, vouch=False)
        if p is not None and box_height(person_box(p, (h, w))) >= MIN_PERSON_FRACTION * h:
            mask = logits_on_grid(p, grid) > 0
            # a person mostly inside the people matted already is one of them again (a face's person may
            # overlap more, and is judged on their own share of a segmentation showing the neighbours too)
            own = mask if face is None else logits_on_grid(face_share(p, k, faces, (h, w)), grid) > 0
            if own.any() and occupied[own].mean() < (COVERED if face is None else _COVERED_FACE):
                occupied |= mask
                people, mine = as_people(p, k, faces, owned, (h, w))
                found.extend(people)
                owned.update(mine)
        if pix is None or requeued >= _MAX_REQUEUE:
            continue
        rest = np.zeros(gh * gw, bool)
        rest[pix[~occupied.flat[pix]]] = True
        if rest.sum() < pix.size:  # people beside the one matted in the same blob
            more = [c for c in blobs(rest.reshape(gh, gw)) if c[3].size >= 0.2 * pix.size]
        else:  # nobody in this blob as a whole: a wide one may be people side by side, strip by strip
            more = strips(pix, gw, grid, (h, w))
        requeued += len(more)
        cands = sorted(cands + more, key=lambda t: -t[0])
    tries = 0  # the faint places have tries of their own (a blob cut into strips used them all up)
    for box in faint_places(prob, grid, _FAINT_FRAME * MIN_PERSON_FRACTION * h) if not tall else []:
        if tries >= _MAX_FAINT:
            break
        pix = grid_pixels(box, grid)
        if pix.size == 0 or occupied.flat[pix].mean() >= COVERED:
            continue
        tries += 1
        p = person_at(matter, rgb, box, None, GIVE_UP, vouch=False)
        if p is None or p.presence < PRESENCE_FAINT or box_height(person_box(p, (h, w))) < MIN_PERSON_FRACTION * h:
            continue
        if box_past_border(person_box(p, (h, w)), (h, w)) is not None:
            # seen whole or not at all: cut by the frame, a faint place was a pattern (rose_hair's poster
            # letters in the top corner, framed on 2x the smallest person: presence 0.95)
            continue
        mask = logits_on_grid(p, grid) > 0
        if mask.any() and occupied[mask].mean() < COVERED:
            occupied |= mask
            found.append(p)
    return without_straddlers(found, grid, faces, (h, w))
