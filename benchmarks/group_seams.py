"""Seams between people relit one by one (`relight --person all`): where two people's shares of the matte meet, does
the relit photo show a step that the photo does not have?

    PYTHONPATH=$PWD python benchmarks/group_seams.py --out /tmp/seams [--people ../shared/realdata/people_masks] \
        [--photos p091,p272,...] [--extra /tmp/relight_rt_people/group_t1.jpg]

Photos: people_masks photos (../shared/realdata: evaluation only) p091 (two men hugging), p272 (three people on a
sofa), p273, p194, p209, p238, p240, and ``--extra`` photos (group_t1.jpg of benchmarks/people_photos.py's cache).
Each is relit with RuntimeConfig(matting="all") (each person on their own) and matting="auto" (the default), under
the white side lamps LEFT and RIGHT of benchmarks/real_photos.py and the preset campfire.

The line: pixel pairs (horizontal and vertical neighbours), both opaque (matte >= 0.5), whose largest share belongs
to different people. Across it, at ``R`` = 1.5 % of the photo's longer side to each side along the pair's axis (both
ends opaque): the step in 8-bit luminance (Rec. 709 weights of the display values) of the relit photo minus that
of the photo itself, at 0 when the photo's is larger. Per light: mean and p95 over the line's pixels of a photo,
and the mean of those over the photos. The same pixels relit with matting="auto" (one body, no split there) are the
line's reference ("auto" column). People relit on their own differ across their boundary however it runs (one lit,
the other not): where the line follows an edge of the photo (a shirt against a dress) that is two people, where it
crosses one surface (the photo's own step under ``FLAT`` levels in every channel: a shirt cut in two) it is a seam.
So also: "flat", the share of the line's pixels on one surface, and "seam", the mean over the line's pixels of the
step there (0 on the pixels at an edge): what a seam shows, in levels a line pixel ("seam_luma": the same with an
edge of luminance only, which calls a change of colour at equal brightness one surface).

Writes OUT/NAME.png (input | LEFT | RIGHT | campfire, rows "all" and "auto", the line drawn in red on the
input of the "all" row), OUT/NAME_shares.png (each person's share in its own colour over the photo) and
OUT/seams.json; prints the table and the seconds `--person all` took per photo (decompose + three lights).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import cv2
import numpy as np

# real_photos puts this checkout (and benchmarks/) first on sys.path: the relight_rt imported below is this one
from real_photos import LEFT, RIGHT

# isort: split
from _shared import shared_path

import relight_rt
from relight_rt import RuntimeConfig
from relight_rt.image.io import read_image

PHOTOS = ("p091", "p272", "p273", "p194", "p209", "p238", "p240")
LIGHTS = {"LEFT": LEFT, "RIGHT": RIGHT, "campfire": "campfire"}
REACH = 0.015  # of the photo's longer side: how far to each side of the line the step is read
FLAT = 8.0  # 8-bit levels: the photo's own step across the line under this: the line crosses no edge there
_COLOURS = np.array([[230, 60, 60], [60, 200, 60], [60, 90, 240], [230, 200, 40], [200, 60, 220], [40, 210, 220]])


def display_luma(rgb: np.ndarray) -> np.ndarray:
    """(H, W) float32 luminance in 8-bit levels of display (sRGB-encoded) values, Rec. 709 weights."""
    return (np.asarray(rgb[..., :3], np.float32) @ np.array([0.2126, 0.7152, 0.0722], np.float32)) * 255


def full_shares(dec) -> np.ndarray:
    """(N, H, W) float32: each person's part of the matte of a matting="all" decomposition, at the photo's size."""
    out = np.zeros((len(dec.people), *dec.mask.shape), np.float32)
    for i, part in enumerate(dec.people):
        (oy, ox), (ph, pw) = part.origin, part.mask.shape
        out[i, oy : oy + ph, ox : ox + pw] = part.mask
    return out


def line_pairs(parts: np.ndarray, alpha: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, int]]:
    """The line where people's shares meet: per axis (0: vertical neighbours, 1: horizontal), the (ys, xs) of the
    first pixel of each pair of opaque neighbours whose largest share is different people's."""
    owner = np.argmax(parts, axis=0)
    opaque = alpha >= 0.5
    out = []
    for axis in (0, 1):
        a = [slice(None), slice(None)]
        b = [slice(None), slice(None)]
        a[axis], b[axis] = slice(0, -1), slice(1, None)
        a, b = tuple(a), tuple(b)
        on = opaque[a] & opaque[b] & (owner[a] != owner[b])
        ys, xs = np.nonzero(on)
        out.append((ys, xs, axis))
    return out


def steps(img: np.ndarray, pairs, reach: int, alpha: np.ndarray) -> np.ndarray:
    """|img| differences across the line: ``img`` at ``reach`` before the pair's first pixel and ``reach`` past its
    second, along the pair's axis, where both ends are opaque; NaN elsewhere."""
    h, w = img.shape
    out = []
    for ys, xs, axis in pairs:
        dy, dx = (1, 0) if axis == 0 else (0, 1)
        y0, x0 = ys - reach * dy, xs - reach * dx
        y1, x1 = ys + (reach + 1) * dy, xs + (reach + 1) * dx
        ok = (y0 >= 0) & (x0 >= 0) & (y1 < h) & (x1 < w)
        d = np.full(ys.shape, np.nan, np.float32)
        y0, x0, y1, x1 = y0[ok], x0[ok], y1[ok], x1[ok]
        both = (alpha[y0, x0] >= 0.5) & (alpha[y1, x1] >= 0.5)
        v = np.abs(img[y0, x0] - img[y1, x1])
        d[np.flatnonzero(ok)] = np.where(both, v, np.nan)
        out.append(d)
    return np.concatenate(out) if out else np.zeros(0, np.float32)


def seam_figures(photo, relit, pairs, reach, alpha) -> dict:
    own = steps(display_luma(photo), pairs, reach, alpha)
    new = steps(display_luma(relit), pairs, reach, alpha)
    colour = np.max([steps(np.asarray(photo[..., c], np.float32) * 255, pairs, reach, alpha) for c in range(3)], axis=0)
    ok = np.isfinite(own) & np.isfinite(new)
    excess = np.maximum(new[ok] - own[ok], 0)
    if excess.size == 0:
        return {"mean": None, "p95": None, "n": 0, "flat": None, "flat_mean": None, "seam": None, "seam_luma": None}
    # the line runs through one surface of the photo here (no channel steps by FLAT levels): a step there is a seam
    flat = colour[ok] < FLAT
    return {"mean": round(float(excess.mean()), 2), "p95": round(float(np.percentile(excess, 95)), 2),
            "n": int(excess.size), "flat": round(float(flat.mean()), 3),
            "flat_mean": round(float(excess[flat].mean()), 2) if flat.any() else 0.0,
            "seam": round(float((excess * flat).mean()), 2),
            "seam_luma": round(float((excess * (own[ok] < FLAT)).mean()), 2)}


def tile(img: np.ndarray, height: int) -> np.ndarray:
    img = np.clip(np.asarray(img[..., :3], np.float32), 0, 1)
    s = height / img.shape[0]
    return cv2.resize((img * 255).astype(np.uint8), None, fx=s, fy=s, interpolation=cv2.INTER_AREA)


def shares_picture(rgb: np.ndarray, parts: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    share = parts / np.maximum(alpha, 1e-6)[None]
    colour = np.tensordot(share.transpose(1, 2, 0), _COLOURS[np.arange(len(parts)) % len(_COLOURS)], axes=1)
    grey = display_luma(rgb)[..., None] * np.ones(3)
    a = np.clip(alpha, 0, 1)[..., None] * 0.6
    return np.clip(grey * (1 - a) + colour * a, 0, 255).astype(np.uint8)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, type=Path)
    ap.add_argument("--people", type=Path, default=None, help="people_masks folder (default: ../shared/realdata)")
    ap.add_argument("--photos", default=",".join(PHOTOS))
    ap.add_argument("--extra", default=str(Path("/tmp/relight_rt_people/group_t1.jpg")),
                    help="more photos, comma-separated paths (default: the people cache's group_t1.jpg)")
    ap.add_argument("--height", type=int, default=400, help="the sheet's row height")
    args = ap.parse_args(argv)
    people = args.people or shared_path("realdata/people_masks")
    paths = [people / "photos" / f"{n}.jpg" for n in args.photos.split(",") if n]
    paths += [Path(p) for p in args.extra.split(",") if p]
    args.out.mkdir(parents=True, exist_ok=True)
    everyone = relight_rt.open(RuntimeConfig(device="cpu", matting="all"))
    default = relight_rt.open(RuntimeConfig(device="cpu", matting="auto"))
    report: dict = {}
    for path in paths:
        if not path.is_file():
            print(f"{path}: absent, skipped")
            continue
        rgb = read_image(path)
        reach = max(int(round(REACH * max(rgb.shape[:2]))), 1)
        t0 = time.perf_counter()
        dec = everyone.decompose(rgb)
        relit_all = {k: everyone.relight(dec, light) for k, light in LIGHTS.items()}
        seconds = time.perf_counter() - t0
        dec_auto = default.decompose(rgb)
        relit_auto = {k: default.relight(dec_auto, light) for k, light in LIGHTS.items()}
        parts = full_shares(dec)
        alpha = np.asarray(dec.mask, np.float32)
        pairs = line_pairs(parts, alpha) if len(parts) > 1 else []
        entry = {"people": len(parts), "seconds_all": round(seconds, 1),
                 "line_px": int(sum(p[0].size for p in pairs))}
        for k in LIGHTS:
            entry[k] = seam_figures(rgb, relit_all[k], pairs, reach, alpha)
            entry[k + "_auto"] = seam_figures(rgb, relit_auto[k], pairs, reach, alpha)
        report[path.stem] = entry
        marked = np.array(rgb[..., :3], np.float32)
        for ys, xs, _ in pairs:
            marked[ys, xs] = (1, 0, 0)
        rows = [np.hstack([tile(marked, args.height)] + [tile(relit_all[k], args.height) for k in LIGHTS]),
                np.hstack([tile(rgb, args.height)] + [tile(relit_auto[k], args.height) for k in LIGHTS])]
        cv2.imwrite(str(args.out / f"{path.stem}.png"), cv2.cvtColor(np.vstack(rows), cv2.COLOR_RGB2BGR))
        cv2.imwrite(str(args.out / f"{path.stem}_shares.png"),
                    cv2.cvtColor(shares_picture(rgb, parts, alpha), cv2.COLOR_RGB2BGR))
        for k in LIGHTS:  # the relit photos at 100 %, for looking at the line closely
            cv2.imwrite(str(args.out / f"{path.stem}_{k}.png"),
                        cv2.cvtColor((np.clip(relit_all[k][..., :3], 0, 1) * 255).astype(np.uint8), cv2.COLOR_RGB2BGR))
        print(path.stem, json.dumps(entry), flush=True)
    print(f"\n{'photo':10s} {'people':>6s} {'line':>6s} " + " ".join(f"{k + ' all/auto mean p95':>30s}" for k in LIGHTS)
          + f" {'s all':>6s}")
    for name, e in report.items():
        cells = []
        for k in LIGHTS:
            a, b = e[k], e[k + "_auto"]
            cells.append(f"{figure(a['mean'])}/{figure(b['mean'])} {figure(a['p95'])}/{figure(b['p95'])}".rjust(30))
        print(f"{name:10s} {e['people']:6d} {e['line_px']:6d} " + " ".join(cells) + f" {e['seconds_all']:6.1f}")
    print(f"\n{'photo':10s} " + " ".join(f"{k + ' flat / seam all, auto':>28s}" for k in LIGHTS))
    for name, e in report.items():
        cells = [(f"{figure(e[k].get('flat'), 2)} / {figure(e[k].get('seam'))}, "
                  f"{figure(e[k + '_auto'].get('seam'))}").rjust(28) for k in LIGHTS]
        print(f"{name:10s} " + " ".join(cells))
    for k in LIGHTS:
        for kind in ("", "_auto"):
            vals = [e[k + kind]["seam"] for e in report.values() if e[k + kind]["n"]]
            if vals:
                print(f"{k + (kind or '_all'):14s} seam over {len(vals)} photos: mean {np.mean(vals):.2f} levels")
    for k in LIGHTS:
        for kind in ("", "_auto"):
            vals = [e[k + kind] for e in report.values() if e[k + kind]["n"]]
            if vals:
                m = np.mean([v["mean"] for v in vals])
                p = np.mean([v["p95"] for v in vals])
                print(f"{k + (kind or '_all'):14s} over {len(vals)} photos: mean {m:.2f}, p95 {p:.2f} (8-bit levels)")
    (args.out / "seams.json").write_text(json.dumps(report, indent=1))
    return 0


def figure(v, digits: int = 1) -> str:
    """A figure for the tables, "-" where there is none."""
    return "-" if v is None else f"{v:.{digits}f}"


if __name__ == "__main__":
    raise SystemExit(main())
