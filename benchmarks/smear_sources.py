"""Where a relit person's change past the photo's edge comes from (smear27), on the first look's photos.

    python benchmarks/smear_sources.py [--only p057,p133] [--lights night,LEFT,RIGHT,campfire]

For each photo of ``first_look.py``'s pick (seed 48, 30 photos), relit as ``relight-rt relight`` does (automatic matte,
the photo's own background): the change (8-bit levels, largest channel, summed) on the pixels outside the photo's
service mask grown by 1 px (background, ``shown_edge_landing.py``'s rule) where the matte is not 0, split by the
matte's alpha there: its soft rim's outer half (< 0.5), its inner half (0.5 to 1) and solid; and the same with the
shown edge off (the matte's own edge and colours, ``compose.own_colours``), so that ``shown / matte`` is the share the
shown edge leaves. Over the photo's own background the composite is the photo plus shown alpha x (relit F - F), so a
change there is the alpha left on background times the person's change. Prints a row per photo and the shares over
all; writes nothing of the data. About 3 min for the 30 photos.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np

# real_photos puts this checkout (and benchmarks/) first on sys.path: the relight_rt imported below is this one
from real_photos import LEFT, RIGHT

# isort: split
from _shared import shared_path
from first_look import picked_photos, read_rgb
from people_masks_eval import read_mask

import relight_rt
from relight_rt import RuntimeConfig
from relight_rt.relight.compose import own_colours

KINDS = ("rim_outer", "rim_inner", "solid")


def split(change: np.ndarray, alpha: np.ndarray, background: np.ndarray) -> dict[str, float]:
    """``change`` (h, w) summed over ``background`` where ``alpha`` > 0, by the matte's alpha there."""
    where = background & (alpha > 0)
    kinds = (alpha < 0.5, (alpha >= 0.5) & (alpha < 1 - 1 / 255), alpha >= 1 - 1 / 255)
    return {k: float(change[where & sel].sum()) for k, sel in zip(KINDS, kinds, strict=True)}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--people", type=Path, default=shared_path("realdata", "people_masks"))
    p.add_argument("--only", default=None, help="comma-separated photo names (of the pick)")
    p.add_argument("--lights", default="night,LEFT,RIGHT,campfire")
    args = p.parse_args(argv)
    found = picked_photos(args.people, 30, 48)
    if found is None:
        return 2
    folder, chosen, halves = found
    if args.only:
        chosen = [n for n in chosen if n in set(args.only.split(","))]
    lights = {n: {"LEFT": LEFT, "RIGHT": RIGHT}.get(n, n) for n in args.lights.split(",")}
    relighter = relight_rt.open(RuntimeConfig(device="cpu"))
    total = dict.fromkeys((*KINDS, "with_edge", "without"), 0.0)
    for name in chosen:
        rgb = read_rgb(folder / f"{name}.jpg")
        service = read_mask(folder / f"{name}_mask.png", rgb.shape[:2]).astype(np.uint8)
        background = cv2.dilate(service, np.ones((3, 3), np.uint8)) == 0
        dec = relighter.decompose(rgb)
        alpha = np.asarray(dec.mask)
        off = None  # the shown edge off: a group relit person by person carries it in its people, not measured
        if not dec.people and dec.edge is not None:
            off = relighter._factor.derive(dec, foreground=own_colours(dec), edge=None)
        row = dict.fromkeys((*KINDS, "with_edge", "without"), 0.0)
        for light in lights.values():
            change = 255 * np.abs(np.asarray(relighter.relight(dec, light), np.float32) - rgb).max(axis=2)
            for k, v in split(change, alpha, background).items():
                row[k] += v
            if off is not None:
                row["with_edge"] += float(change[background & (alpha > 0)].sum())
                without = 255 * np.abs(np.asarray(relighter.relight(off, light), np.float32) - rgb).max(axis=2)
                row["without"] += float(without[background & (alpha > 0)].sum())
        all_kinds = max(sum(row[k] for k in KINDS), 1e-9)
        shown = f"{row['with_edge'] / row['without']:.2f}" if row["without"] else "-"
        print(f"{name} ({halves[name]}): {int((background & (alpha > 0)).sum())} px, "
              + ", ".join(f"{k} {row[k] / all_kinds:.2f}" for k in KINDS) + f"; shown / matte {shown}", flush=True)
        for k in total:
            total[k] += row[k]
    all_kinds = max(sum(total[k] for k in KINDS), 1e-9)
    print("all: " + ", ".join(f"{k} {total[k] / all_kinds:.2f}" for k in KINDS)
          + f"; shown / matte {total['with_edge'] / max(total['without'], 1e-9):.2f} (photos relit as one)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
