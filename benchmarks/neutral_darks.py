"""Near-neutral darks under white lamps: how often dark, near-grey pixels of a photo come out coloured (issue 48's
first look: dark hair blue-grey, a black sweater teal under a white lamp).

    python benchmarks/neutral_darks.py [--n 30] [--seed 48] [--people ../shared/realdata/people_masks]

The photos of ``first_look.py`` (the same ``--n`` and ``--seed``: both halves, the automatic matte, the background
kept), relit under the white lamps LEFT and RIGHT (benchmarks/real_photos.py) and window-left. On the person
(alpha > 0.5), the pixels of the photo with Lab L* < 35 and C* < 10 (per pixel) are the near-neutral darks; a white
light should change their brightness, not their colour. Per photo and light, the share of them whose relit
(a*, b*) hue turned more than 20 degrees or whose C* rose more than 8 (``fault``, the brief's figure; the hue of a
pixel of C* ~1 turns with JPEG's noise, so it counts much that no one sees), and the share whose C* rose more than
8 or that turned more than 20 degrees at a relit C* of 6 or more (``seen``), and ``seen`` among the pixels whose
photo hue is not warm (Lab hue outside ``WARM``: the blue-grey, teal, violet and magenta casts; a warm dark made
browner reads as its material). Prints the mean over the photos per half and light; writes nothing.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np
from real_photos import LEFT, RIGHT

# isort: split
from _shared import shared_path
from first_look import picked_photos, read_rgb

import relight_rt
from relight_rt import RuntimeConfig

LIGHTS = ("LEFT", "RIGHT", "window-left")
WARM = (15.0, 95.0)  # Lab hue angles (degrees) of a warm dark: skin, brown hair (``cool``: the others)


def lab(rgb: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(np.clip(rgb, 0, 1).astype(np.float32), cv2.COLOR_RGB2Lab)


def shares(photo: np.ndarray, relit: np.ndarray, where: np.ndarray) -> tuple[float, float, float]:
    """(fault, seen, seen among the cool or magenta ones) over the near-neutral dark pixels ``where`` (module
    docstring)."""
    p, r = lab(photo)[where], lab(relit)[where]
    c0, c1 = np.hypot(p[:, 1], p[:, 2]), np.hypot(r[:, 1], r[:, 2])
    h0 = np.arctan2(p[:, 2], p[:, 1])
    turn = np.degrees(np.abs(np.angle(np.exp(1j * (np.arctan2(r[:, 2], r[:, 1]) - h0)))))
    rise = c1 - c0 > 8
    seen = rise | ((turn > 20) & (c1 >= 6))
    cool = ~((np.degrees(h0) % 360 >= WARM[0]) & (np.degrees(h0) % 360 <= WARM[1]))
    return float(np.mean((turn > 20) | rise)), float(np.mean(seen)), float(np.mean(seen[cool])) if cool.any() else 0.0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--people", type=Path, default=shared_path("realdata", "people_masks"))
    ap.add_argument("--n", type=int, default=30)
    ap.add_argument("--seed", type=int, default=48)
    ap.add_argument("--models", type=Path, default=None)
    args = ap.parse_args(argv)
    found = picked_photos(args.people, args.n, args.seed)
    if found is None:
        return 2
    folder, chosen, halves = found
    relighter = relight_rt.open(RuntimeConfig(models=args.models, device="cpu"))
    table: dict = {}
    for name in chosen:
        rgb = read_rgb(folder / f"{name}.jpg")
        dec = relighter.decompose(rgb)
        L = lab(rgb)
        where = (np.asarray(dec.mask) > 0.5) & (L[..., 0] < 35) & (np.hypot(L[..., 1], L[..., 2]) < 10)
        if not where.any():
            continue
        row = []
        for light in LIGHTS:
            relit = np.asarray(relighter.relight(dec, {"LEFT": LEFT, "RIGHT": RIGHT}.get(light, light)), np.float32)
            row.append(shares(rgb, relit, where))
        table[name] = (halves[name], row)
        figures = ", ".join(f"{n} {f:.3f}/{s:.3f}/{c:.3f}" for n, (f, s, c) in zip(LIGHTS, row, strict=True))
        print(f"{name} ({halves[name]}): {figures}", flush=True)
    for half in ("A", "B", "AB"):
        rows = [r for h, r in table.values() if h in half]
        if rows:
            mean = np.mean(np.array(rows), axis=0)
            print(f"half {half} ({len(rows)} photos) fault / seen / seen cool: "
                  + ", ".join(f"{n} {f:.4f} / {s:.4f} / {c:.4f}" for n, (f, s, c) in zip(LIGHTS, mean, strict=True)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
