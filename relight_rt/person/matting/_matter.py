"""The person matter: which people a photo holds and their soft alpha at full resolution.

Candidates come from the region finders (relight_rt.person.matting._detect); each is segmented by the pose graph
on a square region re-centred until it settles (:meth:`PersonMatter.segment`), with the selfie graph as the
second way in for close portraits and faces; the chosen people's segmentations become the coarse matte
(relight_rt.person.matting._coarse) and, for photos, its outline is refined from colour (relight_rt.image.matte_edges).
"""

from __future__ import annotations

import logging
import os
import threading
from dataclasses import replace

import cv2
import numpy as np

from ...engine.errors import RelightError
from ...engine.session import Model, load_model
from ...image.matte_edges import band_width, refine_edges, without_doubted_parts
from ...image.regions import Region, crop_region, grid_of_region, reductions_shared
from ..face_detector import Face
from ._behind import without_behind
from ._coarse import region_alpha
from ._colours import OWN_MIN, candidates, colour_model, own_part
from ._cut_body import cut_body, photo_bottom
from ._detect import (
    MIN_TILE,
    Around,
    around_people,
    faint_places,
    find_close_faces,
    find_faces,
    find_people,
    grid_pixels,
    roi_prob,
    strips,
)
from ._layout import (
    COVERED,
    PEER_HEIGHT,
    as_people,
    backed_logits,
    blended,
    box_area,
    box_beside,
    box_height,
    box_past_border,
    face_share,
    grow_where_cut,
    is_portrait,
    joined_part,
    mostly_in,
    people_whole,
    person_outside,
    seen_whole,
    someone_beside,
    within_photo,
    without_straddlers,
)
from ._models import FACE_FILE, POSE_FILE, ROI_FILE, as_rgb, find_matting_models
from ._parts import Crop, rejoin, shares
from ._segmentation import (
    COARSE_MIN_AREA,
    LOGIT_CLIP,
    Person,
    as_logits,
    canvas_points,
    contains,
    logits_on_grid,
    own_person,
    person_box,
    prob_at,
    sigmoid,
    tile_levels,
    warp_to_grid,
    working_grid,
)
from ._selfie import carried_past, confirmed, face_person, owning, reframed, roi_person, seen_on, uncut, widened
from ._shadow import selfie_sure, without_cast_shadow
from ._things_behind import without_things_behind
from ._turned import turned_people

PERSON_MODES = ("largest", "all")
GUIDES = ("gray", "color")
PRESENCE_MIN = 0.5  # pose-presence probability below which a region holds no person (unless a face vouches)
_AGREE = 0.75  # ... or where the selfie graph's segmentation of its region overlaps the pose graph's this much
_NOBODY = 0.05  # person="all": a face under which the pose graph's presence is below this ...
_SURE_FACE = 0.8  # ... is a person only when the face graph's score is at least this
_BACKED = 0.1  # a pose-graph person's pixels at this probability or more are theirs where the selfie graph agrees
_SURE_BLOB = 0.9  # person="largest", nobody else found: the selfie graph's blob is a person when this sure of it
PRESENCE_FAINT = 0.9  # ... for a person the selfie graph hardly sees (faint_places): the pose graph must be sure
MIN_PERSON_FRACTION = 0.06  # person="all": people whose box is shorter than this x the image's height are left out
_COVERED_FACE = 0.8  # ... and a face's person this much inside them
_MAX_REQUEUE = 16  # person="all": leftovers of blobs searched again (several people in one blob)
_MAX_TRIES = 32  # person="all": candidates segmented at most (each costs 1-4 pose-graph runs)
_MAX_FAINT = 16  # ... and faint places (:func:`faint_places`) tried at most after them
_FAINT_FRAME = 2.0  # ... each framed at least this x the smallest person kept (a faint blob is often part of one)
_GIVE_UP = 0.02  # person="all": a blob whose first pose-graph pass says this little is nobody (no re-centring)
_SETTLED_IOU = 0.9  # the region has settled when the next one overlaps it this much
_PORTRAIT_REACH = 0.3  # a pose-graph person ending this close to the bottom (x the height) may be a portrait
_PORTRAIT_FACE = 0.3  # ... and holding a face this x its width wide
_TRACE = 0.1  # person="largest", nobody else found: the pose graph's presence over a blob the whole photo vouches for
_JOINED_FACE = 0.75  # person="largest": a face outside the matte at least this sure, joined to it, is someone with them
# a blob's answer that does not hang on where the pose graph's re-centring wandered (matte39; RESULTS, broad sets):
START_PORTRAIT = True  # the portrait check (:meth:`PersonMatter._portrait_region`) on the region first given too
_WALKED_PART = 0.7  # ... where the re-centred person's box is less than this x the first region's person's
WALKED_LAST = True  # a person reached from nobody, holding no face, tried after the other candidates (_walked)

log = logging.getLogger(__name__)


def _part_of(person: Person, first: Person, shape: tuple[int, int]) -> bool:
    """Whether ``person``'s box is less than _WALKED_PART x the area of ``first``'s (both the pose graph's)."""
    box, start = person_box(person, shape), person_box(first, shape)
    return box is not None and start is not None and box_area(box) < _WALKED_PART * box_area(start)


class PersonMatter:
    """Soft person alpha for any photo, from the bundled MediaPipe-derived graphs (module docstring).

    Args:
        models: folder holding matte_pose.onnx and matte_roi.onnx (default: $RELIGHT_RT_MODELS when it
            holds them, else the bundled ones).
        device: "cpu" (default), "cuda" or "auto".
        person: "largest" (default: the person with the largest area, and the people who stand with them, as
            tall and seen whole: :meth:`_peers`) or "all" (everyone at least
            MIN_PERSON_FRACTION of the photo's height tall that the graphs see at any tile scale; see
            :meth:`people`; people overlapping one another can come as one, see the package docstring).
        refine: refine the edges with the photo (guided filter); False gives the upsampled segmentation.
        guide: "gray" (default, fast) or "color" (a colour guide: separates edges that differ in colour
            but not in brightness, e.g. pale shoes on a white floor; ~4x the refinement time).
        edges: with ``refine``, re-estimate alpha from colour in a band around the outline at full
            resolution (relight_rt.image.matte_edges: hair strands, no smear of the old background).
        max_passes: pose-graph runs per person while the region settles (>= 1).

    Calling it: ``alpha = matter(rgb)``, rgb (H, W, 3) float32 [0, 1] (uint8, RGBA and grayscale are
    accepted too, see :func:`as_rgb`) -> alpha (H, W) float32 in [0, 1].

    Raises (when called):
        RelightError: a bad image (see :func:`as_rgb`), or "no person found in IMAGE".
    """

    def __init__(
        self,
        models: str | os.PathLike | None = None,
        *,
        device: str = "cpu",
        person: str = "largest",
        refine: bool = True,
        guide: str = "gray",
        max_passes: int = 4,
        edges: bool = True,
    ):
        if guide not in GUIDES:
            raise RelightError(f"guide: expected one of {list(GUIDES)}, got {guide!r}")
        if person not in PERSON_MODES:
            raise RelightError(f"person: expected one of {list(PERSON_MODES)}, got {person!r}")
        if int(max_passes) < 1:
            raise RelightError(f"max_passes: expected >= 1, got {max_passes}")
        folder = find_matting_models(models)
        # warmed up on CUDA only (kernels chosen up front); on the CPU a run on zeros is only time lost for one photo
        self.pose: Model = load_model(folder / POSE_FILE, "matte_pose", device=device, warmup=False)
        self.roi: Model = load_model(folder / ROI_FILE, "matte_roi", device=device, warmup=False)
        face = folder / FACE_FILE
        self.face: Model | None = (load_model(face, "matte_face", device=device, warmup=False) if face.is_file()
                                   else None)
        for model in (self.pose, self.roi, self.face):
            if model is not None and model.on_cuda:
                model.warm_up()
        self.person = person
        self.refine = bool(refine)
        self.guide = guide
        self.max_passes = int(max_passes)
        self.edges = bool(edges)

    # -- detection ----------------------------------------------------------------------------------

    def find_people(
        self, rgb: np.ndarray, *, max_level: int | None = None
    ) -> list[tuple[float, tuple[float, float, float, float]]]:
        """Where people are, from the image alone (relight_rt.person.matting._detect.find_people): [(area in image
        pixels, (x0, y0, x1, y1))], largest first; empty when nobody is found. ``max_level``: no tiles finer than
        n x n (1: the whole image alone)."""
        if max_level is not None and (isinstance(max_level, bool) or not isinstance(max_level, int) or max_level < 1):
            raise RelightError(f"find_people: max_level must be a whole number >= 1 or None, got {max_level!r}")
        return find_people(self.roi, rgb, max_level)

    def find_faces(self, rgb: np.ndarray, *, every: bool = False) -> list[Face]:
        """Faces (the bundled face detector; none without it), best first: on the whole image, and with
        ``every`` also in overlapping tiles for smaller faces (relight_rt.person.matting._detect.find_faces)."""
        return find_faces(self.face, rgb, every=every)

    # -- segmentation -------------------------------------------------------------------------------

    def _pose(self, rgb: np.ndarray, region: Region) -> Person:
        out = self.pose.run({"image": crop_region(rgb, region).transpose(2, 0, 1)[None]})
        return Person(region, out["segmentation"][0, 0], float(out["presence"].reshape(-1)[0]))

    def segment(
        self, rgb: np.ndarray, region: Region, give_up: float = 0.0, past_border: bool = False,
        passes: int | None = None,
    ) -> Person:  # fmt: skip
        """Run the pose graph on one square region; re-centre on its segmentation until it settles (or, with
        ``give_up``, stop when the presence flag is below it: nobody there). With ``past_border``, a region
        whose presence stays low while the segmentation runs into the image border is tried once more,
        reaching past that border (:func:`past_border`). ``passes``: at most this many runs (default
        ``max_passes``; 1: the region as given, not re-centred). The pose graph's answer keeps its first pass's presence
        (``start``: :meth:`_walked`); where the re-centring walked onto a part of what the first pass saw
        (:func:`_part_of`) and the settled person calls for no portrait check, the first region is looked at for one.

        Measured (benchmarks/people_masks_eval.py, with :meth:`_walked`; matte39): the photos as they come unchanged
        (0.91399), mirrored 0.88691 -> 0.89694 (p193 0.19 -> 0.91, p085 0.50 -> 0.95, p170 0.00 -> 0.92), clip 0.93254
        -> 0.93277 / 0.93000 -> 0.93001. Checked wherever the first region reached past the bottom it took a runner
        crouching at the frame's bottom for a portrait (clip 0.915)."""
        person = first = None
        for _ in range(self.max_passes if passes is None else passes):
            person = self._pose(rgb, region)
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
                retry = self._pose(rgb, Region.around(*wider))
                person = retry if retry.presence > person.presence else person
        if person is None or first is None:
            return person
        moved = first is not person  # re-centred (asked before ``replace`` makes ``person`` a new object)
        person = replace(person, start=first.presence)
        region = self._portrait_region(rgb, person)
        if region is None and START_PORTRAIT and moved and _part_of(person, first, rgb.shape[:2]):
            # the re-centring walked off the region first given onto a part of what the pose graph saw there (a child
            # in front, a head and shoulders) and no longer reaches the bottom: the portrait check looks at that
            # first region too (_portrait_region)
            region = self._portrait_region(rgb, first)
        if region is None:
            return person
        roi = roi_person(self.roi, rgb, region, person.presence)
        if not is_portrait(roi, rgb.shape[:2]):
            return person
        return confirmed(self.roi, rgb, reframed(self.roi, rgb, roi), self.find_faces)

    def _portrait_region(self, rgb: np.ndarray, person: Person) -> Region | None:
        """Where the selfie graph checks for a portrait (:func:`is_portrait`): the pose graph's region when it
        reaches past the image's bottom; else, when the pose graph's person ends within _PORTRAIT_REACH x the
        image's height above the bottom, a region around that person reaching down to the bottom (the pose graph
        loses the shoulders and chest of a close portrait, and its region, framed on what it saw, then stops
        above the bottom: a portrait before an orange wall was matted down to the collar) and a face at least
        _PORTRAIT_FACE x that person's width wide lies inside it (a portrait's face is half the width the pose
        graph sees; a whole body crouching at the bottom of a frame, whose face is a tenth of it, is no
        portrait: the selfie graph would take the bushes around the runner's legs); None: no check. Either region
        is at most the photo's own square (:func:`within_photo`)."""
        h = rgb.shape[0]
        if person.region.box()[3] > h:
            return within_photo(person.region, rgb.shape[:2])
        box = person_box(person, rgb.shape[:2])
        if box is None or box[3] < h * (1.0 - _PORTRAIT_REACH):
            return None
        if self._big_face_in(rgb, person):
            return within_photo(Region.around(box[0], box[1], box[2], float(h)), rgb.shape[:2])
        return None

    def _big_face_in(self, rgb: np.ndarray, person: Person) -> bool:
        """Whether a face (the face graph's on the whole photo) at least _PORTRAIT_FACE x the width of ``person``'s
        box wide has its middle inside that box: a portrait's face (:meth:`_portrait_region`)."""
        box = person_box(person, rgb.shape[:2])
        if box is None:
            return False
        for f in self.find_faces(rgb):
            cx, cy = (f.box[0] + f.box[2]) / 2, (f.box[1] + f.box[3]) / 2
            inside = box[0] <= cx <= box[2] and box[1] <= cy <= box[3]
            if inside and f.box[2] - f.box[0] >= _PORTRAIT_FACE * (box[2] - box[0]):
                return True
        return False

    def people(self, rgb: np.ndarray, name: str = "image") -> list[Person]:
        """Segmented people (the largest for person="largest", everyone for "all"); empty when nobody is found.

        Candidates come from the selfie graph (blobs of its person probability: bodies seen from any side) and
        from faces; each is segmented by the pose graph (:meth:`segment`) and kept when the pose graph's
        presence flag says a person is there or a face vouches for one (close portraits, where the pose graph
        sees no body: the selfie graph then segments the region). "largest" tries the blobs of the first
        scale that has any (largest first) and the faces only when no blob holds a person. "all" gathers the
        selfie graph's probability over every tile scale and the faces in tiles too, skips candidates that lie
        inside the people already matted (a group seen as one blob is taken face by face; one selfie-graph
        segmentation holding several faces side by side is one person per face, :func:`split_by_faces`),
        drops duplicates, tries last where the selfie graph's probability stays faint (:func:`faint_places`: the pose
        graph must be sure there), and keeps people at least MIN_PERSON_FRACTION of the image's height tall.
        The detectors' crops of one call share the photo's reductions (:func:`reductions_shared`), which keep the
        selfie and face graphs' answers per region too (asked again, a region costs no run). Last, a
        selfie-graph person whose region cuts off the top of their head is given it (:func:`uncut`).
        """
        faces: list[Face] = []
        with reductions_shared(rgb):  # the detectors' crops share one set of reduced copies of the photo
            if self.person == "all":
                found = self._everyone(rgb)
            else:
                found, blobs = self._largest(rgb)
                if found:
                    faces = self.find_faces(rgb)  # the face graph on the whole photo (~4 ms), for both below
                    found += self._peers(rgb, found[0], blobs, faces)
            # who is found is settled: the heads their regions cut are added now (the selfie graph segments
            # everyone in a region, so a higher region found earlier would take in the people beside)
            found = [uncut(self.roi, rgb, widened(self.roi, rgb, p))[0] if p.source == "roi" and p.whole is None else p
                     for p in found]  # fmt: skip
            found = [self._backed(rgb, p) if p.source == "pose" else p for p in found]
            if self.person != "all" and found:
                found += self._joined(rgb, found, faces)
                found += self._own_and_turned(rgb, found)
                side = float(max(rgb.shape[:2]))  # the whole photo's canvas spans its longer side
                found = [blended(p, seen_on(self.roi, rgb, p.region), side) if p.source == "roi" else p for p in found]
                apart = [f for f in faces if not any(contains(p, f, rgb.shape[:2]) for p in found if p.source != "own")]
                found += [q for p in rejoin(found) if p.source == "roi" for q in carried_past(self.roi, rgb, p, apart)]
                found = without_behind(self.roi, rgb, found, faces)  # someone out of focus behind: not theirs
                self._note_others(found, faces, name)
            return found

    def completed(self, rgb: np.ndarray, person: Person) -> list[Person]:
        """One person found on their own (the video matter's :meth:`segment` of a followed region) with what
        :meth:`people` adds to the largest person: the half-seen pixels both graphs see (:meth:`_backed`), the
        parts joined in their own colours (:meth:`_own_colours`) and the limbs seen only turned (_turned):
        [person, *parts]. The turned views run only where an upright view offers a part past the matte."""
        found = [self._backed(rgb, person) if person.source == "pose" else person]
        return found + self._own_and_turned(rgb, found)

    def _own_and_turned(self, rgb: np.ndarray, found: list[Person]) -> list[Person]:
        """The parts joined to ``found`` in their own colours (:meth:`_own_colours`) and the limbs seen only turned
        (_turned), in that order."""
        start = around_people(self.roi, rgb, found)  # the own colours' region, the turned views' too unless
        own = self._own_colours(rgb, found, start)  # ... a part is added (it widens the region: its own run)
        return own + turned_people(self.roi, rgb, found + own, None if own else start)

    def _own_colours(self, rgb: np.ndarray, people: list[Person], start: Around | None = None) -> list[Person]:
        """What the selfie graph sees joined to ``people`` in their own colours (relight_rt.person.matting._colours:
        dark trousers the pose graph misses, not their shadow on the ground): [one Person holding it, source "own": part
        of the matte, no one's share of it in :meth:`parts`] or []. With them, what the selfie graph is sure of under a
        matte that the photo's bottom border cuts (relight_rt.person.matting._cut_body: a trouser leg before a wall of
        its grey, which the colour test refuses). On the canvas of a region around ``people`` (ROI_SCALE x their box),
        where the selfie graph sees it on the whole photo and on that region too (_colours: one run, which _turned's
        search on the same region then shares; under a matte the bottom border cuts, on that region alone suffices
        where the part's colours are the person's: _cut_body).

        Measured (benchmarks/people_masks_eval.py; OWN_SURE 0.7 and OWN_RATIO 0.4 chosen on photos half A among
        0.5-0.9 and 0.2-0.7, where every choice moved A by less than 0.001): clip 0.917 -> 0.923 (the four worst
        frames' trousers +0.13-0.33; the railing's dark post between the legs, their very colour, taken on a few
        frames, up to -0.09), photos half B 0.870 -> 0.875, half A 0.9101 -> 0.9098 (a blurred neighbour's dark hair
        and a dark passer-by beside, -0.04 each), images under 0.8 IoU 9.4 % -> 8.1 % over both sets. ~7 ms a photo
        (the k-means on 1500 samples a side), none where no part can be kept (the candidates only the matte's rim)."""
        start = around_people(self.roi, rgb, people) if start is None else start  # (or the caller's, for them)
        if start is None:
            return []
        region, seen, inside, mine = start
        framed = roi_prob(self.roi, rgb, region)
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

    def _joined(self, rgb: np.ndarray, people: list[Person], faces: list[Face]) -> list[Person]:
        """The people joined to ``people`` in the selfie graph's view of the whole photo who show a face of their
        own (person="largest"): [one "roi" Person holding them] or []. A face at least _JOINED_FACE sure whose
        middle no one in ``people`` covers, lying in a part of the selfie graph's segmentation (>= 0.5, outside
        ``people``) that touches them (:func:`joined_part`), is someone standing with them: a man embracing the
        woman found, a boy sitting against his mother, a monk beside another (the pose graph segments one of them;
        :meth:`_peers` asks for a person seen whole and as tall, which a couple's overlapping bodies and a seated
        child are not). The part is taken as the selfie graph sees it, softly (its probability as logits, one
        canvas pixel around it). One selfie-graph run, only where such a face is.

        Measured (benchmarks/people_masks_eval.py, photos; faces from the whole photo, :meth:`find_faces`): half B
        0.863 -> 0.869 (three photos 0.06-0.40 better), half A unchanged at a face score of 0.75 (at 0.5: two
        photos 0.18-0.20 worse, a shop's mannequin and a child's face beside the person in a street), the clip
        unchanged (no face joined)."""
        h, w = rgb.shape[:2]
        sure = [f for f in faces if f.score >= _JOINED_FACE]
        outside = [f for f in sure if not any(contains(p, f, (h, w)) for p in people)]
        if not outside and len(sure) < 2:
            return []
        region = Region(w / 2, h / 2, float(max(h, w)))
        prob = roi_prob(self.roi, rgb, region)
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

    def _backed(self, rgb: np.ndarray, person: Person) -> Person:
        """A pose-graph person with the pixels it half-sees (probability >= _BACKED) that the selfie graph on the
        same region sees as a person (>= 0.5) made part of them (:func:`backed_logits`: soft at the outline, sure
        inside). The pose graph half-sees dark trousers (the parkour runner's legs at 0.1-0.5 in several frames) and
        clothes before a background of their colour; the selfie graph alone takes in shadows and the wall behind, so
        only what both see is added. ~10 ms. Measured (_BACKED 0.05-0.3): clip 0.914 -> 0.917, photos A +0.004-0.006."""
        roi = roi_prob(self.roi, rgb, person.region) > 0.5
        lift = roi & (person.logits > np.float32(np.log(_BACKED / (1.0 - _BACKED)))) & (person.logits < 1.0)
        if not lift.any():
            return person
        return replace(person, logits=backed_logits(person.logits, lift))

    def _largest(self, rgb: np.ndarray) -> tuple[list[Person], list]:
        """The largest person ([] or [one]) and the selfie graph's blobs (:meth:`find_people`) they were
        looked for in (:meth:`_peers` reads them again)."""
        h, w = rgb.shape[:2]
        found = self.find_people(rgb)  # the selfie graph over the photo and its tiles: once, for every use below
        walked = None  # a person the re-centring reached from nobody, holding no face: kept unless a larger is found
        for _, box in found:
            p = self._person_at(rgb, box, None)
            if p is not None and WALKED_LAST and walked is None and self._walked(rgb, p):
                walked = p
                continue
            if p is not None:
                return [self._over_walked(rgb, walked, p)], found
        faces = self.find_faces(rgb)  # no body found: a face is the second way in
        for face in sorted(faces, key=lambda f: -box_area(f.body_box((h, w)))):
            p = self._person_at(rgb, face.body_box((h, w)), face)
            if p is not None:
                return [self._over_walked(rgb, walked, p)], found
        if walked is not None:
            return [self._larger_than_walked(rgb, walked)], found
        # a frame that is mostly one face (a crop through the forehead or the eyes): the face graph finds it
        # zoomed out only, and the pose graph sees no body in it
        for face in find_close_faces(self.face, rgb):
            p = self._person_at(rgb, face.body_box((h, w)), face)
            if p is not None:
                return [p], found
        # neither the pose graph nor a face vouches for anyone: the selfie graph's own segmentation of its largest
        # blob, when it is sure of it (a man lying on a shop floor, a couple taking a selfie, a woman seen from
        # behind: the pose graph's presence 0.003-0.27 there, and no face found; the selfie graph alone 0.69-0.84
        # IoU where the matte was empty)
        for _, box in found[:1]:
            roi = reframed(self.roi, rgb, roi_person(self.roi, rgb, Region.around(*box), 0.0))
            mine = roi.logits > 0
            if mine.sum() >= COARSE_MIN_AREA and float(sigmoid(roi.logits[mine]).mean()) >= _SURE_BLOB:
                return [roi], found
            # ... else the pose graph's, when it sees a trace of a person there and the selfie graph on the whole photo
            # sees the same shape (:func:`seen_whole`; a man in dark clothes in a dim arcade, the selfie graph on his
            # region seeing nothing of him)
            p = self.segment(rgb, Region.around(*box), past_border=True)
            if p.presence >= _TRACE and seen_whole(p.logits > 0, seen_on(self.roi, rgb, p.region) > 0.5):
                return [p], found
        return [], found

    def _walked(self, rgb: np.ndarray, person: Person) -> bool:
        """Whether ``person`` (a blob's, person="largest") was reached by re-centring from a region where the pose
        graph saw nobody (its first pass's presence below _GIVE_UP) and holds no face of the face graph's on the whole
        photo: the walk may have settled on anything person-like near the blob (a shop sign beside a woman the selfie
        graph joined to her blob: presence 0.007 on the blob, 0.907 on the sign), so the other candidates (the other
        blobs, the faces) come first."""
        if person.start is None or person.start >= _GIVE_UP or person.presence <= person.start:
            return False
        return not any(contains(person, f, rgb.shape[:2]) for f in self.find_faces(rgb))

    @staticmethod
    def _over_walked(rgb: np.ndarray, walked: Person | None, other: Person) -> Person:
        """``other`` (a later blob's or a face's person) unless a set-aside ``walked`` person (:meth:`_walked`) is at
        least as large (box area): being reached from nobody with no face is no evidence against a person seen from
        behind, so a smaller passer-by does not displace them (the choice before matte39's rule)."""
        if walked is None:
            return other
        shape = rgb.shape[:2]
        size = box_area(person_box(walked, shape) or (0, 0, 0, 0))
        return other if box_area(person_box(other, shape) or (0, 0, 0, 0)) > size else walked

    def _larger_than_walked(self, rgb: np.ndarray, walked: Person) -> Person:
        """The largest person that person="all" finds (:meth:`_everyone`, which does not re-centre from a region
        where the pose graph sees nobody, and tries a blob holding nobody strip by strip) when their box is larger
        than ``walked``'s (:meth:`_walked`), else ``walked``."""
        shape = rgb.shape[:2]
        size = box_area(person_box(walked, shape) or (0, 0, 0, 0))
        best = max(self._everyone(rgb), key=lambda p: box_area(person_box(p, shape) or (0, 0, 0, 0)), default=None)
        if best is None or box_area(person_box(best, shape) or (0, 0, 0, 0)) <= size:
            return walked
        return best if best.whole is None else replace(best, whole=None)

    def _peers(self, rgb: np.ndarray, main: Person, blobs: list, faces: list[Face]) -> list[Person]:
        """The people who stand with the largest person ``main`` (person="largest"): a group posing together is the
        photo's subject, a passer-by further back is not. A peer is a person that person="all" finds (:meth:`_everyone`)
        who is as tall as ``main`` within a factor PEER_HEIGHT (seen at the same distance), seen whole (their box
        touches no border of the photo but the bottom, and that only where ``main``'s does too), not mostly ``main``
        again (at most COVERED of them inside ``main``'s segmentation), and a body the pose graph sees or holding a
        face outside ``main`` (the selfie graph's segmentation of a treadmill beside a runner is neither; ``faces``:
        the face graph's on the whole photo). Looked for only where the selfie graph's ``blobs`` or ``faces`` show
        someone beside ``main`` (:func:`someone_beside`): a photo of one person costs nothing more.

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
        everyone = self._everyone(rgb, PEER_HEIGHT * tall)
        peers = []
        for p in everyone:
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
            peers.append(p)
        # a part split from a selfie-graph segmentation holding several people is matted from the whole of it
        # (rejoin): only where every part of that whole is taken, else from its own part
        taken = {id(p.whole) for p in peers if p.whole is not None}
        split = {key: sum(id(q.whole) == key for q in everyone) for key in taken}
        return [p if p.whole is None or sum(id(q.whole) == id(p.whole) for q in peers) == split[id(p.whole)]
                else replace(p, whole=None) for p in peers]  # fmt: skip

    def _note_others(self, people: list[Person], faces: list[Face], name: str) -> None:
        """Say (log, INFO) how many of ``faces`` lie outside the segmentations of ``people`` (the largest person
        and those standing with them): a group photo relit for part of it is a surprise unless said."""
        if not faces:
            return
        xs = np.array([(f.box[0] + f.box[2]) / 2 for f in faces])
        ys = np.array([(f.box[1] + f.box[3]) / 2 for f in faces])
        n = int(np.all([prob_at(p, xs, ys) < 0.5 for p in people], axis=0).sum())
        who = "the largest person is" if len(people) == 1 else f"the largest person and {len(people) - 1} beside are"
        if n:
            log.info("%s: %s matted, %d more face%s seen beside them (person=\"all\", relight --person all: "
                     "everyone, each relit on their own)", name, who, n, "s" if n > 1 else "")

    def _everyone(self, rgb: np.ndarray, tall: float = 0.0) -> list[Person]:
        """Everyone (person="all", :meth:`people`); with ``tall`` (image pixels), only those who may be that tall:
        blobs shorter than half of it are not tried, nor the faint places (:meth:`_peers`' search)."""
        h, w = rgb.shape[:2]
        grid = working_grid((0, 0, w, h))
        gw, gh, kx, ky, bx, by = grid
        prob = np.zeros((gh, gw), np.float32)
        for windows in tile_levels(h, w, MIN_TILE):
            for win in windows:
                np.maximum(prob, warp_to_grid(roi_prob(self.roi, rgb, win), win, grid, 0.0), out=prob)
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

        faces = self.find_faces(rgb, every=True)
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
            p = self._person_at(rgb, box, face, _GIVE_UP, sure_face=_SURE_FACE if found else 0.0, vouch=not found)
            if p is not None and face is None and mostly_in(logits_on_grid(p, grid) > 0, occupied):
                # it slid onto a neighbour matted already (two passers-by side by side, one blob): the pose graph
                # framed on the blob's part beside that neighbour, not re-centred, may see the other one
                beside = box_beside(box, person_box(p, (h, w)))
                p = None if beside is None else self._person_at(rgb, beside, None, _GIVE_UP, passes=1, vouch=False)
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
            p = self._person_at(rgb, box, None, _GIVE_UP, vouch=False)
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

    def _person_at(
        self, rgb: np.ndarray, box, face: Face | None, give_up: float = 0.0, passes: int | None = None,
        sure_face: float = 0.0, vouch: bool = True,
    ) -> Person | None:  # fmt: skip
        """The person in ``box`` (a blob's or a face's body box), or None when the pose graph says nobody is
        there and no face vouches for one (``give_up``: see :meth:`segment`). A face vouches when the pose graph
        sees at least a trace of a body under it (presence >= _NOBODY) or its score is at least ``sure_face``
        (person="all" asks for _SURE_FACE once someone is found: its faces come from tiles, where the face graph
        also finds faces in things, 0.66-0.73 on a red bench and a treadmill's console beside the person, with
        presence 0.00-0.01 under them, while the faces of other people under which the pose graph sees nobody
        scored 0.87-0.90 on the photos of benchmarks/people_masks_eval.py; a close portrait's face, the only
        person in the photo, can score 0.71). With ``vouch`` False only the pose graph's flag says whether a blob
        holds a person (person="all" once someone is found: a pile of clothes on a chair beside a man at a desk,
        which both graphs segment alike, was a second person)."""
        p = self.segment(
            rgb, Region.around(*box), give_up if face is None else 0.0, past_border=face is None, passes=passes
        )
        # the pose graph segments something in any region; its presence output says whether a person is there
        # (0.0000 on a colour gradient the region finder took for one, >= 0.87 on people in full view), or the
        # selfie graph sees the same shape there (:meth:`vouched`)
        if face is None and (p.presence >= PRESENCE_MIN or (vouch and self.vouched(rgb, p))):
            return p
        if p.presence >= PRESENCE_MIN and face is not None and contains(p, face, rgb.shape[:2]):
            return p
        if face is None or (p.presence < _NOBODY and face.score < sure_face):
            return None
        # a face, but the pose graph sees no body here (a close portrait) or another person: the selfie graph
        # segments the face's region instead (made for head-and-shoulders framing)
        roi = face_person(self.roi, rgb, face, max(p.presence, face.score))
        return roi if contains(roi, face, rgb.shape[:2]) else None

    def vouched(self, rgb: np.ndarray, person: Person) -> bool:
        """Whether ``person`` (the pose graph's segmentation of a region) is a person: the pose graph's presence
        flag says so, or the selfie graph on the same region segments the same shape (IoU >= _AGREE of their
        two masks on the canvas). The presence flag is made for upright bodies: it says nobody for a runner in
        mid-air over a railing (0.00-0.09 on 10 of the 100 frames of the parkour clip), a man lying on a floor,
        a woman seen from behind reaching out (0.003), while both graphs segment the same body there (IoU
        0.78-0.95); on a region holding nobody the two disagree or see nothing."""
        if person.presence >= PRESENCE_MIN:
            return True
        if person.source == "pose":
            mine, other = person.logits > 0, roi_prob(self.roi, rgb, person.region) > 0.5
        else:  # the selfie graph's (a portrait's): the pose graph on the same region must see the same shape
            mine, other = person.logits > 0, self._pose(rgb, person.region).logits > 0
        return bool(mine.any() and (mine & other).sum() >= _AGREE * (mine | other).sum())

    # -- full resolution ----------------------------------------------------------------------------

    def alpha(self, rgb: np.ndarray, people: list[Person], *, refine: bool | None = None) -> np.ndarray:
        """Full-resolution soft alpha (H, W) of ``people`` (max over them)."""
        h, w = rgb.shape[:2]
        alpha = np.zeros((h, w), np.float32)
        refine = self.refine if refine is None else refine
        for p in rejoin(people):
            x0, y0, x1, y1 = p.region.box()
            rx0, ry0 = max(int(np.floor(x0)), 0), max(int(np.floor(y0)), 0)
            rx1, ry1 = min(int(np.ceil(x1)), w), min(int(np.ceil(y1)), h)
            if rx1 <= rx0 or ry1 <= ry0:
                continue
            a = region_alpha(rgb, p, (rx0, ry0, rx1, ry1), refine=refine, guide=self.guide)
            np.maximum(alpha[ry0:ry1, rx0:rx1], a, out=alpha[ry0:ry1, rx0:rx1])
        if refine and self.edges and people:
            alpha = refine_edges(rgb, alpha)
            if self.person != "all":  # in everyone's matte a faint person apart is someone
                alpha = without_doubted_parts(alpha, band_width(alpha.shape))
                alpha = without_cast_shadow(rgb, alpha, selfie_sure(self.roi, rgb))  # (_shadow)
                alpha = without_things_behind(  # (_things_behind: the pose graph's view of a selfie-graph person)
                    rgb, alpha, people, lambda p: self._pose(rgb, p.region).logits, lambda: self.find_faces(rgb)
                )
        return alpha

    def __call__(self, image: np.ndarray, name: str = "image") -> np.ndarray:
        return self._matte(image, name)[0]

    def parts(self, image: np.ndarray, name: str = "image") -> tuple[np.ndarray, list[np.ndarray]]:
        """The matte (what calling the matter returns) and each person's share of it.

        Returns:
            (alpha, parts): alpha (H, W) float32 as ``matter(image)``; parts, one (H, W) float32 alpha per person
            found (one for person="largest"), summing to ``alpha``. Where people overlap, each pixel goes to the
            person whose segmentation is surer of it, softly over a few pixels (:func:`shares`): a group photo can
            then be relit person by person, each with their own shape (relight_rt.Relighter, matting="all").

        Raises:
            RelightError: a bad image, or "no person found in IMAGE".
        """
        rgb = as_rgb(image, name, copy=False)
        alpha, people = self._matte(rgb, name)
        return alpha, [alpha * s for s in shares(people, alpha, rgb)] if len(people) > 1 else [alpha]

    def part_crops(self, image: np.ndarray, name: str = "image") -> tuple[np.ndarray, list[Crop]]:
        """:meth:`parts`, each person's share held only where it is not 0: (alpha, [((y0, y1, x0, x1), part)]),
        ``part`` the (y1 - y0, x1 - x0) float32 piece of what :meth:`parts` gives (0 outside its box). A group
        photo of many people then holds about one photo of shares, not one per person (issue 50 bug 1)."""
        rgb = as_rgb(image, name, copy=False)
        alpha, people = self._matte(rgb, name)
        h, w = alpha.shape
        if len(people) < 2:
            return alpha, [((0, h, 0, w), alpha)]
        return alpha, [(box, alpha[box[0] : box[1], box[2] : box[3]] * share)
                       for box, share in shares(people, alpha, rgb, crops=True)]  # fmt: skip

    def _matte(self, image: np.ndarray, name: str) -> tuple[np.ndarray, list[Person]]:
        rgb = as_rgb(image, name, copy=False)  # only read from here on
        # one block for both: the graphs' answers on a region of this very photo hold for the matte too (the face
        # graph's on the whole photo, which the things-behind step asks for again), and its crops reuse the reductions
        with reductions_shared(rgb):
            people = self.people(rgb, name)
            alpha = self.alpha(rgb, people) if people else None
        if alpha is None or not (alpha >= 0.5).any():
            raise RelightError(
                f"no person found in {name} (no body or face the bundled detectors recognise; people shorter than "
                f"{MIN_PERSON_FRACTION:.0%} of the photo, seen only in part or in deep shadow can be missed)"
            )
        # the own colours' part is the others' to share; a part carried past a region's side, its person's
        carried = [p for p in people if p.source == "own" and p.of is not None]
        return alpha, [owning(p, [q for q in carried if q.of == p.region]) for p in people if p.source != "own"]


_SHARED: dict[tuple[str, str, str], PersonMatter] = {}
_SHARED_LOCK = threading.Lock()


def shared_matter(
    models: str | os.PathLike | None = None, *, device: str = "cpu", person: str = "largest"
) -> PersonMatter:
    """A PersonMatter per (models folder, device, person), loaded on first use and reused afterwards
    (loading the two graphs takes ~0.3 s). A PersonMatter keeps no state between calls and onnxruntime
    sessions may run from several threads, so the shared one can serve them all."""
    key = (str(find_matting_models(models).resolve()), device, person)
    with _SHARED_LOCK:
        if key not in _SHARED:
            _SHARED[key] = PersonMatter(key[0], device=device, person=person)
        return _SHARED[key]
