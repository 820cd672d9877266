"""The new light's shadow side black with a hard edge against the kept background (ambient29).

    PYTHONPATH=$PWD python benchmarks/dark_edge.py [--out /tmp/dark_edge.json] [--lights LEFT,RIGHT,campfire,rim]

The first look's 30 photos (benchmarks/first_look.py: seed 48 over both halves, the automatic matte, the background
kept, as ``relight-rt relight`` does by default), relit under white side lamps and presets. Per photo and light:

- ``dark_edge``: of the person's pixels within ``EDGE`` px inside the matte's 0.5 outline (alpha >= 0.5) that have
  solid background (alpha <= ``BG_ALPHA``) within ``REACH`` px, the share whose relit L* is below ``FRACTION`` of that
  adjacent background's mean L* while the input's was not: a new dark-against-bright edge, the person pasted onto a
  scene whose own light would reach that side.
- ``decile``: the relit person's darkest decile (10th percentile of L*, alpha > 0.5) over the background's median L*
  (alpha <= ``BG_ALPHA``), beside the input's (``decile_in``).

The summary prints, per half (A: tuning, B: checked) and light, the mean of both over the photos. L* is CIE L* of the
photo (``photo_faults.lab``: OpenCV's sRGB to Lab).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import cv2
import numpy as np

# first_look (through real_photos) puts this checkout and benchmarks/ first on sys.path: relight_rt below is this one
from first_look import picked_photos, read_rgb, side_colour

# isort: split
from _shared import shared_path
from photo_faults import lab
from real_photos import LEFT, RIGHT

import relight_rt
from relight_rt import RuntimeConfig

LIGHTS = ("LEFT", "RIGHT", "campfire", "rim")
EDGE = 8  # the person's pixels this near the outline (px) ...
REACH = 12  # ... with solid background within this many px, whose mean L* they are compared with
BG_ALPHA = 0.02  # the background: the matte at or below this
FRACTION = 0.4  # dark against bright: relit L* below this share of the adjacent background's, the input's not


def edge_band(alpha: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(band, background, depth): the person's pixels within ``EDGE`` px inside the matte's 0.5 outline, the solid
    background (alpha <= ``BG_ALPHA``) and each pixel's distance (px) from the outline."""
    inside = (alpha >= 0.5).astype(np.uint8)
    depth = cv2.distanceTransform(np.pad(inside, 1, constant_values=1), cv2.DIST_L2, 3)[1:-1, 1:-1]
    band = (inside > 0) & (depth <= EDGE)
    return band, alpha <= BG_ALPHA, depth


def measure(photo: np.ndarray, alpha: np.ndarray, relit: np.ndarray) -> dict:
    band, bg, _ = edge_band(alpha)
    l_in, l_out = lab(photo)[..., 0], lab(relit)[..., 0]
    bg_mean, has_bg = side_colour(np.repeat(l_in[..., None], 3, axis=2), bg, REACH)
    bg_mean = bg_mean[..., 0]
    where = band & has_bg & (bg_mean > 1.0)
    n = int(where.sum())
    person = alpha > 0.5
    bg_med = float(np.median(l_in[bg])) if bg.any() else 0.0
    out = {"band": n, "dark_edge": 0.0, "decile": None, "decile_in": None}
    if n:
        limit = FRACTION * bg_mean[where]
        new_dark = (l_out[where] < limit) & (l_in[where] >= limit)
        out["dark_edge"] = float(new_dark.mean())
    if person.any() and bg_med > 1.0:
        out["decile"] = float(np.percentile(l_out[person], 10)) / bg_med
        out["decile_in"] = float(np.percentile(l_in[person], 10)) / bg_med
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, default=None, help="a JSON file for the per-photo figures")
    p.add_argument("--people", type=Path, default=shared_path("realdata", "people_masks"))
    p.add_argument("--n", type=int, default=30)
    p.add_argument("--seed", type=int, default=48)
    p.add_argument("--lights", default=",".join(LIGHTS))
    p.add_argument("--models", type=Path, default=None)
    p.add_argument("--save", type=Path, default=None, help="a folder for the relit pictures (PNG), not the repo")
    args = p.parse_args(argv)
    found = picked_photos(args.people, args.n, args.seed)
    if found is None:
        return 2
    folder, chosen, halves = found
    lights = args.lights.split(",")
    relighter = relight_rt.open(RuntimeConfig(models=args.models, device="cpu"))
    if args.save:
        args.save.mkdir(parents=True, exist_ok=True)
    t0 = time.time()
    photos: dict = {}
    for name in chosen:
        rgb = read_rgb(folder / f"{name}.jpg")
        dec = relighter.decompose(rgb)
        alpha = np.asarray(dec.mask, np.float32)
        figures = {}
        for light in lights:
            img = np.asarray(relighter.relight(dec, {"LEFT": LEFT, "RIGHT": RIGHT}.get(light, light)), np.float32)
            figures[light] = measure(rgb, alpha, img)
            if args.save:
                bgr = cv2.cvtColor(np.round(np.clip(img, 0, 1) * 255).astype(np.uint8), cv2.COLOR_RGB2BGR)
                cv2.imwrite(str(args.save / f"{name}_{light}.png"), bgr)
        photos[name] = {"half": halves[name], "lights": figures}
        print(f"{name} ({halves[name]}): " + ", ".join(f"{k} {v['dark_edge']:.3f}" for k, v in figures.items())
              + f"  {time.time() - t0:.0f} s", flush=True)
    if args.out:
        args.out.write_text(json.dumps({"seed": args.seed, "n": args.n, "photos": photos}, indent=1))
    print(f"dark edge (share of the edge band turned below {FRACTION} of the background's L*), darkest decile / bg")
    for half in ("A", "B", "AB"):
        rows = [v for v in photos.values() if v["half"] in half]
        parts = []
        for light in lights:
            share = [v["lights"][light]["dark_edge"] for v in rows]
            dec = [v["lights"][light]["decile"] for v in rows if v["lights"][light]["decile"] is not None]
            parts.append(f"{light} {np.mean(share):.4f} / {np.mean(dec):.3f}")
        every = [v["lights"][x]["dark_edge"] for v in rows for x in lights]
        dec_in = [v["lights"][lights[0]]["decile_in"] for v in rows if v["lights"][lights[0]]["decile_in"] is not None]
        print(f"half {half} ({len(rows)}): all {np.mean(every):.4f}; " + "; ".join(parts)
              + f"; input decile {np.mean(dec_in):.3f}")
    print(f"{len(photos)} photos, {time.time() - t0:.0f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
