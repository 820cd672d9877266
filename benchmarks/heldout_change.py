"""Held-out renders under directional lights: is the relit change as strong as the true one? (issue 32)

    # once (renders; ~1 min per person and framing on the shared 2-core CPU, so ~10 min for --n 2):
    python benchmarks/heldout_change.py make --out runs/h32 --n 2
    # measure (seconds; or through benchmarks/real_photos.py --heldout runs/h32/photos_*):
    python benchmarks/heldout_change.py measure runs/h32/photos_* [--models DIR] [--json OUT.json] \
        [--turn 90|180|270] [--upright on|off]

``make`` writes six environment maps of one white lamp each (a 0.25-rad disc, from the image's left, right,
upper left, upper right, above, and low in front; irradiance 1 at the facing normal, plus ambient 0.05) to
OUT/lights_directional/*.hdr, then for every framing renders ``--n`` held-out people (seeds 100000...) with
``python -m export render`` and photographs each under ``--k`` of the lamps with ``python -m export render-photos``
(OUT/test_FRAMING, OUT/photos_FRAMING). Add ``--full-shading`` for hard shadows in the truth (a camera's view) rather
than the SH shading the models can reproduce.

``measure``: for every ordered pair (i, j) of photos of one person, photo i is relit by the runtime (automatic
exposure off: the true light j as given, the photo's mask given) and compared with photo j in the mask (pixel values
as stored, the pipeline's radiance scale; luminance = Rec. 709 weights):
- contrast: least-squares slope of log(relit / input) on log(truth / input) per pixel (1 = as strong as the truth),
  and their correlation; the slope is the correlation times the ratio of the two changes' spreads (standard
  deviations, also printed): at a correlation of 0.67 a slope of 0.8 needs a change 1.2x as spread as the truth's;
- RMSE of relit vs truth (RGB, in the mask), for the full runtime path and (its layers, ``layers(...)``)
  for stage 1's diffuse image alone (the quantity of docs/RESULTS.md's framing table, measured through the runtime).
Per framing (the folder name after its last "_"): means over pairs. ``--turn``: every photo, its mask and its light
turned by that many degrees counter-clockwise (the light about the view axis), compared with the turned truth: a
person lying or tilted (the runtime's upright rule, relight_rt.relight.upright, on by default; ``--upright off``: the
runtime without it).

``bands``: stage 1 alone (``--stage1`` graph, default the bundled one) on every photo, against the true transport of
its person (OUT/test_FRAMING/NAME_transport.npz) and the photo's true light, per pixel in the mask: the degree-1
band's magnitude over the degree-0 coefficient and the degree-2 band's, the angle between the degree-1 vectors, and
the same two ratios of the light's luminance (what relight_rt/relight/strength.py's gains and refit make up for).

    python benchmarks/heldout_change.py bands runs/h32/photos_* [--stage1 PATH]
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from relight_rt.image.color import REC709  # noqa: E402

FRAMINGS = ("full", "knees-up", "waist-up", "head-shoulders", "face")
EPS = 1e-3
LAMPS = {  # direction the light comes from, subject frame: +x toward the camera, +y image right, +z up
    "left": (0.35, -1.0, 0.25), "right": (0.35, 1.0, 0.25), "upper_left": (0.6, -0.7, 0.7),
    "upper_right": (0.6, 0.7, 0.7), "above": (0.3, 0.0, 1.0), "low_front": (1.0, 0.2, -0.5),
}


def lamp_envmap(direction, height: int = 64, radius: float = 0.25, ambient: float = 0.05) -> np.ndarray:
    """(H, 2H, 3) float32 map (DESIGN.md §3 layout): a white disc of half-angle ``radius`` plus uniform ambient."""
    from relight_rt.light.envmap import directions_envmap

    d = np.asarray(direction, np.float64)
    d /= np.linalg.norm(d)
    dirs = directions_envmap(height)
    disc = (dirs @ d) >= math.cos(radius)
    solid = 2 * math.pi * (1 - math.cos(radius))
    env = np.full(dirs.shape[:2], ambient / math.pi)
    env[disc] += 1.0 / solid  # irradiance ≈ 1 at the normal facing the lamp
    return np.repeat(env[..., None], 3, axis=2).astype(np.float32)


def make(args) -> int:
    out = args.out
    lights = out / "lights_directional"
    lights.mkdir(parents=True, exist_ok=True)
    for name, d in LAMPS.items():
        cv2.imwrite(str(lights / f"{name}.hdr"), lamp_envmap(d)[..., ::-1].copy())
    py = [sys.executable, "-m", "export"]
    for f in args.framings:
        test, photos = out / f"test_{f}", out / f"photos_{f}"
        subprocess.run([*py, "render", "--n", str(args.n), "--views", "1", "--resolution", "256", "--dirs", "128",
                        "--seed", "100000", "--framings", f, "--workers", str(args.workers), "--out", str(test)],
                       check=True, cwd=REPO)
        cmd = [*py, "render-photos", "--data", str(test), "--envmaps", str(lights), "--out", str(photos),
               "--k", str(args.k), "--samples", "32", "--workers", str(args.workers)]
        subprocess.run(cmd + (["--full-shading"] if args.full_shading else []), check=True, cwd=REPO)
    return 0


# -------------------------------------------------------------------------------------------- measuring


def _read(folder: Path, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    bgr = cv2.imread(str(folder / f"{name}_photo.png"), cv2.IMREAD_COLOR)
    mask = cv2.imread(str(folder / f"{name}_mask.png"), cv2.IMREAD_GRAYSCALE)
    light = np.load(folder / f"{name}_light.npy", allow_pickle=False)[:, ::-1]  # stored B, G, R
    return (cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB).astype(np.float32) / 255, mask.astype(np.float32) / 255,
            np.ascontiguousarray(light, dtype=np.float32))


def _rmse(a: np.ndarray, b: np.ndarray, m: np.ndarray) -> float:
    return float(np.sqrt(((a - b) ** 2)[m].mean()))


def turned(photo: tuple, quarters: int) -> tuple:
    """A held-out photo (image, mask, light) turned ``quarters`` x 90 deg counter-clockwise in the picture
    (np.rot90), and its light turned with it about the view axis (+x; the picture's right, +y, toward its top, +z:
    relight_rt.relight.upright ``quarter_rotation``)."""
    from relight_rt.light import sh
    from relight_rt.relight.upright import quarter_rotation

    img, mask, light = photo
    return (np.ascontiguousarray(np.rot90(img, quarters)), np.ascontiguousarray(np.rot90(mask, quarters)),
            sh.rotate(light, quarter_rotation(quarters)).astype(np.float32))


def pair_figures(relighter, src, dst) -> dict:
    (img_i, mask_i, _), (img_j, mask_j, light_j) = src, dst
    m = (mask_i > 0.5) & (mask_j > 0.5)
    res = relighter.layers(img_i, light_j, mask=mask_i, exposure="physical")
    relit, diffuse = np.asarray(res.image, np.float32), np.asarray(res.layers["diffuse"], np.float32)
    lum = lambda x: x[m] @ REC709  # noqa: E731
    ours = np.log(lum(relit) + EPS) - np.log(lum(img_i) + EPS)
    truth = np.log(lum(img_j) + EPS) - np.log(lum(img_i) + EPS)
    do, dt = ours - ours.mean(), truth - truth.mean()
    out = {"slope": float((do * dt).sum() / max((dt * dt).sum(), 1e-30)),
           "corr": float((do * dt).sum() / math.sqrt((do * do).sum() * (dt * dt).sum() + 1e-30)),
           "spread": float(math.sqrt((do * do).sum() / max((dt * dt).sum(), 1e-30))),
           "rmse": _rmse(relit, img_j, m), "rmse_stage1_diffuse": _rmse(np.clip(diffuse, 0, 1), img_j, m)}
    return out


def heldout_figures(relighter, folders: list[Path], quarters: int = 0) -> dict:
    """{framing: {"pairs", "slope_mean", "corr_mean", "rmse_mean", ...}} over the folders' photo pairs, every photo
    and its light turned ``quarters`` x 90 deg (``turned``; 0: as rendered, upright)."""
    result = {}
    for folder in map(Path, folders):
        names = sorted(p.name[: -len("_photo.png")] for p in folder.glob("*__L*_photo.png"))
        by_subject: dict[str, list[str]] = {}
        for n in names:
            by_subject.setdefault(n.rpartition("__L")[0], []).append(n)
        rows = []
        for group in by_subject.values():
            data = {n: turned(_read(folder, n), quarters) for n in group}
            rows += [pair_figures(relighter, data[a], data[b]) for a in group for b in group if a != b]
        framing = folder.name.rsplit("_", 1)[-1]
        summary = {"folder": str(folder), "pairs": len(rows), "subjects": len(by_subject)}
        for key in ("slope", "corr", "spread", "rmse", "rmse_stage1_diffuse"):
            vals = [r[key] for r in rows if key in r]
            if vals:
                summary[f"{key}_mean"] = float(np.mean(vals))
        summary["slope_min"] = float(min((r["slope"] for r in rows), default=float("nan")))
        result[framing] = summary
    return result


def measure(args) -> int:
    import relight_rt
    from relight_rt import RuntimeConfig

    relighter = relight_rt.open(RuntimeConfig(models=args.models, device="cpu"))
    relighter.upright = args.upright == "on"
    figs = heldout_figures(relighter, args.folders, (args.turn // 90) % 4)
    print(f"turned {args.turn} deg, upright rule {args.upright}")
    print("| framing | pairs (people) | change contrast vs truth (min) | correlation | spread ratio | relight RMSE | "
          "stage-1 RMSE |")
    print("|---|---|---|---|---|---|---|")
    for f, s in figs.items():
        g = lambda key, s=s: s.get(key, float("nan"))  # noqa: E731
        print(f"| {f} | {s['pairs']} ({s['subjects']}) | {g('slope_mean'):.2f} ({s['slope_min']:.2f}) | "
              f"{g('corr_mean'):.2f} | {g('spread_mean'):.2f} | {g('rmse_mean'):.4f} | "
              f"{g('rmse_stage1_diffuse_mean'):.4f} |")
    if args.json:
        Path(args.json).write_text(json.dumps(figs, indent=1))
    return 0


def _band_ratios(sh: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(..., 9) SH -> degree-1 magnitude / |degree 0|, degree-2 magnitude / |degree 0|."""
    d0 = np.abs(sh[..., 0]) + 1e-6
    return np.linalg.norm(sh[..., 1:4], axis=-1) / d0, np.linalg.norm(sh[..., 4:9], axis=-1) / d0


def band_figures(stage1_path: Path, folders: list[Path]) -> dict:
    """{framing: mean per-pixel band ratios of stage 1's and the true transport, degree-1 angle, light ratios}."""
    import onnxruntime as ort

    session = ort.InferenceSession(str(stage1_path), providers=["CPUExecutionProvider"])
    result = {}
    for folder in map(Path, folders):
        framing = folder.name.rsplit("_", 1)[-1]
        test = folder.parent / f"test_{framing}"
        rows = []
        for photo in sorted(folder.glob("*__L*_photo.png")):
            name = photo.name[: -len("_photo.png")]
            img, mask, light = _read(folder, name)
            with np.load(test / f"{name.rpartition('__L')[0]}_transport.npz", allow_pickle=False) as z:
                true = np.asarray(z["T"], np.float32)
            out = dict(zip([o.name for o in session.get_outputs()],
                           session.run(None, {"image": img.transpose(2, 0, 1)[None],
                                              "mask": mask[None, None]}), strict=True))
            pred = out["transport"][0].transpose(1, 2, 0)
            m = (mask > 0.5) & (true[..., 0] > 0.05)
            (p1, p2), (t1, t2) = _band_ratios(pred[m]), _band_ratios(true[m])
            a, b = pred[m][:, 1:4], true[m][:, 1:4]
            cos = (a * b).sum(1) / (np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1) + 1e-9)
            (lp1, lp2), (lt1, lt2) = _band_ratios(out["light"][0] @ REC709), _band_ratios(light @ REC709)
            rows.append({"d1": p1.mean(), "d1_true": t1.mean(), "d2": p2.mean(), "d2_true": t2.mean(),
                         "angle": np.degrees(np.arccos(np.clip(cos, -1, 1))).mean(),
                         "light_d1": lp1, "light_d1_true": lt1, "light_d2": lp2, "light_d2_true": lt2})
        result[framing] = {k: float(np.mean([r[k] for r in rows])) for k in rows[0]} | {"photos": len(rows)}
    return result


def bands(args) -> int:
    stage1 = args.stage1 or REPO / "relight_rt" / "models" / "stage1.onnx"
    figs = band_figures(stage1, args.folders)
    print(f"stage 1: {stage1}")
    print("| framing | photos | degree-1/0 (true) | degree-2/0 (true) | degree-1 angle | light degree-1/0 (true) "
          "| light degree-2/0 (true) |")
    print("|---|---|---|---|---|---|---|")
    for f, s in figs.items():
        print(f"| {f} | {s['photos']} | {s['d1']:.3f} ({s['d1_true']:.3f}) | {s['d2']:.3f} ({s['d2_true']:.3f}) | "
              f"{s['angle']:.1f}° | {s['light_d1']:.2f} ({s['light_d1_true']:.2f}) | "
              f"{s['light_d2']:.2f} ({s['light_d2_true']:.2f}) |")
    if args.json:
        Path(args.json).write_text(json.dumps(figs, indent=1))
    return 0


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    mk = sub.add_parser("make", help="render the held-out people under single-lamp maps")
    mk.add_argument("--out", type=Path, required=True)
    mk.add_argument("--n", type=int, default=2, help="people per framing")
    mk.add_argument("--k", type=int, default=3, help="lamps (photos) per person")
    mk.add_argument("--framings", nargs="+", default=list(FRAMINGS))
    mk.add_argument("--workers", type=int, default=1)
    mk.add_argument("--full-shading", action="store_true", help="truth shaded by the full map (hard shadows)")
    me = sub.add_parser("measure", help="figures over render-photos folders")
    me.add_argument("folders", type=Path, nargs="+")
    me.add_argument("--models", type=Path, default=None)
    me.add_argument("--json", type=Path, default=None)
    me.add_argument("--turn", type=int, default=0, choices=(0, 90, 180, 270),
                    help="turn every photo (and its light about the view axis) counter-clockwise by this many degrees")
    me.add_argument("--upright", choices=("on", "off"), default="on",
                    help="the runtime's upright rule (relight_rt.relight.upright): on (default) or off")
    bd = sub.add_parser("bands", help="stage 1's transport bands and light against the truth")
    bd.add_argument("folders", type=Path, nargs="+")
    bd.add_argument("--stage1", type=Path, default=None)
    bd.add_argument("--json", type=Path, default=None)
    args = p.parse_args(argv)
    return {"make": make, "measure": measure, "bands": bands}[args.cmd](args)


if __name__ == "__main__":
    raise SystemExit(main())
