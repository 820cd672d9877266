"""``relight-rt video``: relight a video under a light that may change over time.

The work is relight_rt.video.job.relight_clip; ``--ray`` runs one clip per Ray task (relight_rt.cli.ray).
Examples::

    relight-rt video clip.mp4 --masks masks/ -o out.mp4 --preset studio --rotate-per-second 0.25
    relight-rt video frames/ -o out.mp4 --frames-out out_frames/ --lights per_frame.npy
    relight-rt video frames/ -o out.mp4 --interpolate golden-hour sky.hdr night
    relight-rt video frames/ -o out.mp4 --lights per_frame.npy --dvp dvp.onnx
    relight-rt video clip.mp4 -o night.mp4 --preset night --grade-background

Deep video prior, from any light schedule: relight frame by frame keeping the frames and the lights
used (``--no-stabilize --frames-out relit/ --lights-out lights.npy``), fit it (``python -m export
fit-dvp --frames frames/ --relit relit/ --lights lights.npy --out dvp.onnx``), then apply it
(``--lights lights.npy --dvp dvp.onnx``).
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from ..engine.errors import RelightError
from .options import (
    add_background_option,
    add_exposure_option,
    add_grade_background_option,
    add_light_options,
    add_ray_options,
    add_runtime_options,
    background,
    light_spec,
    runtime_config,
)
from .ray import finish_job
from .report import finish

logger = logging.getLogger(__name__)


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``video`` command to the ``relight-rt`` subparsers; returns its parser."""
    p = subparsers.add_parser("video", help="relight a video (file or frame folder) with per-frame lights",
                              description="Relight a video under a light that may change over time.")
    p.add_argument("input", nargs="+", help="video file (OpenCV) or folder of frames; several with --ray")
    p.add_argument("-o", "--output", help="output video file (.mp4, .avi, .mkv); with --ray, a folder")
    p.add_argument("--frames-out", help="also (or only) write the relit frames as PNGs into this folder")
    p.add_argument("--masks", help="mask folder, mask video or 'auto' (default: STEM_mask files beside the frames, "
                                   "else the alpha channel of RGBA frames, else the automatic matte, steady over "
                                   "time)")
    group = p.add_mutually_exclusive_group()
    add_light_options(p, group=group)
    group.add_argument("--lights", help="(N, 9, 3) RGB .npy: one light per frame")
    group.add_argument("--interpolate", nargs="+", metavar="LIGHT",
                       help="key lights (files, env maps or presets) interpolated over the whole clip")
    p.add_argument("--rotate-per-second", type=float, metavar="TURNS",
                   help="turn the light about the vertical axis at TURNS revolutions per second")
    p.add_argument("--dvp", help="a fitted dvp.onnx (python -m export fit-dvp): used instead of stage 1/2")
    p.add_argument("--dvp-size", type=int, help="long side the DVP was fitted at (fit-dvp --size)")
    p.add_argument("--no-stabilize", action="store_true", help="turn the training-free stabiliser off")
    p.add_argument("--stabilize-strength", type=float, default=0.8,
                   help="weight of the warped history where the flow is reliable, in [0, 1) (default 0.8)")
    p.add_argument("--batch-size", type=int, default=4, help="frames per stage-1 / DVP run")
    add_background_option(p)
    add_grade_background_option(p)  # one global grade per frame, followed over time (video.BackgroundGrade)
    add_exposure_option(p)
    p.add_argument("--fps", type=float, help="frame rate of a frame folder (default 25) or override the video's")
    add_runtime_options(p)
    p.add_argument("--lights-out", help="write the (N, 9, 3) RGB light of every frame to this .npy "
                                        "(e.g. for python -m export fit-dvp --lights)")
    p.add_argument("--metrics", help="write temporal error, warping error and light-following to this JSON file")
    p.add_argument("--skip-bad-frames", action="store_true",
                   help="leave out frames that cannot be decoded or differ in size, report each, exit 2")
    add_ray_options(p, video=True)  # --ray: one clip per Ray task (relight_rt.apps.ray_jobs)
    p.set_defaults(func=cmd_video)
    return p


def clip_lights(args: argparse.Namespace):
    """The ClipLights of ``video``'s light options (one light [turning], --lights or --interpolate)."""
    from ..video.job import ClipLights

    if args.lights or args.interpolate:
        what = "--lights" if args.lights else "--interpolate"
        if args.rotate or args.rotate_per_second is not None or args.bgr:
            raise RelightError(f"{what}: give either a per-frame schedule or one light [--rotate-per-second], "
                               "not both")
        if args.lights:
            return ClipLights(per_frame=args.lights)
        return ClipLights(keys=tuple(args.interpolate))
    spec = light_spec(args)
    if spec is None:
        raise RelightError("light: expected --preset, --light, --envmap, --light-from, --lights or --interpolate")
    return ClipLights(spec=spec, rotate_per_second=args.rotate_per_second)


def clip_settings(args: argparse.Namespace) -> dict:
    """The keyword arguments of relight_rt.video.job.relight_clip that ``video``'s options give, but for the clip
    and its per-clip outputs (input, output, frames_out, lights_out, metrics)."""
    return {
        "lights": clip_lights(args), "masks": args.masks, "fps": args.fps, "skip_bad_frames": args.skip_bad_frames,
        "background": background(args), "exposure": args.exposure, "config": runtime_config(args), "dvp": args.dvp,
        "dvp_size": args.dvp_size, "stabilize": not args.no_stabilize, "stabilize_strength": args.stabilize_strength,
        "batch_size": args.batch_size,
    }  # fmt: skip


def cmd_video(args: argparse.Namespace) -> int:
    """Run ``relight-rt video``; returns 0, or 2 when frames were left out (--skip-bad-frames)."""
    from ..builder import open as open_relighter
    from ..builder import video_matter
    from ..video.job import relight_clip
    from .progress import Progress

    if getattr(args, "ray", None):
        return cmd_video_ray(args)
    if len(args.input) != 1:  # several clips need --ray
        raise RelightError(f"{len(args.input)} inputs: one clip at a time, or several with --ray")
    settings = clip_settings(args)  # the matters are handed in (relight_rt.builder): the video job builds none
    relighter = None if args.dvp else open_relighter(settings["config"])
    report = relight_clip(args.input[0], output=args.output, frames_out=args.frames_out, lights_out=args.lights_out,
                          metrics=args.metrics, progress=lambda total: Progress(total, "frame"),
                          relighter=relighter, matter=video_matter(settings["config"]), **settings)  # fmt: skip
    logger.info("%d frames, %.3f s per frame, lights: %s", report.frames, report.seconds_per_frame, report.lights)
    # --skip-bad-frames: the output is kept, the run still fails
    return finish([("", message) for message in report.skipped],
                  f"{report.lost} frame(s) left out, {report.frames} written")  # fmt: skip


# ------------------------------------------------------------------------------------------- --ray


def plan_videos(args: argparse.Namespace) -> tuple[list[dict], list[tuple[str, str]]]:
    """Per-clip settings (relight_rt.video.job.relight_clip's keyword arguments) for ``relight-rt video SRC...
    --ray``: -o DST/ gives DST/STEM_relit.mp4; --frames-out, --lights-out and --metrics name folders that get
    STEM/, STEM_lights.npy and STEM_metrics.json. Returns (settings per clip, failures)."""
    if not args.output and not args.frames_out:
        raise RelightError("output: expected -o FOLDER and/or --frames-out FOLDER (with --ray, one file per clip)")
    for name in ("output", "frames_out", "lights_out", "metrics"):
        value = getattr(args, name, None)
        if value and Path(value).suffix and not Path(value).is_dir():
            raise RelightError(f"--{name.replace('_', '-')} {value}: with --ray, expected a folder (one file per clip)")
    base = clip_settings(args)
    clips, failures, seen = [], [], {}
    for clip in args.input:
        stem = Path(clip).stem
        if stem in seen:
            failures.append((clip, f"two clips named {stem} would both write {stem}_relit.mp4 ({seen[stem]})"))
            continue
        seen[stem] = clip
        settings = dict(base, src=clip)
        settings["output"] = str(Path(args.output) / f"{stem}_relit.mp4") if args.output else None
        settings["frames_out"] = str(Path(args.frames_out) / stem) if args.frames_out else None
        settings["lights_out"] = str(Path(args.lights_out) / f"{stem}_lights.npy") if args.lights_out else None
        settings["metrics"] = str(Path(args.metrics) / f"{stem}_metrics.json") if args.metrics else None
        clips.append(settings)
    return clips, failures


def cmd_video_ray(args: argparse.Namespace) -> int:
    """``relight-rt video SRC... -o DST/ --ray``: one Ray task per clip, a manifest of the clips."""
    from ..apps.ray_jobs import MANIFEST_NAME, import_ray, relight_videos

    import_ray()  # missing: say so before anything is written
    clips, failures = plan_videos(args)
    for folder in (args.output, args.frames_out, args.lights_out, args.metrics):
        if folder:
            Path(folder).mkdir(parents=True, exist_ok=True)
    manifest = Path(args.manifest) if args.manifest else Path(args.output or args.frames_out) / MANIFEST_NAME
    report = relight_videos(clips, manifest, ray_address=args.ray, gpus_per_task=args.ray_gpus,
                            cpus_per_task=args.ray_cpus, failures=failures)  # fmt: skip
    return finish_job(report, many=len(args.input) > 1)
