"""A graph's segmentation of one square region of a photo, and how it is read back over the photo.

A :class:`Person` is one graph's segmentation (logits on the 256² canvas) of one :class:`Region`; the square
regions themselves, their canvases (``crop_region``) and the map from image coordinates to canvas indices
(``grid_of_region``) live in relight_rt.image.regions, below matting, for the face meshes too. Here: a person's
box, probability at image points and faces it covers (:func:`person_box`, :func:`prob_at`, :func:`contains`), the
search tiles (:func:`tile_levels`), and a working grid (:func:`working_grid`, long side <= 512 px) that carries
canvases back over the image (:func:`warp_to_grid`, :func:`logits_on_grid`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from ...image.regions import Region, grid_of_region
from ..face_detector import Face
from ._models import SIZE

COARSE_MIN_AREA = 24  # canvas pixels: smaller blobs of the region finder are noise or far-away people
_TILE_LEVELS = (1, 2, 3, 4, 6)  # whole image, then n x n overlapping tiles while nobody is found ...
_WORK_MAX = 512  # long side of the working grid (guided-filter fit, temporal blend)
LOGIT_CLIP = 30.0

Grid = tuple[int, int, float, float, float, float]  # (gw, gh, kx, ky, bx, by): see working_grid



@dataclass(frozen=True)
class Person:
    """One matted person: the region the pose graph saw, its logits there, and its presence score."""

    region: Region
    logits: np.ndarray  # (256, 256) float32 person logits in the region's canvas
    presence: float
    source: str = "pose"  # which graph's segmentation: "pose" (bodies) or "roi" (head-and-shoulders); "own": the
    # selfie graph's, kept to the people's own colours (_completion.own_colours: part of them, not a person)
    whole: np.ndarray | None = field(default=None, repr=False, compare=False)  # split from these logits (see
    # relight_rt.person.matting._parts.split_by_faces): the matte is made from the whole, not from the parts
    of: Region | None = field(default=None, compare=False)  # source "own": the region of the person this part goes
    # on from (relight_rt.person.matting._selfie.carried_past), whose share of the matte it is; None: everyone's
    face: Face | None = field(default=None, compare=False)  # split from ``whole`` as this face's share, among the
    split: tuple[Face, ...] = field(default=(), compare=False)  # faces side by side it was split by (split_by_faces),
    # which relight_rt.person.matting._parts.along_edges cuts again along the photo's edges
    start: float | None = field(default=None, compare=False)  # the pose graph's presence on the region first given
    # (PersonMatter.segment's first pass, before re-centring); None: not re-centred by segment




def sigmoid(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, -LOGIT_CLIP, LOGIT_CLIP)
    return 1.0 / (1.0 + np.exp(-x))


def as_logits(prob: np.ndarray) -> np.ndarray:
    """A probability map as float32 logits (clipped at 1e-7 from 0 and 1)."""
    p = prob.astype(np.float64)
    return (np.log(np.clip(p, 1e-7, 1.0)) - np.log(np.clip(1.0 - p, 1e-7, 1.0))).astype(np.float32)


def own_person(region: Region, part: np.ndarray, mine: np.ndarray, prob: np.ndarray, presence: float) -> Person:
    """A part found beside the people whose pixels ``mine`` are on ``region``'s canvas, as a Person of source "own"
    (part of the matte, no one's share of it): ``prob``'s logits over the part and a pixel round it, off the people's
    own; nothing elsewhere."""
    rim = cv2.dilate(part.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool) & ~mine
    return Person(region, np.where(rim, as_logits(prob), -LOGIT_CLIP).astype(np.float32), presence, "own")


def canvas_points(region: Region) -> tuple[np.ndarray, np.ndarray]:
    """Image coordinates (xs, ys), each (256, 256) float64, of the centres of ``region``'s canvas pixels."""
    k, bx, by = grid_of_region(region)
    c = np.arange(SIZE, dtype=np.float64)
    return np.meshgrid((c - bx) / k, (c - by) / k)


def components(prob: np.ndarray, min_area: int) -> list[tuple[int, tuple[int, int, int, int]]]:
    """(area, (x0, y0, x1, y1)) of the 8-connected regions of prob > 0.5, largest first."""
    n, _, stats, _ = cv2.connectedComponentsWithStats((prob > 0.5).astype(np.uint8), connectivity=8)
    out = []
    for i in range(1, n):
        x, y, bw, bh, area = (int(v) for v in stats[i])
        if area >= min_area:
            out.append((area, (x, y, x + bw, y + bh)))
    out.sort(key=lambda t: -t[0])
    return out


def person_box(person: Person, shape: tuple[int, int]) -> tuple[float, float, float, float] | None:
    """Image-space box (x0, y0, x1, y1) of the person's segmentation (logits > 0), clipped to the image;
    None when it is empty."""
    comps = components(person.logits > 0, COARSE_MIN_AREA)
    if not comps:
        return None
    k, bx, by = grid_of_region(person.region)
    x0 = min(b[0] for _, b in comps)
    y0 = min(b[1] for _, b in comps)
    x1 = max(b[2] for _, b in comps)
    y1 = max(b[3] for _, b in comps)
    h, w = shape
    box = ((x0 - bx - 0.5) / k, (y0 - by - 0.5) / k, (x1 - bx - 0.5) / k, (y1 - by - 0.5) / k)
    return max(box[0], 0.0), max(box[1], 0.0), min(box[2], float(w)), min(box[3], float(h))


def tile_levels(h: int, w: int, min_tile: float, max_level: int = _TILE_LEVELS[-1]) -> list[list[Region]]:
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


def canvas_index(region: Region, xs: np.ndarray, ys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(i, j) int arrays: the row and column of ``region``'s canvas pixel nearest each image point (xs, ys); a point
    outside the region gets an index outside [0, SIZE)."""
    k, bx, by = grid_of_region(region)
    return np.floor(k * ys + by + 0.5).astype(int), np.floor(k * xs + bx + 0.5).astype(int)


def prob_at(person: Person, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """The person's probability (sigmoid of its logits) at image points (xs, ys); 0 outside its region."""
    i, j = canvas_index(person.region, xs, ys)
    inside = (i >= 0) & (i < SIZE) & (j >= 0) & (j < SIZE)
    out = np.zeros(xs.shape, np.float32)
    out[inside] = sigmoid(person.logits[i[inside], j[inside]])
    return out


def face_middle(face: Face) -> tuple[np.ndarray, np.ndarray]:
    """(xs, ys), three image points across the middle of ``face``'s box (its centre and 15 % of its width to each
    side), which :func:`contains` reads."""
    x0, y0, x1, y1 = face.box
    return np.array([(x0 + x1) / 2, 0.35 * x0 + 0.65 * x1, 0.65 * x0 + 0.35 * x1]), np.array([(y0 + y1) / 2] * 3)


def contains(person: Person, face: Face, shape: tuple[int, int]) -> bool:
    """Whether the person's segmentation covers the middle of the face (two of :func:`face_middle`'s points)."""
    return bool((prob_at(person, *face_middle(face)) > 0.5).sum() >= 2)


def working_grid(rect: tuple[int, int, int, int]) -> Grid:
    """(gw, gh, kx, ky, bx, by): a grid over the image rectangle with long side <= _WORK_MAX."""
    rx0, ry0, rx1, ry1 = rect
    return grid_over(rect, min(1.0, _WORK_MAX / max(rx1 - rx0, ry1 - ry0)))


def grid_over(rect: tuple[int, int, int, int], s: float) -> Grid:
    """(gw, gh, kx, ky, bx, by): a grid over the image rectangle ``rect`` at ``s`` grid px an image px (rounded to
    whole grid pixels, at least one), pixel centres matched as cv2.resize's."""
    rx0, ry0, rx1, ry1 = rect
    rw, rh = rx1 - rx0, ry1 - ry0
    gw, gh = max(int(round(rw * s)), 1), max(int(round(rh * s)), 1)
    kx, ky = gw / rw, gh / rh
    return gw, gh, kx, ky, -kx * rx0 - 0.5, -ky * ry0 - 0.5


def logits_on_grid(person: Person, grid: Grid) -> np.ndarray:
    """The person's canvas logits resampled onto a working grid (very negative outside the region)."""
    return warp_to_grid(np.clip(person.logits, -LOGIT_CLIP, LOGIT_CLIP), person.region, grid, -LOGIT_CLIP)


def warp_to_grid(canvas: np.ndarray, region: Region, grid: Grid, outside: float) -> np.ndarray:
    """A (256, 256) map over ``region`` resampled onto a working grid (``outside`` beyond the region)."""
    gw, gh, kx, ky, bx, by = grid
    k, cbx, cby = grid_of_region(region)
    m = np.array([[k / kx, 0.0, cbx - k / kx * bx], [0.0, k / ky, cby - k / ky * by]])
    return cv2.warpAffine(
        canvas, m, (gw, gh), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_CONSTANT,
        borderValue=outside,
    )  # fmt: skip
