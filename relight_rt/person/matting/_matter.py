"""The person matter: which people a photo holds and their soft alpha at full resolution.

:class:`PersonMatter` orders the stages and holds the graphs' sessions. Candidates come from the region finders
(relight_rt.person.matting._detect); each is segmented by the pose graph on a square region re-centred until it settles,
with the selfie graph as the second way in for close portraits and faces (relight_rt.person.matting._candidate); the
largest person is searched for in relight_rt.person.matting._largest, everyone (person="all") in ._everyone, the people
with the largest in ._company, and what is added to a person found in ._completion. The chosen people's segmentations
become the coarse matte (relight_rt.person.matting._coarse) and, for photos, its outline is refined from colour
(relight_rt.image.matte_edges).
"""

from __future__ import annotations

import logging
import os
import threading

import numpy as np

from ...engine.errors import RelightError
from ...engine.session import Model, load_model
from ...image.matte_edges import band_width, refine_edges, without_doubted_parts
from ...image.regions import Region, crop_region, reductions_shared
from ..face_detector import Face
from ._behind import without_behind
from ._candidate import segment, vouched
from ._coarse import region_alpha
from ._company import joined, peers
from ._completion import backed, own_and_turned
from ._detect import find_faces, find_people
from ._everyone import MIN_PERSON_FRACTION, everyone
from ._largest import largest
from ._layout import blended
from ._models import FACE_FILE, POSE_FILE, ROI_FILE, as_rgb, find_matting_models
from ._parts import Crop, rejoin, shares
from ._segmentation import Person, contains, prob_at
from ._selfie import carried_past, owning, seen_on, uncut, widened
from ._shadow import selfie_sure, without_cast_shadow
from ._things_behind import without_things_behind

PERSON_MODES = ("largest", "all")
GUIDES = ("gray", "color")

log = logging.getLogger(__name__)


class PersonMatter:
    """Soft person alpha for any photo, from the bundled MediaPipe-derived graphs (module docstring).

    Args:
        models: folder holding matte_pose.onnx and matte_roi.onnx (default: $RELIGHT_RT_MODELS when it
            holds them, else the bundled ones).
        device: "cpu" (default), "cuda" or "auto".
        person: "largest" (default: the person with the largest area, and the people who stand with them, as
            tall and seen whole: relight_rt.person.matting._company.peers) or "all" (everyone at least
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
        reaching past that border. ``passes``: at most this many runs (default ``max_passes``; 1: the region as
        given, not re-centred). A close portrait is handed to the selfie graph (the portrait check). See
        relight_rt.person.matting._candidate.segment."""
        passes = self.max_passes if passes is None else passes
        return segment(self._pose, self.roi, self.find_faces, rgb, region, passes, give_up, past_border)

    # -- choosing the people ------------------------------------------------------------------------

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
                found = everyone(self, rgb)  # (_everyone)
            else:
                found, blobs = largest(self, rgb)  # (_largest)
                if found:
                    faces = self.find_faces(rgb)  # the face graph on the whole photo (~4 ms), for both below
                    found += peers(self, rgb, found[0], blobs, faces)  # (_company)
            # who is found is settled: the heads their regions cut are added now (the selfie graph segments
            # everyone in a region, so a higher region found earlier would take in the people beside)
            found = [uncut(self.roi, rgb, widened(self.roi, rgb, p))[0] if p.source == "roi" and p.whole is None else p
                     for p in found]  # fmt: skip
            found = [backed(self.roi, rgb, p) if p.source == "pose" else p for p in found]
            if self.person != "all" and found:
                found += joined(self.roi, rgb, found, faces)  # (_company)
                found += own_and_turned(self.roi, rgb, found)  # (_completion)
                side = float(max(rgb.shape[:2]))  # the whole photo's canvas spans its longer side
                found = [blended(p, seen_on(self.roi, rgb, p.region), side) if p.source == "roi" else p for p in found]
                apart = [f for f in faces if not any(contains(p, f, rgb.shape[:2]) for p in found if p.source != "own")]
                found += [q for p in rejoin(found) if p.source == "roi" for q in carried_past(self.roi, rgb, p, apart)]
                found = without_behind(self.roi, rgb, found, faces)  # someone out of focus behind: not theirs
                self._note_others(found, faces, name)
            return found

    def completed(self, rgb: np.ndarray, person: Person) -> list[Person]:
        """One person found on their own (the video matter's :meth:`segment` of a followed region) with what
        :meth:`people` adds to the largest person (relight_rt.person.matting._completion): the half-seen pixels both
        graphs see (``backed``), the parts joined in their own colours (``own_colours``) and the limbs seen only turned
        (_turned): [person, *parts]. The turned views run only where an upright view offers a part past the matte."""
        found = [backed(self.roi, rgb, person) if person.source == "pose" else person]
        return found + own_and_turned(self.roi, rgb, found)

    def vouched(self, rgb: np.ndarray, person: Person) -> bool:
        """Whether ``person`` (the pose graph's segmentation of a region) is a person: the pose graph's presence
        flag says so, or the selfie graph on the same region segments the same shape (a runner in mid-air, a man
        lying on a floor: relight_rt.person.matting._candidate.vouched)."""
        return vouched(self._pose, self.roi, rgb, person)

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
