"""Someone behind the person, out of focus, left out of the default matte (person="largest"): whole or not at all.

The selfie graph segments everyone in its region, and so does the pose graph framed on a close portrait: a blurred
woman standing behind a sharp one, a man's face behind a woman's hand, come into her matte with her. Such a person
shows a face of their own inside the matte that is smaller than the subject's (further back) and blurred where the
subject's is sharp (defocus is depth), read where the subject's face is FACE_PX wide: :func:`behind_faces`. Their
pixels, read where their own face is FACE_PX wide, are the matte's pixels that their own region's segmentation claims
(the selfie graph on their face's body box) and that read blurred (:func:`blurred_side`), the part under their face
with its holes, its blurred rim and the pieces it cuts off, their body below the subject's sharp arm too, less any
blurred person standing with the subject (a staying face's) they touch (:func:`behind_part`); they leave every
person's segmentation (:func:`without_behind`), and the matte's outline along the subject is then the photo's to draw.
"""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple

import cv2
import numpy as np

from ...engine.session import Model
from ...image.regions import Region, crop_region
from ..face_detector import Face
from ._detect import roi_prob
from ._parts import rejoin
from ._segmentation import Person, as_logits, contains, logits_on_grid, prob_at, warp_to_grid

BEHIND_SIZE = 0.7  # a face at most this x as wide as the subject's (the largest face in the matte) is further back ...
BEHIND_SHARP = 0.7  # ... and, where its fine detail (:func:`fine_detail`) is at most this x the subject's, behind them
TEXTURE = 0.01  # blurred_side: the photo shows texture where its mid-scale detail (mean |I - G3 I|) is this or more
_FINE, _MID = 1.0, 3.0  # Gaussian sigmas (photo px) of the fine and mid-scale detail
_WINDOW = 12  # blurred_side: detail averaged over windows this many times smaller than the face behind is wide
OUTSIDE_REACH = 0.5  # a face behind has the matte's outside within this x its width of its box (not a print inside)
FACE_PX = 100  # the photo is read reduced until a face is at most this wide (never enlarged): behind_faces, _part_of
_FILL = 4  # behind_part: holes of the part up to this many times smaller than the face behind are filled


def grey_of(rgb: np.ndarray) -> np.ndarray:
    """(H, W) float32 grey of an (H, W, 3) RGB photo (OpenCV's weights), the one the detail measures read."""
    return cv2.cvtColor(np.ascontiguousarray(rgb, np.float32), cv2.COLOR_RGB2GRAY)


def details(gray: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """|I - G(_FINE) I| and |I - G(_MID) I| of a grey image: the detail finer than about 1 and 3 pixels."""
    fine = np.abs(gray - cv2.GaussianBlur(gray, (0, 0), _FINE))
    mid = np.abs(gray - cv2.GaussianBlur(gray, (0, 0), _MID))
    return fine, mid


def fine_detail(gray: np.ndarray, box) -> float:
    """How sharp the photo is in ``box`` (image px; a face's): the mean fine detail over the mean mid-scale detail
    there (:func:`details`, with a margin of 3 * _MID pixels around the box). Blurred, a face loses its finest detail
    first: 0.17 and 0.20 on the two blurred faces behind a subject among benchmarks/people_masks_eval.py's photos,
    their subjects' 0.36-0.37; the faces the default matte holds there measure 0.17-0.70 (median 0.39): a photo's own
    sharpness varies, so a face is compared with the subject's of the same photo. A ratio: contrast and light cancel."""
    h, w = gray.shape
    m = int(np.ceil(3 * _MID))
    x0, y0 = max(int(np.floor(box[0])) - m, 0), max(int(np.floor(box[1])) - m, 0)
    x1, y1 = min(int(np.ceil(box[2])) + m, w), min(int(np.ceil(box[3])) + m, h)
    if x1 - x0 <= 2 * m or y1 - y0 <= 2 * m:
        return float("nan")
    fine, mid = details(gray[y0:y1, x0:x1])
    fine, mid = fine[m:-m, m:-m], mid[m:-m, m:-m]
    return float(fine.mean() / max(float(mid.mean()), 1e-6))


class Behind(NamedTuple):
    """The faces behind the subject (:func:`behind_faces`): ``faces``, the subject's face, and the photo's grey
    (H, W) float32 that they were read on."""

    faces: list[Face]
    subject: Face
    gray: np.ndarray


def _scaled(face: Face, scale: float) -> Face:
    return Face(tuple(v * scale for v in face.box), face.score)


def _width(face: Face) -> float:
    return face.box[2] - face.box[0]


def reduced(gray: np.ndarray, face: Face) -> tuple[np.ndarray, float]:
    """``gray`` reduced (INTER_AREA) until ``face`` is at most FACE_PX wide, never enlarged, and the scale."""
    scale = min(1.0, FACE_PX / max(_width(face), 1e-6))
    if scale >= 1.0:
        return gray, 1.0
    h, w = gray.shape
    size = (max(int(round(w * scale)), 1), max(int(round(h * scale)), 1))
    return cv2.resize(gray, size, interpolation=cv2.INTER_AREA), scale


def _own(face: Face, faces: list[Face]) -> bool:
    """Whether ``face``'s middle lies inside a larger one of ``faces``' box (a second box on that face)."""
    cx, cy = (face.box[0] + face.box[2]) / 2, (face.box[1] + face.box[3]) / 2
    return any(_width(g) > _width(face) and g.box[0] <= cx <= g.box[2] and g.box[1] <= cy <= g.box[3] for g in faces)


def reaches_outside(people: list[Person], face: Face, shape: tuple[int, int]) -> bool:
    """Whether the matte's outside (no one of ``people`` > 0.5) lies within OUTSIDE_REACH x ``face``'s width around
    its box, inside the photo: someone behind shows past the subject's outline (a face printed on a shirt, or a badge,
    lies inside it). The whole band (the box grown by that margin, less the box) is read, on a grid of one pixel, or
    of width / FACE_PX pixels for a face wider than FACE_PX (the scale the faces are read at): a ring of 68 points at
    the margin missed a pocket of outside between it and the box, and a gap narrower than its spacing."""
    h, w = shape
    x0, y0, x1, y1 = face.box
    m = OUTSIDE_REACH * (x1 - x0)
    step = max(1.0, (x1 - x0) / FACE_PX)
    xs = np.arange(np.floor(max(x0 - m, 0.0)) + 0.5, min(x1 + m, w), step)
    ys = np.arange(np.floor(max(y0 - m, 0.0)) + 0.5, min(y1 + m, h), step)
    gx, gy = np.meshgrid(xs, ys)
    band = ~((gx >= x0) & (gx <= x1) & (gy >= y0) & (gy <= y1))
    if not band.any():
        return False
    held = np.any([prob_at(p, gx[band], gy[band]) > 0.5 for p in people], axis=0)
    return bool((~held).any())


def _finite(faces: list[Face]) -> list[Face]:
    """``faces`` less any whose box is not finite (a NaN box is nobody's face)."""
    return [f for f in faces if np.all(np.isfinite(f.box))]


def behind_faces(rgb: np.ndarray, people: list[Person], faces: list[Face]) -> Behind | None:
    """The faces behind the subject (:class:`Behind`), or None where none is. Of ``faces`` whose middle ``people``
    cover (:func:`contains`), less a second box on a larger face (:func:`_own`), the largest is the subject's; another
    is behind them when it is at most BEHIND_SIZE x as wide, shows past the matte's outline (:func:`reaches_outside`:
    not a print on a shirt) and its fine detail (:func:`fine_detail`) is at most BEHIND_SHARP x the subject's, both
    measured on the photo reduced until the subject's face is at most FACE_PX wide (a web photo enlarged 5x reads as
    blurred everywhere at full size; the blur of a face behind keeps its share of a face's width).

    Measured on benchmarks/people_masks_eval.py's photos (the faces the default matte holds beside the subject's: 34
    on 28 photos): the two behind, which the service's masks leave out, 0.58 / 0.61 x as wide and 0.50 / 0.59 x as
    sharp; the 32 standing with the subject (couples, a child on a lap, groups), which the masks hold, 0.71-1.00 x as
    wide and 0.83-1.27 x as sharp (each test alone would do on this set; both are asked). Chosen on half A (one
    behind, 15 with the subject: any size limit in 0.61-0.70 and sharpness limit in 0.59-0.90 give the same), half B
    checked (one behind, 17 with the subject: the same answer). FACE_PX among 64, 100, 150 and none (full size): the
    two behind 0.67 / 0.53, 0.59 / 0.50, 0.55 / 0.47, 0.55 / 0.47 x as sharp, the others at least 0.83 at each."""
    shape = rgb.shape[:2]
    held = [f for f in _finite(faces) if any(contains(p, f, shape) for p in people)]
    held = [f for f in held if not _own(f, held)]
    if len(held) < 2:
        return None
    subject = max(held, key=_width)
    small = [f for f in held if f is not subject and _width(f) <= BEHIND_SIZE * _width(subject)]
    small = [f for f in small if reaches_outside(people, f, shape)]
    if not small:
        return None
    full = grey_of(rgb)  # only here: most photos hold one face, or none smaller
    gray, scale = reduced(full, subject)
    sharp = fine_detail(gray, _scaled(subject, scale).box)
    behind = [f for f in small if fine_detail(gray, _scaled(f, scale).box) <= BEHIND_SHARP * sharp]
    return Behind(behind, subject, full) if behind and np.isfinite(sharp) else None


def disc(size: float) -> np.ndarray:
    """An elliptic structuring element about ``size`` px across (odd, at least 1)."""
    size = max(int(size), 1) | 1
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size))


def _box_span(shape: tuple[int, int], box) -> tuple[int, int, int, int]:
    """(y0, y1, x0, x1): the rows y0..y1 - 1 and columns x0..x1 - 1 of an (H, W) image inside ``box`` (x0, y0, x1,
    y1), 0 <= y0, y1 <= H (none where y1 <= y0): [floor(y0), ceil(y1)) clipped at 0 and H, so a box wholly above or
    left of the image holds no pixel (a negative end is not read from the far side)."""
    h, w = shape
    y0 = min(max(int(np.floor(box[1])), 0), h)
    x0 = min(max(int(np.floor(box[0])), 0), w)
    y1 = min(max(int(np.ceil(box[3])), y0), h)
    x1 = min(max(int(np.ceil(box[2])), x0), w)
    return y0, y1, x0, x1


def _box_mask(shape: tuple[int, int], box) -> np.ndarray:
    """(H, W) bool: the pixels inside ``box`` (x0, y0, x1, y1) (:func:`_box_span`)."""
    y0, y1, x0, x1 = _box_span(shape, box)
    out = np.zeros(shape, bool)
    out[y0:y1, x0:x1] = True
    return out


def _middle_half(box) -> tuple[float, float, float, float]:
    x0, y0, x1, y1 = box
    dx, dy = (x1 - x0) / 4, (y1 - y0) / 4
    return x0 + dx, y0 + dy, x1 - dx, y1 - dy


def blurred_side(
    gray: np.ndarray, matte: np.ndarray, level: float, window: int, sharp_box=None, blurred_box=None
) -> np.ndarray:  # fmt: skip
    """Where ``matte`` (bool, the photo's size) reads as blurred: each pixel whose surroundings (a ``window`` px box)
    show texture (mean mid-scale detail >= TEXTURE) is sharp when their fine detail over mid-scale detail is at least
    ``level``, else blurred; the middle halves of ``sharp_box`` and ``blurred_box`` (the two faces, measured as a
    whole), each less the other's box, are sharp and blurred; a texture-less pixel (a plain shirt) takes the side of
    the nearest of those. (H, W) bool, False off the matte. Without the boxes, p257's blurred face read at 0.74 x its
    size had the middle of its smooth cheeks and nose take the side of a few sharp-reading pixels, and nothing was
    found; with the whole boxes, the subject's took a corner of the hair of the man behind her (0.953).

    ``window``: the face behind's width / _WINDOW (a pixel beside the subject's sharp outline reads sharp while its
    window holds that outline: a band of the person behind along it stays with the subject). _WINDOW chosen among 8,
    12, 16 on p257 (half A: 0.958, 0.961, 0.959; enlarged 4.7x to 2.5 MP 0.956, 0.958, 0.914), p103 (half B) checked
    (0.952, 0.952, 0.947)."""
    fine, mid = details(gray)
    fine = cv2.blur(fine, (window, window))
    mid = cv2.blur(mid, (window, window))
    blur = fine < level * mid
    known = mid >= TEXTURE
    boxes = ((sharp_box, blurred_box, False), (blurred_box, sharp_box, True))
    for box, other, side in boxes:
        if box is not None:  # the middle half of the face's box, none of the other's
            inside = _box_mask(gray.shape, _middle_half(box))
            inside &= ~_box_mask(gray.shape, other) if other is not None else True
            known |= inside
            blur[inside] = side
    known &= matte
    if not known.any():
        return np.zeros(matte.shape, bool)
    # the nearest known pixel's side: distance labels on the pixels that are not known
    _, labels = cv2.distanceTransformWithLabels((~known).astype(np.uint8), cv2.DIST_L2, 5,
                                                labelType=cv2.DIST_LABEL_PIXEL)  # fmt: skip
    side = np.zeros(int(labels.max()) + 1, bool)
    side[labels[known]] = blur[known]
    return matte & side[labels]


def _middle(face: Face, shape: tuple[int, int]) -> tuple[int, int]:
    """(row, column) of the pixel at ``face``'s middle, inside the photo."""
    h, w = shape
    cx = min(max(int((face.box[0] + face.box[2]) / 2), 0), w - 1)
    cy = min(max(int((face.box[1] + face.box[3]) / 2), 0), h - 1)
    return cy, cx


def _under(labels: np.ndarray, faces: list[Face], less: tuple[float, ...] | None = None) -> set[int]:
    """The labels (> 0) of ``labels`` under the middle half of any of ``faces`` (a face's middle pixel may lie in a
    hole of the matte), none of box ``less``."""
    out = set()
    ly0, ly1, lx0, lx1 = _box_span(labels.shape, less) if less is not None else (0, 0, 0, 0)
    for f in faces:  # read within the middle half's span (no mask of the photo's size per face)
        y0, y1, x0, x1 = _box_span(labels.shape, _middle_half(f.box))
        inside = labels[y0:y1, x0:x1]
        if less is not None and inside.size:
            keep = np.ones(inside.shape, bool)
            keep[max(ly0 - y0, 0) : max(ly1 - y0, 0), max(lx0 - x0, 0) : max(lx1 - x0, 0)] = False
            inside = inside[keep]
        out.update(int(v) for v in np.unique(inside))
    out.discard(0)
    return out


def _staying_blur(matte: np.ndarray, blurred: np.ndarray, face: Face, staying: list[Face]) -> np.ndarray | None:
    """The blurred pixels of the matte that are a ``staying`` face's person's (a blurred friend standing with the
    subject, too large to be behind, touching the person behind: 0.92 of them left with that person): the pieces of
    the blurred matte under a staying face's middle half less ``face``'s box (there the subject's may read blurred, as
    :func:`blurred_side` reads it: p257). Where one is also under ``face``'s middle half, the blurred matte is opened
    by a disc of 1 / _FILL, 1 / 2, then 1 x ``face``'s width until the core under it is apart from those under the
    staying faces' (a neck between two people is narrower than they are), and each blurred pixel goes with the
    nearest core. None where no such size parts them, or a core vanishes first: the person behind cannot be told from
    a staying one, and stays whole."""
    blur = (matte & blurred).astype(np.uint8)
    _, labels = cv2.connectedComponents(blur, connectivity=8)
    theirs = _under(labels, staying, face.box)
    if not theirs & _under(labels, [face]):
        return np.isin(labels, list(theirs))
    width = face.box[2] - face.box[0]
    for size in (width / _FILL, width / 2, width):
        opened = cv2.morphologyEx(blur, cv2.MORPH_OPEN, disc(size))
        _, labels = cv2.connectedComponents(opened, connectivity=8)
        theirs, mine = _under(labels, staying, face.box), _under(labels, [face])
        if not theirs or not mine:
            return None
        if not mine & theirs:
            cores = np.isin(labels, list(mine | theirs))
            _, nearest = cv2.distanceTransformWithLabels((~cores).astype(np.uint8), cv2.DIST_L2, 5,
                                                         labelType=cv2.DIST_LABEL_CCOMP)  # fmt: skip
            return blur.astype(bool) & np.isin(nearest, np.unique(nearest[np.isin(labels, list(theirs))]))
    return None


def _grown(core: np.ndarray, matte: np.ndarray, blurred: np.ndarray, claim: np.ndarray, window) -> np.ndarray:
    """``core`` with its holes up to the ``window``'s size closed where claimed and the blurred matte within the
    window around it (their blurred outline, which their region's segmentation leaves out where the matte holds it)."""
    closed = cv2.morphologyEx(core.astype(np.uint8), cv2.MORPH_CLOSE, window).astype(bool) & claim
    return matte & (closed | (blurred & cv2.dilate(closed.astype(np.uint8), window).astype(bool)))


def behind_part(
    matte: np.ndarray, blurred: np.ndarray, claim: np.ndarray, face: Face, staying: list[Face]
) -> np.ndarray | None:  # fmt: skip
    """The pixels of the person behind with ``face``: of ``matte`` (bool, the photo's size) those that read
    ``blurred`` and that their own region's segmentation ``claims``, less the blurred people of the ``staying`` faces
    (:func:`_staying_blur`), the 8-connected part under the face's middle, its holes up to 1 / _FILL of the face's
    width closed (noise and a print on a blurred blouse read as sharp specks) and its blurred outline up to that far
    around it (a ghost ring left, :func:`_grown`). Then the pieces of the matte this cuts off: one under the middle
    half of none of the ``staying`` faces that reads mostly blurred leaves whole (a blurred flower on their blouse,
    which their region's segmentation leaves out: a blob left floating); from one that stays (the subject's sharp hand
    before them, though their region's segmentation holds it too), the blurred and claimed parts at least half the
    face's width square once opened by the window (not the subject's outline, which reads blurred against a plain
    backdrop) under no staying face's middle half leave, grown as the part (their body below the subject's sharp arm,
    joined by that arm to the subject: 0.99 of it was left). None when the face's middle is not in such a
    part, or the person behind cannot be told from a staying one's."""
    k = max(int((face.box[2] - face.box[0]) / _FILL), 1) | 1
    window = np.ones((k, k), np.uint8)
    theirs = _staying_blur(matte, blurred, face, staying)
    if theirs is None:
        return None
    mine = matte & ~theirs
    cand = mine & blurred & claim
    n, labels = cv2.connectedComponents(cand.astype(np.uint8), connectivity=8)
    cy, cx = _middle(face, matte.shape)
    if n <= 1 or labels[cy, cx] == 0:
        return None
    part = _grown(labels == labels[cy, cx], mine, blurred, claim, window)
    n, pieces = cv2.connectedComponents((matte & ~part).astype(np.uint8), connectivity=8)
    near = cv2.dilate(part.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    kept = _under(pieces, staying) | {int(v) for v in np.unique(pieces[theirs])}  # a staying person's piece
    large = ((face.box[2] - face.box[0]) / 2) ** 2
    out = part.copy()
    for label in np.unique(pieces[near & ~part]):
        piece = pieces == label
        if label == 0:
            continue
        if int(label) not in kept:
            if blurred[piece].mean() >= 0.5:
                out |= piece
            continue
        body = cv2.morphologyEx((piece & cand).astype(np.uint8), cv2.MORPH_OPEN, window)  # not a thin outline
        m, parts, stats, _ = cv2.connectedComponentsWithStats(body, connectivity=8)
        held = _under(parts, staying)
        for j in range(1, m):
            if stats[j, cv2.CC_STAT_AREA] >= large and j not in held:
                out |= _grown(parts == j, mine & piece, blurred, claim, window)
    return out


def on_canvas(mask: np.ndarray, region: Region) -> np.ndarray:
    """A (H, W) mask of the photo on ``region``'s canvas (:func:`crop_region`: 0 past the photo)."""
    return crop_region(np.ascontiguousarray(mask, np.float32), region)


def _part_of(
    roi: Model, rgb: np.ndarray, full: np.ndarray, people: list[Person], staying: list[Face], subject: Face, face: Face
) -> np.ndarray:  # fmt: skip
    """The person behind with ``face`` on the photo ((H, W) float32 in [0, 1]: :func:`behind_part` found on the photo
    reduced until ``face`` is at most FACE_PX wide, enlarged back; 0 where none is found). ``full``: the photo's grey.
    Read where that face is FACE_PX wide, not the subject: reduced to the subject's scale (p257: 0.74), the two faces'
    fine detail lies closer (0.18 and 0.31, at full size 0.20 and 0.37), and the map of what reads blurred lost a
    strip of the man's hair (0.964 -> 0.953). ``staying``: the faces not behind (:func:`behind_part`)."""
    h, w = full.shape
    gray, scale = reduced(full, face)
    gh, gw = gray.shape
    grid = (gw, gh, gw / w, gh / h, -0.5, -0.5)  # the reduced photo's pixels (cv2.resize's centres)
    seen, mine = _scaled(face, scale), _scaled(subject, scale)
    matte = np.zeros(gray.shape, bool)  # the matte as the people's segmentations hold it (> 0.5), at that scale
    for p in rejoin(people):  # a part split from one segmentation is read as that whole (its parts leave seams)
        matte |= logits_on_grid(p, grid) > 0
    level = 0.5 * (fine_detail(gray, mine.box) + fine_detail(gray, seen.box))
    window = max(int(_width(seen) / _WINDOW), 1) | 1
    blurred = blurred_side(gray, matte, level, window, mine.box, seen.box)
    region = Region.around(*face.body_box((h, w)))
    claim = warp_to_grid(roi_prob(roi, rgb, region), region, grid, 0.0) > 0.5
    part = behind_part(matte, blurred, claim, seen, [_scaled(f, scale) for f in staying])
    if part is None:
        return np.zeros((h, w), np.float32)
    if scale >= 1.0:
        return part.astype(np.float32)
    return cv2.resize(part.astype(np.float32), (w, h), interpolation=cv2.INTER_LINEAR)


def without_behind(roi: Model, rgb: np.ndarray, people: list[Person], faces: list[Face]) -> list[Person]:
    """``people`` (the default matte's, person="largest") less anyone behind the subject (module docstring): where a
    face is behind them (:func:`behind_faces`), its person's pixels (:func:`behind_part`: the matte's that the selfie
    graph on the face's body box claims and that read blurred, :func:`blurred_side`, at the level halfway between the
    two faces' fine detail) leave every segmentation, softly over a canvas pixel (each person's logit held under the
    logit of 1 - that part's share of the pixel). ``people`` itself where no face is behind (the usual case: only the
    face graph's boxes are looked at, no graph is run). A face box that is not finite is no one's.

    Measured (benchmarks/people_masks_eval.py --methods ours,selfie): p103 (a blurred woman behind a sharp blonde)
    0.664 -> 0.952, p257 (a blurred man's face beside a woman's hand) 0.805 -> 0.961, no other photo nor clip frame
    has a face behind the subject (all unchanged): half A 0.92087 -> 0.92236, half B 0.89581 -> 0.89858, the clip
    0.93254; photos under the selfie graph alone 48 -> 47, gross errors (< 0.8) over both sets 5.2 -> 4.9 %. Time
    (this 2-core CPU, shared): < 1 ms where no face is behind (p093: the face boxes only), 20-25 ms on p103 / p257,
    40-80 ms on them enlarged to 2.5 MP (one selfie-graph run, the photo's detail at the scale of the face behind)."""
    h, w = rgb.shape[:2]
    faces = _finite(faces)
    found = behind_faces(rgb, people, faces)
    if found is None:
        return people
    staying = [f for f in faces if all(f is not g for g in found.faces)]
    share = np.zeros((h, w), np.float32)
    for face in found.faces:
        share = np.maximum(share, _part_of(roi, rgb, found.gray, people, staying, found.subject, face))
    if not share.any():
        return people
    out, wholes = [], {}
    for p in people:
        leaving = on_canvas(share, p.region)
        keep = np.where(leaving > 0, as_logits(1.0 - leaving), np.float32(np.inf))  # untouched where nothing leaves
        logits = np.minimum(p.logits, keep).astype(np.float32)
        whole = p.whole
        if whole is not None:  # the parts of one segmentation keep one whole (relight_rt.person.matting._parts.rejoin)
            whole = wholes.setdefault(id(whole), np.minimum(whole, keep).astype(np.float32))
        out.append(replace(p, logits=logits, whole=whole))
    return out
