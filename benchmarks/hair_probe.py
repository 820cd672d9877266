"""A hair rule tried and dropped (hair25): the selfie graph's soft region round a head, kept where the colour is the
hair's. ../shared/realdata/people_masks, evaluation only.

    python benchmarks/hair_probe.py --sets A                     # the rule off / on, half A, ~1.5 min on 2 cores
    python benchmarks/hair_probe.py --sets A --grid seen=0.3,0.5 ratio=0.8,1.0 down=-0.5,0.25   # constants on half A
    python benchmarks/hair_probe.py --sets A,B,clip              # both halves and the clip, ~4 min
    python benchmarks/hair_probe.py --sets A,B,clip --grid reach=0.1,0.2 seen=0.3,0.5   # hair25's grids, ~6 min
    python benchmarks/hair_probe.py --sets A,B,clip --grid detail=0,0.3,0.6,0.9,1.2   # (detail 0: no detail test)

The rule lives in this file, not the product (docs/RESULTS.md "Real photos, broad sets", tried and dropped: with the
constants below, chosen on half A: A +0.00027, B +0.00022, the clip -0.00006; a halo's glow round a bald head taken).
The default matte misses crowns whose colour lies close to the backdrop's (a blonde crown before a golden wall): the
pose graph stops at the skull and the selfie graph framed on the person sees the hair softly. Round each face inside
the matte (a box ``side`` x its width to either side, ``up`` x its height above, down to ``down`` x its height below its
bottom; less the same box round any face outside the matte), a pixel outside the matte within ``reach`` x the face's
height of it that the selfie graph framed on the matte sees (>= ``seen``), joined to it, is hair where its CIELAB colour
lies nearer to the hair's nearest k-means centre (the matte's interior in the box outside the face's own box) than
``ratio`` x its distance to the backdrop's (the box outside the matte and the candidates grown by 3 px), and where its
fine detail is at least ``detail`` x the hair's median (a glow or a blurred backdrop is smooth). Kept pixels are
made opaque before the edge refinement (``refine_edges``, which then places the outline), so the things-behind step
after it still removes what it would.

The graphs' answers are memoised for the process (benchmarks/matte_ablation.py's ``memoise_graphs``): the rule off is
computed first and reproduces people_masks_eval.py's figures; every variant after it pays only its new graph runs. For
each variant: the mean IoU (alpha >= 0.5 against mask >= 0.5) per set and its change from the rule off, the photos
below the selfie graph (by any amount / by more than 0.01), and every image that moves by more than 0.01. Nothing of the
data is written.
"""

from __future__ import annotations

import argparse
import itertools
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

from matte_ablation import memoise_graphs, scores  # noqa: E402
from people_masks_eval import data_root, half_of, iou, items, read_mask, read_rgb, whole_image  # noqa: E402

from relight_rt.engine.session import Model  # noqa: E402
from relight_rt.image.regions import Region, grid_of_region  # noqa: E402
from relight_rt.person import matting as M  # noqa: E402
from relight_rt.person.face_detector import Face  # noqa: E402
from relight_rt.person.matting import _matter as PM  # noqa: E402
from relight_rt.person.matting._colours import centres, joined, nearest  # noqa: E402
from relight_rt.person.matting._detect import roi_prob  # noqa: E402

Box = tuple[int, int, int, int]  # (x0, y0, x1, y1) image pixels

HAIR_SEEN = 0.5  # the framed selfie graph's probability over a pixel that may be hair
HAIR_RATIO = 1.0  # ... nearer to the hair's colours than this x its distance to the backdrop's
HAIR_SIDE = 0.6  # the head's box: this x the face's width to either side of it ...
HAIR_UP = 0.8  # ... this x its height above it ...
HAIR_DOWN = -0.5  # ... down to this x its height below its bottom (-0.5: the face's middle)
HAIR_REACH = 0.1  # candidates at most this x the face's height from the matte (0: no limit)
HAIR_DETAIL = 0.6  # candidates with less fine detail than this x the hair's median are smooth backdrop (0: no test)
_GAP = 3  # px: the backdrop's samples start this far from the matte and the candidates
_MIN_SAMPLES = 20  # hair or backdrop samples below this: nothing decided

CONSTANTS = {
    "seen": "HAIR_SEEN",
    "ratio": "HAIR_RATIO",
    "side": "HAIR_SIDE",
    "up": "HAIR_UP",
    "down": "HAIR_DOWN",
    "reach": "HAIR_REACH",
    "detail": "HAIR_DETAIL",
}


def _box(face: Face, shape: tuple[int, int]) -> tuple[int, int, int, int]:
    x0, y0, x1, y1 = face.box
    fw, fh = x1 - x0, y1 - y0
    h, w = shape
    return (max(int(x0 - HAIR_SIDE * fw), 0), max(int(y0 - HAIR_UP * fh), 0),
            min(int(np.ceil(x1 + HAIR_SIDE * fw)), w), min(int(np.ceil(y1 + HAIR_DOWN * fh)), h))  # fmt: skip


def _inside(face: Face, mine: np.ndarray) -> bool:
    h, w = mine.shape
    cx, cy = int((face.box[0] + face.box[2]) / 2), int((face.box[1] + face.box[3]) / 2)
    return 0 <= cx < w and 0 <= cy < h and bool(mine[cy, cx])


def hair_part(lab: np.ndarray, mine: np.ndarray, seen: np.ndarray, face_box: tuple[float, float, float, float],
              apart: np.ndarray) -> np.ndarray:  # fmt: skip
    """The hair kept in one head's box (module docstring), all arrays the box's own.

    Args:
        lab: (h, w, 3) float32 L*a*b* of the box.
        mine: (h, w) bool, the matte (alpha >= 0.5).
        seen: (h, w) float32, the framed selfie graph's probability.
        face_box: the face's box in the box's pixels (x0, y0, x1, y1).
        apart: (h, w) bool, pixels that are someone else's head (never candidates).

    Returns:
        (h, w) bool: the pixels outside ``mine`` taken as hair, joined to it.
    """
    cand = (seen >= HAIR_SEEN) & ~mine & ~apart
    if HAIR_REACH > 0:  # a layer on the head, not a patch far off it
        gap = cv2.distanceTransform((~mine).astype(np.uint8), cv2.DIST_L2, 3)
        cand &= gap <= HAIR_REACH * (face_box[3] - face_box[1])
    cand = joined(cand, mine)
    if not cand.any():
        return cand
    h, w = mine.shape
    x0, y0, x1, y1 = face_box
    face = np.zeros((h, w), bool)
    face[max(int(y0), 0) : max(int(np.ceil(y1)), 0), max(int(x0), 0) : max(int(np.ceil(x1)), 0)] = True
    hair = cv2.erode(mine.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool) & ~face
    near = cv2.dilate((mine | cand).astype(np.uint8), np.ones((2 * _GAP + 1, 2 * _GAP + 1), np.uint8)).astype(bool)
    backdrop = ~near & ~apart
    if hair.sum() < _MIN_SAMPLES or backdrop.sum() < _MIN_SAMPLES:
        return np.zeros_like(cand)
    x = lab[cand]
    ok = nearest(x, centres(lab[hair]))[0] < HAIR_RATIO * nearest(x, centres(lab[backdrop]))[0]
    if HAIR_DETAIL > 0:  # hair is fine texture; a glow or a blurred backdrop is smooth
        lum = lab[..., 0]
        detail = cv2.blur(np.abs(lum - cv2.GaussianBlur(lum, (0, 0), 1.0)), (5, 5))
        ok &= detail[cand] >= HAIR_DETAIL * float(np.median(detail[hair]))
    part = np.zeros_like(cand)
    part[cand] = ok
    return joined(part, mine)


def framed_seen(roi: Model, rgb: np.ndarray, mine: np.ndarray) -> Callable[[Box], np.ndarray]:
    """The selfie graph framed on the matte ``mine`` (ROI_SCALE x its box; one run, ~5 ms, made when first asked):
    a function of an image box (x0, y0, x1, y1) giving the graph's (y1 - y0, x1 - x0) float32 probability there."""
    ys, xs = np.nonzero(mine)
    region = Region.around(float(xs.min()), float(ys.min()), float(xs.max() + 1), float(ys.max() + 1))
    prob: list[np.ndarray] = []

    def seen(box: Box) -> np.ndarray:
        if not prob:
            prob.append(roi_prob(roi, rgb, region).astype(np.float32))
        k, bx, by = grid_of_region(region)
        x0, y0, x1, y1 = box
        to_canvas = np.array([[k, 0.0, bx + k * x0], [0.0, k, by + k * y0]], np.float64)
        return cv2.warpAffine(prob[0], to_canvas, (x1 - x0, y1 - y0), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                              borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)  # fmt: skip

    return seen


def with_hair(rgb: np.ndarray, alpha: np.ndarray, faces: Sequence[Face],
              seen: Callable[[Box], np.ndarray]) -> np.ndarray:  # fmt: skip
    """``alpha`` (H, W) float32 with the hair it cuts off round each face inside it made opaque (module docstring).

    Args:
        rgb: (H, W, 3) float32 image, 0-1.
        alpha: (H, W) float32 matte, 0-1 (not modified).
        faces: the face detector's faces on the whole photo (image pixels).
        seen: the selfie graph framed on the matte, a function of an image box (:func:`framed_seen`).

    Returns:
        A new (H, W) float32 alpha, or ``alpha`` itself when nothing is added.
    """
    mine = alpha >= 0.5
    heads = [f for f in faces if _inside(f, mine)]
    if not heads:
        return alpha
    others = np.zeros(mine.shape, bool)
    for f in faces:
        if f not in heads:
            bx0, by0, bx1, by1 = _box(f, mine.shape)
            others[by0:by1, bx0:bx1] = True
    add = np.zeros(mine.shape, bool)
    for f in heads:
        bx0, by0, bx1, by1 = _box(f, mine.shape)
        if bx1 <= bx0 or by1 <= by0:
            continue
        box = (slice(by0, by1), slice(bx0, bx1))
        lab = cv2.cvtColor(np.ascontiguousarray(rgb[box], dtype=np.float32), cv2.COLOR_RGB2Lab)
        fx0, fy0, fx1, fy1 = f.box
        add[box] |= hair_part(
            lab, mine[box], seen((bx0, by0, bx1, by1)), (fx0 - bx0, fy0 - by0, fx1 - bx0, fy1 - by0), others[box]
        )
    if not add.any():
        return alpha
    out = alpha.copy()
    out[add] = 1.0
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sets", default="A", help="comma list of A, B, clip")
    ap.add_argument("--grid", nargs="*", default=[], help="NAME=v1,v2,... (names: " + ", ".join(CONSTANTS) + ")")
    args = ap.parse_args(argv)
    pairs = [g.split("=", 1) for g in args.grid]
    if any(len(kv) != 2 or kv[0] not in CONSTANTS for kv in pairs):
        ap.error(f"--grid: NAME=v1,v2,... with NAME one of {', '.join(CONSTANTS)}; got {args.grid}")
    grid = [(CONSTANTS[k], [float(v) for v in vs.split(",")]) for k, vs in pairs]
    root = data_root()
    photos = items(root, "photos")
    halves = half_of([n for n, _, _ in photos])
    sets = [s for s in args.sets.split(",") if s]
    listed = {s: items(root, "clip") if s == "clip" else [p for p in photos if halves[p[0]] == s] for s in sets}
    memoise_graphs()
    matter = M.PersonMatter(person="largest")
    selfie = {}
    for n, p, m in (x for s in sets if s != "clip" for x in listed[s]):
        rgb = read_rgb(p)
        selfie[n] = iou(whole_image(matter.roi, rgb, "segmentation", logits=False) >= 0.5, read_mask(m, rgb.shape[:2]))
    refine = PM.refine_edges

    def hair_then_refine(rgb: np.ndarray, alpha: np.ndarray) -> np.ndarray:
        if (alpha >= 0.5).any():  # (PersonMatter.alpha calls refine_edges only with people, person="largest" here)
            alpha = with_hair(rgb, alpha, matter.find_faces(rgb), framed_seen(matter.roi, rgb, alpha >= 0.5))
        return refine(rgb, alpha)

    t = time.perf_counter()
    off = {s: scores(matter, listed[s]) for s in sets}
    PM.refine_edges = hair_then_refine

    def line(name: str, got: dict[str, dict[str, float]]) -> str:
        out = f"{name:28s}"
        for s in sets:
            d = float(np.mean(list(got[s].values()))) - float(np.mean(list(off[s].values())))
            out += f" {s} {np.mean(list(got[s].values())):.5f} ({d:+.5f})"
            if s != "clip":
                below = [n for n in got[s] if got[s][n] < selfie[n] - 1e-9]
                out += f" below {len(below)}/{sum(got[s][n] < selfie[n] - 0.01 for n in below)}"
        moved = sorted((got[s][n] - off[s][n], n) for s in sets for n in got[s] if abs(got[s][n] - off[s][n]) > 0.01)
        return out + "  moved > 0.01: " + ", ".join(f"{n} {v:+.3f}" for v, n in moved)

    print(line("rule off", off) + f"  [{time.perf_counter() - t:.0f} s]", flush=True)
    for values in itertools.product(*[vs for _, vs in grid]) if grid else [()]:
        saved = {name: globals()[name] for name, _ in grid}
        for (name, _), v in zip(grid, values, strict=True):
            globals()[name] = v
        t = time.perf_counter()
        got = {s: scores(matter, listed[s]) for s in sets}
        for name, v in saved.items():
            globals()[name] = v
        tag = " ".join(f"{k}={v}" for (k, _), v in zip(grid, values, strict=True)) or "rule on"
        print(line(tag, got) + f"  [{time.perf_counter() - t:.0f} s]", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
