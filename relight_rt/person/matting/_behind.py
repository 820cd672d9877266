"""Someone behind the person, out of focus, left out of the default matte (person="largest"): whole or not at all.

The selfie graph segments everyone in its region, and so does the pose graph framed on a close portrait: a blurred
woman standing behind a sharp one, a man's face behind a woman's hand, come into her matte with her. Such a person
shows a face of their own inside the matte that is smaller than the subject's (further back) and blurred where the
subject's is sharp (defocus is depth): :func:`behind_faces`. Their pixels are the matte's pixels their own region's
segmentation claims (the selfie graph on their face's body box) that read as blurred where the photo shows texture,
the texture-less ones going to the nearest textured pixel's side (:func:`blurred_side`), the part joined to their
face, its small holes filled (:func:`behind_part`); they leave every person's segmentation (:func:`without_behind`).
"""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np

from ...engine.session import Model
from ...image.regions import Region, grid_of_region
from ..face_detector import Face
from ._detect import roi_prob
from ._models import SIZE
from ._segmentation import LOGIT_CLIP, Person, as_logits, contains

BEHIND_SIZE = 0.7  # a face at most this x as wide as the subject's (the largest face in the matte) is further back ...
BEHIND_SHARP = 0.7  # ... and, where its fine detail (:func:`fine_detail`) is at most this x the subject's, behind them
TEXTURE = 0.01  # blurred_side: the photo shows texture where its mid-scale detail (mean |I - G3 I|) is this or more
_FINE, _MID = 1.0, 3.0  # Gaussian sigmas (photo px) of the fine and mid-scale detail
_WINDOW = 8  # blurred_side: detail averaged over windows this many times smaller than the face behind is wide
_FILL = 4  # behind_part: holes of the part up to this many times smaller than the face behind are filled


def _gray(rgb: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(np.ascontiguousarray(rgb, np.float32), cv2.COLOR_RGB2GRAY)


def _details(gray: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """|I - G(_FINE) I| and |I - G(_MID) I| of a grey image: the detail finer than about 1 and 3 pixels."""
    fine = np.abs(gray - cv2.GaussianBlur(gray, (0, 0), _FINE))
    mid = np.abs(gray - cv2.GaussianBlur(gray, (0, 0), _MID))
    return fine, mid


def fine_detail(gray: np.ndarray, box) -> float:
    """How sharp the photo is in ``box`` (image px; a face's): the mean fine detail over the mean mid-scale detail
    there (:func:`_details`), computed on the box and a margin of 3 * _MID pixels. Blurred, a face loses its finest
    detail first: 0.17-0.20 on the two blurred faces behind a subject of benchmarks/people_masks_eval.py's photos, where
    sharp faces measure 0.30-0.70 (that photo's subject 0.36-0.37). A ratio, so a face's contrast and lighting cancel."""
    h, w = gray.shape
    m = int(np.ceil(3 * _MID))
    x0, y0 = max(int(np.floor(box[0])) - m, 0), max(int(np.floor(box[1])) - m, 0)
    x1, y1 = min(int(np.ceil(box[2])) + m, w), min(int(np.ceil(box[3])) + m, h)
    if x1 - x0 <= 2 * m or y1 - y0 <= 2 * m:
        return float("nan")
    fine, mid = _details(gray[y0:y1, x0:x1])
    fine, mid = fine[m:-m, m:-m], mid[m:-m, m:-m]
    return float(fine.mean() / max(float(mid.mean()), 1e-6))


def behind_faces(
    gray: np.ndarray, people: list[Person], faces: list[Face]
) -> tuple[Face, list[tuple[Face, float]], float] | None:  # fmt: skip
    """The subject's face and the faces behind them: (subject, [(face, its fine detail)], the subject's fine detail),
    or None where no face is behind. Of ``faces`` whose middle ``people`` cover (:func:`contains`), the largest is the
    subject's; another is behind them when it is at most BEHIND_SIZE x as wide and its fine detail (:func:`fine_detail`)
    at most BEHIND_SHARP x the subject's. Measured on benchmarks/people_masks_eval.py's photos (the faces the default
    matte holds beside the subject's, 35 on 30 photos): the two behind, which the service's masks leave out, 0.58 / 0.61
    x as wide and 0.48 / 0.57 x as sharp; the 33 standing with the subject (couples, a child on a lap, groups), which the
    masks hold, 0.71-1.00 x as wide and 0.82-1.26 x as sharp, none under both thresholds."""
    shape = gray.shape
    held = [f for f in faces if any(contains(p, f, shape) for p in people)]
    if len(held) < 2:
        return None
    subject = max(held, key=lambda f: f.box[2] - f.box[0])
    width = subject.box[2] - subject.box[0]
    small = [f for f in held if f is not subject and f.box[2] - f.box[0] <= BEHIND_SIZE * width]
    if not small:
        return None
    sharp = fine_detail(gray, subject.box)
    behind = [(f, d) for f in small for d in [fine_detail(gray, f.box)] if d <= BEHIND_SHARP * sharp]
    return (subject, behind, sharp) if behind and np.isfinite(sharp) else None


def blurred_side(gray: np.ndarray, matte: np.ndarray, level: float, window: int) -> np.ndarray:
    """Where ``matte`` (bool, the photo's size) reads as blurred: each pixel whose surroundings (a ``window`` px box)
    show texture (mean mid-scale detail >= TEXTURE) is sharp when their fine detail over mid-scale detail is at least
    ``level``, else blurred; a texture-less pixel (a plain shirt, a smooth cheek) takes the side of the nearest
    textured pixel of the matte. (H, W) bool, False off the matte."""
    fine, mid = _details(gray)
    fine = cv2.blur(fine, (window, window))
    mid = cv2.blur(mid, (window, window))
    textured = matte & (mid >= TEXTURE)
    if not textured.any():
        return np.zeros(matte.shape, bool)
    blur = fine < level * mid
    # the nearest textured pixel's side: distance labels on the pixels that are not textured
    _, labels = cv2.distanceTransformWithLabels((~textured).astype(np.uint8), cv2.DIST_L2, 5,
                                                labelType=cv2.DIST_LABEL_PIXEL)  # fmt: skip
    side = np.zeros(int(labels.max()) + 1, bool)
    side[labels[textured]] = blur[textured]
    return matte & side[labels]


def _middle(face: Face, shape: tuple[int, int]) -> tuple[int, int]:
    """(row, column) of the pixel at ``face``'s middle, inside the photo."""
    h, w = shape
    cx = min(max(int((face.box[0] + face.box[2]) / 2), 0), w - 1)
    cy = min(max(int((face.box[1] + face.box[3]) / 2), 0), h - 1)
    return cy, cx


def behind_part(
    matte: np.ndarray, blurred: np.ndarray, claim: np.ndarray, face: Face, staying: list[Face]
) -> np.ndarray | None:  # fmt: skip
    """The pixels of the person behind with ``face``: of ``matte`` (bool, the photo's size) those that read
    ``blurred`` and that their own region's segmentation ``claims``, the 8-connected part under the face's middle, its
    holes up to 1 / _FILL of the face's width closed (noise and a print on a blurred blouse read as sharp specks), and
    the blurred pixels of the matte up to 1 / _FILL of the face's width around it (their blurred outline, which their
    region's segmentation leaves out where the matte holds it: a ghost ring left), and last the pieces of the matte this
    cuts off that hold none of the ``staying`` faces and lie mostly inside their region's segmentation or read mostly
    blurred (a blurred flower on their blouse, which their region's segmentation leaves out: a blob left floating);
    None when the face's middle is not in such a part."""
    cand = (matte & blurred & claim).astype(np.uint8)
    n, labels = cv2.connectedComponents(cand, connectivity=8)
    cy, cx = _middle(face, matte.shape)
    if n <= 1 or labels[cy, cx] == 0:
        return None
    part = (labels == labels[cy, cx]).astype(np.uint8)
    k = max(int((face.box[2] - face.box[0]) / _FILL), 1) | 1
    window = np.ones((k, k), np.uint8)
    closed = cv2.morphologyEx(part, cv2.MORPH_CLOSE, window).astype(bool) & claim
    part = matte & (closed | (blurred & cv2.dilate(closed.astype(np.uint8), window).astype(bool)))
    n, labels = cv2.connectedComponents((matte & ~part).astype(np.uint8), connectivity=8)
    near = cv2.dilate(part.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    kept = {int(labels[_middle(f, matte.shape)]) for f in staying}
    for k in np.unique(labels[near & ~part]):
        piece = labels == k
        if k > 0 and int(k) not in kept and max(claim[piece].mean(), blurred[piece].mean()) >= 0.5:
            part |= piece
    return part


def on_canvas(mask: np.ndarray, region: Region) -> np.ndarray:
    """A (H, W) float mask of the photo on ``region``'s (SIZE, SIZE) canvas (its mean over each canvas pixel where the
    canvas is coarser than the photo; 0 past the photo)."""
    k, bx, by = grid_of_region(region)
    src = mask.astype(np.float32)
    if k < 1.0:
        n = max(int(round(1.0 / k)), 1)
        src = cv2.blur(src, (n, n))
    m = np.array([[k, 0.0, bx], [0.0, k, by]], np.float64)
    return cv2.warpAffine(src, m, (SIZE, SIZE), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                          borderValue=0.0)  # fmt: skip


def without_behind(roi: Model, rgb: np.ndarray, people: list[Person], faces: list[Face]) -> list[Person]:
    """``people`` (the default matte's, person="largest") less anyone behind the subject (module docstring): where a
    face is behind them (:func:`behind_faces`), its person's pixels (:func:`behind_part`: the matte's that the selfie
    graph on the face's body box claims and that read blurred, :func:`blurred_side`, at the level halfway between the
    two faces' fine detail) leave every segmentation, softly over a canvas pixel (each person's logit held under the
    logit of 1 - that part's share of the pixel). ``people`` itself where no face is behind (the usual case: only the
    face graph's boxes are looked at, no graph is run).

    Measured (benchmarks/people_masks_eval.py): p103 (a blurred woman behind a sharp blonde) 0.664 -> 0.91, p257 (a
    blurred man's face beside a woman's hand) 0.805 -> 0.94; no other photo has a face behind the subject."""
    h, w = rgb.shape[:2]
    gray = _gray(rgb)
    found = behind_faces(gray, people, faces)
    if found is None:
        return people
    _, behind, sharp = found
    gone = {id(f) for f, _ in behind}
    staying = [f for f in faces if id(f) not in gone]
    # the matte as the people's segmentations hold it (> 0.5), on the photo
    matte = np.zeros((h, w), bool)
    for p in people:
        k, bx, by = grid_of_region(p.region)
        m = np.array([[k, 0.0, bx], [0.0, k, by]], np.float64)
        logits = cv2.warpAffine(p.logits, m, (w, h), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                borderMode=cv2.BORDER_CONSTANT, borderValue=-LOGIT_CLIP)  # fmt: skip
        matte |= logits > 0
    drop = np.zeros((h, w), bool)
    for face, detail in behind:
        window = max(int((face.box[2] - face.box[0]) / _WINDOW), 1) | 1
        blurred = blurred_side(gray, matte, 0.5 * (sharp + detail), window)
        region = Region.around(*face.body_box((h, w)))
        k, bx, by = grid_of_region(region)
        m = np.array([[k, 0.0, bx], [0.0, k, by]], np.float64)
        claim = cv2.warpAffine(roi_prob(roi, rgb, region), m, (w, h), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                               borderMode=cv2.BORDER_CONSTANT, borderValue=0.0) > 0.5  # fmt: skip
        part = behind_part(matte, blurred, claim, face, staying)
        if part is not None:
            drop |= part
    if not drop.any():
        return people
    out, wholes = [], {}
    for p in people:
        keep = as_logits(1.0 - on_canvas(drop, p.region))
        logits = np.minimum(p.logits, keep).astype(np.float32)
        whole = p.whole
        if whole is not None:  # the parts of one segmentation keep one whole (relight_rt.person.matting._parts.rejoin)
            whole = wholes.setdefault(id(whole), np.minimum(whole, keep).astype(np.float32))
        out.append(replace(p, logits=logits, whole=whole))
    return out
