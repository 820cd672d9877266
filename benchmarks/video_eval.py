"""The video table of docs/RESULTS.md: frame-by-frame vs stabiliser vs DVP (unconditioned, conditioned).

    python benchmarks/video_eval.py --models MODELS_DIR --video ../shared/reference/video --out runs/video_eval \\
        [--size 512] [--light window-left] [--device cpu|cuda] [--dvp-width 64] [--dvp-max-epochs 100]

Steps (everything at one working size, the frames' long side scaled to ``--size``):
1. The frames and masks are resized into OUT/frames (the inputs are never written).
2. The light turns one full revolution about the vertical axis over the clip
   (relight_rt.lights.rotation_sequence), saved as OUT/lights.npy (RGB, (N, 9, 3)).
3. frame-by-frame: the runtime's stage 1 + stage 2 per frame, no stabiliser (OUT/framewise).
   Its per-frame albedo/transport (input frame) are kept in OUT/layers as the reference for the
   light-following score of every method.
4. stabiliser: the same with relight_rt.video.stabilize (OUT/stabilized).
5. DVP unconditioned and DVP conditioned: ``export.dvp.fit_dvp`` on (frames, frame-by-frame
   results, lights), exported to ONNX, then applied through the runtime (OUT/dvp_*).
6. Metrics (relight_rt.video.metrics) on each output sequence: temporal error (the paper's), warping
   error, residual error (change explained neither by motion nor by the light), light-following
   (correlation) and its gain; seconds per frame measured around the
   runtime's processing (reading and writing included; DVP fitting time listed apart).

Writes OUT/results.json, OUT/table.md (the markdown table for docs/RESULTS.md) and OUT/comparison.png
(the outputs side by side at six frames, and each method's mean frame-to-frame change).
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from relight_rt import lights as rt_lights  # noqa: E402
from relight_rt.image.io import read_image, write_image  # noqa: E402
from relight_rt.video import metrics as rt_metrics  # noqa: E402
from relight_rt.video.job import (  # noqa: E402
    DVPModel,
    FrameSink,
    FrameSource,
    LightSchedule,
    RelighterEngine,
    relight_video,
    resolve_light,
)
from relight_rt.video.stabilize import Stabilizer  # noqa: E402

log = logging.getLogger("video_eval")


def prepare_frames(video: Path, out: Path, size: int) -> Path:
    """Resize the frames (long side = size) and their masks into out/frames as NAME.png / NAME_mask.png."""
    folder = out / "frames"
    folder.mkdir(parents=True, exist_ok=True)
    for frame in FrameSource(video):
        h, w = frame.image.shape[:2]
        scale = size / max(h, w)
        shape = (max(1, round(w * scale)), max(1, round(h * scale)))
        write_image(folder / f"{frame.name}.png", cv2.resize(frame.image, shape, interpolation=cv2.INTER_AREA))
        write_image(folder / f"{frame.name}_mask.png", cv2.resize(frame.mask, shape, interpolation=cv2.INTER_AREA))
    return folder


def measure(out_dir: Path, frames: Path, layers_dir: Path, lights: np.ndarray) -> rt_metrics.MetricsResult:
    """Metrics of the frames in out_dir against the inputs, with the frame-by-frame layers as reference."""
    acc = rt_metrics.TemporalMetrics(flow_preset="medium")
    for frame in FrameSource(frames):
        out = read_image(out_dir / f"{frame.name}.png", frame.name)
        with np.load(layers_dir / f"{frame.name}.npz", allow_pickle=False) as layer:
            albedo, transport = layer["albedo"].astype(np.float32), layer["transport"].astype(np.float32)
        acc.update(out, frame.mask, frame.image, albedo, transport, lights[frame.index])
    return acc.result()


def write_comparison(path: Path, frames: Path, rows: dict[str, dict], columns: int = 6, tile: int = 192) -> None:
    """A PNG to look at: the input and every method's output at ``columns`` evenly spaced frames, one row
    each, then per method the mean |output[t+1] − output[t]| over the clip (×8, inside both masks), where
    flicker shows as speckle and the light's own change as smooth shading."""
    from export.render.contact_sheet import write_sheet

    source = list(FrameSource(frames))
    picks = np.linspace(0, len(source) - 1, min(columns, len(source))).round().astype(int)
    sheet = [[(f"input {source[i].name}", source[i].image) for i in picks]]
    changes = []
    for label, row in rows.items():
        tiles, total, prev = [], np.zeros(source[0].image.shape, np.float32), None
        for t, frame in enumerate(source):  # one pass over the outputs, two at a time
            cur = read_image(path.parent / row["dir"] / f"{frame.name}.png", label)
            if t in picks:
                tiles.append((label if not tiles else frame.name, cur))
            if prev is not None:
                total += np.abs(cur - prev) * ((source[t - 1].mask >= 0.5) & (frame.mask >= 0.5))[..., None]
            prev = cur
        sheet.append(tiles)
        changes.append((f"{label}: mean |change| x8", 8 * total / (len(source) - 1)))
    sheet.append(changes)
    write_sheet(path, sheet, tile=tile)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", required=True, help="folder with stage1.onnx and stage2.onnx")
    parser.add_argument("--video", required=True, help="frame folder (NAME.png + NAME_mask.png) or video")
    parser.add_argument("--masks", help="mask folder/video when --video has no STEM_mask files")
    parser.add_argument("--out", required=True, help="output folder")
    parser.add_argument("--size", type=int, default=512, help="working size of the long side")
    parser.add_argument("--light", default="window-left", help="the light that turns once over the clip")
    parser.add_argument("--device", default="cpu", help="cpu / cuda (runtime and DVP fitting)")
    parser.add_argument("--fps", type=float, default=24.0, help="frame rate of a frame folder")
    parser.add_argument("--dvp-width", type=int, default=64)
    parser.add_argument("--dvp-max-epochs", type=int, default=100)
    parser.add_argument("--dvp-patience", type=int, default=8)
    parser.add_argument("--dvp-ema", type=float, help="DVP weight average decay per step (export.dvp; default off)")
    parser.add_argument("--dvp-output-activation", choices=("none", "tanh"), default="none",
                        help="DVP output activation: none (the reference's) or tanh (the runs in docs/RESULTS.md "
                             "made before 2026-11-23 21:50)")
    parser.add_argument("--vgg-weights", help="local VGG19 weights for the DVP perceptual loss")
    parser.add_argument("--skip-dvp", action="store_true", help="only frame-by-frame and the stabiliser")
    parser.add_argument("--dvp-variants", default="unconditioned,conditioned",
                        help="which DVP fits to run, comma-separated (default: both)")
    args = parser.parse_args(argv)
    variants = {v.strip() for v in args.dvp_variants.split(",") if v.strip()}
    if not variants or variants - {"unconditioned", "conditioned"}:
        parser.error(f"--dvp-variants: expected unconditioned and/or conditioned, got {args.dvp_variants!r}")
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    from relight_rt.engine.config import RuntimeConfig
    from relight_rt.relight.relighter import Relighter

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    frames = prepare_frames(Path(args.video), out, args.size)
    n = len(FrameSource(frames))
    lights = rt_lights.rotation_sequence(resolve_light(args.light), n, axis="z", turns=1.0).astype(np.float32)
    np.save(out / "lights.npy", lights)
    schedule = LightSchedule.sequence(lights)
    device = "cuda" if args.device.startswith("cuda") else "cpu"
    engine = RelighterEngine(Relighter(RuntimeConfig(models=args.models, device=device)))
    layers_dir = out / "layers"
    layers_dir.mkdir(exist_ok=True)

    def keep_layers(frame, _out, extras):
        np.savez_compressed(layers_dir / f"{frame.name}.npz", albedo=extras["albedo"].astype(np.float16),
                            transport=extras["transport"].astype(np.float16))

    rows: dict[str, dict] = {}
    src = FrameSource(frames, fps=args.fps)
    report = relight_video(src, schedule, FrameSink(frames_dir=out / "framewise", protect=src.paths), engine=engine)
    rows["frame-by-frame"] = {"dir": "framewise", "seconds_per_frame": report.seconds_per_frame}
    src = FrameSource(frames, fps=args.fps)  # again, untimed, keeping the per-frame layers
    relight_video(src, schedule, FrameSink(frames_dir=out / "framewise_again", protect=src.paths), engine=engine,
                  on_frame=keep_layers, with_layers=True)
    src = FrameSource(frames, fps=args.fps)
    report = relight_video(src, schedule, FrameSink(frames_dir=out / "stabilized", protect=src.paths), engine=engine,
                           stabilizer=Stabilizer())
    rows["training-free stabiliser"] = {"dir": "stabilized", "seconds_per_frame": report.seconds_per_frame}

    if not args.skip_dvp:
        from export.dvp import export_dvp, fit_dvp, load_clip

        clip = load_clip(frames, out / "framewise", out / "lights.npy")
        for conditioned, label in ((False, "DVP, unconditioned"), (True, "DVP, light-conditioned")):
            if ("conditioned" if conditioned else "unconditioned") not in variants:
                continue
            tag = "dvp_conditioned" if conditioned else "dvp_unconditioned"
            t0 = time.perf_counter()
            model, history = fit_dvp(clip, conditioned=conditioned, width=args.dvp_width, vgg_weights=args.vgg_weights,
                                     max_epochs=args.dvp_max_epochs, patience=args.dvp_patience, device=args.device,
                                     ema=args.dvp_ema, output_activation=args.dvp_output_activation)
            fit_seconds = time.perf_counter() - t0
            (out / f"{tag}.fit.json").write_text(json.dumps(history, indent=1))
            export_dvp(model, out / f"{tag}.onnx", source=f"video_eval {tag}")
            dvp = DVPModel(out / f"{tag}.onnx", device="cuda" if args.device.startswith("cuda") else "cpu")
            src = FrameSource(frames, fps=args.fps)
            report = relight_video(src, schedule, FrameSink(frames_dir=out / tag, protect=src.paths), dvp=dvp)
            rows[label] = {"dir": tag, "seconds_per_frame": report.seconds_per_frame, "fit_seconds": fit_seconds,
                           "best_epoch": history["best_epoch"], "epochs": len(history["epochs"]),
                           "loss": history["loss"]}

    for row in rows.values():
        res = measure(out / row["dir"], frames, layers_dir, lights)
        row.update(temporal_error=res.temporal_error, warping_error=res.warping_error,
                   light_following=res.light_following, light_gain=res.light_gain,
                   residual_error=res.residual_error)
    (out / "results.json").write_text(json.dumps({"frames": n, "size": args.size, "light": args.light,
                                                  "models": args.models, "rows": rows}, indent=1))
    lines = ["| method | temporal error ×100 ↓ | warping error ×100 ↓ | residual error ×100 ↓ "
             "| light-following ↑ (gain) | s / frame |",
             "|---|---|---|---|---|---|"]
    for label, row in rows.items():
        fit = f" (+ {row['fit_seconds']:.0f} s fitting, epoch {row['best_epoch']})" if "fit_seconds" in row else ""
        lines.append(f"| {label} | {100 * row['temporal_error']:.3f} | {100 * row['warping_error']:.3f} | "
                     f"{100 * row['residual_error']:.3f} | {row['light_following']:.3f} ({row['light_gain']:.2f}) | "
                     f"{row['seconds_per_frame']:.3f}{fit} |")
    table = "\n".join(lines) + "\n"
    (out / "table.md").write_text(table)
    write_comparison(out / "comparison.png", frames, rows)
    print(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
