"""Which pairs the estimate loses to the realistic paste, and why (issue 49's bar "better than the paste on >= 80 %").

    PYTHONPATH=$PWD:/tmp/scene_pylib python benchmarks/scene_losses.py --results runs/scene/loso100/results.json \
        --photos runs/scene/photos --people runs/scene/people --envs runs/scene/envs [--out FILE.json]

RESULTS: the ``results.json`` of ``benchmarks/scene_eval.py`` (any protocol); its per-scene fitted numbers give each
map's estimated light again (checked against its rows' ``si_est``). A pair (person P, place B, paste from place A)
is lost where the estimate's scale-invariant RMSE in the mask is not below the paste's. That score is blind to
exposure (one scalar is fitted away), so a lost pair is lost to the light's colour or to its shape (the spread of
its light over directions: what the shading's gradients and the shadows show). Each lost pair is put to two
counterfactual lights, both scored as scene_eval scores the estimate:
- ``colour fixed``: the estimate with each channel scaled so that its camera-facing irradiance has the true light's
  colour (its shape unchanged);
- ``shape fixed``: the true SH light with each channel scaled so that its camera-facing irradiance has the
  estimate's colour (the true shape in the estimate's colour).
A pair is lost to colour where only the colour fix wins it, to shape where only the shape fix does, to both where
either does, and ``unwinnable`` where the true SH light itself (scene_eval's oracle: no colour, no shape error) does
not beat the paste: the paste's photo carries what no SH light on the diffuse model has (hard shadows, specular,
subsurface), and its light A is often close to B (another turn of the same place, or a place alike).

The shape is then taken apart: ``side fixed`` gives the estimate the true light's left-right term (its SH y
coefficient, luminance, per unit camera-facing irradiance) and nothing else; y weighs nothing in the camera-facing
or the back irradiance (FRONT_WEIGHTS[1] = BACK_WEIGHTS[1] = 0), so this changes neither the exposure, the colour nor
the front/back scores. ``side read`` puts there the raw light's own y (steps 1-5 of
relight_rt.light.from_background: what the view says of the side), ``side wrong`` the true y with its sign turned,
``side gated T xK`` K × the raw light's y where that is at least T in size (``GATES``), none elsewhere; ``up fixed``
the true light's up-down term (z, also weightless in those scores) in place of the estimate's.
The pairs are also counted by how side-lit the place is (|y| of the true light, bands ``SIDE_BANDS``), per set, and
the view's side readings (the raw light's y, the brighter half, ``shading_side``) scored by their sign on the maps
with |y| >= 0.3.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
for p in (REPO, REPO / "benchmarks"):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

import scene_eval as se  # noqa: E402  (the benchmark's cameras and scores)

from relight_rt import envmap, sh  # noqa: E402
from relight_rt.image.color import REC709, srgb8_to_linear  # noqa: E402
from relight_rt.light import from_background as bgmod  # noqa: E402

SETS = {"shared": "../shared/hdri", "blender": "blender-data", "npm": "@pmndrs/assets"}
SIDE_BANDS = (0.3, 0.6)  #: |y| bands (low, mid, high) of the true light's left-right term (module docstring)
#: ``side gated``: the raw light's y × k where its size is >= t, else none (the view's strongest side readings only)
GATES = tuple((t, k) for t in (0.5, 1.0, 1.5) for k in (0.125, 0.25, 0.5))
COUNTERFACTUALS = ("colour fixed", "shape fixed", "side fixed", "side read", "side wrong", "up fixed",
                   *(f"side gated {t:g} x{k:g}" for t, k in GATES))  # fmt: skip


def side(light: np.ndarray, term: int = 1) -> float:
    """The left-right term of a (9, 3) light: its luminance SH y coefficient over its camera-facing irradiance
    (> 0: more light from the image's right, +y); ``term`` 2: the up-down term (z) alike."""
    lum = np.asarray(light, np.float64) @ REC709
    return float(lum[term] / max(float(se.FRONT_W @ lum), 1e-12))


def with_side(light: np.ndarray, y: float, term: int = 1) -> np.ndarray:
    """(9, 3) ``light`` with its left-right term (``side``; ``term`` 2: its up-down term) set to ``y`` in every
    channel alike (in proportion to the channel's camera-facing irradiance); its camera-facing and back irradiance
    unchanged."""
    rgb = se.side_rgb(light)
    out = np.array(light, np.float64)
    out[term] = y * rgb
    return out


def recolour(light: np.ndarray, like: np.ndarray) -> np.ndarray:
    """(9, 3) ``light`` with each channel scaled so that its camera-facing irradiance has the colour (RGB direction)
    of ``like``'s, its luminance unchanged."""
    a, b = se.side_rgb(light), se.side_rgb(like)
    gain = np.maximum(b, 1e-12) / np.maximum(a, 1e-12)
    out = np.asarray(light, np.float64) * gain[None, :]
    return out * (se.lum(a) / max(se.lum(se.side_rgb(out)), 1e-12))


def cause(si_paste: float, si_oracle: float, colour_fixed: float, shape_fixed: float) -> str:
    """What loses a pair (module docstring): "unwinnable", "colour", "shape", "both" (either fix wins) or "neither"
    (each fix alone keeps it lost, both together win it)."""
    if si_oracle >= si_paste:
        return "unwinnable"
    c, s = colour_fixed < si_paste, shape_fixed < si_paste
    return {(True, False): "colour", (False, True): "shape", (True, True): "both"}.get((c, s), "neither")


def analyse(rows: list, extra: dict, sides: dict) -> dict:
    """Per scene set and all: pairs, lost, each cause's count, the lost pairs' places B (most lost first), how many
    lost pairs paste another turn of B's own place, the win share with each counterfactual and by how side-lit B is.
    ``extra``: per row index, the scale-invariant RMSE of each of COUNTERFACTUALS; ``sides``: per map, its true
    light's ``side``."""
    out = {}
    for label in ("all", *SETS):
        idx = [i for i, r in enumerate(rows) if label == "all" or se.scene_set(r["B"]) == label]
        lost = [i for i in idx if rows[i]["si_est"] >= rows[i]["si_paste"]]
        won = [i for i in idx if rows[i]["si_est"] < rows[i]["si_paste"]]
        causes = Counter(cause(rows[i]["si_paste"], rows[i]["si_oracle"], *extra[i][:2]) for i in lost)
        bands = {}
        for name, lo, hi in (("low", 0, SIDE_BANDS[0]), ("mid", *SIDE_BANDS), ("high", SIDE_BANDS[1], np.inf)):
            band = [i for i in idx if lo <= abs(sides[rows[i]["B"]]) < hi]
            bands[name] = {"maps": len({rows[i]["B"] for i in band}),
                           "better_than_paste": float(np.mean([rows[i]["si_est"] < rows[i]["si_paste"]
                                                               for i in band])) if band else None}  # fmt: skip
        by_b = Counter(rows[i]["B"] for i in lost)
        by_scene = Counter(se.scene_of(rows[i]["B"]) for i in lost)
        out[label] = {
            "pairs": len(idx),
            "better_than_paste": 1 - len(lost) / max(len(idx), 1),
            "oracle_better_than_paste": float(np.mean([rows[i]["si_oracle"] < rows[i]["si_paste"] for i in idx])),
            **{
                f"{name}_better": float(np.mean([extra[i][k] < rows[i]["si_paste"] for i in idx]))
                for k, name in enumerate(COUNTERFACTUALS)
            },
            "by_side": bands,
            "lost": len(lost),
            "causes": dict(causes.most_common()),
            "lost_same_place": sum(se.scene_of(rows[i]["A"]) == se.scene_of(rows[i]["B"]) for i in lost),
            "pairs_same_place": sum(se.scene_of(rows[i]["A"]) == se.scene_of(rows[i]["B"]) for i in idx),
            "lost_by_scene": dict(by_scene.most_common()),
            "lost_by_map": dict(by_b.most_common()),
            "lost_colour_est_median": float(np.median([rows[i]["colour_est"] for i in lost])) if lost else 0.0,
            "won_colour_est_median": float(np.median([rows[i]["colour_est"] for i in won])),
            "lost_ev_est_median": float(np.median(np.abs([rows[i]["ev_est_background"] for i in lost] or [0.0]))),
            "won_ev_est_median": float(np.median(np.abs([rows[i]["ev_est_background"] for i in won]))),
        }
    return out


def shading_side(lum: np.ndarray) -> tuple[float, float]:
    """Two readings of the side from the (h, w) linear view's shading (> 0: light from the image's right): things lit
    from the right are brighter on their right (log2 luminance after a 1-px blur, steps over 2 px): the mean step
    to the right, each clipped to +-1, and over the strong steps (> 0.5) the share brighter on the right minus the
    share brighter on the left."""
    import cv2

    ll = cv2.GaussianBlur(np.log2(np.maximum(lum, 2.0**-13)).astype(np.float32), (0, 0), 1.0)
    dx = ll[:, 2:] - ll[:, :-2]
    strong = int((np.abs(dx) > 0.5).sum())
    polarity = float(((dx > 0.5).sum() - (dx < -0.5).sum()) / strong) if strong else 0.0
    return float(np.clip(dx, -1, 1).mean()), polarity


def side_signs(reads: dict, sides: dict) -> dict:
    """Per scene set and all: on the maps whose true ``side`` is at least SIDE_BANDS[0] in size, the share where
    each reading in ``reads`` ({name: {map: value}}) has its sign."""
    out = {}
    for label in ("all", *SETS):
        ms = [m for m in sides if (label == "all" or se.scene_set(m) == label) and abs(sides[m]) >= SIDE_BANDS[0]]
        out[label] = {"maps": len(ms), **{name: float(np.mean([np.sign(v[m]) == np.sign(sides[m]) for m in ms]))
                                          for name, v in reads.items()}}  # fmt: skip
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--results", type=Path, required=True)
    ap.add_argument("--photos", type=Path, required=True)
    ap.add_argument("--people", type=Path, required=True)
    ap.add_argument("--envs", type=Path, required=True)
    ap.add_argument("--out", type=Path)
    args = ap.parse_args(argv)
    from export import dataset

    res = json.loads(args.results.read_text())
    rows, fits = res["rows"], res["loso_fit"]
    by_subject, _, _ = se.photos_by_subject(args.photos)
    est, true1 = {}, {}
    reads = {"raw light's y": {}, "brighter half": {}, "shading gradient": {}, "edge polarity": {}}
    for m in sorted({r["B"] for r in rows}):
        env = envmap.load_envmap(args.envs / f"{m}.hdr")
        lin = se.view_linear(env)
        photo = se.photograph(lin, se.GREY / max(se.mean_lum(lin), 1e-9))
        parts = bgmod.scene_light(photo, 60.0)
        reads["shading gradient"][m], reads["edge polarity"][m] = shading_side(srgb8_to_linear(photo) @ REC709)
        est[m] = parts.light(**fits[se.scene_of(m)])
        true1[m] = envmap.project_envmap(env)
        reads["raw light's y"][m] = side(parts.light(**{**fits[se.scene_of(m)], "shape_weight": 1.0,
                                                        "front_back_power": 1.0}))  # fmt: skip
        reads["brighter half"][m] = parts.side
    sides = {m: side(t) for m, t in true1.items()}
    extra, checked = {}, []
    for subject in sorted({r["subject"] for r in rows}):
        sample = dataset.read_sample(args.people, subject)
        albedo, transport = sample["albedo"], sample["transport"]
        for m in sorted({r["B"] for r in rows if r["subject"] == subject}):
            truth = dataset.read_photo(args.photos, by_subject[subject][m])
            inside = truth["mask"] > 0.5

            def si(light, a=albedo, t=transport, truth=truth, inside=inside):
                return se.si_rmse(a * sh.shading(t, light), truth["photo"], inside)

            scores = (
                si(recolour(est[m], true1[m])),
                si(recolour(true1[m], est[m])),
                si(with_side(est[m], sides[m])),
                si(with_side(est[m], reads["raw light's y"][m])),
                si(with_side(est[m], -sides[m])),
                si(with_side(est[m], side(true1[m], 2), 2)),
                *(
                    si(with_side(est[m], k * y) if abs(y := reads["raw light's y"][m]) >= t else est[m])
                    for t, k in GATES
                ),
            )
            again = si(est[m])
            for i, r in enumerate(rows):
                if r["subject"] == subject and r["B"] == m:
                    extra[i] = scores
                    checked.append(abs(again - r["si_est"]))
    report = {"results": str(args.results), "si_est_recomputed_max_diff": float(max(checked)),
              **analyse(rows, extra, sides), "side_signs": side_signs(reads, sides)}  # fmt: skip
    for label in ("all", *SETS):
        a = report[label]
        fixes = ", ".join(f"{n} {100 * a[f'{n}_better']:.0f} %" for n in COUNTERFACTUALS if "gated" not in n)
        gated = ", ".join(f"{n[11:]} {100 * a[f'{n}_better']:.1f} %" for n in COUNTERFACTUALS if "gated" in n)
        print(f"{label:8s} pairs {a['pairs']:4d}  better than paste {100 * a['better_than_paste']:.0f} %  "
              f"(oracle {100 * a['oracle_better_than_paste']:.0f} %, {fixes})")  # fmt: skip
        print(f"         lost {a['lost']}: {a['causes']}  same place {a['lost_same_place']}/{a['lost']} "
              f"(of all pairs {a['pairs_same_place']}); |EV| lost / won {a['lost_ev_est_median']:.2f} / "
              f"{a['won_ev_est_median']:.2f}, colour {a['lost_colour_est_median']:.1f} / "
              f"{a['won_colour_est_median']:.1f} deg")  # fmt: skip
        print("         by |side|: " + ", ".join(f"{k} {100 * v['better_than_paste']:.0f} % ({v['maps']} maps)"
                                                 for k, v in a["by_side"].items() if v["maps"]))  # fmt: skip
        print(f"         lost by scene: {a['lost_by_scene']}")
        print(f"         today {100 * a['better_than_paste']:.1f} %; side gated: {gated}")
    for label, v in report["side_signs"].items():
        print(
            f"side's sign read from the view, {label} ({v['maps']} maps with |side| >= {SIDE_BANDS[0]}): "
            + ", ".join(f"{k} {100 * x:.0f} %" for k, x in v.items() if k != "maps")
        )
    print(f"si_est recomputed: max difference {report['si_est_recomputed_max_diff']:.2e}")
    if args.out:
        args.out.write_text(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
