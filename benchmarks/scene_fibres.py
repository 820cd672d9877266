"""Where a hard mask's outline is hair: a back light's fibre share on the head's outline against the body's, on real
photos with binary masks and on the benchmark's renders; the cue tried for issue 49 (scene12) and not shipped.

    python benchmarks/scene_fibres.py --photos ../shared/realdata/people_masks/photos \\
        --renders runs/scene/photos [--auto-matte] [--out docs/bench_results/scene_fibres_49.json]

A back light glows through hair and only grazes smooth cloth. ``relight_rt.apps.scene_rim.fibre_share`` (shipped)
reads that from the matte's softness, so a binary mask gives hair the coat's thin line. The cue tried here reads it
from the photo instead (``photo_fibre_share``): across the matte's outline, each pixel's linear colour as a mix t of
the two sides' local colours (the rings one to two band widths inside and outside), in transition where t is within
an edge's 10-90 % rise; the transition's width per pixel of outline against the outline's own lower quartile (at
least ``HARD_PX``), full fibres from ``FIBRE_RATIO`` times it, as the shipped rule does with the matte's fractional
pixels. Chosen, not fitted; read where the two sides differ by at least ``PHOTO_CONTRAST`` (else the matte's).

With no truth of where hair is, the face says where it mostly is: on each photo with one face (the bundled face
graph), the **head's outline** is the outline above the face's middle (x within half a face of its box, y from a
face above its top to half a face below it: hair, or a scalp), the **body's** the outline more than a face below its
chin (shoulders, sleeves, trousers; arms' skin too). A cue that finds hair gives the head more share than the body.
Also tried: the photo's variation *along* the outline (strands cross it, a smooth or defocused edge varies only
across it): the tangential gradient energy in the band, less the two sides' own, over the normal energy there
(``texture``), alone and times the width's (``both``). ``--auto-matte``: the same on the bundled matter's soft matte
(no mask): its own softness (``auto``, shipped) and the photo's cue on its outline (``auto_photo``).

On the renders (hard masks, no fibres in their truth: black backdrop, no strands) every share is a false fibre: the
mean share on their outlines is what the benchmark's rim would pay. The photos are for measuring only: nothing is
written but numbers.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from relight_rt.apps import scene_rim  # noqa: E402
from relight_rt.apps.scene_rim import FIBRE_RATIO, HARD_PX, wide_blur  # noqa: E402
from relight_rt.image.color import srgb8_to_linear  # noqa: E402

PHOTO_RISE = (0.1, 0.9)  # in transition: the mix of the two sides within an edge's 10-90 % rise
PHOTO_CONTRAST = 0.05  # the photo tells where its two sides differ by at least this (linear RGB, Euclidean)
PHOTO_TOLD = 0.1  # ... on at least this share of the outline (else the matte's reading)
PHOTO_BAND = 4  # read within at least this many pixels of the outline (else 2 % of the person's height)
PHOTO_WORK = 640  # read on a copy where the person is at most this many rows tall
WIDTH_REACH = 0.02  # scene_rim's: an edge's width is averaged over this share of the person's height
RISE = (0.07, 0.5)  # texture: the share rises from tan²(15°) (a mask drawn 15° off the edge leaks that much) to 1/2


def outline_of(a: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """(inside: alpha >= 1/2 as uint8, its outline (bool), the reach σ along it: 2 % of the person's height)."""
    inside = (a >= 0.5).astype(np.uint8)
    line = (inside - cv2.erode(inside, np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], np.uint8),
                               borderType=cv2.BORDER_REPLICATE)) > 0  # fmt: skip
    rows = np.flatnonzero(inside.any(1))
    return inside, line, max(2.0, WIDTH_REACH * float(rows[-1] + 1 - rows[0])) if rows.size else 2.0


def local_mean(lin: np.ndarray, ring: np.ndarray, reach: float, at: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The mean colour of ``lin`` over ``ring`` under a Gaussian of ``reach`` px at the pixels ``at`` ((N, 3)) and
    whether the ring reaches each: on copies shrunk to ~4 px per ``reach``, read back bilinearly."""
    h, w = ring.shape
    f = max(1, int(reach // 4))
    r = ring.astype(np.float32)
    parts = [lin * r[..., None], r]
    if f > 1:
        size = (max(1, -(-w // f)), max(1, -(-h // f)))
        parts = [cv2.resize(x, size, interpolation=cv2.INTER_AREA) for x in parts]
    small = np.dstack([cv2.GaussianBlur(x, (0, 0), reach / f, borderType=cv2.BORDER_REFLECT) for x in parts])
    ys, xs = np.nonzero(at)
    n, cols = ys.size, 4096  # remap's maps stay under 32767 a side
    mx = np.pad((xs + 0.5) / f - 0.5, (0, -n % cols)).astype(np.float32).reshape(-1, cols)
    my = np.pad((ys + 0.5) / f - 0.5, (0, -n % cols)).astype(np.float32).reshape(-1, cols)
    vals = cv2.remap(small, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE).reshape(-1, 4)[:n]
    return vals[:, :3] / np.maximum(vals[:, 3:], 1e-6), vals[:, 3] > 1e-3


def photo_transition(lin: np.ndarray, inside: np.ndarray, sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """(where the photo is in transition across the outline, where it tells): module docstring."""
    band = max(PHOTO_BAND, int(math.ceil(sigma)))
    reach = max(sigma, float(band))
    d_in = cv2.distanceTransform(inside, cv2.DIST_L2, 3)
    d_out = cv2.distanceTransform(1 - inside, cv2.DIST_L2, 3)
    near = ((inside > 0) & (d_in <= band)) | ((inside == 0) & (d_out <= band))
    rings = ((inside > 0) & (d_in > band) & (d_in <= 2 * band), (inside == 0) & (d_out > band) & (d_out <= 2 * band))
    (c_in, has_in), (c_out, has_out) = (local_mean(lin, ring, reach, near) for ring in rings)
    step = c_in - c_out
    size2 = (step * step).sum(1)
    told_at = has_in & has_out & (size2 >= PHOTO_CONTRAST**2)
    t = ((lin[near] - c_out) * step).sum(1) / np.maximum(size2, 1e-12)
    told, seen = np.zeros(near.shape, bool), np.zeros(near.shape, bool)
    told[near] = told_at
    seen[near] = told_at & (t > PHOTO_RISE[0]) & (t < PHOTO_RISE[1])
    return seen, told


def photo_fibre_share(alpha: np.ndarray, lin: np.ndarray) -> np.ndarray:
    """The tried cue (module docstring): scene_rim.fibre_share's rule on the photo's transition, read on a copy where
    the person is at most PHOTO_WORK rows tall."""
    a = np.clip(np.asarray(alpha, np.float32), 0, 1)
    inside, line, sigma = outline_of(a)
    if not line.any():
        return np.zeros(a.shape, np.float32)
    h, w = a.shape
    k = max(1, math.ceil(sigma / (WIDTH_REACH * PHOTO_WORK)))
    if k == 1:
        seen, told = photo_transition(lin, inside, sigma)
    else:
        size = (max(2, round(w / k)), max(2, round(h / k)))
        small_in = (cv2.resize(a, size, interpolation=cv2.INTER_AREA) >= 0.5).astype(np.uint8)
        answers = photo_transition(cv2.resize(lin, size, interpolation=cv2.INTER_AREA), small_in, max(2.0, sigma / k))
        seen, told = (cv2.resize(x.astype(np.uint8), (w, h), interpolation=cv2.INTER_NEAREST) > 0 for x in answers)
    moving = seen if np.count_nonzero(told[line]) >= PHOTO_TOLD * np.count_nonzero(line) else (a > 0.02) & (a < 0.98)
    along = wide_blur(line.astype(np.float32), sigma)
    near = along > 1e-3 * float(along.max())
    width = np.zeros(a.shape, np.float32)
    width[near] = wide_blur(moving.astype(np.float32), sigma)[near] / along[near]
    hard = max(HARD_PX, float(np.percentile(width[line], 25)))
    out = np.zeros(a.shape, np.float32)
    out[near] = np.clip((width[near] / hard - 1) / (FIBRE_RATIO - 1), 0, 1)
    return out


def outline(alpha: np.ndarray) -> np.ndarray:
    inside = (alpha >= 0.5).astype(np.uint8)
    return (inside - cv2.erode(inside, np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], np.uint8),
                               borderType=cv2.BORDER_REPLICATE)) > 0  # fmt: skip


def texture_share(lin: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """The tried cue: strands cross the outline, so the photo varies along it as much as across it."""
    inside = (alpha >= 0.5).astype(np.uint8)
    rows = np.flatnonzero(inside.any(1))
    sigma = max(2.0, 0.02 * float(rows[-1] + 1 - rows[0])) if rows.size else 2.0
    band = max(PHOTO_BAND, int(math.ceil(sigma)))
    d_in = cv2.distanceTransform(inside, cv2.DIST_L2, 3)
    d_out = cv2.distanceTransform(1 - inside, cv2.DIST_L2, 3)
    near = ((inside > 0) & (d_in <= band)) | ((inside == 0) & (d_out <= band))
    sides = ((inside > 0) & (d_in > band) & (d_in <= 2 * band)) | ((inside == 0) & (d_out > band) & (d_out <= 2 * band))
    soft = cv2.GaussianBlur(inside.astype(np.float32), (0, 0), band)
    nx, ny = cv2.Sobel(soft, cv2.CV_32F, 1, 0), cv2.Sobel(soft, cv2.CV_32F, 0, 1)
    nn = np.maximum(np.hypot(nx, ny), 1e-9)
    nx, ny = nx / nn, ny / nn
    img = np.sqrt(np.maximum(lin, 0))
    gx = np.stack([cv2.Sobel(img[..., c], cv2.CV_32F, 1, 0) for c in range(3)], 2)
    gy = np.stack([cv2.Sobel(img[..., c], cv2.CV_32F, 0, 1) for c in range(3)], 2)
    en = ((gx * nx[..., None] + gy * ny[..., None]) ** 2).sum(2)
    et = ((-gx * ny[..., None] + gy * nx[..., None]) ** 2).sum(2)

    def mean(v, where):
        return wide_blur(v * where, sigma) / np.maximum(wide_blur(where.astype(np.float32), sigma), 1e-6)

    rho = np.maximum(mean(et, near) - mean(et, sides), 0) / np.maximum(mean(en, near), 1e-9)
    return np.clip((rho - RISE[0]) / (RISE[1] - RISE[0]), 0, 1).astype(np.float32)


def cues(lin: np.ndarray, alpha: np.ndarray) -> dict[str, np.ndarray]:
    width = photo_fibre_share(alpha, lin)
    texture = texture_share(lin, alpha)
    return {"matte": scene_rim.fibre_share(alpha), "width": width, "texture": texture, "both": width * texture}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--photos", type=Path, required=True, help="NAME.jpg with NAME_mask.png (binary)")
    ap.add_argument("--renders", type=Path, default=None, help="export render-photos output (*_photo.png, *_mask.png)")
    ap.add_argument("--max-renders", type=int, default=200)
    ap.add_argument("--auto-matte", action="store_true",
                    help="also on the bundled matter's soft matte of each photo (no mask): its own reading "
                    "(auto: fibre_share without the photo, as before) and with the photo (auto_photo); ~1 s a "
                    "photo")  # fmt: skip
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args(argv)
    from relight_rt.person.matting import as_rgb, shared_matter

    matter = shared_matter(device="cpu")
    per_photo = []
    for mask_path in sorted(args.photos.glob("*_mask.png")):
        photo_path = mask_path.with_name(mask_path.name.replace("_mask.png", ".jpg"))
        bgr, m = cv2.imread(str(photo_path)), cv2.imread(str(mask_path), cv2.IMREAD_GRAYSCALE)
        if bgr is None or m is None or bgr.shape[:2] != m.shape:
            continue
        rgb8 = np.ascontiguousarray(bgr[..., ::-1])
        faces = matter.find_faces(as_rgb(rgb8, photo_path.name))
        if len(faces) != 1:
            continue
        x0, y0, x1, y1 = faces[0].box
        s, sw = y1 - y0, x1 - x0
        alpha = m.astype(np.float32) / 255
        line = outline(alpha)
        ys, xs = np.nonzero(line)
        head = (xs >= x0 - 0.5 * sw) & (xs <= x1 + 0.5 * sw) & (ys >= y0 - s) & (ys <= y0 + 0.5 * s)
        bodyp = ys > y1 + s
        if head.sum() < 5 or bodyp.sum() < 5:
            continue
        lin = srgb8_to_linear(rgb8)
        shares = cues(lin, alpha)
        if args.auto_matte:  # its own outline: the head and body regions as above, on it
            soft = matter(rgb8, photo_path.name)
            sl = outline(soft)
            sy, sx = np.nonzero(sl)
            sh = (sx >= x0 - 0.5 * sw) & (sx <= x1 + 0.5 * sw) & (sy >= y0 - s) & (sy <= y0 + 0.5 * s)
            sb = sy > y1 + s
            shares_auto = {}
            for k, f in (("auto", scene_rim.fibre_share(soft)), ("auto_photo", photo_fibre_share(soft, lin))):
                ok = sh.sum() >= 5 and sb.sum() >= 5
                shares_auto[k] = (float(f[sy[sh], sx[sh]].mean()), float(f[sy[sb], sx[sb]].mean())) if ok else None
        per_photo.append({"name": photo_path.stem})
        for k, v in shares.items():
            per_photo[-1][k] = (float(v[ys[head], xs[head]].mean()), float(v[ys[bodyp], xs[bodyp]].mean()))
        if args.auto_matte:
            per_photo[-1].update(shares_auto)
    renders = {}
    if args.renders is not None:
        found = sorted(args.renders.glob("*_photo.png"))[:: max(1, len(sorted(args.renders.glob("*_photo.png")))
                                                                  // args.max_renders)][: args.max_renders]  # fmt: skip
        sums: dict[str, list[float]] = {}
        for p in found:
            rgb8 = np.ascontiguousarray(cv2.imread(str(p))[..., ::-1])
            alpha = cv2.imread(str(p).replace("_photo.png", "_mask.png"), cv2.IMREAD_GRAYSCALE).astype(np.float32) / 255
            line = outline(alpha)
            for k, v in cues(srgb8_to_linear(rgb8), alpha).items():
                sums.setdefault(k, []).append(float(v[line].mean()))
        renders = {k: {"n": len(v), "mean_share": statistics.fmean(v)} for k, v in sums.items()}
    summary = {}
    for k in ("matte", "width", "texture", "both") + (("auto", "auto_photo") if args.auto_matte else ()):
        heads = [r[k][0] for r in per_photo if r[k] is not None]
        bodies = [r[k][1] for r in per_photo if r[k] is not None]
        summary[k] = {
            "photos": len(heads),
            "head_median": statistics.median(heads) if heads else None,
            "body_median": statistics.median(bodies) if bodies else None,
            "head_mean": statistics.fmean(heads) if heads else None,
            "body_mean": statistics.fmean(bodies) if bodies else None,
            "head_over_body": sum(h > b + 0.1 for h, b in zip(heads, bodies, strict=True)) / max(len(heads), 1),
            "body_over_head": sum(b > h + 0.1 for h, b in zip(heads, bodies, strict=True)) / max(len(heads), 1),
            "renders_mean_share": renders.get(k, {}).get("mean_share"),
        }
        s = summary[k]
        print(f"{k:8s} photos {s['photos']:3d}  head {s['head_median']:.2f} / body {s['body_median']:.2f} (medians; "
              f"means {s['head_mean']:.2f} / {s['body_mean']:.2f})  head > body {100 * s['head_over_body']:3.0f} %  "
              f"body > head {100 * s['body_over_head']:3.0f} %  renders "
              f"{'-' if s['renders_mean_share'] is None else format(s['renders_mean_share'], '.3f')}")
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps({"summary": summary, "renders": renders, "photos": per_photo}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
