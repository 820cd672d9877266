"""Square regions of a photo and the canvases a graph sees there: a :class:`Region` is a square (it may reach
past the image border); :func:`crop_region` resamples it to a canvas by one exact affine warp (from a
:class:`Pyramid` of block-mean reductions, shared by the crops of one photo inside :func:`reductions_shared`), and
:func:`grid_of_region` maps image coordinates to canvas indices. Person matting (relight_rt.person.matting) and the face
meshes (relight_rt.person.face_mesh) crop with it.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TypeVar

import cv2
import numpy as np

from ..engine.errors import RelightError

SIZE = 256  # the person-matting graphs' input side: the default canvas
ROI_SCALE = 1.25  # square region side = this x the person's longest box side (MediaPipe's choice)
_KEEP_CROPS = 4  # crops a Pyramid keeps (the 66 tiles of person="all" would hold 50 MB)


Crop = tuple[tuple[int, int, int, int], np.ndarray]  # ((y0, y1, x0, x1), an array's values inside that box)
T = TypeVar("T")


@dataclass(frozen=True)
class Region:
    """A square region of the image: centre (cx, cy) and side, in continuous pixel coordinates
    (pixel (i, j) covers [j, j+1) x [i, i+1)); it may reach past the image border."""

    cx: float
    cy: float
    side: float

    def __post_init__(self):
        # one place for every crop (a side of 0 divided by zero in grid_of_region, NaN failed converting to int)
        if not (math.isfinite(self.cx) and math.isfinite(self.cy) and math.isfinite(self.side) and self.side > 0):
            raise RelightError(f"region: expected a finite centre and a finite side > 0, got {self}")

    @staticmethod
    def around(x0: float, y0: float, x1: float, y1: float, scale: float = ROI_SCALE) -> Region:
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


def grid_of_region(region: Region, size: int = SIZE) -> tuple[float, float, float]:
    """(k, bx, by): canvas index = k * X + b for continuous image coordinate X (pixel centres at i + 0.5)."""
    k = size / region.side
    x0, y0, _, _ = region.box()
    return k, -k * x0 - 0.5, -k * y0 - 0.5


def warp_matrix(src: tuple[float, float, float], dst: tuple[float, float, float]) -> np.ndarray:
    """2x3 matrix taking a dst grid index to a src grid index (for cv2.warpAffine with WARP_INVERSE_MAP).
    Each grid is (k, bx, by) with index = k * X + b."""
    ks, bxs, bys = src
    kd, bxd, byd = dst
    r = ks / kd
    return np.array([[r, 0.0, bxs - r * bxd], [0.0, r, bys - r * byd]], np.float64)


def crop_region(rgb: np.ndarray, region: Region, size: int = SIZE) -> np.ndarray:
    """The square ``region`` of ``rgb`` resampled to (size, size, 3), zero outside the image.

    Large regions are first reduced by block means to about twice the canvas resolution (:class:`Pyramid`;
    shared by all crops of one photo inside :func:`reductions_shared`); the final
    resampling is one exact affine warp, so :func:`grid_of_region` describes the result exactly. The
    result is read-only when it comes from the shared crops.
    """
    return pyramid_of(rgb).crop(region, size)


class Pyramid:
    """An image (H, W, C) float32 and its reductions by 2, 4, 8, ... (each pixel the mean of an n x n block,
    zero past the image's edge: :func:`_blocks`; each reduction made from the one before), so that the
    crops of one photo share them instead of each reducing the photo again (a 2-megapixel float photo
    reduced to an arbitrary size costs ~5 ms, halved ~2 ms and only once).

    The reduction by n has index = X / n - 0.5 for continuous image coordinate X. A crop at canvas scale
    k < 0.5 is warped from the reduction by the power of 2 nearest to 1 / (2 k) (at least 2): a box filter
    about as wide as half the canvas's pixel pitch, then one bilinear warp that reduces by 1-2.8 (by 2
    at the nearest power), where one area reduction to exactly 2 k per crop came before.
    """

    def __init__(self, rgb: np.ndarray):
        self.rgb = rgb
        self.memo = False  # keep the reductions, each crop and the graphs' answers (read-only) for the next request
        self._levels: dict[int, np.ndarray] = {}
        self._crops: dict[tuple[Region, int], np.ndarray] = {}
        # per graph (its id, the graph held so the id stays its own) and kind of question, its answer per region
        self._answers: dict[tuple[int, str], tuple[object, dict[Region, object]]] = {}

    def answer(self, graph: object, kind: str, region: Region, ask: Callable[[], T], keep: int) -> T:
        """``ask()``: ``graph``'s answer on ``region`` of this image. With memo (:func:`reductions_shared`) it is
        asked once and kept, ``keep`` regions per graph and ``kind`` (the first asked dropped first; the selfie
        graph's probability, the face graph's boxes: the people search, the portrait check and the pose-graph
        person's backing ask for the same region); the answer is then shared, so the caller hands out a read-only
        one. Without memo, asked every time."""
        if not self.memo:
            return ask()
        kept = self._answers.setdefault((id(graph), kind), (graph, {}))[1]
        if region not in kept:
            kept[region] = ask()
            while len(kept) > keep:
                del kept[next(iter(kept))]
        return kept[region]  # type: ignore[return-value]

    def level(self, n: int) -> np.ndarray:
        """The whole image reduced by n (a power of 2), from the reduction by n / 2."""
        if n == 1:
            return self.rgb
        if n not in self._levels:
            self._levels[n] = _blocks(self.level(n // 2), 2, _all_blocks(self.rgb.shape, n))
        return self._levels[n]

    def crop(self, region: Region, size: int = SIZE) -> np.ndarray:
        """:func:`crop_region` of the image."""
        key = (region, int(size))
        if key in self._crops:
            return self._crops[key]
        out = self._crop(region, size)
        if self.memo:  # the last few only: a region is cropped again right after (pose pass, portrait check)
            out.flags.writeable = False
            self._crops[key] = out
            while len(self._crops) > _KEEP_CROPS:
                del self._crops[next(iter(self._crops))]
        return out

    def _crop(self, region: Region, size: int) -> np.ndarray:
        h, w = self.rgb.shape[:2]
        k, bx, by = grid_of_region(region, size)
        x0, y0, x1, y1 = region.box()
        ix0, iy0 = max(int(np.floor(x0)) - 1, 0), max(int(np.floor(y0)) - 1, 0)
        ix1, iy1 = min(int(np.ceil(x1)) + 1, w), min(int(np.ceil(y1)) + 1, h)
        if ix1 <= ix0 or iy1 <= iy0:
            return np.zeros((size, size, *self.rgb.shape[2:]), np.float32)  # (a 2-D map: a 2-D canvas)
        if k < 0.5:  # reduce by a power of 2 to about twice the canvas resolution first
            n = 2 ** max(1, int(np.floor(np.log2(0.5 / k) + 0.5)))
            bx0, by0, bx1, by1 = ix0 // n, iy0 // n, -(-ix1 // n), -(-iy1 // n)  # the blocks the crop touches
            if self.memo:  # the whole reduction, kept
                sub = self.level(n)[by0:by1, bx0:bx1]
            else:
                sub = _reduced(self.rgb, n, (bx0, by0, bx1, by1))
            m = warp_matrix((1.0 / n, -0.5 - bx0, -0.5 - by0), (k, bx, by))  # sub index = X / n - 0.5 - b0
        else:
            sub = self.rgb[iy0:iy1, ix0:ix1]
            m = warp_matrix((1.0, -0.5 - ix0, -0.5 - iy0), (k, bx, by))  # sub index = X - i0 - 0.5
        return cv2.warpAffine(
            np.ascontiguousarray(sub), m, (size, size), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
            borderMode=cv2.BORDER_CONSTANT, borderValue=(0.0, 0.0, 0.0),
        )  # fmt: skip


def _all_blocks(shape: tuple[int, ...], n: int) -> tuple[int, int, int, int]:
    return 0, 0, -(-shape[1] // n), -(-shape[0] // n)


def _reduced(img: np.ndarray, n: int, blocks: tuple[int, int, int, int]) -> np.ndarray:
    """Blocks (bx0, by0, bx1, by1) of ``img`` reduced by n (a power of 2) by halving n times, as
    :meth:`Pyramid.level` does for the whole image (the same values: each block only reads its own)."""
    if n == 1:
        return img[blocks[1] : blocks[3], blocks[0] : blocks[2]]
    bx0, by0, bx1, by1 = blocks
    _, _, hx, hy = _all_blocks(img.shape, n // 2)
    half = _reduced(img, n // 2, (2 * bx0, 2 * by0, min(2 * bx1, hx), min(2 * by1, hy)))
    # block c of the half reductions kept starts at 2 * bx0; their blocks are this level's blocks bx0 ...
    return _blocks(half, 2, (0, 0, bx1 - bx0, by1 - by0))


def _blocks(img: np.ndarray, n: int, blocks: tuple[int, int, int, int]) -> np.ndarray:
    """The means of ``img``'s n x n blocks (bx0, by0, bx1, by1), (by1 - by0, bx1 - bx0, C) of its dtype: block
    (r, c) covers rows [n r, n r + n) and columns [n c, n c + n), the image being zero past its edge (as
    everywhere in a crop), so a block cut by the edge is the sum of its pixels there over n²."""
    h, w = img.shape[:2]
    bx0, by0, bx1, by1 = blocks
    fx, fy = min(bx1, w // n), min(by1, h // n)  # blocks whole inside the image end here
    out = np.empty((by1 - by0, bx1 - bx0) + img.shape[2:], img.dtype)
    if fx > bx0 and fy > by0:
        part = img[n * by0 : n * fy, n * bx0 : n * fx]
        out[: fy - by0, : fx - bx0] = cv2.resize(part, (fx - bx0, fy - by0), interpolation=cv2.INTER_AREA)
    c = img.shape[2:]
    if bx1 > fx and fy > by0:  # the last column of blocks, cut by the right edge
        col = img[n * by0 : n * fy, n * fx :]
        out[: fy - by0, fx - bx0] = col.reshape((fy - by0, n, col.shape[1]) + c).sum(axis=(1, 2)) / (n * n)
    if by1 > fy and fx > bx0:  # the last row of blocks, cut by the bottom edge
        row = img[n * fy :, n * bx0 : n * fx]
        out[fy - by0, : fx - bx0] = row.reshape((row.shape[0], fx - bx0, n) + c).sum(axis=(0, 2)) / (n * n)
    if bx1 > fx and by1 > fy:  # the corner block
        out[fy - by0, fx - bx0] = img[n * fy :, n * fx :].sum(axis=(0, 1)) / (n * n)
    return out


_SCOPE = threading.local()  # the Pyramid of the photo a matter is working on (reductions_shared)


def pyramid_of(rgb: np.ndarray) -> Pyramid:
    """The image's :class:`Pyramid`: the one shared inside :func:`reductions_shared` for this very array,
    else a new one (the same maths, nothing kept)."""
    shared = getattr(_SCOPE, "pyramid", None)
    return shared if shared is not None and shared.rgb is rgb else Pyramid(rgb)


@contextmanager
def reductions_shared(rgb: np.ndarray) -> Iterator[Pyramid]:
    """Within the block, every :func:`crop_region` of this array (in this thread) reduces it from one
    :class:`Pyramid`, the same region and size is cropped once, and a graph asked for the same region again
    answers from the first time (:meth:`Pyramid.answer`). The matters open it around one call, and a caller
    around several on one photo (relight_rt.apps.scene_people: the people search, then each blob's
    segmentation): they only read the photo then, so the reductions and answers stay true to it (a caller
    may change the array between blocks)."""
    prev = getattr(_SCOPE, "pyramid", None)
    pyr = prev if prev is not None and prev.rgb is rgb else Pyramid(rgb)
    pyr.memo = True
    _SCOPE.pyramid = pyr
    try:
        yield pyr
    finally:
        _SCOPE.pyramid = prev
