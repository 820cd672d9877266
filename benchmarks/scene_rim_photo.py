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

Also printed: the rim's colour, from the clipped pixels (``photo_rim(..., halo=False)``) and with the halo rule
(the default), against the rim of the map's brightest source inside the view (the angle between their linear RGB;
median over the views where that rim is at least ``RIM_SEEN``, and over all); and ``gate``: where a rule of "a
source in frame" fires against where the map has one (that source's rim at least ``RIM_SEEN``), for today's gate
(``photo_rim`` finds a region and the light reads back-lit: ``composite(rim="auto")``) and for tests of the
region's shape (compactness 4 pi area / perimeter^2) and of its glow (the luminance round it over the frame's
median, falling off outward).
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
from relight_rt.apps.scene_rim import LOBE_SR, SCATTER, brightest, panorama_rim, photo_rim, rim_colour  # noqa: E402
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


RIM_SEEN = 0.1  # a map's rim at least this (linear, the plate's units: ~a third of the median) is worth a rim


def angle(a, b) -> float:
    """Degrees between two RGB colours."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    c = float(a @ b) / max(float(np.linalg.norm(a) * np.linalg.norm(b)), 1e-12)
    return math.degrees(math.acos(min(1.0, max(-1.0, c))))


def in_view(dirs, shape, fov: float = 60.0):
    """Which (camera-frame, (..., 3)) directions lie inside a view of ``shape`` (h, w) and horizontal ``fov``."""
    d = np.asarray(dirs, np.float64)
    t = math.tan(math.radians(fov) / 2)
    back = np.maximum(-d[..., 0], 1e-9)
    return (d[..., 0] < 0) & (np.abs(d[..., 1]) <= t * back) & (np.abs(d[..., 2]) <= t * shape[0] / shape[1] * back)


def view_rim(env: np.ndarray, k: float, shape) -> tuple[np.ndarray, np.ndarray] | None:
    """The rim of the map's brightest source inside the view (scene_rim's model, its halo rule), as panorama_rim's
    for the view's camera (the map's frame), plate = pi k env: what a photo of that view could show."""
    found = brightest(env, within=lambda dirs: in_view(dirs, shape), halo=True)
    if found is None:
        return None
    return found[0], rim_colour(found[1] * math.pi * k, found[2], found[0])


def region_features(view: np.ndarray) -> dict | None:
    """The largest clipped region of an 8-bit view (any size): its share of the frame, compactness, and its glow: the
    mean luminance of the unclipped pixels 0-1/2, 1/2-1, 1-2 and 2-4 equivalent radii from it, over the frame's
    median."""
    clipped = (view.max(2) >= 250).astype(np.uint8)
    n, labels, stats, centroids = cv2.connectedComponentsWithStats(clipped, connectivity=8)
    if n <= 1:
        return None
    j = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    row = float(centroids[j][1]) / view.shape[0]  # its centre's row, a fraction of the height (0: the top)
    region = (labels == j).astype(np.uint8)
    area = int(stats[j, cv2.CC_STAT_AREA])
    contours, _ = cv2.findContours(region, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    perimeter = max(1.0, sum(cv2.arcLength(c, True) for c in contours))
    lum = srgb8_to_linear(view) @ REC709
    dist = cv2.distanceTransform(1 - region, cv2.DIST_L2, 5)
    r, med = math.sqrt(area / math.pi), max(float(np.median(lum)), 1e-6)
    glow = []
    for lo, hi in ((0, 0.5), (0.5, 1), (1, 2), (2, 4)):
        ring = (dist > r * lo) & (dist <= r * hi) & (clipped == 0)
        glow.append(float(lum[ring].mean()) / med if ring.any() else 0.0)
    return {"area": area / clipped.size, "compact": 4 * math.pi * area / perimeter**2, "glow": glow, "row": row,
            "clipped": float(clipped.mean())}  # fmt: skip


def glowing(f: dict | None, level: float, max_area: float = 0.1) -> bool:
    """A glow round the region: at least ``level`` times the frame's median just outside it, falling off outward."""
    if f is None or f["area"] > max_area:
        return False
    g = f["glow"]
    return g[0] >= level and g[0] > g[1] > g[2] and g[2] >= 0.9 * g[3]


GATES = {  # name: rule(view row) -> fires
    "today: compact clipped region (<= 3 %) and back-lit": lambda r: r["found"] and r["back_call"],
    "compact clipped region alone": lambda r: r["found"],
    "glow >= 3x median, falling (region <= 10 %)": lambda r: glowing(r["region"], 3.0),
    "glow >= 3x, falling, and back-lit": lambda r: glowing(r["region"], 3.0) and r["back_call"],
    "glow >= 5x, falling": lambda r: glowing(r["region"], 5.0),
    "glow >= 5x, falling, and back-lit": lambda r: glowing(r["region"], 5.0) and r["back_call"],
    "compactness >= 0.5 (region <= 10 %) and back-lit": lambda r: (
        r["region"] is not None and r["region"]["area"] <= 0.1 and r["region"]["compact"] >= 0.5 and r["back_call"]
    ),
    "compact region in the upper half": lambda r: r["found"] and r["region"]["row"] < 0.5,
    "compact region in the upper half, and back-lit": lambda r: (
        r["found"] and r["region"]["row"] < 0.5 and r["back_call"]
    ),
    "compact region, at most 5 % of the frame clipped": lambda r: r["found"] and r["region"]["clipped"] <= 0.05,
    "never": lambda r: False,
}


def gate_table(rows: list[dict]) -> dict:
    """Each rule against the truth (the map's brightest source inside the view gives a rim >= RIM_SEEN): fires,
    right, wrong, missed, the share of views where it agrees."""
    truth = [r["view_rim"] >= RIM_SEEN for r in rows]
    out = {"views": len(rows), "with_a_source_in_view": int(sum(truth))}
    for name, rule in GATES.items():
        fire = [bool(rule(r)) for r in rows]
        out[name] = {"fires": sum(fire), "right": sum(f and t for f, t in zip(fire, truth, strict=True)),
                     "wrong": sum(f and not t for f, t in zip(fire, truth, strict=True)),
                     "missed": sum(t and not f for f, t in zip(fire, truth, strict=True)),
                     "agree": round(float(np.mean([f == t for f, t in zip(fire, truth, strict=True)])), 2)}  # fmt: skip
    return out


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
    rows, views = [], []
    for path in sorted(args.envs.glob("*.hdr")):
        env = envmap.load_envmap(path)
        lin = se.view_linear(env)
        k = se.GREY / max(se.mean_lum(lin), 1e-9)
        view = se.photograph(lin, k)
        _, back = bgmod.scene_light(view, 60.0).key(None)
        truth = panorama_rim(env, np.eye(3), math.pi * k)  # the view's camera is the map's frame; plate = π k env
        found = photo_rim(view, 60.0)
        seen = view_rim(env, k, view.shape[:2])
        seen_lum = 0.0 if seen is None else float(seen[1] @ REC709)
        views.append({"map": path.stem, "back_call": bool(back), "found": found is not None,
                      "view_rim": seen_lum, "region": region_features(view)})  # fmt: skip
        if truth is None or found is None:
            continue
        clip_only = photo_rim(view, 60.0, halo=False)[1]
        rows.append({"map": path.stem, "back_call": bool(back), "map_rim": float(truth[1] @ REC709),
                     "photo_rim": float(found[1] @ REC709), "old_photo_rim": old_photo_rim(view),
                     "view_rim": seen_lum, "colour_deg_halo": angle(found[1], seen[1]),
                     "colour_deg_clipped": angle(clip_only, seen[1])})  # fmt: skip
    res = {"found": {k: summary(rows, k) for k in ("photo_rim", "old_photo_rim")},
           "found_and_back": {k: summary([r for r in rows if r["back_call"]], k)
                              for k in ("photo_rim", "old_photo_rim")}}  # fmt: skip
    for name, sel in (("colour_seen", [r for r in rows if r["view_rim"] >= RIM_SEEN]), ("colour_all", rows)):
        res[name] = {"views": len(sel), **{key: round(float(np.median([r[key] for r in sel])), 1) if sel else None
                                           for key in ("colour_deg_clipped", "colour_deg_halo")},
                     "halo_changed": sum(abs(r["colour_deg_halo"] - r["colour_deg_clipped"]) > 0.05 for r in sel),
                     "halo_better": sum(r["colour_deg_halo"] < r["colour_deg_clipped"] - 0.05 for r in sel),
                     }  # fmt: skip
    res["gate"] = gate_table(views)
    print(json.dumps(res, indent=1))
    if args.out is not None:
        args.out.write_text(json.dumps({**res, "views": rows, "gate_views": views}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
