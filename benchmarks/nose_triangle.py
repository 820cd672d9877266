"""The nose's cast-shadow triangle when a side-lit face is de-lit (issue 48, faces23): how dark it comes out against the
real frontal photo, on every de-light pair of Extended Yale B (../shared/realdata/yale; evaluation only).

    python benchmarks/nose_triangle.py [--yale ../shared/realdata/yale] [--subjects yaleB02 ...] [--half even|odd]
        [--out DIR]

benchmarks/yale_eval.py's de-light pairs (a photo lit from |azimuth| 50 or 70, elevation 0, relit to the frontal lamp,
the same ellipse mask, lamp and exposure). The region: on the photo's dark side, the cheek beside the nose (the convex
hull of the real frontal photo's face mesh points down the nose's ridge and across that cheek to below the eye and the
nose's wing, ``TRIANGLE``), where the side-lit photo is in hard shadow (its luminance, linear, under ``HARD`` of the
ellipse's 90th percentile). The error: log of ours over the real frontal photo's luminance (Rec. 709 of linearised
sRGB, + 1e-3), less its median over the ellipse (the exposure's level is not the fill's), averaged over the region:
negative where the triangle stays too dark. Printed per pair, and the mean by |azimuth| and side; with the fill's
weight there (the share of the change added, not multiplied: ``ShadowFill.shadow_weight``), whether a face mesh was
found, and the fill's albedo there against the lit cheek's (``lift``: the fill's albedo over stage 1's).

``--half even`` / ``odd``: the subjects at even / odd positions of the sorted list (choose on one, check the other).
``--out DIR``: a PNG per pair (relit | real frontal | input, 3x, the region outlined) for looking at them at 100 %.
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import cv2
import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from _shared import shared_path  # noqa: E402
from real_photos import luminance  # noqa: E402
from yale_eval import EPS, find_file, lamp, read_frontal, read_grey  # noqa: E402  (puts this checkout first)

from relight_rt import Relighter, RuntimeConfig  # noqa: E402
from relight_rt.person.face_mesh import FaceMesh  # noqa: E402

# MediaPipe face mesh points: the nose's ridge (shared), then the cheek beside it on the image's right (the subject's
# left) and, mirrored, on the image's left
RIDGE = (168, 6, 197, 195, 5, 4, 1)
TRIANGLE = {"right": RIDGE + (358, 423, 425, 280, 347), "left": RIDGE + (129, 203, 205, 50, 118)}
HARD = 0.12  # the side-lit photo's hard shadow: luminance under this share of the ellipse's 90th percentile
AZIMUTHS = (50, 70)


def region(points: np.ndarray, side: str, source: np.ndarray, face: np.ndarray) -> np.ndarray:
    """(H, W) bool: the cheek beside the nose on ``side`` (``TRIANGLE``) where ``source`` is in hard shadow."""
    hull = np.zeros(face.shape, np.uint8)
    xy = np.asarray(points)[list(TRIANGLE[side]), :2].astype(np.float32)
    cv2.fillConvexPoly(hull, np.round(cv2.convexHull(xy) * 16).astype(np.int32), 1, shift=4)
    lum = luminance(source)
    return (hull > 0) & (face > 0.5) & (lum < HARD * np.percentile(lum[face > 0.5], 90))


def triangle_error(relit: np.ndarray, truth: np.ndarray, face: np.ndarray, where: np.ndarray) -> float:
    """Mean over ``where`` of log(ours / truth's luminance) less its median over the face."""
    err = np.log(luminance(relit) + EPS) - np.log(luminance(truth) + EPS)
    return float(err[where].mean() - np.median(err[face > 0.5]))


def internals(relighter: Relighter, dec, where: np.ndarray) -> dict:
    """The fill's weight and albedo lift (its chroma's luminance: the fill's albedo over stage 1's) over ``where``."""
    factor = relighter._factor
    shadow = factor.fill.shadow_weight(dec)
    out = {"mesh": bool(dec.face_meshes)}
    if shadow is None:
        return {**out, "w": 0.0, "lift": 1.0}
    own = factor.own(dec, with_residual=False)
    y0, y1, x0, x1 = own["window"]
    full = np.zeros(dec.network_mask.shape + (2,), np.float32)
    full[y0:y1, x0:x1, 0] = shadow[0]
    full[y0:y1, x0:x1, 1] = shadow[1] @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    back = dec.to_input(full)
    return {**out, "w": float(back[..., 0][where].mean()), "lift": float(back[..., 1][where].mean())}


def strip(relit: np.ndarray, truth: np.ndarray, source: np.ndarray, where: np.ndarray) -> np.ndarray:
    """(H x 3, 3 W x 3, 3) uint8 RGB: relit | truth | source, 3x, the region outlined in red."""
    tiles = []
    line = cv2.morphologyEx(where.astype(np.uint8), cv2.MORPH_GRADIENT, np.ones((3, 3), np.uint8)) > 0
    for img in (relit, truth, source):
        t = (np.clip(img, 0, 1) * 255 + 0.5).astype(np.uint8)
        t = cv2.resize(t, None, fx=3, fy=3, interpolation=cv2.INTER_NEAREST)
        edge = cv2.resize(line.astype(np.uint8), None, fx=3, fy=3, interpolation=cv2.INTER_NEAREST) > 0
        t[edge] = (t[edge] * 0.5 + np.array([127, 0, 0])).astype(np.uint8)
        tiles.append(t)
    return np.hstack(tiles)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--yale", type=Path, default=shared_path("realdata", "yale"))
    p.add_argument("--subjects", nargs="*", default=None)
    p.add_argument("--half", choices=("even", "odd"), default=None)
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args(argv)
    if not (args.yale / "lights.csv").is_file():
        print(f"no Yale data at {args.yale}", file=sys.stderr)
        return 2
    with open(args.yale / "lights.csv") as f:
        subjects = sorted({row["subject"] for row in csv.DictReader(f)})
    if args.half is not None:
        subjects = subjects[0 if args.half == "even" else 1 :: 2]
    subjects = args.subjects or subjects
    relighter = Relighter(RuntimeConfig(device="cpu"))
    mesh = FaceMesh(relighter.models_dir)
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
    rows = []
    for subject in subjects:
        found = read_frontal(args.yale, subject, mesh)
        if found is None:
            continue
        frontal, face, points = found
        if points is None:
            print(f"{subject}: no face mesh on the frontal photo: skipped", file=sys.stderr)
            continue
        for a in AZIMUTHS:
            for az in (-a, a):
                path = find_file(args.yale, subject, az)
                if not path.is_file():
                    continue
                source = read_grey(path)
                side = "right" if az > 0 else "left"  # a positive azimuth lights the image's left
                where = region(points, side, source, face)
                if where.sum() < 20:
                    continue
                dec = relighter.decompose(source, face)
                relit = relighter.relight(dec, lamp(0))
                row = {"subject": subject, "az": az, "px": int(where.sum()),
                       "error": triangle_error(relit, frontal, face, where), **internals(relighter, dec, where)}
                rows.append(row)
                print(f"{subject} {az:+d}: error {row['error']:+.3f} over {row['px']} px, fill weight "
                      f"{row['w']:.2f}, lift {row['lift']:.2f}, mesh {'yes' if row['mesh'] else 'no'}", flush=True)
                if args.out is not None:
                    cv2.imwrite(str(args.out / f"{subject}_{az:+d}.png"),
                                cv2.cvtColor(strip(relit, frontal, source, where), cv2.COLOR_RGB2BGR))
    for a in AZIMUTHS:
        for sign in (-1, 1):
            sel = [r["error"] for r in rows if r["az"] == sign * a]
            if sel:
                print(f"az {sign * a:+d}: mean error {np.mean(sel):+.3f}, worst {min(sel):+.3f} ({len(sel)} pairs)")
    if rows:
        errs = np.array([r["error"] for r in rows])
        print(f"all {len(rows)} pairs: mean {errs.mean():+.3f}, mean |error| {np.abs(errs).mean():.3f}, "
              f"under -0.3: {int((errs < -0.3).sum())}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
