"""What the photo matte adds to a person found (:meth:`PersonMatter.completed`, and the largest person's matte in
:meth:`PersonMatter.people`): the pixels the pose graph half-sees that the selfie graph sees too (:func:`backed`),
the parts joined to them in their own colours (:func:`own_colours`), and the limbs seen only turned
(relight_rt.person.matting._turned). Each takes the selfie graph (``roi``) and the photo.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ...engine.session import Model
from ...image.regions import crop_region
from ._colours import OWN_MIN, candidates, colour_model, own_part
from ._cut_body import cut_body, photo_bottom
from ._detect import Around, around_people, roi_prob
from ._layout import backed_logits
from ._segmentation import Person, own_person
from ._turned import turned_people

_BACKED = 0.1  # a pose-graph person's pixels at this probability or more are theirs where the selfie graph agrees


def backed(roi: Model, rgb: np.ndarray, person: Person) -> Person:
    """A pose-graph person with the pixels it half-sees (probability >= _BACKED) that the selfie graph (``roi``) on the
    same region sees as a person (>= 0.5) made part of them (:func:`backed_logits`: soft at the outline, sure
    inside). The pose graph half-sees dark trousers (the parkour runner's legs at 0.1-0.5 in several frames) and
    clothes before a background of their colour; the selfie graph alone takes in shadows and the wall behind, so
    only what both see is added. ~10 ms. Measured (_BACKED 0.05-0.3): clip 0.914 -> 0.917, photos A +0.004-0.006."""
    seen = roi_prob(roi, rgb, person.region) > 0.5
    lift = seen & (person.logits > np.float32(np.log(_BACKED / (1.0 - _BACKED)))) & (person.logits < 1.0)
    if not lift.any():
        return person
    return replace(person, logits=backed_logits(person.logits, lift))


def own_and_turned(roi: Model, rgb: np.ndarray, found: list[Person]) -> list[Person]:
    """The parts joined to ``found`` in their own colours (:func:`own_colours`) and the limbs seen only turned
    (:func:`turned_people`), in that order."""
    start = around_people(roi, rgb, found)  # the own colours' region, the turned views' too unless
    own = own_colours(roi, rgb, found, start)  # ... a part is added (it widens the region: its own run)
    return own + turned_people(roi, rgb, found + own, None if own else start)


def own_colours(roi: Model, rgb: np.ndarray, people: list[Person], start: Around | None = None) -> list[Person]:
    """What the selfie graph (``roi``) sees joined to ``people`` in their own colours
    (relight_rt.person.matting._colours: dark trousers the pose graph misses, not their shadow on the ground): [one
    Person holding it, source "own": part of the matte, no one's share of it in :meth:`PersonMatter.parts`] or [].
    With them, what the selfie graph is sure of under a matte that the photo's bottom border cuts
    (relight_rt.person.matting._cut_body: a trouser leg before a wall of its grey, which the colour test refuses). On
    the canvas of a region around ``people`` (ROI_SCALE x their box; ``start``: :func:`around_people`'s answer when the
    caller has it), where the selfie graph sees it on the whole photo and on that region too (_colours: one run, which
    _turned's search on the same region then shares; under a matte the bottom border cuts, on that region alone
    suffices where the part's colours are the person's: _cut_body).

    Measured (benchmarks/people_masks_eval.py; OWN_SURE 0.7 and OWN_RATIO 0.4 chosen on photos half A among
    0.5-0.9 and 0.2-0.7, where every choice moved A by less than 0.001): clip 0.917 -> 0.923 (the four worst
    frames' trousers +0.13-0.33; the railing's dark post between the legs, their very colour, taken on a few
    frames, up to -0.09), photos half B 0.870 -> 0.875, half A 0.9101 -> 0.9098 (a blurred neighbour's dark hair
    and a dark passer-by beside, -0.04 each), images under 0.8 IoU 9.4 % -> 8.1 % over both sets. ~7 ms a photo
    (the k-means on 1500 samples a side), none where no part can be kept (the candidates only the matte's rim)."""
    start = around_people(roi, rgb, people) if start is None else start  # (or the caller's, for them)
    if start is None:
        return []
    region, seen, inside, mine = start
    framed = roi_prob(roi, rgb, region)
    cand = candidates(inside, mine, seen, framed)  # the own colours' (_colours)
    cut = cut_body(inside, mine, cand, framed, photo_bottom(region, rgb.shape[:2]))  # the bottom border's
    own = cand.sum() >= max(1.0, OWN_MIN * mine.sum())
    if not own and cut is None:
        return []  # (no part can be kept: no colours looked at)
    model = colour_model(crop_region(rgb, region), inside, mine, mine | cand)  # (the k-means: one model for both)
    if model is None:
        return []
    found = own_part(mine, cand, model) if own else None, cut.part(model) if cut is not None else None
    parts = [p for p in found if p is not None]
    if not parts:
        return []
    # the part's alpha: the whole photo's answer where both see it (_colours), the framed one where it alone does
    alone = cut.below & ~cand if cut is not None else np.zeros_like(cand)
    prob = np.where(alone, framed, np.where(framed >= 0.5, seen, 0.0)).astype(np.float32)
    return [own_person(region, np.any(parts, axis=0), mine, prob, people[0].presence)]
