"""Where the people in a photo are, before any is segmented: blobs of the selfie graph's person probability
over the whole image and over overlapping tiles, and faces from the face detector (relight_rt.person.face_detector)."""

from __future__ import annotations

from typing import NamedTuple

import cv2
import numpy as np

from ...engine.session import Model
from ...image.regions import Region, crop_region, grid_of_region, pyramid_of
from ..face_detector import FACE_SIZE, Face, decode, weighted_nms
from ._models import SIZE
from ._segmentation import COARSE_MIN_AREA, Person, canvas_points, components, person_box, prob_at, tile_levels

MIN_TILE = SIZE  # tiles are searched as long as they stay at least 256 px (a smaller one would only be upsampled)
CLOSE_ZOOM = 2.0  # find_close_faces: the window is this x the image's longer side
CLOSE_FACE = 0.5  # ... and keeps faces at least this x the image's shorter side wide
_KEEP_ANSWERS = 8  # selfie-graph answers kept while the photo's reductions are shared (roi_prob)
_KEEP_FACES = 16  # face-graph answers kept so (_face_boxes): the whole photo and every tile of every=True
_FACE_TILE_MIN = 2 * FACE_SIZE  # face search in tiles (every=True) while the tiles stay this large
# the whole photo (and find_close_faces' window) is asked as it is and mirrored, the mirror's boxes mirrored back and
# both merged (_face_boxes): MediaPipe's face graph scores a face and its mirror image apart (a blurred face behind a
# portrait 0.70 as it comes, under the 0.6 threshold mirrored), and the matte's rules turn on which faces it finds.
# The tiles of every=True are asked as they come: both ways they found more faces that are none (faceflip44)
FACE_BOTH_WAYS = True
FAINT_PROB = 0.25  # person="all": the selfie graph's probability that marks where such a person may stand
_PAIR_WIDTH = 0.45  # person="all": a blob nobody is found in, this x as wide as tall or wider, may be two

Box = tuple[float, float, float, float]


def roi_prob(roi: Model, rgb: np.ndarray, region: Region) -> np.ndarray:
    """The selfie graph's (256, 256) person probability over ``region`` (read-only). Inside
    :func:`reductions_shared` a region's answer is kept for the block (the portrait check and the pose-graph
    person's backing, _completion.backed, ask for the same region): :meth:`Pyramid.answer`."""

    def ask() -> np.ndarray:
        prob = roi.run({"image": crop_region(rgb, region).transpose(2, 0, 1)[None]})["segmentation"][0, 0]
        prob.flags.writeable = False
        return prob

    # the last few (person="all" runs it on ~70 tiles once each)
    return pyramid_of(rgb).answer(roi, "selfie", region, ask, _KEEP_ANSWERS)


class Around(NamedTuple):
    """What the searches for a part beside the people start from (:func:`around_people`): a square ``region`` around
    their boxes (``Region.around``) and on its (S, S) canvas the selfie graph's answer on the whole photo (``seen``,
    float32; 0 where the canvas leaves the photo), the pixels inside the photo (``inside``, bool) and the people's own
    (``mine``, bool: > 0.5)."""

    region: Region
    seen: np.ndarray
    inside: np.ndarray
    mine: np.ndarray


def around_people(roi: Model, rgb: np.ndarray, people: list[Person]) -> Around | None:
    """Where the searches for a part beside ``people`` start (``_completion.own_colours``, ``_turned``): the
    region around their boxes, and on its canvas the selfie graph's answer on the whole photo, where the canvas lies
    inside the photo, and the people's own pixels (:class:`Around`); None when no one has a box."""
    h, w = rgb.shape[:2]
    boxes = [b for b in (person_box(p, (h, w)) for p in people) if b is not None]
    if not boxes:
        return None
    region = Region.around(min(b[0] for b in boxes), min(b[1] for b in boxes), max(b[2] for b in boxes),
                           max(b[3] for b in boxes))  # fmt: skip
    whole = Region(w / 2, h / 2, float(max(h, w)))
    k, bx, by = grid_of_region(region)
    kw, bxw, byw = grid_of_region(whole)
    s = kw / k  # region canvas index -> whole canvas index
    m = np.array([[s, 0.0, bxw - s * bx], [0.0, s, byw - s * by]])
    seen = cv2.warpAffine(roi_prob(roi, rgb, whole), m, (SIZE, SIZE), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)  # fmt: skip
    xs, ys = canvas_points(region)
    inside = (xs >= 0) & (xs < w) & (ys >= 0) & (ys < h)
    mine = np.any([prob_at(p, xs, ys) > 0.5 for p in people], axis=0)
    return Around(region, seen, inside, mine)


def find_people(roi: Model, rgb: np.ndarray, max_level: int | None = None) -> list[tuple[float, Box]]:
    """Where people are, from the image alone: [(area in image pixels, (x0, y0, x1, y1))], largest
    first; empty when nobody is found. Whole image first, then 2x2, 3x3, 4x4 and 6x6 overlapping tiles
    (each 1.5x its share of the image, at least 256 px: small images stop early) while nobody is found;
    ``max_level``: no tiles finer than n x n (1: the whole image alone, one selfie-graph run)."""
    h, w = rgb.shape[:2]
    levels = tile_levels(h, w, MIN_TILE) if max_level is None else tile_levels(h, w, MIN_TILE, max_level)
    for windows in levels:
        found = []
        for win in windows:
            prob = roi_prob(roi, rgb, win)
            k, bx, by = grid_of_region(win)
            for area, (x0, y0, x1, y1) in components(prob, COARSE_MIN_AREA):
                box = ((x0 - bx - 0.5) / k, (y0 - by - 0.5) / k, (x1 - bx - 0.5) / k, (y1 - by - 0.5) / k)
                box = (max(box[0], 0.0), max(box[1], 0.0), min(box[2], float(w)), min(box[3], float(h)))
                if box[2] > box[0] and box[3] > box[1]:
                    found.append((area / k / k, box))
        if found:
            return merge_boxes(found)
    return []


def find_faces(face: Model | None, rgb: np.ndarray, *, every: bool = False) -> list[Face]:
    """Faces (none without a face graph), best first: on the whole image, and with ``every`` also in 2x2 and
    3x3 overlapping tiles (while they stay >= 384 px) for smaller faces."""
    if face is None:
        return []
    h, w = rgb.shape[:2]
    levels = tile_levels(h, w, _FACE_TILE_MIN, max_level=3)
    # the whole photo both ways (FACE_BOTH_WAYS), the tiles as they come
    asked = [(win, FACE_BOTH_WAYS and level == 0) for level, windows in enumerate(levels if every else levels[:1])
             for win in windows]
    return _faces_in(face, rgb, asked)


def find_close_faces(face: Model | None, rgb: np.ndarray) -> list[Face]:
    """Faces that fill the frame, best first: the face graph on a window CLOSE_ZOOM x the image's longer side,
    centred on it (zero beyond the image), so that a face cut by the frame's edges (a crop through the forehead
    or the eyes) is seen at the size the graph was made for; only faces at least CLOSE_FACE x the image's shorter
    side wide are kept (a frame that is mostly one face). On the whole image the graph finds no such face
    (a crop of lin-manuel-miranda.png from the eyebrows to the chin: none; here 0.67)."""
    if face is None:
        return []
    h, w = rgb.shape[:2]
    side = CLOSE_ZOOM * max(h, w)
    win = Region.around(w / 2 - side / 2, h / 2 - side / 2, w / 2 + side / 2, h / 2 + side / 2)
    return _faces_in(face, rgb, [(win, FACE_BOTH_WAYS)], min_width=CLOSE_FACE * min(h, w))


def _faces_in(face: Model, rgb: np.ndarray, windows: list[tuple[Region, bool]], min_width: float = 0.0) -> list[Face]:
    """The face graph on each window (:func:`_face_boxes`; ``windows``: (window, asked both ways)), its boxes merged
    (weighted NMS) and clipped to the image; boxes narrower than ``min_width`` (or empty) are left out."""
    h, w = rgb.shape[:2]
    found = [answer for win, both in windows for answer in _face_boxes(face, rgb, win, both)]
    faces = []
    for box, score in weighted_nms(found):
        b = (max(box[0], 0.0), max(box[1], 0.0), min(box[2], float(w)), min(box[3], float(h)))
        if b[2] > b[0] and b[2] - b[0] >= min_width and b[3] > b[1]:
            faces.append(Face(b, score))
    return faces


def _face_boxes(face: Model, rgb: np.ndarray, win: Region, both_ways: bool) -> tuple[tuple[np.ndarray, float], ...]:
    """The face graph's boxes on one window, before merging: ((x0, y0, x1, y1) in image pixels, read-only; score),
    with ``both_ways`` those of the window's mirror image too, mirrored back (:func:`_faces_in` merges a face seen
    both ways into one box, its score the better).
    Inside :func:`reductions_shared` a window's answer is kept (:meth:`Pyramid.answer`), as the selfie graph's is
    (:func:`roi_prob`): the portrait check of each region segmented (:meth:`PersonMatter.segment`), the faces for
    the people beside the largest (:meth:`PersonMatter.people`) and the tiles' search (``every``) look at the whole
    photo again, and relight_rt.apps.scene_people segments each blob of a background in one such block."""

    def ask() -> tuple[tuple[np.ndarray, float], ...]:
        canvas = crop_region(rgb, win, FACE_SIZE)
        views = (canvas, canvas[:, ::-1]) if both_ways else (canvas,)
        x0, y0, _, _ = win.box()
        found = []
        for mirrored, view in enumerate(views):
            out = face.run({"image": np.ascontiguousarray(view.transpose(2, 0, 1)[None])})
            for box, score in decode(out["boxes"][0], out["scores"][0]):
                if mirrored:  # (canvas fractions: x -> 1 - x)
                    box = np.array([1 - box[2], box[1], 1 - box[0], box[3]])
                box = np.array([x0, y0, x0, y0]) + box * win.side
                box.flags.writeable = False
                found.append((box, score))
        return tuple(found)

    return pyramid_of(rgb).answer(face, "face both ways" if both_ways else "face", win, ask, _KEEP_FACES)


def merge_boxes(found: list[tuple[float, Box]]) -> list[tuple[float, Box]]:
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


def faint_places(prob: np.ndarray, grid, min_height: float) -> list[tuple[float, float, float, float]]:
    """Boxes (image pixels) where the selfie graph's probability on the working grid rises above FAINT_PROB
    but nowhere reaches 0.5 (a person it hardly sees: small, in shade, in colours like the background; the
    woman in purple by the kiosk of the street photo peaks at 0.42 there, and the pose graph framed on her
    is sure: 0.99), each widened to a square at least ``min_height`` tall around its centre (such a blob is
    often one part of a person, too small to frame them)."""
    _, _, kx, ky, bx, by = grid
    n, labels, stats, _ = cv2.connectedComponentsWithStats((prob > FAINT_PROB).astype(np.uint8), connectivity=8)
    if n <= 1:
        return []
    peak = np.zeros(n, np.float32)
    np.maximum.at(peak, labels.ravel(), prob.ravel())
    out = []
    for i in np.argsort(-stats[:, cv2.CC_STAT_AREA]):
        if i == 0 or peak[i] >= 0.5:
            continue
        x, y, bw, bh, _ = (int(v) for v in stats[i])
        x0, y0, x1, y1 = (x - bx) / kx, (y - by) / ky, (x + bw - bx) / kx, (y + bh - by) / ky
        half = max(x1 - x0, y1 - y0, min_height) / 2
        cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
        out.append((cx - half, cy - half, cx + half, cy + half))
    return out


def grid_pixels(box, grid) -> np.ndarray:
    """Flat indices of the working-grid pixels inside an image box."""
    gw, gh, kx, ky, bx, by = grid
    x0, x1 = max(int(kx * box[0] + bx + 0.5), 0), min(int(np.ceil(kx * box[2] + bx + 0.5)), gw)
    y0, y1 = max(int(ky * box[1] + by + 0.5), 0), min(int(np.ceil(ky * box[3] + by + 0.5)), gh)
    if x1 <= x0 or y1 <= y0:
        return np.zeros(0, np.int64)
    ys, xs = np.mgrid[y0:y1, x0:x1]
    return (ys * gw + xs).ravel()


def strips(pix: np.ndarray, gw: int, grid, shape: tuple[int, int]) -> list:
    """A wide blob (flat pixel indices on the working grid) as overlapping upright strips, each about half as
    wide as the blob is tall: candidates for people standing side by side. A blob narrower than that but at
    least _PAIR_WIDTH x as wide as tall is two strips, each two thirds of its width: two people walking side by
    side, one half behind the other (the reference street photo shifted by a column: the pose graph framed on
    such a blob, 76 x 153 px, saw nobody, and both men were missed), when it is clear of the image border
    (a blob the frame cuts was the skater's blurred crowd, where a strip gave a person of blur, presence 0.76)."""
    _, _, kx, ky, bx, by = grid
    ys, xs = np.divmod(pix, gw)
    x0, x1, y0, y1 = xs.min(), xs.max() + 1, ys.min(), ys.max() + 1
    width = 0.5 * (y1 - y0)
    if x1 - x0 < 1.4 * width:
        gh = grid[1]
        if x1 - x0 < _PAIR_WIDTH * (y1 - y0) or min(x0, y0) <= 0 or x1 >= gw or y1 >= gh:
            return []
        width = (x1 - x0) / 1.5  # two people walking side by side, one half behind the other: a strip each
    out = []
    for left in np.arange(x0, x1 - width + 1, width / 2):
        keep = pix[(xs >= left) & (xs < left + width)]
        if keep.size:
            sy = keep // gw
            box = ((left - bx) / kx, (sy.min() - by) / ky, (left + width - bx) / kx, (sy.max() + 1 - by) / ky)
            out.append((keep.size / kx / ky, box, None, keep))
    return out
