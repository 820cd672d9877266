"""Does the light wrap of ``composite`` bring the person's edge closer to a photo taken in the place?

    python benchmarks/light_wrap_eval.py --photos PHOTOS --people PEOPLE --envs ENVS [--out report.json]

The renders and maps of benchmarks/scene_eval.py (its docstring: the background photo of a map B, the truth
frame, the person at 75 % of a 256 x 192 view). The truth is the person rendered in B (``render-photos
--full-shading``: light from behind grazes the silhouette, as in a photograph) at the background camera's
exposure, laid over the background photo. The estimate is the renderer's albedo and transport of the person lit
by relight_rt.light.from_background's light from the background photo (shipped numbers) or by the true SH light of B
(oracle: no exposure or colour error, only the SH's missing rim), laid over the same photo; then
relight_rt.scene's light wrap with each (radius, strength) of the grid, radius a fraction of the frame height
(the default is WRAP_RADIUS, WRAP_STRENGTH); ``r=rim``: the shipped wrap and then the rim (relight_rt.apps.scene_rim):
for the estimate, a compact clipped source in the background photo, else its back key (``composite --rim``); for
the oracle, the map's own brightest source behind the person (``composite --view``'s default).

Scores, over every (person, map): the RMSE (linear RGB, both frames clipped to [0, 1] as a camera records them)
in the *edge band* (matte > 0.02 and within 3 px of the
outside, i.e. of matte < 0.5) between the composed estimate and the composed truth, raw and with the person's
overall scale fixed first (the best single factor over the whole mask, so that the band's error is the edge's
own, not the exposure's); and the same in the body's *interior* (more than 3 px inside), which the wrap
must leave alone. Reported for all maps and for the back-lit ones (the truth's back brighter than its front by
>= 1 EV).
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
for p in (REPO, REPO / "benchmarks"):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

import scene_eval as se  # noqa: E402

from relight_rt import envmap, sh  # noqa: E402
from relight_rt import scene as scene_mod  # noqa: E402
from relight_rt.apps.scene_rim import key_rim, panorama_rim, photo_rim  # noqa: E402
from relight_rt.image.color import srgb_to_linear  # noqa: E402
from relight_rt.light import from_background as bgmod  # noqa: E402

GRID_RADIUS = (0.003, 0.006, 0.01, 0.015)
GRID_STRENGTH = (0.25, 0.5, 0.75, 1.0)
BAND_PX = 3
WRAP_PX, WRAP_S = scene_mod.WRAP_RADIUS * se.VIEW[0], scene_mod.WRAP_STRENGTH  # the shipped wrap


def placed_alpha(mask: np.ndarray, place) -> np.ndarray:
    (y0, y1, x0, x1), (top, left, nh, nw) = place
    out = np.zeros(se.VIEW, np.float32)
    out[top : top + nh, left : left + nw] = cv2.resize(mask[y0:y1, x0:x1], (nw, nh), interpolation=cv2.INTER_AREA)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--photos", type=Path, required=True)
    ap.add_argument("--people", type=Path, required=True)
    ap.add_argument("--envs", type=Path, required=True)
    ap.add_argument("--out", type=Path)
    args = ap.parse_args(argv)
    from export import dataset

    by_subject, subjects, maps = se.photos_by_subject(args.photos)

    configs = [(None, 0.0)] + [(r, s) for r in GRID_RADIUS for s in GRID_STRENGTH] + [("rim", 0.0)]
    rows = []
    for m in maps:
        env = envmap.load_envmap(args.envs / f"{m}.hdr")
        lin1 = se.view_linear(env)
        k = se.GREY / max(se.mean_lum(lin1), 1e-9)
        view = se.photograph(lin1, k)
        bg_lin = srgb_to_linear(view)
        true_light = envmap.project_envmap(env) * np.float32(k)
        parts = bgmod.scene_light(view, 60.0)
        lights = {"est": parts.light(), "oracle": true_light}
        (az, el), back_key = parts.key()
        # the rims composite's step 7 uses (relight_rt.apps.scene_rim): the estimate's, a clipped source in the photo or
        # else its back key; the oracle's, the map's own source behind the person (composite --view's)
        rims = {"est": photo_rim(view, 60.0), "oracle": panorama_rim(env * np.float32(math.pi), np.eye(3), k)}
        if rims["est"] is None and back_key:
            front = np.maximum(bgmod.FRONT_WEIGHTS @ np.asarray(lights["est"], np.float64), 0)
            rims["est"] = (bgmod.key_direction(az, el), scene_mod._rim_gain(parts, lights["est"]) * front)
        back_lit = se.front_back(true_light) <= -se.CLEAR_EV
        for subject in subjects:
            sample = dataset.read_sample(args.people, subject)
            truth = dataset.read_photo(args.photos, by_subject[subject][m])
            place = se.placement(truth["mask"])
            a = placed_alpha(truth["mask"], place)
            solid = (a >= 0.5).astype(np.uint8)
            depth = cv2.distanceTransform(solid, cv2.DIST_L2, 3)
            band = (a > 0.02) & (depth <= BAND_PX)
            interior = depth > BAND_PX
            t_frame = se.frame(bg_lin, truth["photo"] * np.float32(k), truth["mask"], place)
            inside = truth["mask"] > 0.5
            for kind, light in lights.items():
                person = sample["albedo"] * sh.shading(sample["transport"], light)
                # the person's overall scale fixed first (best factor over the mask, on the unplaced renders)
                p, t = person[inside].reshape(-1), truth["photo"][inside].reshape(-1) * k
                scale = float(p @ t) / max(float(p @ p), 1e-12)
                for fixed, f in (("raw", 1.0), ("scaled", scale)):
                    e_frame = se.frame(bg_lin, person * np.float32(f), truth["mask"], place)
                    for radius, strength in configs:
                        out = e_frame
                        if radius == "rim":  # the shipped wrap, then the rim (composite's step 7)
                            out = scene_mod._light_wrap(e_frame, bg_lin, a, max(0.5, WRAP_PX), WRAP_S)
                            rim = rims[kind]
                            if rim is not None:
                                height = float((a > 0.005).any(1).sum())
                                out = key_rim(
                                    out, a, rim[0], rim[1], max(0.5, scene_mod.RIM_RADIUS * height)
                                )
                        elif radius is not None:
                            out = scene_mod._light_wrap(e_frame, bg_lin, a, max(0.5, radius * se.VIEW[0]), strength)
                        diff = np.clip(out, 0, 1) - np.clip(t_frame, 0, 1)  # what the cameras record
                        err = diff**2
                        rows.append({"map": m, "subject": subject, "light": kind, "fixed": fixed, "radius": radius,
                                     "strength": strength, "back_lit": bool(back_lit),
                                     "band": float(np.sqrt(err[band].mean())),
                                     "interior": float(np.sqrt(err[interior].mean())),
                                     "band_bias": float(diff[band].mean())})  # fmt: skip
        print(m, file=sys.stderr)

    summary = {}
    for kind in ("est", "oracle"):
        for fixed in ("raw", "scaled"):
            for subset in ("all", "back_lit"):
                sel = [r for r in rows if r["light"] == kind and r["fixed"] == fixed
                       and (subset == "all" or r["back_lit"])]  # fmt: skip
                base = {(r["map"], r["subject"]): r["band"] for r in sel if r["radius"] is None}
                for radius, strength in configs:
                    cur = [r for r in sel if r["radius"] == radius and r["strength"] == strength]
                    band = np.array([r["band"] for r in cur])
                    better = np.mean([r["band"] < base[(r["map"], r["subject"])] - 1e-9 for r in cur])
                    key = f"{kind}/{fixed}/{subset}/r={radius}/s={strength}"
                    summary[key] = {"n": len(cur), "band_rmse": float(band.mean()),
                                    "interior_rmse": float(np.mean([r["interior"] for r in cur])),
                                    "band_bias": float(np.mean([r["band_bias"] for r in cur])),
                                    "better_than_no_wrap": float(better)}  # fmt: skip
    for key, v in summary.items():
        print(f"{key:48s} n={v['n']:4d} band {v['band_rmse']:.4f} interior {v['interior_rmse']:.4f} "
              f"bias {v['band_bias']:+.4f} better {100 * v['better_than_no_wrap']:.0f}%")  # fmt: skip
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        command = "python benchmarks/light_wrap_eval.py " + " ".join(argv or sys.argv[1:])
        args.out.write_text(json.dumps({"command": command, "summary": summary}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
