"""Light from a background photo, measured on rendered scenes (the "into any scene" table of docs/RESULTS.md).

    python benchmarks/scene_eval.py --prepare-envs ../shared/hdri --envs ENVS
    python benchmarks/scene_eval.py --photos PHOTOS --people PEOPLE --envs ENVS --out runs/scene_eval \\
        [--pairs-per-target 2] [--subjects anny_100004,...] [--gain 6] [--no-stage1]

Inputs (made by the commands in docs/RESULTS.md): PEOPLE, held-out people from ``python -m export render``
(albedo, transport); ENVS, a folder of normalised .hdr maps (the nine CC0 maps of ../shared/hdri, each
turned by 0/90/180/270°); PHOTOS, ``python -m export render-photos --full-shading`` of every person
under every map of ENVS (hard shadows, GGX specular, subsurface: what a camera records).

For a person P and maps A != B:
- the background photo: a 256 x 192 perspective view of B (60° horizontal field of view, the camera at
  the subject looking along −x; relight_rt.background.envmap_view), of the radiance π·B (the scale at
  which the person's renders are in the same units as the view), auto-exposed like a camera (mean linear
  luminance 0.18), clipped and sRGB-encoded to 8 bits. Its exposure k_B puts everything in its units.
- ground truth: the photo of P under B, times k_B.
- (i) no relighting: the photo of P under A, times k_B (the same camera).
- (ii) estimated light: L = relight_rt.background.light_from_background(view) (the view alone), applied
  physically ("physical" exposure; for a light from the background composite's "auto" is the same) to
  (a) the renderer's own albedo and transport (isolates the light estimate) and (b) the bundled
  stage 1 + 2 run on the photo under A (the whole runtime).
- (ii) also with the scale that keeps the input person's mean luminance (``relight``'s "auto" exposure).
- (ii') the estimated light with the overall scale of the truth (diagnostic: direction and colour only).
- (iii) oracle: the true SH light of B (k_B · its projection), same two pipelines.
RMSE inside the mask (linear values, all clipped to [0, 1] as a camera records them), mean over pairs with
a 95 % bootstrap interval.
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

from export import dataset  # noqa: E402
from relight_rt import background as bgmod  # noqa: E402
from relight_rt import sh  # noqa: E402
from relight_rt.color import linear_to_srgb  # noqa: E402
from relight_rt.exposure import REC709  # noqa: E402

VIEW = (192, 256)  # (height, width)
GREY = 0.18


def view_photo(env: np.ndarray) -> tuple[np.ndarray, float]:
    """8-bit sRGB background photo of π·env and its exposure k (linear photo = k · π · env, clipped)."""
    view = bgmod.envmap_view(env * np.float32(math.pi), VIEW, 60.0)
    k = GREY / max(float((view @ REC709).mean()), 1e-6)
    disp = linear_to_srgb(np.clip(view * np.float32(k), 0, 1))
    return (disp * 255 + 0.5).astype(np.uint8), k


def prepare_envs(hdri: Path, out: Path, height: int = 128) -> None:
    """The evaluation maps: every .hdr of ``hdri`` area-resized to ``height``, normalised (brightest SH
    irradiance 1, export.render.envmaps.normalize_envmap) and turned by 0/90/180/270° about +z."""
    from export.render.envmaps import normalize_envmap, resize_envmap, rotate_envmap, write_hdr

    out.mkdir(parents=True, exist_ok=True)
    for path in sorted(hdri.glob("*.hdr")):
        env = normalize_envmap(resize_envmap(sh.load_envmap(path), height), 1.0)
        for step in range(4):
            write_hdr(out / f"{path.stem}_y{step * 90:03d}.hdr", rotate_envmap(env, step, 4))


def rmse(a, b, inside) -> float:
    """RMSE inside the mask of two linear images, both clipped to [0, 1] as the camera records them."""
    d = np.clip(a[inside], 0, 1) - np.clip(b[inside], 0, 1)
    return float(np.sqrt(np.mean(d**2)))


def diffuse(albedo, transport, light):
    return albedo * sh.shading(transport, light)


def bootstrap(values, n=2000, seed=0):
    v = np.asarray(values)
    rng = np.random.default_rng(seed)
    means = v[rng.integers(0, len(v), (n, len(v)))].mean(1)
    return float(v.mean()), float(np.percentile(means, 2.5)), float(np.percentile(means, 97.5))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--prepare-envs", type=Path, metavar="HDRI", help="only write the maps of HDRI into --envs")
    p.add_argument("--photos", type=Path)
    p.add_argument("--people", type=Path)
    p.add_argument("--envs", type=Path, required=True)
    p.add_argument("--out", type=Path)
    p.add_argument("--subjects", default=None, help="comma-separated subjects (default: all)")
    p.add_argument("--pairs-per-target", type=int, default=2, help="maps A drawn per (person, B)")
    p.add_argument("--gain", type=float, default=None, help="override background.HIGHLIGHT_GAIN")
    p.add_argument("--behind-blur", type=float, default=None, help="override background._BEHIND_BLUR (tuning)")
    p.add_argument(
        "--max-exposure",
        type=float,
        default=None,
        help="leave out maps B whose view needs an exposure k above this (near-black views)",
    )
    p.add_argument("--no-stage1", action="store_true", help="skip the bundled-model rows")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    if args.prepare_envs:
        prepare_envs(args.prepare_envs, args.envs)
        return 0
    if not (args.photos and args.people and args.out):
        p.error("--photos, --people and --out are needed (unless --prepare-envs)")
    if args.gain is not None:
        bgmod.HIGHLIGHT_GAIN = args.gain
    if args.behind_blur is not None:
        bgmod._BEHIND_BLUR = args.behind_blur
    args.out.mkdir(parents=True, exist_ok=True)

    photos = dataset.list_photos(args.photos)
    by_subject: dict[str, dict[str, str]] = {}
    for name in photos:
        subject, _ = dataset.split_photo_name(name)
        env = (args.photos / f"{name}_env.txt").read_text().strip()
        by_subject.setdefault(subject, {})[env] = name
    subjects = sorted(by_subject) if args.subjects is None else args.subjects.split(",")
    envs = sorted(set.intersection(*(set(by_subject[s]) for s in subjects)))
    views, exposure, true_light, est_light = {}, {}, {}, {}
    for e in envs:
        env = sh.load_envmap(args.envs / e)
        views[e], exposure[e] = view_photo(env)
        true_light[e] = sh.project_envmap(env) * exposure[e]  # the renders' units: image = albedo ⊙ T·L
        est_light[e] = bgmod.light_from_background(views[e], 60.0)[0].astype(np.float64)
    if args.max_exposure is not None:
        left_out = [e for e in envs if exposure[e] > args.max_exposure]
        print(f"left out (k > {args.max_exposure:g}): {', '.join(left_out) or 'none'}", file=sys.stderr)
        envs = [e for e in envs if e not in left_out]
    relighter = None
    if not args.no_stage1:
        from relight_rt import Relighter

        relighter = Relighter(device="cpu")
    rng = np.random.default_rng(args.seed)
    rows = []
    for s in subjects:
        sample = dataset.read_sample(args.people, s)
        albedo, transport = sample["albedo"], sample["transport"]
        decs = {}
        for b in envs:
            gt_photo = dataset.read_photo(args.photos, by_subject[s][b])
            inside = gt_photo["mask"] > 0.5
            gt = gt_photo["photo"] * exposure[b]
            l_est, l_true = est_light[b], true_light[b]
            r_est = diffuse(albedo, transport, l_est)
            r_true = diffuse(albedo, transport, l_true)
            lum = lambda img, m=inside: float((img[m] @ REC709).mean())  # noqa: E731
            scale = lum(gt) / max(lum(r_est), 1e-8)
            others = [a for a in envs if a != b]
            for a in rng.choice(others, size=min(args.pairs_per_target, len(others)), replace=False):
                src = dataset.read_photo(args.photos, by_subject[s][a])
                row = {
                    "subject": s, "A": str(a), "B": b,
                    "none": rmse(src["photo"] * exposure[b], gt, inside),
                    "est_renderer": rmse(r_est, gt, inside),
                    "est_keep_input_renderer": rmse(r_est * lum(src["photo"] * exposure[b]) / max(lum(r_est), 1e-8), gt,
                                                    inside),
                    "est_scaled_renderer": rmse(r_est * scale, gt, inside),
                    "oracle_renderer": rmse(r_true, gt, inside),
                }  # fmt: skip
                if relighter is not None:
                    if a not in decs:
                        decs[a] = relighter.decompose(src["photo"], src["mask"])
                    dec = decs[a]
                    black = np.zeros(src["photo"].shape, np.float32)
                    for key, light in (("est_stage1", l_est), ("oracle_stage1", l_true)):
                        out = relighter.relight(dec, light, background=black, exposure="physical")
                        row[key] = rmse(out, gt, inside)
                rows.append(row)
        print(f"{s}: {len(rows)} pairs so far", file=sys.stderr)
    keys = [k for k in rows[0] if k not in ("subject", "A", "B")]
    summary = {k: bootstrap([r[k] for r in rows]) for k in keys}
    gap = summary["none"][0] - summary["oracle_renderer"][0]
    closed = (summary["none"][0] - summary["est_renderer"][0]) / gap if gap else float("nan")
    better = float(np.mean([r["est_renderer"] < r["none"] for r in rows]))
    result = {"pairs": len(rows), "subjects": subjects, "envs": envs, "gain": bgmod.HIGHLIGHT_GAIN,
              "summary": summary, "gap_closed_renderer": closed, "est_better_than_none": better}  # fmt: skip
    if "est_stage1" in keys:
        gap1 = summary["none"][0] - summary["oracle_stage1"][0]
        result["gap_closed_stage1"] = (summary["none"][0] - summary["est_stage1"][0]) / gap1 if gap1 else float("nan")
    (args.out / "results.json").write_text(json.dumps({**result, "rows": rows}, indent=1))
    names = {
        "none": "(i) no relighting",
        "est_renderer": "(ii) light estimated from the background, renderer's albedo + transport",
        "est_keep_input_renderer": "(ii) estimated light, scaled to keep the input person's luminance (relight's auto)",
        "est_scaled_renderer": "(ii') the same, overall scale taken from the truth (diagnostic)",
        "oracle_renderer": "(iii) oracle: true SH light of B, renderer's albedo + transport",
        "est_stage1": "(ii) light estimated from the background, bundled stage 1 + 2",
        "oracle_stage1": "(iii) oracle: true SH light of B, bundled stage 1 + 2",
    }
    lines = ["| method | RMSE in mask | 95 % interval |", "|---|---|---|"]
    for k in keys:
        m, lo, hi = summary[k]
        lines.append(f"| {names[k]} | {m:.4f} | [{lo:.4f}, {hi:.4f}] |")
    (args.out / "table.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    print(json.dumps({k: v for k, v in result.items() if k not in ("summary", "envs", "subjects")}))
    sheet = np.concatenate([np.concatenate([views[e] for e in envs[i : i + 6]], 1) for i in range(0, 36, 6)
                            if len(envs[i : i + 6]) == 6], 0) if len(envs) >= 6 else None  # fmt: skip
    if sheet is not None:
        cv2.imwrite(str(args.out / "views.png"), cv2.cvtColor(sheet, cv2.COLOR_RGB2BGR))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
