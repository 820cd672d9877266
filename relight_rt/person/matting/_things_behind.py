"""Things out of focus behind the person, left out of the default matte (person="largest", photos only).

The selfie graph segments a person with what lies close behind them when it is out of focus: a guitar leaning behind a
girl's shoulder, a red stage light beside a singer's head, a blob of foliage below a couple's joined hands. The pose
graph, made for bodies, does not take those in; but it does not see every body the selfie graph holds either (a close
portrait's torso, the second partner of a couple: 37-51 % of the matte of p064, p089, p285). So a part leaves only
where it has every mark of a thing behind and none of a person:

1. the pose graph does not see it (probability under _UNSEEN): only a selfie-graph person's matte can hold such a part
   (a pose-graph person's segmentation is the pose graph's own view: nothing is looked at, no time is spent);
2. it is blurred where the person is sharp: its fine over mid-scale detail (:func:`detail_ratio`, on the detail maps
   of relight_rt.person.matting._behind) is at most _BLURRED x that of the matte's pixels the pose graph sees (defocus
   is depth: the person is the photo's focus);
3. it sticks out of the matte: under _APART of a thin ring around it lies inside the matte (a thing beside the person
   is mostly surrounded by the backdrop; a held phone or a sleeve lies against the body);
4. it is a thing, not part of someone: at most _MAX_PART of the segmentation of the person who holds it most (a torso
   is more; so is a second person of a group segmented on their own, however small a share of everyone's matte),
   holding no face's middle and reaching under none (:func:`bodily`, the faces of PersonMatter.find_faces on the whole
   photo: a face's person goes on below it; who is behind the subject, whole, is relight_rt.person.matting._behind's
   to decide), and not cut by the photo's bottom border (a body cut by the frame goes on: the grid reaches _MARGIN
   grid px below the matte, so only such a part reaches its last row). A side or the top border is no such sign:
   p016's blob and p064's stage light, both things behind, are cut by them.

A part is a piece of the matte's pose-unseen pixels that an opening by a disc of _OPEN x the matte's side leaves (the
pose graph's outline lies a pixel or two inside the matte's: the opening parts that strip from the thing)
(:func:`sticking_out`). It leaves the matte softly (:func:`without_things_behind`, :func:`_leave`): alpha x (1 - its
share of each pixel), with the pieces its cut leaves apart from the matte (slivers; what the opening stripped off it, a
guitar's neck; its own tail, joined to it before the cut, which the pose graph half-sees) and its soft rim (the soft
pixels nearer it than the matte that stays, up to _HALO x the matte's side: the selfie graph's soft take on a blurred
thing reaches far); the body's soft edge beside it stays. Parts the people's segmentations hardly hold (the own colours'
parts, relight_rt.person.matting._colours) are not looked at. The matte is read on a grid whose side is at most _SIDE
pixels on the side of the matte's area (:func:`reading_grid`: a 2.5-MP photo costs what a web photo does); the leaving
works on the photo's pixels in the box of what can change, but splits the soft rim on blocks of int(1 / s) px (the
grid's pitch, s its scale: the hard matte is the same as per pixel; 41-521 soft pixels of a 2.5-4.5 MP photo go the
other way, and none up to twice the grid's side, where a block is a pixel). VideoMatter
does not apply the rule: a part leaving on some frames and not on others would flicker, and each frame would pay for it.

What each threshold is measured on (benchmarks/people_masks_eval.py --methods ours; chosen on photos half A, four
photos in all: the margins are thin): _BLURRED 0.6-0.7 and _OPEN 0.02-0.05 gave the same four photos and nothing
else; _APART 0.3, where p089's foliage has a ring share of 0.27 and p285's torso, below a white band added under the
photo, 0.38 (0.4 adds small pieces of a group of three that the service's mask holds, -0.005 on p266; 0.5 a smooth red
phone held up to the camera, ring share 0.47, -0.07 on p287); _MAX_PART 0.2, where the four parts that leave are
0.025-0.106 of the matte and a couple's blurred partner 0.47; _NECK 0.5, where p064's stage light overlaps the edge
of its singer's face box and p104's guitar lies 0.2 face widths beside it (beside, not under); _HALO 0.5, where the
soft rim left beside p016's blob reaches 0.55 x its matte's side (95th percentile: 2892 -> 342 px of alpha < 0.5 nearer
the blob than the body) and p064's 0.18 (4385 -> 21). _UNSEEN, _SEEN, _RING, _TAIL, _SIDE and _MARGIN are set by
reasoning, not fitted. Half A 0.92340 -> 0.92575 (p104's guitar 0.859 -> 0.947, p064's stage light 0.877 -> 0.979,
p016's blurred blob 0.927 -> 0.956, p089's foliage below the joined hands 0.918 -> 0.940, p083 and p234 +0.002 and
+0.001), half B and the clip unchanged (no part qualifies). Time (benchmarks/things_behind_speed.py --before):
nothing for pose-graph people; with a selfie-graph person, one pose-graph run per region and, when a part would leave,
the faces (PersonMatter answers them from its people search's face-graph run on the photo) and the leaving: 25-60 ms a
web photo (p064 29 -> 42 ms with the soft rim and the tails), 130-175 ms at 4.5 MP (p064, p089, p104 enlarged; 210-350
ms before the blocks and the box, speed17: the window reaches twice _HALO x the matte's side, the whole photo there).
Things the rule cannot tell stay: at the photo's bottom border (p192's floor, p265's grass), in focus, or sharp where
the graphs are unsure. Sharpness is read on the photo's own pixels until the matte is
wider than _SIDE, so it depends on the photo's size: p016's blob enlarged 2x-4x no longer reads blurred against the
body, and stays.
"""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np

from ...image.matte_edges import band_width
from ...image.regions import Region
from ..face_detector import Face
from ._behind import details, disc, grey_of
from ._segmentation import Grid, Person, grid_over, logits_on_grid, sigmoid

_SIDE = 300  # the matte is read with the square of its area at most this many pixels on a side
_UNSEEN = 0.1  # the pose graph does not see a pixel under this probability ...
_SEEN = 0.5  # ... and sees it at this or more (the person's own sharpness is read there)
_OPEN = 0.03  # a part is what an opening by a disc this x the matte's side leaves of the unseen pixels ...
_MAX_PART = 0.2  # ... at most this share of the matte (more is a body: a torso, a second person)
_HELD = 0.3  # the people's segmentations hold a part at this mean probability or more (else an own-colours part)
_BLURRED = 0.65  # a part's fine / mid-scale detail at most this x the seen body's: out of focus
_APART = 0.3  # a part sticks out when under this share of the ring around it lies in the matte
_RING = 3  # the ring's width (grid px)
_NECK = 0.5  # a face's person goes on this x the face's width below its box (the chin, the neck)
_MARGIN = 12  # grid px read around the matte's bounding box (the ring, and the blurs' reach)
_TAIL = 0.1  # a piece cut off beside the part goes with it when the pose graph sees at most this share of it
_FEW_PIECES = 256  # more pieces than this: joined read in one window-wide look-up, not one per piece
_HALO = 0.5  # a part's soft rim is cleared up to this x the matte's side (square root of its area, px) from it
_REACH = 9  # grid px: three sigmas of the mid-scale blur of _behind.details, read around the matte

PoseLogits = Callable[[Person], np.ndarray]  # a selfie-graph person -> the pose graph's logits on their region's canvas
Faces = Callable[[], list[Face]]  # the photo's faces (asked only when a part would leave)
Box = tuple[float, float, float, float]  # (x0, y0, x1, y1), pixel edges


def detail_ratio(fine: np.ndarray, mid: np.ndarray, where: np.ndarray) -> float:
    """Sum of the fine detail over the sum of the mid-scale detail (relight_rt.person.matting._behind.details) at
    ``where`` (bool): how sharp a part is, light and contrast cancelled (_behind.fine_detail reads it on a box); NaN
    where the part shows no detail at all."""
    total = float(mid[where].sum())
    return float(fine[where].sum()) / total if total > 1e-6 else float("nan")


def sticking_out(matte: np.ndarray, held: list[np.ndarray], pose: np.ndarray) -> list[np.ndarray]:
    """The parts of ``matte`` that may be things behind the person before their sharpness is read (bool, each): the
    pieces of the matte's pixels that the pose graph does not see that an opening by a disc of _OPEN x the matte's
    side leaves, at most _MAX_PART of the segmentation of the person who holds them most (a second person of a group
    is measured against their own, not against everyone's matte), not reaching the grid's last row, that the people's
    segmentations hold (mean max of ``held`` >= _HELD) and that stick out of the matte (under _APART of the ring
    around them in it).

    Args:
        matte: (h, w) bool, the matte (alpha >= 0.5) on the grid.
        held: one (h, w) float32 map in [0, 1] per person, their segmentation on the grid.
        pose: (h, w) float32 in [0, 1], the pose graph's probability on the people's regions (max over them).

    The grid reaches _MARGIN grid px past the matte unless the photo ends first: a part on its last row is cut by the
    photo's bottom border (a body cut by the frame goes on)."""
    area = int(matte.sum())
    unseen = (matte & (pose < _UNSEEN)).astype(np.uint8)
    if area == 0 or not unseen.any():
        return []
    opened = cv2.morphologyEx(unseen, cv2.MORPH_OPEN, disc(_OPEN * np.sqrt(area)))
    n, labels, stats, _ = cv2.connectedComponentsWithStats(opened, connectivity=8)
    h = matte.shape[0]
    ring_k = np.ones((2 * _RING + 1, 2 * _RING + 1), np.uint8)
    anyone = np.max(held, axis=0)
    parts = []
    for i in range(1, n):
        x, y, bw, bh, size = (int(v) for v in stats[i])
        if size > _MAX_PART * area or y + bh >= h:
            continue  # a body (more than a share of everyone's matte is more than one person's), or cut by the bottom
        y0, x0 = max(y - _RING, 0), max(x - _RING, 0)  # read in its box and the ring's
        box = (slice(y0, y + bh + _RING), slice(x0, x + bw + _RING))
        part = labels[box] == i
        if float(anyone[box][part].mean()) < _HELD:
            continue
        mine = max(held, key=lambda m: float(m[box][part].mean()))  # the person who holds it most ...
        if size > _MAX_PART * int((matte & (mine >= 0.5)).sum()):
            continue  # ... and more than a share of them: a torso, or a person of the group
        ring = cv2.dilate(part.astype(np.uint8), ring_k).astype(bool) & ~part
        if ring.any() and (ring & matte[box]).sum() >= _APART * ring.sum():
            continue
        whole = np.zeros(matte.shape, bool)
        whole[box] = part
        parts.append(whole)
    return parts


def blurred_of(gray: np.ndarray, matte: np.ndarray, pose: np.ndarray, parts: list[np.ndarray]) -> list[np.ndarray]:
    """Those of ``parts`` (:func:`sticking_out`) that are out of focus: their fine / mid-scale detail at most _BLURRED
    x that of the matte's pixels the pose graph sees (the body). The detail is read in the matte's bounding box only;
    a body without detail decides nothing."""
    if not parts:
        return []
    ys, xs = np.nonzero(matte)
    box = (
        slice(max(int(ys.min()) - _REACH, 0), int(ys.max()) + _REACH + 1),
        slice(max(int(xs.min()) - _REACH, 0), int(xs.max()) + _REACH + 1),
    )
    fine, mid = details(np.ascontiguousarray(gray[box], np.float32))
    sharp = detail_ratio(fine, mid, matte[box] & (pose[box] >= _SEEN))  # NaN (no detail): no part compares below it
    return [part for part in parts if detail_ratio(fine, mid, part[box]) < _BLURRED * sharp]


def bodily(part: np.ndarray, faces: list[Box]) -> bool:
    """Whether ``part`` (bool, a grid) is someone's: it holds a pixel of a face's middle half or of the strip below it
    (the middle half's columns, down to _NECK x the face's width below its box: a chin, a neck, a torso going on).
    ``faces``: boxes on that grid (pixel edges)."""
    h, w = part.shape
    for x0, y0, x1, y1 in faces:
        fw, fh = x1 - x0, y1 - y0
        c0, c1 = max(int(np.floor(x0 + fw / 4)), 0), min(int(np.ceil(x1 - fw / 4)), w)
        r0, r1 = max(int(np.floor(y0 + fh / 4)), 0), min(int(np.ceil(y1 + _NECK * fw)), h)
        if c1 > c0 and r1 > r0 and part[r0:r1, c0:c1].any():
            return True
    return False


def _leave(alpha: np.ndarray, weight: np.ndarray, seen: np.ndarray, reach: int, halo: float, ramp: float,
           alone: bool, most: float, step: int = 1, sides: tuple[bool, bool, bool, bool] = (True,) * 4
           ) -> np.ndarray:  # fmt: skip
    """``alpha`` (a (h, w) window around a part) less the part, whose share of each pixel is ``weight``: alpha x
    (1 - weight); then the pieces of the matte (>= 0.5) left apart from the rest go: those within ``reach`` px of the
    part (slivers along the cut, bits of the part's own soft rim that read >= 0.5; only when the matte lies wholly in
    the window, ``alone``, does its largest piece stay when none reaches further), and those that were joined to the
    part before the cut (a piece apart from it all along, a hand or a small peer beside it, is not its tail), lie
    wholly in the window, hold at most ``most`` pixels (a body apart is more) and of which the pose graph sees
    (``seen``, bool) at most _TAIL (the part's own tail, cut off from it); the part's own pixels go except within
    ``ramp`` px of the matte that stays (there the cut stays soft); and each soft pixel (< 0.5) within ``halo`` px of
    the part goes with the nearer of the part and the matte that stays (the part's soft rim leaves, the body's stays).
    The window reaches 2 ``halo`` + 1 px past the part (the matte past it is further from such a pixel than the part)
    or to the photo's edge.

    ``sides`` (top, bottom, left, right): whether the matte may go on past each of the window's sides (a piece at
    one is no tail); where the caller cut the window to the box of what can change, it does not.

    The soft pixels' split is read on blocks of ``step`` x ``step`` px (:func:`_soft_rim`; 1: each pixel), every other
    decision on the photo's pixels; distances up to ``reach`` and ``ramp`` are measured in boxes around the part
    only (:func:`_near`), which gives them exactly as over the whole window."""
    _, before = cv2.connectedComponents((alpha >= 0.5).astype(np.uint8), connectivity=8)
    # the pieces joined to the part itself (>= 0.5: its bilinear share reaches ~1 / (2 s) px past it on a reduced grid)
    touched = np.bincount(before[weight >= 0.5], minlength=int(before.max()) + 1) > 0
    touched[0] = False
    out = alpha * (1.0 - weight)
    shared = weight > 0
    zone = _near(shared, reach)
    hard = (out >= 0.5).astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(hard, connectivity=8)
    area = stats[:, cv2.CC_STAT_AREA]
    # a piece lies in one piece of the matte before the cut (it only lost pixels): read at its first pixel, or with
    # one window-wide look-up where the pieces are too many for a loop (specks: the same answer)
    if n - 1 <= _FEW_PIECES:
        joined = np.array([False] + [touched[before[at]] for at in _first_pixels(labels, stats)])  # (within ``reach``)
    else:
        joined = np.zeros(n, bool)
        joined[labels[touched[before]]] = True
        joined[0] = False
    apart = np.bincount(labels[zone], minlength=n) == area  # a piece reaching past the zone goes on into the matte
    apart[0] = False
    if alone and n > 1 and apart[1:].all():
        apart[1 + int(np.argmax(area[1:]))] = False
    at_edge = np.zeros(n, bool)  # (a piece at the window's edge may go on)
    for rim, on in zip((labels[0], labels[-1], labels[:, 0], labels[:, -1]), sides, strict=True):
        at_edge[rim] |= on
    tail = joined & ~at_edge & (area <= most)
    for k in np.flatnonzero(tail):  # (few and small: read in their boxes)
        x, y, bw, bh = stats[k, :4]
        box = (slice(y, y + bh), slice(x, x + bw))
        tail[k] = np.count_nonzero((labels[box] == k) & seen[box]) <= _TAIL * area[k]
    fate = (apart | tail).view(np.uint8) + tail  # per piece: 0 kept, 1 apart, 2 a tail (one look-up for both)
    fate[0] = 1  # (not the matte)
    piece = fate[labels]
    kept = piece == 0
    part = (zone | (piece == 2)) & (alpha >= 0.5) & ~kept
    cut = part & ~_near(kept, ramp, part)  # the part's pixels further than ``ramp`` from the matte that stays
    out[cut | (_soft_rim(shared, part, kept, halo, step) & ~part & ~kept)] = 0.0  # (soft: >= 0.5 is either)
    return out


def _first_pixels(labels: np.ndarray, stats: np.ndarray) -> list[tuple[int, int]]:
    """(row, column) of one pixel of each piece 1, 2, ... of cv2.connectedComponentsWithStats (``labels``, ``stats``):
    the first of its top row."""
    out = []
    for k in range(1, len(stats)):
        x, y, bw = (int(v) for v in stats[k, :3])
        out.append((y, x + int(np.argmax(labels[y, x : x + bw] == k))))
    return out


def _near(mask: np.ndarray, reach: float, where: np.ndarray | None = None) -> np.ndarray:
    """The pixels within ``reach`` px of ``mask`` (bool, (h, w); cv2.distanceTransform's 3x3 L2 mask) among those of
    ``where`` (default: every pixel), measured in the box around ``where``'s pixels (``mask``'s by default) and
    reach / 0.95 + 1 px past it: the mask's 3x3 distance is at least 0.955 x the larger of the row and column steps
    and is taken along a path inside the box of its two ends, so no pixel of ``mask`` outside that box is as near,
    and one inside it is measured as over the whole array."""
    near = np.zeros(mask.shape, bool)
    box = cv2.boundingRect((mask if where is None else where).view(np.uint8))
    if box[2] == 0 or not mask.any():
        return near
    m = int(np.ceil(reach / 0.95)) + 1
    h, w = mask.shape
    y0, x0, y1, x1 = max(box[1] - m, 0), max(box[0] - m, 0), min(box[1] + box[3] + m, h), min(box[0] + box[2] + m, w)
    inside = mask[y0:y1, x0:x1]
    if inside.any():
        near[y0:y1, x0:x1] = cv2.distanceTransform((~inside).view(np.uint8), cv2.DIST_L2, 3) <= reach
    if where is not None:
        near &= where
    return near


def _soft_rim(weight: np.ndarray, part: np.ndarray, kept: np.ndarray, halo: float, step: int) -> np.ndarray:
    """(h, w) bool: the pixels within ``halo`` px of ``weight`` (bool, the part's share > 0) and nearer ``part`` than
    ``kept`` (bool), read on blocks of ``step`` x ``step`` px from the window's corner (a block holds a mask when one
    of its pixels does; distances between the blocks' centres), each pixel given its block's answer. With ``step`` 1:
    each pixel's own (cv2.distanceTransform's 3x3 L2 mask, as everywhere here)."""
    h, w = weight.shape
    to_weight, to_part = (_distance(_blocks(m, step)) for m in (weight, part))  # (in blocks)
    to_kept = _distance(_blocks(kept, step)) if kept.any() else np.inf
    near = (to_weight <= halo / step) & (to_part < to_kept)
    return near if step == 1 else near.repeat(step, axis=0).repeat(step, axis=1)[:h, :w]


def _blocks(mask: np.ndarray, step: int) -> np.ndarray:
    """(ceil(h / step), ceil(w / step)) bool: whether each ``step`` x ``step`` block of ``mask`` (bool, (h, w); blocks
    from the top left corner, the last ones cut by the edge) holds a True pixel; ``mask`` itself for a step of 1."""
    if step == 1:
        return mask
    block = np.ones((step, step), np.uint8)  # each pixel the max of the block it starts (0 past the edge)
    return cv2.dilate(mask.view(np.uint8), block, anchor=(0, 0), borderType=cv2.BORDER_CONSTANT, borderValue=0
                      )[::step, ::step] > 0  # fmt: skip


def _distance(mask: np.ndarray) -> np.ndarray:
    """(h, w) float32: each pixel's distance to ``mask`` (bool), cv2.distanceTransform's 3x3 L2 mask."""
    return cv2.distanceTransform((~mask).view(np.uint8), cv2.DIST_L2, 3)  # (3: a few % off, 4x as fast as 5)


def reading_grid(inside: np.ndarray) -> tuple[Grid, tuple[int, int, int, int], float]:
    """The grid the matte ``inside`` ((H, W) uint8, alpha >= 0.5, not empty) is read on: (grid, (x0, y0, x1, y1) the
    photo's box it covers, the matte's bounding box with _MARGIN grid px around it, scale s <= 1 that makes the matte's
    side at most _SIDE px). Its pixels are those of the box reduced by cv2.resize (their centres)."""
    h, w = inside.shape
    s = min(1.0, _SIDE / float(np.sqrt(cv2.countNonZero(inside))))
    bx, by, bw, bh = cv2.boundingRect(inside)
    m = int(np.ceil(_MARGIN / s))
    x0, y0, x1, y1 = max(bx - m, 0), max(by - m, 0), min(bx + bw + m, w), min(by + bh + m, h)
    return grid_over((x0, y0, x1, y1), s), (x0, y0, x1, y1), s


def without_things_behind(
    rgb: np.ndarray, alpha: np.ndarray, people: list[Person], pose: PoseLogits, faces: Faces
) -> np.ndarray:  # fmt: skip
    """``alpha`` without the things out of focus behind ``people`` (module docstring), read on a grid over the matte's
    bounding box (with _MARGIN grid px around it) whose scale makes the matte's side at most _SIDE px.

    Args:
        rgb: (H, W, 3) float32 RGB in [0, 1], the photo.
        alpha: (H, W) float32 matte in [0, 1] (person="largest"'s, refined).
        people: the people matted; those of source "own" (a part in the person's own colours) are not read, and
            without a selfie-graph person ("roi") nothing is.
        pose: gives the pose graph's logits on a selfie-graph person's region canvas (asked once per region; a
            pose-graph person's view is their own logits).
        faces: gives the photo's faces (image px), asked only when a part would leave.

    Returns:
        (H, W) float32: ``alpha`` itself when nothing leaves, else a copy without the parts (:func:`_leave`).
    """
    people = [p for p in people if p.source != "own"]
    if not any(p.source == "roi" for p in people):
        return alpha  # the pose graph's own segmentations: nothing they hold is unseen
    inside = (alpha >= 0.5).view(np.uint8)
    area = cv2.countNonZero(inside)
    if area == 0:
        return alpha
    h, w = alpha.shape
    grid, (x0, y0, x1, y1), s = reading_grid(inside)
    gw, gh, kx, ky = grid[:4]
    small = alpha[y0:y1, x0:x1]
    small = small if s >= 1.0 else cv2.resize(small, (gw, gh), interpolation=cv2.INTER_AREA)
    matte = small >= 0.5
    held = [sigmoid(logits_on_grid(p, grid)) for p in people]
    views: dict[Region, np.ndarray] = {}  # one pose-graph view per region (the parts split from one segmentation)
    for p in people:
        if p.region not in views:
            views[p.region] = logits_on_grid(p if p.source == "pose" else Person(p.region, pose(p), 0.0), grid)
    seen = sigmoid(np.max(list(views.values()), axis=0))
    parts = sticking_out(matte, held, seen)
    if not parts:
        return alpha
    gray = grey_of(rgb[y0:y1, x0:x1])
    gray = gray if s >= 1.0 else cv2.resize(gray, (gw, gh), interpolation=cv2.INTER_AREA)
    parts = blurred_of(gray, matte, seen, parts)
    if parts:
        boxes = [(kx * (f.box[0] - x0), ky * (f.box[1] - y0), kx * (f.box[2] - x0), ky * (f.box[3] - y0))
                 for f in faces() if np.all(np.isfinite(f.box))]  # fmt: skip
        parts = [p for p in parts if not bodily(p, boxes)]
    if not parts:
        return alpha
    weight = np.any(parts, axis=0).astype(np.float32)
    if s < 1.0:  # the part's share of each pixel of the photo (a soft cut, not a staircase of grid pixels)
        weight = cv2.resize(weight, (x1 - x0, y1 - y0), interpolation=cv2.INTER_LINEAR)
    r = band_width(alpha.shape)  # how far the slivers its cut leaves reach
    px, py, pw, ph = cv2.boundingRect((weight > 0).view(np.uint8))  # the part's box
    halo = max(float(r), _HALO * np.sqrt(float(area)))  # how far its soft rim is cleared (the matte's size's)
    m = int(np.ceil(2 * halo)) + 2
    wx0, wy0 = max(x0 + px - m, 0), max(y0 + py - m, 0)
    wx1, wy1 = min(x0 + px + pw + m, w), min(y0 + py + ph + m, h)
    alone = cv2.countNonZero(inside[wy0:wy1, wx0:wx1]) == area  # no matte past the window
    # only the window's matte (> 0) and the part's share change: the leaving reads their box (the window's sides
    # that it keeps are those a piece may go on past)
    mx, my, mw, mh = cv2.boundingRect((alpha[wy0:wy1, wx0:wx1] > 0).view(np.uint8))
    cx0, cy0 = min(wx0 + mx, x0 + px), min(wy0 + my, y0 + py)
    cx1, cy1 = max(wx0 + mx + mw, x0 + px + pw), max(wy0 + my + mh, y0 + py + ph)
    sides = (cy0 == wy0, cy1 == wy1, cx0 == wx0, cx1 == wx1)
    wx0, wy0, wx1, wy1 = cx0, cy0, cx1, cy1
    share = np.zeros((wy1 - wy0, wx1 - wx0), np.float32)
    iy0, iy1, ix0, ix1 = max(y0, wy0), min(y1, wy1), max(x0, wx0), min(x1, wx1)
    share[iy0 - wy0 : iy1 - wy0, ix0 - wx0 : ix1 - wx0] = weight[iy0 - y0 : iy1 - y0, ix0 - x0 : ix1 - x0]
    sure = (seen >= _SEEN).astype(np.float32)  # what the pose graph sees, on the photo's pixels
    sure = sure if s >= 1.0 else cv2.resize(sure, (x1 - x0, y1 - y0), interpolation=cv2.INTER_LINEAR)
    looked = np.zeros(share.shape, bool)
    looked[iy0 - wy0 : iy1 - wy0, ix0 - wx0 : ix1 - wx0] = sure[iy0 - y0 : iy1 - y0, ix0 - x0 : ix1 - x0] > 0
    out = alpha.copy()
    out[wy0:wy1, wx0:wx1] = _leave(alpha[wy0:wy1, wx0:wx1], share, looked, r, halo, 1.0 / s + 1.0, alone,
                                   _MAX_PART * area, int(1.0 / s), sides)  # fmt: skip
    return out
