"""How well relight_rt.apps.scene_place.estimate_horizon finds the horizon: on panorama views, whose horizon is known.

    python benchmarks/scene_horizon.py --hdri ../shared/hdri [--size 640x480] [--out runs/scene/horizon.json] \
        [--places PLACE ...]

Every map of ``--hdri``, seen at azimuths 0/120/240° and elevations −12/0/+12° (60° field of view; the plate of
relight_rt.apps.panorama.panorama_view, 8-bit sRGB, whose ``horizon`` is exact): how often the estimate answers, and
its error (fractions of the picture's height) where it does, against the level camera's 0.5 that stands without it.
``--photos DIR``: also every .jpg/.png there (real photos, no truth): how often it answers and the spread of its
answers (most photos of people are taken nearly level: a wide spread means wild answers).

Also the sky line (``sky_line``: no sky below the horizon) and what ``composite`` uses (``find_horizon``: the
verticals' answer or 0.5; where they see the camera turned up, no higher than the sky line; at most 0.9): on the
views, how often the sky line lies more than 0.02 below the true horizon (a bound should not), and the error of
``find_horizon`` against the verticals' answer-or-0.5 over all views. Every view's readings go to ``--out``, so
other ways to combine them can be scored from the file. ``--places``: photos of places (centre-cropped to
``--size``'s aspect as benchmarks/scene_sheet.py does) with each reading, to look at.
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
from relight_rt.apps.scene_place import HORIZON_ESTIMATE_MAX, estimate_horizon, find_horizon, sky_line  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hdri", type=Path, required=True)
    ap.add_argument("--size", default="640x480")
    ap.add_argument("--out", type=Path)
    ap.add_argument("--photos", type=Path, help="a folder of real photos (no truth): the spread of the answers")
    ap.add_argument("--places", type=Path, nargs="*", default=[], help="photos of places: each reading, printed")
    args = ap.parse_args(argv)
    size = parse_size(args.size)
    rows = []
    for path in sorted(args.hdri.glob("*.hdr")):
        env = envmap.load_envmap(path)
        for az in (0, 120, 240):
            for el in (-12, 0, 12):
                pv = panorama_view(env, size, (az, el, 60))
                est = estimate_horizon(pv.plate, 60.0)
                rows.append({"map": path.stem, "az": az, "el": el, "truth": pv.horizon, "estimate": est,
                             "sky_line": sky_line(pv.plate), "used": find_horizon(pv.plate, 60.0)})  # fmt: skip
    found = [r for r in rows if r["estimate"] is not None]
    err = np.array([abs(r["estimate"] - r["truth"]) for r in found])
    level = np.array([abs(0.5 - r["truth"]) for r in found])
    summary = {
        "views": len(rows), "answered": len(found),
        "median_error": float(np.median(err)), "p90_error": float(np.quantile(err, 0.9)), "max_error": float(err.max()),
        "level_camera_median_error_same_views": float(np.median(level)),
        "within_0.05": float(np.mean(err <= 0.05)),
    }  # fmt: skip
    # what composite used before the sky line (the verticals' answer or 0.5, clipped) and uses now, on every view
    before = np.array([abs(min(max(0.5 if r["estimate"] is None else r["estimate"], 0.0), HORIZON_ESTIMATE_MAX)
                           - r["truth"]) for r in rows])  # fmt: skip
    after = np.array([abs(r["used"] - r["truth"]) for r in rows])
    sky = [r for r in rows if r["sky_line"] is not None]
    summary["sky_line"] = {
        "answered": len(sky), "below_truth_by_over_0.02": sum(r["sky_line"] > r["truth"] + 0.02 for r in sky),
        "composite_horizon_error_before": {"median": float(np.median(before)), "mean": float(before.mean()),
                                           "p90": float(np.quantile(before, 0.9)), "max": float(before.max())},
        "composite_horizon_error_after": {"median": float(np.median(after)), "mean": float(after.mean()),
                                          "p90": float(np.quantile(after, 0.9)), "max": float(after.max())},
        "views_changed": int(np.sum(np.abs(after - before) > 1e-9)),
        "views_better_by_0.02": int(np.sum(after < before - 0.02)),
        "views_worse_by_0.02": int(np.sum(after > before + 0.02)),
    }  # fmt: skip
    print(json.dumps(summary, indent=1))
    for r in found:
        if abs(r["estimate"] - r["truth"]) > 0.05:
            print(f"off: {r['map']} {r['az']},{r['el']}: {r['estimate']:.2f} for {r['truth']:.2f}")
    photos, skies, moved = {}, {}, {}
    if args.photos:
        import cv2

        for path in sorted(p for p in args.photos.iterdir() if p.suffix.lower() in (".jpg", ".png")):
            img = cv2.imread(str(path), cv2.IMREAD_COLOR)
            if img is not None and not path.stem.endswith("_mask"):
                rgb = np.ascontiguousarray(img[..., ::-1])
                photos[path.name], skies[path.name] = estimate_horizon(rgb, 60.0), sky_line(rgb)
                old = min(max(0.5 if photos[path.name] is None else photos[path.name], 0.0), HORIZON_ESTIMATE_MAX)
                if abs(find_horizon(rgb, 60.0) - old) > 1e-9:
                    moved[path.name] = (old, find_horizon(rgb, 60.0))
        for name, found in (("verticals", photos), ("sky_line", skies)):
            got = np.array([v for v in found.values() if v is not None])
            print(json.dumps({"photos": len(found), name: int(got.size),
                              "percentiles_5_25_50_75_95": np.percentile(got, [5, 25, 50, 75, 95]).round(3).tolist()
                              if got.size else []}))  # fmt: skip
        print(
            f"composite's horizon moved by the sky line on {len(moved)} photos: "
            + ", ".join(f"{k} {a:.2f} -> {b:.2f}" for k, (a, b) in sorted(moved.items()))
        )
    if args.places:
        from scene_sheet import photo_background

        for path in args.places:
            bg = photo_background(path, (size[1], size[0]))
            est, line = estimate_horizon(bg, 60.0), sky_line(bg)
            est_s, line_s = "-" if est is None else f"{est:.3f}", "-" if line is None else f"{line:.3f}"
            print(f"{path.name:28s} verticals {est_s:>6s}  sky line {line_s:>6s}  used {find_horizon(bg, 60.0):.3f}")
    if args.out:
        args.out.write_text(
            json.dumps({"summary": summary, "views": rows, "photos": photos, "photo_sky_lines": skies}, indent=1)
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
