"""A group's people as parts of one matte: a selfie-graph segmentation holding several people split by their
faces (:func:`split_by_faces`), the parts joined again for the matte (:func:`rejoin`), and each person's share
of the matte (:func:`shares`: relight_rt.person.matting.PersonMatter.parts and part_crops), where people split by
their faces meet along the photo's own edges (:func:`along_edges`)."""

from __future__ import annotations

import cv2
import numpy as np

from ...image.color import colour_gradient
from ...image.regions import Crop, grid_of_region
from ..face_detector import Face
from ._models import SIZE
from ._segmentation import LOGIT_CLIP, Grid, Person, logits_on_grid, working_grid

_PART_SOFT = 0.01  # parts: people's shares meet softly over about this x the photo's longer side
_SHARE_MIN = 0.01  # parts: a person's share below this is none
_EDGE_DE = 2.0  # along_edges: a cell on a colour edge of this CIE Lab distance (dE) per cell costs half as much to cut
_EDGE_SMOOTH = 1.0  # along_edges: the photo on the working grid is blurred over this many cells (its grain)
_FACE_CORE = 0.25  # along_edges: in a face's rows a cut keeps this fraction of its width off its centre
_CUT_STAY = 0.5  # along_edges: a cut one face width off the straight cut costs this a row more
_NO_CUT = 1e9  # along_edges: the cost of a cell a cut may not pass (a face's middle)
_CUT_SLOPE = 2  # along_edges: a cut moves at most this many columns a row
_MIN_PART = 256  # parts: a person with fewer opaque pixels of the matte than this (hidden) is not a part of their own


def split_by_faces(person: Person, faces: list[Face]) -> list[Person]:
    """One selfie-graph segmentation holding several people (their faces inside it) as one Person per face:
    every canvas pixel goes to the face nearest in x (in units of that face's width: a nearer, larger face
    claims more), so the parts partition the canvas and their logits' maximum is the segmentation again
    (:func:`rejoin`)."""
    k, bx, by = grid_of_region(person.region)
    cols = np.arange(SIZE, dtype=np.float64)
    dist = []
    for f in faces:
        x0, _, x1, _ = f.box
        centre, width = k * (x0 + x1) / 2 + bx, max(k * (x1 - x0), 1.0)
        dist.append(np.abs(cols - centre) / width)
    owner = np.argmin(np.stack(dist), axis=0)  # per canvas column
    out = []
    for i in range(len(faces)):
        logits = np.where(owner[None, :] == i, person.logits, np.float32(-LOGIT_CLIP)).astype(np.float32)
        out.append(Person(person.region, logits, person.presence, person.source, whole=person.logits, face=faces[i],
                          split=tuple(faces)))
    return out


def faces_side_by_side(faces: list[Face]) -> list[Face]:
    """The faces that can stand for people side by side, largest first: a face whose centre lies within a
    larger one's width of its centre is left out (a badge or a print below a face, found as a face: a
    split by columns cannot hold two people there)."""
    kept: list[Face] = []
    for f in sorted(faces, key=lambda f: -f.size):
        c = (f.box[0] + f.box[2]) / 2
        if all(abs(c - (g.box[0] + g.box[2]) / 2) >= g.box[2] - g.box[0] for g in kept):
            kept.append(f)
    return kept




def shares(
    people: list[Person], alpha: np.ndarray, rgb: np.ndarray | None = None, *, crops: bool = False
) -> list[np.ndarray] | list[Crop]:
    """Each person's share of the matte ``alpha`` (H, W): (H, W) float32 weights summing to 1 everywhere (with
    ``crops``: each as ((y0, y1, x0, x1), its values there), exact where ``alpha`` is not 0 and 0 far from it, in
    the box holding every pixel where it is not 0: alpha x share is the same, and a person's box stays near them).

    With the photo ``rgb`` (H, W, 3) float32 RGB in [0, 1] (PersonMatter.parts and part_crops give it), people split
    from one segmentation by their faces meet along the photo's own edges (:func:`along_edges`); without it, at the
    straight cut between their faces.

    A pixel goes to the people in proportion to the softmax of their segmentations' logits there (a person
    whose segmentation is surer of it takes it; beyond everyone's segmentation, on a refined hair edge, the
    nearest outline's person, whose logit falls least; a person whose segmentation does not reach it at all, none
    of it; where no one's does, the person whose region is nearest), on a working grid; a share under
    ``_SHARE_MIN`` is none; the shares are blurred over ``_PART_SOFT`` of the photo's longer side (two people meet
    softly; the blur taken over the matte's cells only), a share under ``_SHARE_MIN`` again none, and upsampled
    smoothly. A person left with fewer than ``_MIN_PART`` opaque pixels of the matte (hidden behind others) gets
    no share (the list is shorter by them): theirs goes to the rest.
    """
    h, w = alpha.shape
    if len(people) < 2:
        return [((0, h, 0, w), np.ones((h, w), np.float32))] if crops else [np.ones((h, w), np.float32)]
    grid = working_grid((0, 0, w, h))
    logits = np.stack([logits_on_grid(p, grid) for p in people])
    if rgb is not None:
        logits = along_edges(people, logits, rgb, grid)
    opaque = cv2.resize((alpha >= 0.5).astype(np.float32), (grid[0], grid[1]), interpolation=cv2.INTER_AREA)
    scale = h * w / float(grid[0] * grid[1])
    keep = np.ones(len(people), bool)
    # a person whose segmentation does not reach a cell (their logit at the floor: outside their region) has no
    # share of it; a cell no one's reaches goes to the nearest person's region. An equal share of such cells for
    # everyone put a little of every person into every other's pixels (issue 50 bug 1: with 16 people each
    # person's part spanned the whole group)
    reached = logits > -LOGIT_CLIP + 1e-3
    distance = _region_distance(people, grid)
    while True:
        z, seen = logits[keep], reached[keep]
        weights = np.exp(z - z.max(axis=0, keepdims=True)) * seen
        # the nearest among the people kept: a cell only a person dropped as hidden reached, nearest to that
        # person's region (the parts of one split share a region), went to no one and its shares were NaN
        nearest = np.arange(keep.sum())[:, None, None] == distance[keep].argmin(axis=0)[None]
        weights = np.where(seen.any(axis=0), weights, nearest)
        weights /= weights.sum(axis=0, keepdims=True)
        pixels = (weights * opaque).sum(axis=(1, 2)) * scale
        if keep.sum() == 1 or (pixels >= _MIN_PART).all():
            break
        keep[np.flatnonzero(keep)[int(np.argmin(pixels))]] = False
    # a share too small to see is none (each person's part then stays near them: their crop, not the group's)
    weights[weights < _SHARE_MIN] = 0
    weights /= weights.sum(axis=0, keepdims=True)
    # softened: people split from one segmentation (split_by_faces, along_edges) meet at a hard cut, which a change
    # of light would draw as a hard line; blurred shares still sum to 1
    sigma = _PART_SOFT * max(grid[0], grid[1])
    # blurred over the matte only (where no one's segmentation reaches, the background, every person has an equal
    # share: blurred in, 1/N of it spread into everyone's pixels, so with 16 people every person's part spanned
    # the whole group, and each was decomposed as small as the group's crop made them: issue 50 bug 1), and a
    # share under _SHARE_MIN again none
    present = cv2.resize(alpha, (grid[0], grid[1]), interpolation=cv2.INTER_AREA) > 0  # cells holding some matte
    inside = present.astype(np.float32)
    reach = cv2.GaussianBlur(inside, (0, 0), sigma)
    soft = np.stack([cv2.GaussianBlur(wk.astype(np.float32) * inside, (0, 0), sigma) for wk in weights])
    soft = np.where(reach > 0, soft / np.maximum(reach, 1e-30), np.float32(1 / len(weights)))
    soft[soft < _SHARE_MIN] = 0
    soft = (soft / soft.sum(axis=0, keepdims=True)).astype(np.float32)
    if crops:  # only where the matte is: the cells holding some of it and their neighbours (a pixel's taps)
        near = cv2.dilate(present.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
        return [_upsampled_crop(np.where(near, wk, np.float32(0)), (h, w)) for wk in soft]
    return [cv2.resize(wk, (w, h), interpolation=cv2.INTER_LINEAR) for wk in soft]


def along_edges(people: list[Person], logits: np.ndarray, rgb: np.ndarray, grid: Grid) -> np.ndarray:
    """``logits`` (N, gh, gw), the people's on ``grid`` (working_grid over ``rgb`` (H, W, 3) float32 RGB in [0, 1]),
    with the parts of each segmentation split by faces (:func:`split_by_faces`: by columns) cut again along the
    photo's own edges: the straight cut between each two faces side by side becomes the cheapest path from top to
    bottom between them (:func:`_cheapest_cut`), where a cell on a colour edge of the photo costs little to cut
    through, a cell off the segmentation nothing, and a cell far from the straight cut more. The straight cut ran
    through people wherever they overlap, which a change of light drew as a seam (two men hugging, the one in front
    lit, the other dark: a line down the middle of a shirt, p091 of people_masks); along an edge of the photo (a
    shirt against a dress, an arm against a chest) the change of light meets the photo's own line. Every face of the
    split is cut from its neighbours, the faces of people matted before too (their parts are not in ``people``:
    relight_rt.person.matting._layout.as_people)."""
    groups: dict[int, list[int]] = {}
    for i, p in enumerate(people):
        if p.whole is not None and p.face is not None and any(f is p.face for f in p.split):
            groups.setdefault(id(p.whole), []).append(i)
    todo = list(groups.values())
    if not todo:
        return logits
    gw, gh, kx, ky, bx, by = grid
    small = cv2.GaussianBlur(cv2.resize(rgb, (gw, gh), interpolation=cv2.INTER_AREA), (0, 0), _EDGE_SMOOTH)
    lab = cv2.cvtColor(small.astype(np.float32), cv2.COLOR_RGB2Lab)
    edge = colour_gradient(lab)  # CIE Lab distance (dE) per cell
    crossing = 1 / (1 + (edge / _EDGE_DE) ** 2)  # what cutting through a cell costs: little on an edge
    out = logits.copy()
    for idx in todo:
        first = people[idx[0]]
        whole = logits_on_grid(Person(first.region, first.whole, first.presence), grid)
        held = whole > 0
        faces = sorted(first.split, key=lambda f: f.box[0] + f.box[2])
        boxes = np.array([(kx * f.box[0] + bx, ky * f.box[1] + by, kx * f.box[2] + bx, ky * f.box[3] + by)
                          for f in faces])  # fmt: skip
        cols = np.arange(gw, dtype=np.float64)[None, :]
        owner = np.zeros((gh, gw), np.intp)
        for j in range(len(faces) - 1):
            cut = _cheapest_cut(np.where(held, crossing, 0), boxes[j : j + 2])
            owner += cols >= cut[:, None]
        for i in idx:
            j = next(k for k, f in enumerate(faces) if f is people[i].face)
            out[i] = np.where(owner == j, whole, np.float32(-LOGIT_CLIP))
    return out


def _cheapest_cut(cost: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """(gh,) float64: per row of ``cost`` (gh, gw), the column where the cut between two people side by side lies
    (cells left of it are the left one's), their faces' boxes ``boxes`` (2, 4) (x0, y0, x1, y1) in grid cells, left
    one first. The straight cut of :func:`split_by_faces` lies where the two faces' distances in their own widths are
    equal; the cut here is the path from the top row to the bottom, at most _CUT_SLOPE columns a row, between the
    two faces' centres and, in the rows of a face, off its middle (_FACE_CORE of its width to each side of its
    centre), that costs least: each cell its ``cost`` plus _CUT_STAY x (its distance from the straight cut / the
    faces' mean width)², each sideways column as much again."""
    (cl, cr), (wl, wr) = (boxes[:, 0] + boxes[:, 2]) / 2, np.maximum(boxes[:, 2] - boxes[:, 0], 1.0)
    straight = (cl * wr + cr * wl) / (wl + wr)
    lo, hi = max(int(np.ceil(cl)), 0), min(int(np.floor(cr)) + 1, cost.shape[1])
    if hi - lo < 2:
        return np.full(cost.shape[0], np.ceil(straight))
    xs = np.arange(lo, hi, dtype=np.float64)
    band = cost[:, lo:hi] + _CUT_STAY * ((xs - straight) / ((wl + wr) / 2)) ** 2
    rows = np.arange(cost.shape[0])[:, None]
    for (x0, y0, x1, y1), keep_left in zip(boxes, (True, False), strict=True):
        c, w = (x0 + x1) / 2, x1 - x0
        beside = xs[None, :] < c + _FACE_CORE * w if keep_left else xs[None, :] > c - _FACE_CORE * w
        band = np.where(beside & (rows >= y0) & (rows <= y1), _NO_CUT, band)
    n = hi - lo
    total = band[0].copy()
    came = np.zeros(band.shape, np.intp)
    moves = np.arange(-_CUT_SLOPE, _CUT_SLOPE + 1)
    for y in range(1, band.shape[0]):
        options = np.full((moves.size, n), np.inf)
        for m, dx in enumerate(moves):  # from column x + dx of the row above
            src = slice(max(dx, 0), n + min(dx, 0))
            dst = slice(max(-dx, 0), n - max(dx, 0))
            options[m, dst] = total[src] + abs(dx) * band[y, dst]
        best = options.argmin(axis=0)
        total = options[best, np.arange(n)] + band[y]
        came[y] = np.arange(n) + moves[best]
    path = np.empty(band.shape[0], np.intp)
    path[-1] = int(total.argmin())
    for y in range(band.shape[0] - 1, 0, -1):
        path[y - 1] = came[y, path[y]]
    return (path + lo).astype(np.float64)


def _region_distance(people: list[Person], grid: Grid) -> np.ndarray:
    """(N, gh, gw) float32: the distance in image pixels from each cell of ``grid`` (working_grid) to each person's
    region (0 inside it)."""
    gw, gh, kx, ky, bx, by = grid
    xs = (np.arange(gw) - bx) / kx  # cell centres in pixels
    ys = (np.arange(gh) - by) / ky
    dist = np.empty((len(people), gh, gw), np.float32)
    for k, p in enumerate(people):
        x0, y0, x1, y1 = p.region.box()
        dx = np.maximum(np.maximum(x0 - xs, xs - x1), 0)
        dy = np.maximum(np.maximum(y0 - ys, ys - y1), 0)
        dist[k] = np.hypot(dy[:, None], dx[None, :])
    return dist


def _linear_taps(start: int, stop: int, n_in: int, n_out: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Output pixels start..stop-1 of a linear resize from n_in to n_out samples (cv2.resize's INTER_LINEAR:
    centres aligned, the edge sample repeated): (i0, i1, f), each output = (1 - f) in[i0] + f in[i1]."""
    s = np.clip((np.arange(start, stop) + 0.5) * (n_in / n_out) - 0.5, 0, n_in - 1)
    i0 = np.floor(s).astype(np.intp)
    return i0, np.minimum(i0 + 1, n_in - 1), (s - i0).astype(np.float32)


def _upsampled_crop(grid: np.ndarray, size: tuple[int, int]) -> Crop:
    """``grid`` (gh, gw) resized linearly to ``size`` (h, w), computed only inside the box beyond which the result
    is 0: the pixels whose taps reach a non-zero cell."""
    (h, w), (gh, gw) = size, grid.shape
    rows, cols = np.flatnonzero(grid.any(axis=1)), np.flatnonzero(grid.any(axis=0))
    if rows.size == 0:
        return (0, 0, 0, 0), np.zeros((0, 0), np.float32)
    # an output pixel's taps lie within a cell of its centre: beyond one cell from the non-zero cells it is 0
    y0 = max(int(np.floor((rows[0] - 0.5) * h / gh - 0.5)), 0)
    y1 = min(int(np.ceil((rows[-1] + 1.5) * h / gh + 0.5)), h)
    x0 = max(int(np.floor((cols[0] - 0.5) * w / gw - 0.5)), 0)
    x1 = min(int(np.ceil((cols[-1] + 1.5) * w / gw + 0.5)), w)
    r0, r1, fy = _linear_taps(y0, y1, gh, h)
    c0, c1, fx = _linear_taps(x0, x1, gw, w)
    lines = grid[r0] * (1 - fy)[:, None] + grid[r1] * fy[:, None]
    out = lines[:, c0] * (1 - fx)
    out += lines[:, c1] * fx
    return (y0, y1, x0, x1), out.astype(np.float32, copy=False)


def rejoin(people: list[Person]) -> list[Person]:
    """People split from one segmentation (:func:`split_by_faces`) joined again for the matte: cut apart, each
    part's upsampled edge would open a seam between them."""
    out, seen = [], set()
    for p in people:
        if p.whole is None:
            out.append(p)
        elif id(p.whole) not in seen:
            seen.add(id(p.whole))
            out.append(Person(p.region, p.whole, p.presence, p.source))
    return out
