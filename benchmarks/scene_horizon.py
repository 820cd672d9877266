"""How well relight_rt.apps.scene_place.estimate_horizon finds the horizon: on panorama views, whose horizon is known.

    python benchmarks/scene_horizon.py --hdri ../shared/hdri [--size 640x480] [--out runs/scene/horizon.json]

Every map of ``--hdri``, seen at azimuths 0/120/240° and elevations −12/0/+12° (60° field of view; the plate of
relight_rt.apps.panorama.panorama_view, 8-bit sRGB, whose ``horizon`` is exact): how often the estimate answers, and
its error (fractions of the picture's height) where it does, against the level camera's 0.5 that stands without it.
``--photos DIR``: also every .jpg/.png there (real photos, no truth): how often it answers and the spread of its
answers (most photos of people are taken nearly level: a wide spread means wild answers).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from relight_rt import envmap  # noqa: E402
from relight_rt.apps.panorama import panorama_view, parse_size  # noqa: E402
from relight_rt.apps.scene_place import estimate_horizon  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hdri", type=Path, required=True)
    ap.add_argument("--size", default="640x480")
    ap.add_argument("--out", type=Path)
    ap.add_argument("--photos", type=Path, help="a folder of real photos (no truth): the spread of the answers")
    args = ap.parse_args(argv)
    size = parse_size(args.size)
    rows = []
    for path in sorted(args.hdri.glob("*.hdr")):
        env = envmap.load_envmap(path)
        for az in (0, 120, 240):
            for el in (-12, 0, 12):
                pv = panorama_view(env, size, (az, el, 60))
                est = estimate_horizon(pv.plate, 60.0)
                rows.append({"map": path.stem, "az": az, "el": el, "truth": pv.horizon, "estimate": est})
    found = [r for r in rows if r["estimate"] is not None]
    err = np.array([abs(r["estimate"] - r["truth"]) for r in found])
    level = np.array([abs(0.5 - r["truth"]) for r in found])
    summary = {
        "views": len(rows), "answered": len(found),
        "median_error": float(np.median(err)), "p90_error": float(np.quantile(err, 0.9)), "max_error": float(err.max()),
        "level_camera_median_error_same_views": float(np.median(level)),
        "within_0.05": float(np.mean(err <= 0.05)),
    }  # fmt: skip
    print(json.dumps(summary, indent=1))
    for r in found:
        if abs(r["estimate"] - r["truth"]) > 0.05:
            print(f"off: {r['map']} {r['az']},{r['el']}: {r['estimate']:.2f} for {r['truth']:.2f}")
    photos = {}
    if args.photos:
        import cv2

        for path in sorted(p for p in args.photos.iterdir() if p.suffix.lower() in (".jpg", ".png")):
            img = cv2.imread(str(path), cv2.IMREAD_COLOR)
            if img is not None and not path.stem.endswith("_mask"):
                photos[path.name] = estimate_horizon(np.ascontiguousarray(img[..., ::-1]), 60.0)
        got = np.array([v for v in photos.values() if v is not None])
        print(json.dumps({"photos": len(photos), "answered": int(got.size),
                          "percentiles_5_25_50_75_95": np.percentile(got, [5, 25, 50, 75, 95]).round(3).tolist()
                          if got.size else []}))  # fmt: skip
    if args.out:
        args.out.write_text(json.dumps({"summary": summary, "views": rows, "photos": photos}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
