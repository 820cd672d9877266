"""Where the runtime puts a real photo's own light, against Yale's known lamps (../shared/realdata/yale).

    python benchmarks/own_light_yale.py [--yale ../shared/realdata/yale] [--max-elevation 45] [--out OUT.json]
    python benchmarks/own_light_yale.py --renders ~/.cache/relight_rt_real_photos/heldout   # the same on renders

Every Yale photo whose lamp lies within ``--max-elevation`` of the horizon (and is not flagged bad) is decomposed
as benchmarks/yale_eval.py does (grey, the ellipse mask); the photo's light ``Decomposition.light`` (stage 1's
estimate, refit so that albedo x shading explains the photo) gives a direction from its degree-1 band (luminance
weighted; DESIGN.md §3: k = 3, 1, 2 are x, y, z), compared with the lamp's (yale_eval ``lamp_direction``).
Printed per lamp azimuth band: the median angle between the two, the median elevation of ours against the
lamp's, the share whose left-right side (the sign of y) is right, and the degree-1 band's length over degree 0
(how directional the light is read). Two later sessions found the own light read "from above" on soft-lit real
photos (spec28: p080's soft front light, blacks28: p041); this measures that bias where the truth is known.
``--renders DIR``: the held-out renders instead (DIR/photos_*/NAME_photo.png with NAME_mask.png and the true light
NAME_light.npy, as benchmarks/heldout_change.py writes them): the same reading of both lights, its angle and
elevation. Evaluation only: nothing of the data is written but figures.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
from pathlib import Path

import cv2
import numpy as np
from _shared import missing, shared_path
from yale_eval import ellipse, lamp_direction, read_grey

from relight_rt import Relighter, RuntimeConfig

LUMA = np.array([0.2126, 0.7152, 0.0722])
BANDS = ((0, 15), (15, 40), (40, 65), (65, 95), (95, 181))


def light_direction(light: np.ndarray) -> tuple[np.ndarray, float]:
    """The unit direction of a (9, 3) SH light's degree-1 band (luminance weighted) and its length over degree 0."""
    y = np.asarray(light, np.float64) @ LUMA
    d = np.array([y[3], y[1], y[2]])
    n = float(np.linalg.norm(d))
    return (d / n if n > 0 else d), n / max(abs(float(y[0])), 1e-9)


def read_rgb(path: Path) -> np.ndarray:
    bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if bgr is None:
        raise FileNotFoundError(path)
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB).astype(np.float32) / 255


def renders(folder: Path, relighter: Relighter) -> int:
    """The own light of every held-out render under ``folder`` against the light it was rendered under."""
    photos = sorted(folder.glob("photos_*/*_photo.png"))
    if not photos:
        print(f"own_light_yale: no photos_*/*_photo.png under {folder}", file=sys.stderr)
        return 2
    angle, ours_el, true_el = [], [], []
    for f in photos:
        mask = cv2.imread(str(f.with_name(f.name.replace("_photo.png", "_mask.png"))), cv2.IMREAD_GRAYSCALE)
        truth, _ = light_direction(np.load(f.with_name(f.name.replace("_photo.png", "_light.npy"))))
        ours, _ = light_direction(relighter.decompose(read_rgb(f), mask.astype(np.float32) / 255).light)
        angle.append(math.degrees(math.acos(float(np.clip(ours @ truth, -1, 1)))))
        ours_el.append(math.degrees(math.asin(float(np.clip(ours[2], -1, 1)))))
        true_el.append(math.degrees(math.asin(float(np.clip(truth[2], -1, 1)))))
    high = float(np.mean(ours_el) - np.mean(true_el))
    print(f"{len(photos)} renders: angle median {np.median(angle):.1f} deg; elevation ours / true (medians) "
          f"{np.median(ours_el):+.1f} / {np.median(true_el):+.1f}, ours minus true mean {high:+.1f}")
    return 0


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--yale", type=Path, default=shared_path("realdata", "yale"))
    p.add_argument("--models", type=Path, default=None)
    p.add_argument("--max-elevation", type=float, default=45.0)
    p.add_argument("--out", type=Path, default=None)
    p.add_argument("--renders", type=Path, default=None, help="held-out renders' folder (photos_*/*_photo.png)")
    args = p.parse_args(argv)
    if args.renders is not None:
        return renders(args.renders.expanduser(), Relighter(RuntimeConfig(models=args.models, device="cpu")))
    if not args.yale.is_dir():
        print(missing(args.yale), file=sys.stderr)
        return 2
    relighter = Relighter(RuntimeConfig(models=args.models, device="cpu"))
    rows = []
    with open(args.yale / "lights.csv") as f:
        lamps = [r for r in csv.DictReader(f)
                 if abs(float(r["elevation_deg"])) <= args.max_elevation and r["flagged_bad_in_source"] in ("", "0")]
    for r in lamps:
        az, el = float(r["azimuth_deg"]), float(r["elevation_deg"])
        rgb = read_grey(args.yale / r["file"])
        dec = relighter.decompose(rgb, ellipse(rgb.shape[:2]))
        ours, strength = light_direction(dec.light)
        truth = np.array(lamp_direction(az, el))
        rows.append({"subject": r["subject"], "azimuth": az, "elevation": el,
                     "angle": math.degrees(math.acos(float(np.clip(ours @ truth, -1, 1)))),
                     "our_elevation": math.degrees(math.asin(float(np.clip(ours[2], -1, 1)))),
                     "side_right": None if abs(az) < 10 else bool(np.sign(ours[1]) == np.sign(truth[1])),
                     "strength": strength})
    print(f"{len(rows)} photos, lamps within {args.max_elevation:g} deg of the horizon")
    print("|azimuth| | photos | angle (median) | elevation: ours / lamp (medians) | side right | degree 1 / 0")
    for lo, hi in BANDS:
        band = [r for r in rows if lo <= abs(r["azimuth"]) < hi]
        if not band:
            continue
        sides = [r["side_right"] for r in band if r["side_right"] is not None]
        side = f"{np.mean(sides):.0%}" if sides else "-"
        print(f"{lo}-{hi} | {len(band)} | {np.median([r['angle'] for r in band]):.1f} | "
              f"{np.median([r['our_elevation'] for r in band]):+.1f} / {np.median([r['elevation'] for r in band]):+.1f}"
              f" | {side} | {np.median([r['strength'] for r in band]):.2f}")
    if args.out is not None:
        args.out.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
