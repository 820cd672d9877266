"""Automatic person matting, bundled and offline: any photo of a person, no mask needed.

Three graphs converted from Google MediaPipe (Apache-2.0; ``python -m export mask-models``, model card):

- ``matte_roi.onnx`` (MediaPipe selfie segmentation, 250 kB) runs on the whole image letterboxed to
  256x256 and says where people are (connected regions of its probability map). When it finds nobody
  at that scale, overlapping tiles (2x2 up to 6x6, each >= 256 px) are searched, so a small person in
  a big photo is still found.
- ``matte_pose.onnx`` (MediaPipe pose landmark "full", segmentation head, 5.7 MB) runs on a square
  region 1.25x the person's box (zero-padded past the image border, as MediaPipe does) and gives
  person logits at 256x256 plus a pose-presence probability. The region is re-centred on that
  segmentation until it is stable (at most ``max_passes`` runs), so a crude first box is corrected;
  where the segmentation runs into the region's edge, the next region reaches further that way.
- ``matte_face.onnx`` (MediaPipe BlazeFace full range, 1.1 MB; optional: relight_rt._faces) finds faces.
  A face is the second way in where the pose graph's presence flag says nobody (close portraits: the
  selfie graph then segments the face's region), and with ``person="all"`` it tells apart people whom
  the selfie graph sees as one blob (a group is matted face by face).

``person="all"`` gathers the selfie graph's probability over every tile scale (not only the first that
finds anybody), so passers-by beside a big subject are candidates too; a candidate already inside the
people matted is skipped, a wide blob where the pose graph sees nobody is tried strip by strip, and
people shorter than MIN_PERSON_FRACTION of the photo's height are left out.

The 256² logits are mapped back onto a working grid (the region at <= 512 px), turned into a
probability, and refined to full resolution by a fast guided filter steered by the photo (He & Sun
2015: the local linear model alpha ≈ a·I + b is fitted on the working grid with the gray photo as
guide; a and b are upsampled and applied to the full-resolution gray photo), so hair and arm outlines
follow the photo's own edges. Only the person's region is processed at full resolution. Then
(``edges=True``, photos only) the alpha is re-estimated from colour in a band around the outline at
full resolution (relight_rt._refine: hair strands, no smear of the old background).

:class:`VideoMatter` keeps state between frames: the person's region comes from the previous frame's
matte (the detector runs again only when the person is lost or every ``redetect_every`` frames), and
the working-grid probability is blended with the previous one warped by DIS optical flow, weighted by
how well the flow explains the frame (photometric agreement), which steadies the outline without
dragging it behind a moving person. :func:`outline_flicker` measures what is left.

Public API (the matting protocol of relight_rt.masks: rgb (H, W, 3) float32 in [0, 1] -> soft alpha
(H, W) float32 in [0, 1] at full resolution): ``PersonMatter``, ``VideoMatter``, ``outline_flicker``,
``find_matting_models``, ``shared_matter``, and ``estimate_foreground`` (relight_rt.foreground: the
decontaminated foreground colour of a matte's soft edge, for compositing over a new backdrop).
"""

from __future__ import annotations

import logging
import os
import threading
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from . import _faces
from ._errors import RelightError
from ._limits import check_array_pixels
from ._refine import guided_refine, refine_edges
from .contract import KINDS
from .foreground import estimate_foreground as estimate_foreground  # re-exported (issue 33)
from .session import ENV_MODELS, Model, bundled_models_dir, load_model

log = logging.getLogger(__name__)

POSE_FILE = KINDS["matte_pose"].filename  # the kinds are declared in relight_rt.contract
ROI_FILE = KINDS["matte_roi"].filename
FACE_FILE = KINDS["matte_face"].filename  # optional: a models folder without it finds people by body only
SIZE = 256  # both graphs' input side
PERSON_MODES = ("largest", "all")
GUIDES = ("gray", "color")
MIN_SIDE = 16  # smaller images cannot show a person to these models
_ROI_SCALE = 1.25  # square region side = this x the person's longest box side (MediaPipe's choice)
_COARSE_MIN_AREA = 24  # canvas pixels: smaller blobs of the region finder are noise or far-away people
_TILE_LEVELS = (1, 2, 3, 4, 6)  # whole image, then n x n overlapping tiles while nobody is found ...
_MIN_TILE = SIZE  # ... as long as the tiles stay at least 256 px (a smaller tile would only be upsampled)
_PRESENCE_MIN = 0.5  # pose-presence probability below which a region holds no person (unless a face vouches)
MIN_PERSON_FRACTION = 0.06  # person="all": people whose box is shorter than this x the image's height are left out
_COVERED = 0.5  # a candidate (blob) this much inside people already matted is one of them
_COVERED_FACE = 0.8  # ... and a face's person this much inside them
_MAX_REQUEUE = 16  # person="all": leftovers of blobs searched again (several people in one blob)
_MAX_TRIES = 32  # person="all": candidates segmented at most (each costs 1-4 pose-graph runs)
_GIVE_UP = 0.02  # person="all": a blob whose first pose-graph pass says this little is nobody (no re-centring)
_FACE_TILE_MIN = 2 * _faces.FACE_SIZE  # face search in tiles (person="all") while the tiles stay this large
_SETTLED_IOU = 0.9  # the region has settled when the next one overlaps it this much
_WORK_MAX = 512  # long side of the working grid (guided-filter fit, temporal blend)
_GF_EPS = 1e-3  # guided-filter regulariser (guide in [0, 1]); benchmarks/matting_eval.py picked it
_GF_RADIUS = 1.0  # guided-filter window radius, in pixels of the 256² segmentation
_LOGIT_CLIP = 30.0
_ONES_1x3 = np.ones((1, 3), np.float32)


@dataclass(frozen=True)
class Region:
    """A square region of the image: centre (cx, cy) and side, in continuous pixel coordinates
    (pixel (i, j) covers [j, j+1) x [i, i+1)); it may reach past the image border."""

    cx: float
    cy: float
    side: float

    @staticmethod
    def around(x0: float, y0: float, x1: float, y1: float, scale: float = _ROI_SCALE) -> Region:
        """The square of ``scale`` x the longest side of a box, centred on it."""
        return Region((x0 + x1) / 2, (y0 + y1) / 2, max(x1 - x0, y1 - y0, 1.0) * scale)

    def box(self) -> tuple[float, float, float, float]:
        h = self.side / 2
        return self.cx - h, self.cy - h, self.cx + h, self.cy + h

    def iou(self, other: Region) -> float:
        a, b = self.box(), other.box()
        iw = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
        ih = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
        inter = iw * ih
        return inter / (self.side**2 + other.side**2 - inter)


# ------------------------------------------------------------------------------------------- inputs


def as_rgb(image: np.ndarray, name: str = "image") -> np.ndarray:
    """Check and convert an image for matting: float32 (H, W, 3) RGB in [0, 1].

    Accepts (H, W, 3) RGB, (H, W, 4) RGBA (the alpha is ignored: matting looks at the picture), and
    grayscale (H, W) or (H, W, 1) (repeated into three channels); uint8 (0-255) or float (0-1).

    Raises:
        RelightError: not an array, another shape, another dtype, NaN/Inf, values outside [0, 1], or an
            image smaller than 16x16.
    """
    if not isinstance(image, np.ndarray):
        raise RelightError(f"{name}: expected an (H, W, 3) RGB array, got {type(image).__name__}")
    a = image
    check_array_pixels(a, name)
    if a.ndim == 3 and a.shape[2] == 1:
        a = a[..., 0]
    if a.ndim == 2:
        a = np.repeat(a[..., None], 3, axis=2)
    if a.ndim != 3 or a.shape[2] not in (3, 4):
        raise RelightError(f"{name}: expected an (H, W, 3) RGB image, got shape {tuple(image.shape)}")
    if a.shape[0] < MIN_SIDE or a.shape[1] < MIN_SIDE:
        raise RelightError(
            f"{name}: image is {a.shape[0]}x{a.shape[1]} (HxW), too small to find a person in "
            f"(expected at least {MIN_SIDE}x{MIN_SIDE})"
        )
    a = a[..., :3]
    if a.dtype == np.uint8:
        return np.multiply(a, np.float32(1 / 255), dtype=np.float32)
    if a.dtype.kind != "f":
        raise RelightError(f"{name}: expected uint8 or float in [0, 1], got {a.dtype}")
    out = np.ascontiguousarray(a, dtype=np.float32)
    lo, hi = float(out.min()), float(out.max())  # NaN propagates into min/max: one pass checks everything
    if np.isnan(lo) or np.isnan(hi):
        raise RelightError(f"{name}: expected finite values in [0, 1], got NaN")
    if not (lo >= -1e-3 and hi <= 1 + 1e-3):
        raise RelightError(f"{name}: expected float values in [0, 1], got [{lo:.4g}, {hi:.4g}]")
    return np.clip(out, 0.0, 1.0) if lo < 0 or hi > 1 else out


# ------------------------------------------------------------------------------------------- models


def find_matting_models(models: str | os.PathLike | None = None) -> Path:
    """The folder holding matte_pose.onnx and matte_roi.onnx: ``models`` if given, else $RELIGHT_RT_MODELS
    when it holds them, else the bundled models.

    Raises:
        RelightError: the folder lacks one of the two graphs.
    """
    if models is not None:
        place = Path(models)
    else:
        env = os.environ.get(ENV_MODELS, "").strip()
        place = Path(env) if env and (Path(env) / POSE_FILE).is_file() else bundled_models_dir()
    for f in (POSE_FILE, ROI_FILE):
        if not (place / f).is_file():
            raise RelightError(
                f"person matting: {place / f} not found (the bundled graphs come with the package; "
                f"rebuild them with python -m export mask-models)"
            )
    return place


# --------------------------------------------------------------------------------------- geometry


def _grid_of_region(region: Region, size: int = SIZE) -> tuple[float, float, float]:
    """(k, bx, by): canvas index = k * X + b for continuous image coordinate X (pixel centres at i + 0.5)."""
    k = size / region.side
    x0, y0, _, _ = region.box()
    return k, -k * x0 - 0.5, -k * y0 - 0.5


def _warp_matrix(src: tuple[float, float, float], dst: tuple[float, float, float]) -> np.ndarray:
    """2x3 matrix taking a dst grid index to a src grid index (for cv2.warpAffine with WARP_INVERSE_MAP).
    Each grid is (k, bx, by) with index = k * X + b."""
    ks, bxs, bys = src
    kd, bxd, byd = dst
    r = ks / kd
    return np.array([[r, 0.0, bxs - r * bxd], [0.0, r, bys - r * byd]], np.float64)


def crop_region(rgb: np.ndarray, region: Region, size: int = SIZE) -> np.ndarray:
    """The square ``region`` of ``rgb`` resampled to (size, size, 3), zero outside the image.

    Large regions are first reduced with area averaging (no aliasing); the final resampling is one exact
    affine warp, so :func:`_grid_of_region` describes the result exactly.
    """
    h, w = rgb.shape[:2]
    k, bx, by = _grid_of_region(region, size)
    x0, y0, x1, y1 = region.box()
    ix0, iy0 = max(int(np.floor(x0)) - 1, 0), max(int(np.floor(y0)) - 1, 0)
    ix1, iy1 = min(int(np.ceil(x1)) + 1, w), min(int(np.ceil(y1)) + 1, h)
    if ix1 <= ix0 or iy1 <= iy0:
        return np.zeros((size, size, 3), np.float32)
    sub = rgb[iy0:iy1, ix0:ix1]
    if k < 0.5:  # pre-reduce to about twice the canvas resolution
        sw = max(int(round(sub.shape[1] * 2 * k)), 1)
        sh = max(int(round(sub.shape[0] * 2 * k)), 1)
        sub = cv2.resize(sub, (sw, sh), interpolation=cv2.INTER_AREA)
        # INTER_AREA / LINEAR: (dst + 0.5) / s = (src + 0.5), s = dst / src size, per axis
        sx, sy = sw / (ix1 - ix0), sh / (iy1 - iy0)  # sub index = s * X - s * i0 - 0.5, per axis
        m = np.array([[sx / k, 0.0, -sx * ix0 - 0.5 - sx / k * bx], [0.0, sy / k, -sy * iy0 - 0.5 - sy / k * by]])
    else:
        m = _warp_matrix((1.0, -0.5 - ix0, -0.5 - iy0), (k, bx, by))  # sub index = X - i0 - 0.5
    return cv2.warpAffine(
        np.ascontiguousarray(sub), m, (size, size), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
        borderMode=cv2.BORDER_CONSTANT, borderValue=(0.0, 0.0, 0.0),
    )  # fmt: skip


def _sigmoid(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, -_LOGIT_CLIP, _LOGIT_CLIP)
    return 1.0 / (1.0 + np.exp(-x))


def _components(prob: np.ndarray, min_area: int) -> list[tuple[int, tuple[int, int, int, int]]]:
    """(area, (x0, y0, x1, y1)) of the 8-connected regions of prob > 0.5, largest first."""
    n, _, stats, _ = cv2.connectedComponentsWithStats((prob > 0.5).astype(np.uint8), connectivity=8)
    out = []
    for i in range(1, n):
        x, y, bw, bh, area = (int(v) for v in stats[i])
        if area >= min_area:
            out.append((area, (x, y, x + bw, y + bh)))
    out.sort(key=lambda t: -t[0])
    return out


# -------------------------------------------------------------------------------------------- matter


@dataclass(frozen=True)
class Person:
    """One matted person: the region the pose graph saw, its logits there, and its presence score."""

    region: Region
    logits: np.ndarray  # (256, 256) float32 person logits in the region's canvas
    presence: float
    source: str = "pose"  # which graph's segmentation: "pose" (bodies) or "roi" (head-and-shoulders)


class PersonMatter:
    """Soft person alpha for any photo, from the bundled MediaPipe-derived graphs (module docstring).

    Args:
        models: folder holding matte_pose.onnx and matte_roi.onnx (default: $RELIGHT_RT_MODELS when it
            holds them, else the bundled ones).
        device: "cpu" (default), "cuda" or "auto".
        person: "largest" (default: the person with the largest area) or "all" (everyone found at the
            first scale where anybody is found: a photo with one big person and far-away passers-by gets
            the big person only, as the whole-image pass does not see the small ones).
        refine: refine the edges with the photo (guided filter); False gives the upsampled segmentation.
        guide: "gray" (default, fast) or "color" (a colour guide: separates edges that differ in colour
            but not in brightness, e.g. pale shoes on a white floor; ~4x the refinement time).
        edges: with ``refine``, re-estimate alpha from colour in a band around the outline at full
            resolution (relight_rt._refine: hair strands, no smear of the old background).
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
        self.pose: Model = load_model(folder / POSE_FILE, "matte_pose", device=device)
        self.roi: Model = load_model(folder / ROI_FILE, "matte_roi", device=device)
        face = folder / FACE_FILE
        self.face: Model | None = load_model(face, "matte_face", device=device) if face.is_file() else None
        self.person = person
        self.refine = bool(refine)
        self.guide = guide
        self.max_passes = int(max_passes)
        self.edges = bool(edges)

    # -- detection ----------------------------------------------------------------------------------

    def _roi_prob(self, rgb: np.ndarray, region: Region) -> np.ndarray:
        canvas = crop_region(rgb, region)
        return self.roi.run({"image": canvas.transpose(2, 0, 1)[None]})["segmentation"][0, 0]


    def _roi_person(self, rgb: np.ndarray, region: Region, presence: float) -> Person:
        """The selfie graph's segmentation of ``region`` as a Person (its probability kept as logits)."""
        prob = self._roi_prob(rgb, region).astype(np.float64)
        logits = np.log(np.clip(prob, 1e-7, 1.0)) - np.log(np.clip(1.0 - prob, 1e-7, 1.0))
        return Person(region, logits.astype(np.float32), presence, "roi")
    def find_people(self, rgb: np.ndarray) -> list[tuple[float, tuple[float, float, float, float]]]:
        """Where people are, from the image alone: [(area in image pixels, (x0, y0, x1, y1))], largest
        first; empty when nobody is found. Whole image first, then 2x2, 3x3, 4x4 and 6x6 overlapping tiles
        (each 1.5x its share of the image, at least 256 px: small images stop early) while nobody is found."""
        h, w = rgb.shape[:2]
        for windows in _tile_levels(h, w, _MIN_TILE):
            found = []
            for win in windows:
                prob = self._roi_prob(rgb, win)
                k, bx, by = _grid_of_region(win)
                for area, (x0, y0, x1, y1) in _components(prob, _COARSE_MIN_AREA):
                    box = ((x0 - bx - 0.5) / k, (y0 - by - 0.5) / k, (x1 - bx - 0.5) / k, (y1 - by - 0.5) / k)
                    box = (max(box[0], 0.0), max(box[1], 0.0), min(box[2], float(w)), min(box[3], float(h)))
                    if box[2] > box[0] and box[3] > box[1]:
                        found.append((area / k / k, box))
            if found:
                return _merge_boxes(found)
        return []

    def find_faces(self, rgb: np.ndarray, *, every: bool = False) -> list[_faces.Face]:
        """Faces (the bundled face detector; none without it), best first: on the whole image, and with
        ``every`` also in 2x2 and 3x3 overlapping tiles (while they stay >= 384 px) for smaller faces."""
        if self.face is None:
            return []
        h, w = rgb.shape[:2]
        found = []
        levels = _tile_levels(h, w, _FACE_TILE_MIN, max_level=3)
        for windows in levels if every else levels[:1]:
            for win in windows:
                out = self.face.run({"image": crop_region(rgb, win, _faces.FACE_SIZE).transpose(2, 0, 1)[None]})
                x0, y0, _, _ = win.box()
                for box, score in _faces.decode(out["boxes"][0], out["scores"][0]):
                    found.append((np.array([x0, y0, x0, y0]) + box * win.side, score))
        faces = []
        for box, score in _faces.weighted_nms(found):
            b = (max(box[0], 0.0), max(box[1], 0.0), min(box[2], float(w)), min(box[3], float(h)))
            if b[2] > b[0] and b[3] > b[1]:
                faces.append(_faces.Face(b, score))
        return faces

    # -- segmentation -------------------------------------------------------------------------------

    def segment(self, rgb: np.ndarray, region: Region, give_up: float = 0.0) -> Person:
        """Run the pose graph on one square region; re-centre on its segmentation until it settles (or, with
        ``give_up``, stop when the presence flag is below it: nobody there)."""
        person = None
        for _ in range(self.max_passes):
            out = self.pose.run({"image": crop_region(rgb, region).transpose(2, 0, 1)[None]})
            person = Person(region, out["segmentation"][0, 0], float(out["presence"].reshape(-1)[0]))
            if person.presence < give_up:
                break
            box = person_box(person, rgb.shape[:2])
            if box is None or box[2] <= box[0] or box[3] <= box[1]:
                break
            nxt = Region.around(*_grow_where_cut(box, region, rgb.shape[:2]))
            if nxt.iou(region) > _SETTLED_IOU:
                break
            region = nxt
        if person is None or person.region.box()[3] <= rgb.shape[0]:
            return person  # a portrait runs off the bottom, so its region reaches past it: no check needed
        roi = self._roi_person(rgb, person.region, person.presence)
        return roi if _is_portrait(person_box(roi, rgb.shape[:2]), rgb.shape[:2]) else person

    def people(self, rgb: np.ndarray, name: str = "image") -> list[Person]:
        """Segmented people (the largest for person="largest", everyone for "all"); empty when nobody is found.

        Candidates come from the selfie graph (blobs of its person probability: bodies seen from any side) and
        from faces; each is segmented by the pose graph (:meth:`segment`) and kept when the pose graph's
        presence flag says a person is there or a face vouches for one (close portraits, where the pose graph
        sees no body: the selfie graph then segments the region). "largest" tries the blobs of the first
        scale that has any (largest first) and the faces only when no blob holds a person. "all" gathers the
        selfie graph's probability over every tile scale and the faces in tiles too, skips candidates that lie
        inside the people already matted (a group seen as one blob is taken face by face), drops duplicates,
        and keeps people at least MIN_PERSON_FRACTION of the image's height tall.
        """
        if self.person == "all":
            return self._everyone(rgb)
        h, w = rgb.shape[:2]
        for _, box in self.find_people(rgb):
            p = self._person_at(rgb, box, None)
            if p is not None:
                return [p]
        faces = self.find_faces(rgb)  # no body found: a face is the second way in
        for face in sorted(faces, key=lambda f: -_box_area(f.body_box((h, w)))):
            p = self._person_at(rgb, face.body_box((h, w)), face)
            if p is not None:
                return [p]
        return []

    def _everyone(self, rgb: np.ndarray) -> list[Person]:
        h, w = rgb.shape[:2]
        grid = _working_grid((0, 0, w, h))
        gw, gh, kx, ky, bx, by = grid
        prob = np.zeros((gh, gw), np.float32)
        for windows in _tile_levels(h, w, _MIN_TILE):
            for win in windows:
                np.maximum(prob, warp_to_grid(self._roi_prob(rgb, win), win, grid, 0.0), out=prob)
        min_rows = MIN_PERSON_FRACTION * h * ky * 0.5  # (a blob may be part of a person)

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
        cands += [(_box_area(f.body_box((h, w))) * 0.5, f.body_box((h, w)), k, None) for k, f in enumerate(faces)]
        cands.sort(key=lambda t: -t[0])
        occupied = np.zeros((gh, gw), bool)
        owned: set[int] = set()  # faces whose person is matted
        found: list[Person] = []
        requeued = tries = 0
        while cands and tries < _MAX_TRIES:
            _, box, k, pix = cands.pop(0)
            face = faces[k] if k is not None else None
            if (k is not None and k in owned) or (pix is not None and occupied.flat[pix].mean() >= _COVERED):
                continue
            tries += 1
            p = self._person_at(rgb, box, face, _GIVE_UP)
            if p is not None and _box_height(person_box(p, (h, w))) >= MIN_PERSON_FRACTION * h:
                mask = logits_on_grid(p, grid) > 0
                # a person mostly inside the people matted already is one of them again (a face's person may
                # overlap more: in a group, the selfie graph's region of one face shows the neighbours too)
                if mask.any() and occupied[mask].mean() < (_COVERED if face is None else _COVERED_FACE):
                    occupied |= mask
                    found.append(p)
                    mine = [j for j, f in enumerate(faces) if j not in owned and _contains(p, f, (h, w))]
                    owned.update([k] if k is not None else mine[:1])
            if pix is None or requeued >= _MAX_REQUEUE:
                continue
            rest = np.zeros(gh * gw, bool)
            rest[pix[~occupied.flat[pix]]] = True
            if rest.sum() < pix.size:  # people beside the one matted in the same blob
                more = [c for c in blobs(rest.reshape(gh, gw)) if c[3].size >= 0.2 * pix.size]
            else:  # nobody in this blob as a whole: a wide one may be people side by side, strip by strip
                more = _strips(pix, gw, grid, (h, w))
            requeued += len(more)
            cands = sorted(cands + more, key=lambda t: -t[0])
        return found

    def _person_at(self, rgb: np.ndarray, box, face: _faces.Face | None, give_up: float = 0.0) -> Person | None:
        """The person in ``box`` (a blob's or a face's body box), or None when the pose graph says nobody is
        there and no face vouches for one (``give_up``: see :meth:`segment`)."""
        p = self.segment(rgb, Region.around(*box), give_up if face is None else 0.0)
        # the pose graph segments something in any region; its presence output says whether a person is there
        # (0.0000 on a colour gradient the region finder took for one, >= 0.87 on people in full view)
        if p.presence >= _PRESENCE_MIN and (face is None or _contains(p, face, rgb.shape[:2])):
            return p
        if face is None:
            return None
        # a face, but the pose graph sees no body here (a close portrait) or another person: the selfie graph
        # segments the face's region instead (made for head-and-shoulders framing)
        region = Region.around(*face.body_box(rgb.shape[:2]))
        roi = self._roi_person(rgb, region, max(p.presence, face.score))
        return roi if _contains(roi, face, rgb.shape[:2]) else None

    # -- full resolution ----------------------------------------------------------------------------

    def alpha(self, rgb: np.ndarray, people: list[Person], *, refine: bool | None = None) -> np.ndarray:
        """Full-resolution soft alpha (H, W) of ``people`` (max over them)."""
        h, w = rgb.shape[:2]
        alpha = np.zeros((h, w), np.float32)
        refine = self.refine if refine is None else refine
        for p in people:
            x0, y0, x1, y1 = p.region.box()
            rx0, ry0 = max(int(np.floor(x0)), 0), max(int(np.floor(y0)), 0)
            rx1, ry1 = min(int(np.ceil(x1)), w), min(int(np.ceil(y1)), h)
            if rx1 <= rx0 or ry1 <= ry0:
                continue
            a = region_alpha(rgb, p, (rx0, ry0, rx1, ry1), refine=refine, guide=self.guide)
            np.maximum(alpha[ry0:ry1, rx0:rx1], a, out=alpha[ry0:ry1, rx0:rx1])
        if refine and self.edges and people:
            alpha = refine_edges(rgb, alpha)
        return alpha

    def __call__(self, image: np.ndarray, name: str = "image") -> np.ndarray:
        rgb = as_rgb(image, name)
        people = self.people(rgb, name)
        alpha = self.alpha(rgb, people) if people else None
        if alpha is None or not (alpha >= 0.5).any():
            raise RelightError(
                f"no person found in {name} (no body or face the bundled detectors recognise; people shorter than "
                f"{MIN_PERSON_FRACTION:.0%} of the photo, seen only in part or in deep shadow can be missed)"
            )
        return alpha


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


def _grow_where_cut(
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


def _is_portrait(box: tuple[float, float, float, float] | None, shape: tuple[int, int]) -> bool:
    """Head-and-shoulders (or chest-up) framing: the person (as the selfie graph sees them in the region)
    runs off the bottom of the image and their visible box is less than 1.8x as tall as wide. The pose
    graph was trained on bodies and loses the shoulders of such crops (IoU 0.71-0.85 on crops of the
    reference video); the selfie graph, made for them, keeps them (0.97-0.99). Full bodies and knee-up
    crops stay with the pose graph (0.97-0.99 there, the selfie graph 0.92-0.97)."""
    if box is None:
        return False
    x0, y0, x1, y1 = box
    return y1 >= shape[0] - 2 and (y1 - y0) < 1.8 * (x1 - x0)


def person_box(person: Person, shape: tuple[int, int]) -> tuple[float, float, float, float] | None:
    """Image-space box (x0, y0, x1, y1) of the person's segmentation (logits > 0), clipped to the image;
    None when it is empty."""
    comps = _components(person.logits > 0, _COARSE_MIN_AREA)
    if not comps:
        return None
    k, bx, by = _grid_of_region(person.region)
    x0 = min(b[0] for _, b in comps)
    y0 = min(b[1] for _, b in comps)
    x1 = max(b[2] for _, b in comps)
    y1 = max(b[3] for _, b in comps)
    h, w = shape
    box = ((x0 - bx - 0.5) / k, (y0 - by - 0.5) / k, (x1 - bx - 0.5) / k, (y1 - by - 0.5) / k)
    return max(box[0], 0.0), max(box[1], 0.0), min(box[2], float(w)), min(box[3], float(h))


def _merge_boxes(found: list[tuple[float, tuple[float, float, float, float]]]):
    """Merge boxes that overlap or nearly touch (one person seen by two tiles, or split in two by the
    coarse finder); largest area first."""
    items = [(a, list(b)) for a, b in sorted(found, key=lambda t: -t[0])]
    merged = True
    while merged:
        merged = False
        for i in range(len(items)):
            for j in range(i + 1, len(items)):
                a, b = items[i][1], items[j][1]
                gap = 0.25 * min(max(a[2] - a[0], a[3] - a[1]), max(b[2] - b[0], b[3] - b[1]))
                if min(a[2], b[2]) + gap > max(a[0], b[0]) and min(a[3], b[3]) + gap > max(a[1], b[1]):
                    box = [min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3])]
                    items[i] = (max(items[i][0], items[j][0]), box)
                    del items[j]
                    merged = True
                    break
            if merged:
                break
    items.sort(key=lambda t: -t[0])
    return [(a, tuple(b)) for a, b in items]


def _tile_levels(h: int, w: int, min_tile: float, max_level: int = _TILE_LEVELS[-1]) -> list[list[Region]]:
    """The search windows per scale: the whole image, then n x n overlapping tiles (n in _TILE_LEVELS, each
    1.5x its share of the image) while they stay at least ``min_tile`` px."""
    big = max(h, w)
    levels = []
    for level in _TILE_LEVELS:
        if level > max_level:
            break
        if level == 1:
            levels.append([Region(w / 2, h / 2, big)])
            continue
        side = min(big / level * 1.5, max(h, w))
        side = max(side, min(h, w) / level * 1.5)
        if side < min_tile:
            break
        xs = np.linspace(side / 2, max(w - side / 2, side / 2), level) if w > side else [w / 2]
        ys = np.linspace(side / 2, max(h - side / 2, side / 2), level) if h > side else [h / 2]
        levels.append([Region(float(x), float(y), side) for y in ys for x in xs])
    return levels


def _strips(pix: np.ndarray, gw: int, grid, shape: tuple[int, int]) -> list:
    """A wide blob (flat pixel indices on the working grid) as overlapping upright strips, each about half as
    wide as the blob is tall: candidates for people standing side by side."""
    _, _, kx, ky, bx, by = grid
    ys, xs = np.divmod(pix, gw)
    x0, x1, y0, y1 = xs.min(), xs.max() + 1, ys.min(), ys.max() + 1
    width = 0.5 * (y1 - y0)
    if x1 - x0 < 1.4 * width:
        return []
    out = []
    for left in np.arange(x0, x1 - width + 1, width / 2):
        keep = pix[(xs >= left) & (xs < left + width)]
        if keep.size:
            sy = keep // gw
            box = ((left - bx) / kx, (sy.min() - by) / ky, (left + width - bx) / kx, (sy.max() + 1 - by) / ky)
            out.append((keep.size / kx / ky, box, None, keep))
    return out


def _box_area(box) -> float:
    return max(box[2] - box[0], 0.0) * max(box[3] - box[1], 0.0)


def _box_height(box) -> float:
    return 0.0 if box is None else box[3] - box[1]


def _prob_at(person: Person, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """The person's probability (sigmoid of its logits) at image points (xs, ys); 0 outside its region."""
    k, bx, by = _grid_of_region(person.region)
    i = np.floor(k * ys + by + 0.5).astype(int)
    j = np.floor(k * xs + bx + 0.5).astype(int)
    inside = (i >= 0) & (i < SIZE) & (j >= 0) & (j < SIZE)
    out = np.zeros(xs.shape, np.float32)
    out[inside] = _sigmoid(person.logits[i[inside], j[inside]])
    return out


def _contains(person: Person, face: _faces.Face, shape: tuple[int, int]) -> bool:
    """Whether the person's segmentation covers the middle of the face."""
    x0, y0, x1, y1 = face.box
    xs = np.array([(x0 + x1) / 2, 0.35 * x0 + 0.65 * x1, 0.65 * x0 + 0.35 * x1])
    ys = np.array([(y0 + y1) / 2] * 3)
    return bool((_prob_at(person, xs, ys) > 0.5).sum() >= 2)


def _working_grid(rect: tuple[int, int, int, int]) -> tuple[int, int, float, float, float, float]:
    """(gw, gh, kx, ky, bx, by): a grid over the image rectangle with long side <= _WORK_MAX."""
    rx0, ry0, rx1, ry1 = rect
    rw, rh = rx1 - rx0, ry1 - ry0
    s = min(1.0, _WORK_MAX / max(rw, rh))
    gw, gh = max(int(round(rw * s)), 1), max(int(round(rh * s)), 1)
    kx, ky = gw / rw, gh / rh
    return gw, gh, kx, ky, -kx * rx0 - 0.5, -ky * ry0 - 0.5


def logits_on_grid(person: Person, grid: tuple[int, int, float, float, float, float]) -> np.ndarray:
    """The person's canvas logits resampled onto a working grid (very negative outside the region)."""
    return warp_to_grid(np.clip(person.logits, -_LOGIT_CLIP, _LOGIT_CLIP), person.region, grid, -_LOGIT_CLIP)


def warp_to_grid(canvas: np.ndarray, region: Region, grid: tuple[int, int, float, float, float, float],
                 outside: float) -> np.ndarray:  # fmt: skip
    """A (256, 256) map over ``region`` resampled onto a working grid (``outside`` beyond the region)."""
    gw, gh, kx, ky, bx, by = grid
    k, cbx, cby = _grid_of_region(region)
    m = np.array([[k / kx, 0.0, cbx - k / kx * bx], [0.0, k / ky, cby - k / ky * by]])
    return cv2.warpAffine(
        canvas, m, (gw, gh), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_CONSTANT,
        borderValue=outside,
    )  # fmt: skip


def guided_refine_color(prob: np.ndarray, rgb_small: np.ndarray, rgb_full: np.ndarray, radius: int) -> np.ndarray:
    """Fast guided filter with a colour guide (He et al. 2013, eq. 14): fit prob ≈ a·I + b (a: 3-vector per
    window) on the small grid; upsample a, b and apply them with the full-size RGB guide."""
    k = 2 * radius + 1

    def box(x: np.ndarray) -> np.ndarray:
        return cv2.boxFilter(x, -1, (k, k), borderType=cv2.BORDER_REFLECT)

    i = rgb_small
    mean_i = box(i)  # (h, w, 3)
    mean_p = box(prob)
    cov_ip = box(i * prob[..., None]) - mean_i * mean_p[..., None]
    # covariance of the guide: six distinct entries, + eps on the diagonal
    rr = box(i[..., 0] * i[..., 0]) - mean_i[..., 0] ** 2 + _GF_EPS
    rg = box(i[..., 0] * i[..., 1]) - mean_i[..., 0] * mean_i[..., 1]
    rb = box(i[..., 0] * i[..., 2]) - mean_i[..., 0] * mean_i[..., 2]
    gg = box(i[..., 1] * i[..., 1]) - mean_i[..., 1] ** 2 + _GF_EPS
    gb = box(i[..., 1] * i[..., 2]) - mean_i[..., 1] * mean_i[..., 2]
    bb = box(i[..., 2] * i[..., 2]) - mean_i[..., 2] ** 2 + _GF_EPS
    # inverse of the symmetric 3x3 by cofactors
    c00, c01, c02 = gg * bb - gb * gb, gb * rb - rg * bb, rg * gb - gg * rb
    c11, c12, c22 = rr * bb - rb * rb, rg * rb - rr * gb, rr * gg - rg * rg
    det = rr * c00 + rg * c01 + rb * c02
    x, y, z = cov_ip[..., 0], cov_ip[..., 1], cov_ip[..., 2]
    a = np.stack([c00 * x + c01 * y + c02 * z, c01 * x + c11 * y + c12 * z, c02 * x + c12 * y + c22 * z], -1)
    a /= det[..., None]
    b = mean_p - (a * mean_i).sum(-1)
    a, b = box(a), box(b)
    size = (rgb_full.shape[1], rgb_full.shape[0])
    if size != (prob.shape[1], prob.shape[0]):
        a = cv2.resize(a, size, interpolation=cv2.INTER_LINEAR)
        b = cv2.resize(b, size, interpolation=cv2.INTER_LINEAR)
    # sum_c a_c I_c + b with OpenCV's vectorised kernels (numpy's strided channel slices cost 5x more)
    out = cv2.transform(cv2.multiply(a, rgb_full), _ONES_1x3)
    out = cv2.add(out, b)
    return np.clip(out, 0.0, 1.0, out=out)


def region_alpha(
    rgb: np.ndarray, person: Person, rect: tuple[int, int, int, int], *, refine: bool = True,
    prob: np.ndarray | None = None, guide: str = "gray",
) -> np.ndarray:  # fmt: skip
    """Soft alpha of one person over the image rectangle ``rect`` = (x0, y0, x1, y1), full resolution.

    ``prob`` (optional) replaces the person's probability on the working grid (the video matter passes
    its temporally smoothed one)."""
    rx0, ry0, rx1, ry1 = rect
    grid = _working_grid(rect)
    gw, gh = grid[0], grid[1]
    if prob is None:
        prob = _sigmoid(logits_on_grid(person, grid)).astype(np.float32)
    sub = rgb[ry0:ry1, rx0:rx1]
    if not refine:
        if (gw, gh) == (rx1 - rx0, ry1 - ry0):
            return prob
        return cv2.resize(prob, (rx1 - rx0, ry1 - ry0), interpolation=cv2.INTER_LINEAR)
    # radius: _GF_RADIUS canvas pixels of the segmentation, in working-grid pixels (at least 2)
    k_canvas = SIZE / person.region.side
    radius = max(2, int(round(_GF_RADIUS * grid[2] / k_canvas)))
    if guide == "color":
        sub = np.ascontiguousarray(sub)
        small = sub if (gw, gh) == (rx1 - rx0, ry1 - ry0) else cv2.resize(sub, (gw, gh), interpolation=cv2.INTER_AREA)
        return guided_refine_color(prob, small, sub, radius)
    gray_full = cv2.cvtColor(np.ascontiguousarray(sub), cv2.COLOR_RGB2GRAY)
    if (gw, gh) == (rx1 - rx0, ry1 - ry0):
        gray_small = gray_full
    else:
        gray_small = cv2.resize(gray_full, (gw, gh), interpolation=cv2.INTER_AREA)
    return guided_refine(prob, gray_small, gray_full, radius)


# --------------------------------------------------------------------------------------------- video


def _flow_to(dis: cv2.DISOpticalFlow, cur: np.ndarray, prev: np.ndarray) -> np.ndarray:
    """Backward flow (H, W, 2) as sampling maps: pixel p of ``cur`` was at maps[p] in ``prev``."""
    a = np.clip(cur * 255.0, 0, 255).astype(np.uint8)
    b = np.clip(prev * 255.0, 0, 255).astype(np.uint8)
    flow = dis.calc(a, b, None)
    h, w = cur.shape
    flow[..., 0] += np.arange(w, dtype=np.float32)[None, :]
    flow[..., 1] += np.arange(h, dtype=np.float32)[:, None]
    return flow


_REGION_KEEP_IOU = 0.8


def _inside(box: tuple[float, float, float, float], region: Region, margin: float = 0.05) -> bool:
    """True when ``box`` lies inside ``region`` with ``margin`` x side to spare on every side."""
    x0, y0, x1, y1 = region.box()
    m = margin * region.side
    return box[0] >= x0 + m and box[1] >= y0 + m and box[2] <= x1 - m and box[3] <= y1 - m


def _remap(x: np.ndarray, maps: np.ndarray) -> np.ndarray:
    return cv2.remap(x, maps, None, interpolation=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)


class VideoMatter:
    """Person alpha for the frames of a video, steady over time (module docstring).

    The region the pose graph sees follows the person from the previous frame's matte (the region finder
    runs on the first frame, when the person is lost, and every ``redetect_every`` frames if > 0). The
    person probability on the working grid is blended with the previous frame's, warped by DIS optical
    flow: ``p = (1 - w) p_now + w p_prev_warped``, ``w = smoothing * exp(-|I_now - I_prev_warped| / 0.05)``
    (the history counts only where the flow explains the picture), then refined by the guided filter.

    Args:
        matter: a :class:`PersonMatter` to use (default: a new one with ``models`` and ``device``).
        smoothing: weight of the warped history in [0, 1); 0 turns temporal smoothing off.
        redetect_every: run the region finder every N frames even when the person is tracked (0: never).
        refine: guided-filter edge refinement (as in PersonMatter; always with the gray guide, for speed).

    Calling it on each frame in order: ``alpha = vm(rgb)``; a frame with nobody in it gives an all-zero
    alpha (no error) and the next frame searches again. Only the largest person is followed.
    """

    def __init__(
        self,
        matter: PersonMatter | None = None,
        *,
        models: str | os.PathLike | None = None,
        device: str = "cpu",
        smoothing: float = 0.7,
        redetect_every: int = 0,
        refine: bool = True,
    ):
        if not 0.0 <= float(smoothing) < 1.0:
            raise RelightError(f"smoothing: expected a value in [0, 1), got {smoothing}")
        if int(redetect_every) < 0:
            raise RelightError(f"redetect_every: expected >= 0, got {redetect_every}")
        self.matter = matter if matter is not None else PersonMatter(models, device=device)
        self.smoothing = float(smoothing)
        self.redetect_every = int(redetect_every)
        self.refine = bool(refine)
        self._dis = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_ULTRAFAST)
        self.reset()

    def reset(self) -> None:
        """Forget the previous frames (call between videos)."""
        self._region: Region | None = None
        self._prev_prob: np.ndarray | None = None
        self._prev_gray: np.ndarray | None = None
        self._shape: tuple[int, int] | None = None
        self.index = 0

    def __call__(self, image: np.ndarray, name: str = "frame") -> np.ndarray:
        rgb = as_rgb(image, name)
        h, w = rgb.shape[:2]
        if self._shape is not None and self._shape != (h, w):
            raise RelightError(f"{name}: frame is {h}x{w}, the previous frames were {self._shape[0]}x{self._shape[1]}")
        self._shape = (h, w)
        index, self.index = self.index, self.index + 1
        region = self._region
        if region is None or (self.redetect_every and index % self.redetect_every == 0):
            found = self.matter.find_people(rgb)
            region = Region.around(*found[0][1]) if found else None
        person = self.matter.segment(rgb, region) if region is not None else None
        box = person_box(person, (h, w)) if person is not None else None
        if person is None or box is None or person.presence < _PRESENCE_MIN:
            log.debug("%s: no person found; searching again on the next frame", name)
            self._region, self._prev_prob, self._prev_gray = None, None, None
            return np.zeros((h, w), np.float32)
        new = Region.around(*box)
        # hysteresis: the pose graph's answer shifts with its crop, so the region stays put while the
        # person stays well inside it (a crop that moves every frame makes the outline shimmer)
        if self._region is None or new.iou(self._region) < _REGION_KEEP_IOU or not _inside(box, self._region):
            self._region = new

        rect = (0, 0, w, h)
        grid = _working_grid(rect)
        prob = _sigmoid(logits_on_grid(person, grid)).astype(np.float32)
        gray_full = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
        gray_small = gray_full if grid[:2] == (w, h) else cv2.resize(gray_full, grid[:2], interpolation=cv2.INTER_AREA)
        if self.smoothing > 0 and self._prev_prob is not None:
            maps = _flow_to(self._dis, gray_small, self._prev_gray)
            prev_prob = _remap(self._prev_prob, maps)
            agree = np.exp(-np.abs(gray_small - _remap(self._prev_gray, maps)) / np.float32(0.05))
            wgt = np.float32(self.smoothing) * agree
            prob = prob + wgt * (prev_prob - prob)
        self._prev_prob, self._prev_gray = prob, gray_small
        if not self.refine:
            return cv2.resize(prob, (w, h), interpolation=cv2.INTER_LINEAR) if grid[:2] != (w, h) else prob
        k_canvas = SIZE / person.region.side
        radius = max(2, int(round(_GF_RADIUS * grid[2] / k_canvas)))
        return guided_refine(prob, gray_small, gray_full, radius)


def outline_flicker(alphas: list[np.ndarray], frames: list[np.ndarray] | None = None, band: int = 4) -> float:
    """Outline flicker of a matte sequence: mean |alpha_t - alpha_{t-1}| over a band of ``band`` pixels on
    each side of frame t's outline (alpha = 0.5), averaged over frames 1..N-1.

    With ``frames`` (the RGB frames), alpha_{t-1} is first warped onto frame t by DIS optical flow
    (medium preset, full resolution), so the person's own motion is not counted: what remains is the
    edge jumping about. Without frames the raw change is measured (motion included).
    """
    if len(alphas) < 2:
        raise RelightError(f"outline_flicker: expected at least 2 frames, got {len(alphas)}")
    if frames is not None and len(frames) != len(alphas):
        raise RelightError(f"outline_flicker: {len(frames)} frames for {len(alphas)} alphas")
    dis = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM) if frames is not None else None
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * band + 1, 2 * band + 1))
    total, count = 0.0, 0
    for t in range(1, len(alphas)):
        cur = np.asarray(alphas[t], np.float32)
        prev = np.asarray(alphas[t - 1], np.float32)
        if cur.shape != prev.shape:
            raise RelightError(f"outline_flicker: alpha {t} is {cur.shape}, alpha {t - 1} is {prev.shape}")
        if dis is not None:
            g1 = cv2.cvtColor(np.asarray(frames[t], np.float32), cv2.COLOR_RGB2GRAY)
            g0 = cv2.cvtColor(np.asarray(frames[t - 1], np.float32), cv2.COLOR_RGB2GRAY)
            prev = _remap(prev, _flow_to(dis, g1, g0))
        fg = (cur >= 0.5).astype(np.uint8)
        ring = cv2.dilate(fg, kernel) != cv2.erode(fg, kernel)
        if ring.any():
            total += float(np.abs(cur - prev)[ring].sum())
            count += int(ring.sum())
    return total / max(count, 1)
