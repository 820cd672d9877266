"""Things out of focus behind the person, left out of the default matte (person="largest").

The selfie graph segments a person with what lies close behind them when it is out of focus: a guitar leaning behind a
girl's shoulder, a red stage light beside a singer's head, a blob of foliage below a couple's joined hands. Such a part
has three marks that a person's own parts (an arm, the hair, a held phone, a bag) do not have together:

1. the pose graph, made for bodies, does not see it (probability under _UNSEEN on the person's region);
2. it is blurred where the person is sharp: its fine detail over its mid-scale detail (the measure of
   relight_rt.person.matting._behind, :func:`detail_ratio`) is at most _BLURRED x that of the part of the matte that
   the pose graph sees (defocus is depth: the person is the photo's focus);
3. it sticks out of the matte: under _APART of a thin ring around it lies inside the matte (a thing beside the person
   is mostly surrounded by the backdrop; a held phone or a sleeve lies against the body).

Such a part (:func:`blurred_things`: a piece of the matte's pose-unseen pixels that an opening of _OPEN x the matte's
side leaves, at least _MIN_PART of the matte, not touching the photo's bottom border, where a body cut by the frame
goes on) leaves the matte with its soft rim (:func:`without_things_behind`). Parts the people's segmentations hardly
hold (the own colours' parts, relight_rt.person.matting._colours) are not looked at. The matte is read on a grid whose
side is at most _SIDE pixels on the side of the matte's area (a 2.5-MP photo costs what a web photo does).

Measured (benchmarks/people_masks_eval.py --methods ours; chosen on photos half A, where _BLURRED 0.6-0.7, _OPEN
0.02-0.05 and _APART 0.3 gave the same four photos and nothing else; _APART 0.4 adds small pieces of a group of three
that the service's mask holds, -0.005 on p266; 0.5 a smooth red phone held up to the camera, which reads as blurred,
-0.07 on p287): half A 0.92340 -> 0.92569 (p104's guitar 0.859 ->
0.947, p064's stage light 0.877 -> 0.978, p016's blurred blob 0.927 -> 0.953, p089's foliage below the joined hands
0.918 -> 0.940), half B and the clip unchanged (0.90164, 0.93254: no part qualifies), no image worse; the four photos
enlarged to 2.5 MP gain alike. Time: a pose-graph person, 4-6 ms on the 2.5-MP reference photo; a selfie-graph person
(a portrait), one pose-graph run more, 15-30 ms in all (benchmarks/things_behind_speed.py, 2-core CPU under load).
Things the rule cannot tell stay: at the photo's bottom border (p192's floor, p265's grass), in focus, or sharp where
the graphs are unsure.
"""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np

from ...image.matte_edges import band_width
from ...image.regions import Region
from ._segmentation import Grid, Person, logits_on_grid, sigmoid

_SIDE = 300  # the matte is read with the square of its area at most this many pixels on a side
_UNSEEN = 0.1  # the pose graph does not see a pixel under this probability ...
_SEEN = 0.5  # ... and sees it at this or more (the person's own sharpness is read there)
_OPEN = 0.03  # a part is what an opening by a disc this x the matte's side leaves of the unseen pixels ...
_MIN_PART = 0.002  # ... at least this share of the matte
_HELD = 0.3  # the people's segmentations hold a part at this mean probability or more (else an own-colours part)
_BLURRED = 0.65  # a part's fine / mid-scale detail at most this x the seen body's: out of focus
_APART = 0.3  # a part sticks out when under this share of the ring around it lies in the matte
_RING = 3  # the ring's width (grid px) ...
_INSET = 2  # ... and the matte's rim (grid px) left out of the sharpness measures (there the outline is read)
_FINE, _MID = 1.0, 3.0  # Gaussian sigmas (grid px) of the fine and mid-scale detail (as _behind's)
_MARGIN = 12  # grid px read around the matte's bounding box (the ring, and the blurs' reach)

PoseLogits = Callable[[Person], np.ndarray]  # a person -> the pose graph's logits on their region's canvas


def detail_ratio(fine: np.ndarray, mid: np.ndarray, where: np.ndarray) -> float:
    """Sum of the fine detail over the sum of the mid-scale detail at ``where`` (bool): how sharp a part is, light and
    contrast cancelled; NaN where the part shows no detail at all."""
    total = float(mid[where].sum())
    return float(fine[where].sum()) / total if total > 1e-6 else float("nan")


def _disc(size: int) -> np.ndarray:
    size = max(int(size), 1) | 1
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size))


def sticking_out(
    matte: np.ndarray, held: np.ndarray, pose: np.ndarray, bottom: bool = True
) -> tuple[np.ndarray, list[np.ndarray]]:  # fmt: skip
    """The parts of ``matte`` that may be things behind the person before their sharpness is read: (the matte's pixels
    the pose graph does not see, [each part's pixels]), the parts being the pieces of those pixels that an opening by
    a disc of _OPEN x the matte's side leaves, at least _MIN_PART of the matte, above the photo's bottom border, that
    the people's segmentations hold (mean ``held`` >= _HELD) and that stick out of the matte (under _APART of the ring
    around them in it). Arrays as :func:`blurred_things`'s; ``bottom``: whether the grid's last row is the photo's
    bottom row (a grid over part of the photo may end above it)."""
    area = int(matte.sum())
    unseen = (matte & (pose < _UNSEEN)).astype(np.uint8)
    if area == 0 or not unseen.any():
        return unseen.astype(bool), []
    opened = cv2.morphologyEx(unseen, cv2.MORPH_OPEN, _disc(_OPEN * np.sqrt(area)))
    n, labels, stats, _ = cv2.connectedComponentsWithStats(opened, connectivity=8)
    h = matte.shape[0]
    ring_k = np.ones((2 * _RING + 1, 2 * _RING + 1), np.uint8)
    parts = []
    for i in range(1, n):
        x, y, bw, bh, size = (int(v) for v in stats[i])
        if size < _MIN_PART * area or (bottom and y + bh >= h):  # small, or a body cut by the frame's bottom goes on
            continue
        y0, x0 = max(y - _RING, 0), max(x - _RING, 0)  # read in its box and the ring's
        box = (slice(y0, y + bh + _RING), slice(x0, x + bw + _RING))
        part = labels[box] == i
        if float(held[box][part].mean()) < _HELD:
            continue
        ring = cv2.dilate(part.astype(np.uint8), ring_k).astype(bool) & ~part
        if ring.any() and (ring & matte[box]).sum() >= _APART * ring.sum():
            continue
        whole = np.zeros(matte.shape, bool)
        whole[box] = part
        parts.append(whole)
    return unseen.astype(bool), parts


def blurred_things(gray: np.ndarray, matte: np.ndarray, held: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """The parts of ``matte`` that are things out of focus behind the person (module docstring), on one grid.

    Args:
        gray: (h, w) float32 grey photo in [0, 1].
        matte: (h, w) bool, the matte (alpha >= 0.5).
        held: (h, w) float32 in [0, 1], the people's segmentations (max over them; none for the own colours' parts).
        pose: (h, w) float32 in [0, 1], the pose graph's probability on the people's regions (max over them).

    Returns:
        (h, w) bool: the pixels that leave (False everywhere when nothing does): each blurred part of
        :func:`sticking_out`, with the unseen pixels next to it that the opening shaved off.
    """
    unseen, parts = sticking_out(matte, held, pose)
    return blurred_of(gray, matte, pose, unseen, parts)


def blurred_of(gray: np.ndarray, matte: np.ndarray, pose: np.ndarray, unseen: np.ndarray, parts: list[np.ndarray]
               ) -> np.ndarray:  # fmt: skip
    """Of ``parts`` (:func:`sticking_out`), those out of focus (fine / mid-scale detail at most _BLURRED x the seen
    body's, the matte's rim of _INSET px left out of both), grown by the ``unseen`` pixels within the opening's disc:
    :func:`blurred_things`'s answer. The detail is read in the matte's bounding box only."""
    out = np.zeros(matte.shape, bool)
    if not parts:
        return out
    ys, xs = np.nonzero(matte)
    m = int(np.ceil(3 * _MID))
    box = (
        slice(max(int(ys.min()) - m, 0), int(ys.max()) + m + 1),
        slice(max(int(xs.min()) - m, 0), int(xs.max()) + m + 1),
    )
    g = np.ascontiguousarray(gray[box], np.float32)
    fine = np.abs(g - cv2.GaussianBlur(g, (0, 0), _FINE))
    mid = np.abs(g - cv2.GaussianBlur(g, (0, 0), _MID))
    inner = cv2.erode(matte[box].astype(np.uint8), np.ones((2 * _INSET + 1, 2 * _INSET + 1), np.uint8)).astype(bool)
    sharp = detail_ratio(fine, mid, inner & (pose[box] >= _SEEN))
    if not np.isfinite(sharp) or sharp <= 0.0:
        return out
    for part in parts:
        ratio = detail_ratio(fine, mid, part[box] & inner)
        if np.isfinite(ratio) and ratio < _BLURRED * sharp:
            out |= part
    if out.any():  # the part as the opening took it, with the unseen pixels next to it that the opening shaved off
        out = cv2.dilate(out.astype(np.uint8), _disc(_OPEN * np.sqrt(matte.sum()))).astype(bool) & unseen
    return out


def without_things_behind(rgb: np.ndarray, alpha: np.ndarray, people: list[Person], pose: PoseLogits) -> np.ndarray:
    """``alpha`` without the things out of focus behind ``people`` (module docstring), read on a grid over the matte's
    bounding box (with _MARGIN grid px around it) whose scale makes the matte's side at most _SIDE px.

    Args:
        rgb: (H, W, 3) float32 RGB in [0, 1], the photo.
        alpha: (H, W) float32 matte in [0, 1] (person="largest"'s, refined).
        people: the people matted; those of source "own" (a part in the person's own colours) are not read.
        pose: gives the pose graph's logits on a person's region canvas (a pose-graph person's own; asked once per
            region).

    Returns:
        (H, W) float32: ``alpha`` itself when nothing leaves, else a copy with the parts and their soft rim at 0.
    """
    people = [p for p in people if p.source != "own"]
    inside = (alpha >= 0.5).view(np.uint8)
    area = cv2.countNonZero(inside)
    if not people or area == 0:
        return alpha
    h, w = alpha.shape
    s = min(1.0, _SIDE / float(np.sqrt(area)))
    bx, by, bw, bh = cv2.boundingRect(inside)
    m = int(np.ceil(_MARGIN / s))
    x0, y0, x1, y1 = max(bx - m, 0), max(by - m, 0), min(bx + bw + m, w), min(by + bh + m, h)
    gw, gh = max(int(round((x1 - x0) * s)), 1), max(int(round((y1 - y0) * s)), 1)
    kx, ky = gw / (x1 - x0), gh / (y1 - y0)
    grid: Grid = (gw, gh, kx, ky, -kx * x0 - 0.5, -ky * y0 - 0.5)  # the reduced box's pixels (cv2.resize's centres)
    small = alpha[y0:y1, x0:x1]
    small = small if s >= 1.0 else cv2.resize(small, (gw, gh), interpolation=cv2.INTER_AREA)
    matte = small >= 0.5
    held = np.max([logits_on_grid(p, grid) for p in people], axis=0)
    runs: dict[Region, np.ndarray] = {}  # one pose-graph view per region (the parts split from one segmentation)
    for p in people:
        if p.region not in runs:
            runs[p.region] = logits_on_grid(Person(p.region, pose(p), p.presence), grid)
    seen = sigmoid(np.max(list(runs.values()), axis=0))
    unseen, parts = sticking_out(matte, sigmoid(held), seen, bottom=y1 == h)
    if not parts:
        return alpha
    gray = cv2.cvtColor(np.ascontiguousarray(rgb[y0:y1, x0:x1], np.float32), cv2.COLOR_RGB2GRAY)
    gray = gray if s >= 1.0 else cv2.resize(gray, (gw, gh), interpolation=cv2.INTER_AREA)
    things = blurred_of(gray, matte, seen, unseen, parts)
    if not things.any():
        return alpha
    if s < 1.0:
        things = cv2.resize(things.astype(np.float32), (x1 - x0, y1 - y0), interpolation=cv2.INTER_LINEAR) >= 0.5
    r = band_width(alpha.shape)  # the soft rim: the refined band's width around the part, where alpha < 0.5
    rx0, ry0, rx1, ry1 = max(x0 - r, 0), max(y0 - r, 0), min(x1 + r, w), min(y1 + r, h)
    leaving = np.zeros((ry1 - ry0, rx1 - rx0), bool)
    leaving[y0 - ry0 : y1 - ry0, x0 - rx0 : x1 - rx0] = things
    out = alpha.copy()
    near = out[ry0:ry1, rx0:rx1]
    rim = cv2.dilate(leaving.astype(np.uint8), _disc(2 * r + 1)).astype(bool) & (near < 0.5)
    near[leaving | rim] = 0.0
    return out
