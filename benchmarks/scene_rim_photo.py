"""How bright a background photo's clipped source should make the rim (relight_rt.apps.scene_rim, ``RIM_PHOTO``).

    PYTHONPATH=$PWD:/tmp/scene_pylib python benchmarks/scene_rim_photo.py --envs runs/scene/envs \\
        [--out runs/scene/rim_photo.json]

For every map of the benchmark (scene_eval.py's views: 60°, level, exposed to 18 % grey, 8-bit): the rim the map
itself gives (``panorama_rim``: the brightest source behind the person, its power from the HDR) and the rim the view's
photo gives (``photo_rim``, on the views with a compact clipped region), both in the photo's linear units; and the
front/back call (``scene_light(...).key``). Prints, over the views with a source in frame (all, and those the call
reads as back-lit: the default rim's gate):

- how the photo's reading relates to the map's (correlation of their log luminances; what the old rule, the clipped
  white times HIGHLIGHT_GAIN over the clipped pixels, gave: ``--old`` recomputes it);
- the constant luminance that minimises the mean |log2| error (the median of the map's rims), fitted on all views and
  leave-one-scene-out, and its median |log2| error against the map's.

The map's rim is itself a model (scene_rim's lobe and scatter); what this fixes is only that a photo's rim be as
bright as the same model gives from the radiance the photo clipped.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

import scene_eval as se  # noqa: E402  (the benchmark's cameras)

from relight_rt import envmap  # noqa: E402
from relight_rt.apps.scene_rim import LOBE_SR, SCATTER, panorama_rim, photo_rim  # noqa: E402
from relight_rt.image.color import REC709, srgb8_to_linear  # noqa: E402
from relight_rt.light import from_background as bgmod  # noqa: E402


def old_photo_rim(view: np.ndarray) -> float | None:
    """The rule before RIM_PHOTO: the clipped region's pixels read as their (clipped) value times HIGHLIGHT_GAIN,
    its power over the lobe (scene_rim.rim_colour), as luminance; None without a source."""
    found = photo_rim(view, 60.0)
    if found is None:
        return None
    h, w = view.shape[:2]
    clipped = view.max(2) >= 250
    n, labels, stats, _ = cv2.connectedComponentsWithStats(clipped.astype(np.uint8), connectivity=8)
    areas = stats[1:, cv2.CC_STAT_AREA]
    ok = (areas >= 2) & (areas <= 0.03 * h * w)
    k = 1 + int(np.argmax(np.where(ok, areas, 0)))
    ys, xs = np.nonzero(labels == k)
    focal = (w / 2) / math.tan(math.radians(30))
    y, z = (xs + 0.5 - w / 2) / focal, (h / 2 - ys - 0.5) / focal
    norm = np.sqrt(1 + y * y + z * z)
    d_omega = 1 / (focal * focal * norm**3)
    lum = srgb8_to_linear(view[ys, xs]).astype(np.float64) @ REC709 * bgmod.HIGHLIGHT_GAIN
    power = float(lum @ d_omega)
    return min(1.0, SCATTER * -float(found[0][0]) * power / max(LOBE_SR, float(d_omega.sum())))


def summary(rows: list[dict], key: str) -> dict:
    t = np.log2([r["map_rim"] for r in rows])
    p = np.log2([r[key] for r in rows])
    const = float(np.median(t))
    scenes = sorted({se.scene_of(r["map"]) for r in rows})
    loso_err, loso_const = [], []
    for s in scenes:
        c = float(np.median([tt for tt, r in zip(t, rows, strict=True) if se.scene_of(r["map"]) != s]))
        loso_const.append(c)
        loso_err += [abs(c - tt) for tt, r in zip(t, rows, strict=True) if se.scene_of(r["map"]) == s]
    return {"views": len(rows), "corr_log_photo_vs_map": round(float(np.corrcoef(t, p)[0, 1]), 3),
            "photo_median": round(float(2 ** np.median(p)), 4), "map_median": round(2**const, 4),
            "map_q25_q75": [round(float(2**q), 4) for q in np.percentile(t, [25, 75])],
            "photo_median_abs_log2_err": round(float(np.median(np.abs(p - t))), 2),
            "constant_median_abs_log2_err": round(float(np.median(np.abs(const - t))), 2),
            "loso_constant_range": [round(2 ** min(loso_const), 4), round(2 ** max(loso_const), 4)],
            "loso_median_abs_log2_err": round(float(np.median(loso_err)), 2)}  # fmt: skip


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--envs", type=Path, required=True)
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args(argv)
    rows = []
    for path in sorted(args.envs.glob("*.hdr")):
        env = envmap.load_envmap(path)
        lin = se.view_linear(env)
        k = se.GREY / max(se.mean_lum(lin), 1e-9)
        view = se.photograph(lin, k)
        _, back = bgmod.scene_light(view, 60.0).key(None)
        truth = panorama_rim(env, np.eye(3), math.pi * k)  # the view's camera is the map's frame; plate = π k env
        found = photo_rim(view, 60.0)
        if truth is None or found is None:
            continue
        rows.append({"map": path.stem, "back_call": bool(back), "map_rim": float(truth[1] @ REC709),
                     "photo_rim": float(found[1] @ REC709), "old_photo_rim": old_photo_rim(view)})  # fmt: skip
    res = {"found": {k: summary(rows, k) for k in ("photo_rim", "old_photo_rim")},
           "found_and_back": {k: summary([r for r in rows if r["back_call"]], k)
                              for k in ("photo_rim", "old_photo_rim")}}  # fmt: skip
    print(json.dumps(res, indent=1))
    if args.out is not None:
        args.out.write_text(json.dumps({**res, "views": rows}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
