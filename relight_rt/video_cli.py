"""``relight-rt video``: relight a video under a light that may change over time.

Registered by relight_rt.cli through :func:`add_parser`. Examples::

    relight-rt video clip.mp4 --masks masks/ -o out.mp4 --preset studio --rotate-per-second 0.25
    relight-rt video frames/ -o out.mp4 --frames-out out_frames/ --lights per_frame.npy
    relight-rt video frames/ -o out.mp4 --interpolate golden-hour sky.hdr night
    relight-rt video frames/ -o out.mp4 --lights per_frame.npy --dvp dvp.onnx

Deep video prior, from any light schedule: relight frame by frame keeping the frames and the lights
used (``--no-stabilize --frames-out relit/ --lights-out lights.npy``), fit it (``python -m export
fit-dvp --frames frames/ --relit relit/ --lights lights.npy --out dvp.onnx``), then apply it
(``--lights lights.npy --dvp dvp.onnx``).
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import sys
from pathlib import Path

import numpy as np

from ._errors import RelightError

logger = logging.getLogger(__name__)


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``video`` command to the ``relight-rt`` subparsers; returns its parser."""
    from ._options import add_background_option, add_exposure_option, add_light_options, add_runtime_options

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
    add_exposure_option(p)
    p.add_argument("--fps", type=float, help="frame rate of a frame folder (default 25) or override the video's")
    add_runtime_options(p)
    p.add_argument("--lights-out", help="write the (N, 9, 3) RGB light of every frame to this .npy "
                                        "(e.g. for python -m export fit-dvp --lights)")
    p.add_argument("--metrics", help="write temporal error, warping error and light-following to this JSON file")
    p.add_argument("--skip-bad-frames", action="store_true",
                   help="leave out frames that cannot be decoded or differ in size, report each, exit 2")
    from .distributed import add_ray_options

    add_ray_options(p, video=True)  # --ray: one clip per Ray task (relight_rt.distributed)
    p.set_defaults(func=run)
    return p


def _schedule(args, frame_count: int, relighter=None):
    from . import video
    from ._options import light_spec

    spec = None if args.lights or args.interpolate else light_spec(args)
    if args.lights or args.interpolate:
        what = "--lights" if args.lights else "--interpolate"
        if args.rotate or args.rotate_per_second is not None or args.bgr:
            raise RelightError(f"{what}: give either a per-frame schedule or one light [--rotate-per-second], "
                               "not both")
    if args.lights:
        return video.LightSchedule.from_file(args.lights)
    if args.interpolate:
        if len(args.interpolate) < 2:
            raise RelightError("--interpolate: expected at least two key lights")
        if frame_count < 1:
            raise RelightError(f"{args.input}: the frame count is unknown; --interpolate needs it, use --lights")
        keys = [video.resolve_light(k, relighter) for k in args.interpolate]
        return video.LightSchedule.interpolated(keys, frame_count)
    if spec is None:
        raise RelightError("light: expected --preset, --light, --envmap, --light-from, --lights or --interpolate")
    base = video.resolve_light(spec, relighter)
    if args.rotate_per_second is not None:
        return video.LightSchedule.rotating(base, args.rotate_per_second)
    return video.LightSchedule.constant(base)


class _LazyVideoMatter:
    """The automatic video matte (relight_rt.matting.VideoMatter), loaded at the first frame that needs it."""

    def __init__(self, device: str):
        self.device, self._matter = device, None

    def __call__(self, rgb, name: str = "frame"):
        if self._matter is None:
            from .matting import VideoMatter, shared_matter

            self._matter = VideoMatter(shared_matter(device=self.device))
        return self._matter(rgb, name=name)


def _video_matter(args):
    """Frames without a mask get the automatic matte (steady over time) when the matting graphs are installed."""
    import importlib.util

    if importlib.util.find_spec(f"{__package__}.matting") is None:
        return None
    from .matting import find_matting_models

    try:
        find_matting_models()
    except RelightError:
        return None
    return _LazyVideoMatter("cpu" if args.device == "cpu" else args.device)


def run(args: argparse.Namespace) -> int:
    """Run ``relight-rt video``; returns 0 (RelightError goes up to the CLI's main)."""
    from . import metrics as rt_metrics
    from . import video
    from ._io import atomic_path, check_target, write_npy
    from ._progress import Progress
    from .stabilize import Stabilizer

    if getattr(args, "ray", None):
        from .distributed import cmd_video_ray

        return cmd_video_ray(args)
    if isinstance(args.input, list):  # from the parser; several clips need --ray
        if len(args.input) != 1:
            raise RelightError(f"{len(args.input)} inputs: one clip at a time, or several with --ray")
        args.input = args.input[0]
    if not args.output and not args.frames_out:
        raise RelightError("output: expected -o VIDEO and/or --frames-out DIR")
    if args.fps is not None and not (math.isfinite(args.fps) and 0 < args.fps <= video.MAX_FPS):
        raise RelightError(f"--fps: must be > 0 and at most {video.MAX_FPS}, got {args.fps:g}")
    from ._options import background, relighter
    from .exposure import parse_exposure

    source = video.FrameSource(args.input, args.masks, args.fps, skip_bad=args.skip_bad_frames,
                               matter=_video_matter(args))
    bg = background(args)
    if bg.kind == "transparent" and args.output:
        raise RelightError("--background transparent: a video file has no alpha channel; use --frames-out DIR")
    engine = dvp = rl = None
    if args.dvp:
        dvp = video.DVPModel(args.dvp, device=args.device, size=args.dvp_size)
    else:
        rl = relighter(args)
        engine = video.RelighterEngine(rl, exposure=parse_exposure(args.exposure))
    schedule = _schedule(args, len(source), rl)
    light_files = [args.lights, args.light, args.envmap, args.light_from, *(args.interpolate or []), args.dvp,
                   bg.path]
    inputs = [*source.paths, *(Path(p) for p in light_files if p and Path(p).is_file())]
    if rl is not None:
        inputs += Path(rl.models_dir).glob("*.onnx")
    for written_last in (args.lights_out, args.metrics):  # files written after the work: refuse before it
        if written_last:
            check_target(Path(written_last), inputs)
    stabilizer = None if (args.no_stabilize or dvp is not None) else Stabilizer(args.stabilize_strength)
    audio = source.path if source.has_audio else None
    sink = video.FrameSink(args.output, args.frames_out, source.rate, protect=inputs, audio_from=audio)
    acc = rt_metrics.TemporalMetrics() if args.metrics else None
    used_lights: list = []  # (9, 3) per frame: 108 bytes each, bounded for any realistic clip

    def on_frame(frame, out, extras):
        if args.lights_out:
            used_lights.append(extras["light"])
        if acc is not None:
            acc.update(out, frame.mask, frame.image, extras.get("albedo"), extras.get("transport"), extras["light"])
        bar.update()

    with Progress(len(source), "frame") as bar:  # a bar with frames/s and the time left (relight_rt._progress)
        report = video.relight_video(source, schedule, sink, engine=engine, dvp=dvp, stabilizer=stabilizer,
                                     batch_size=args.batch_size, background=bg, on_frame=on_frame,
                                     with_layers=acc is not None)
    logger.info("%d frames, %.3f s per frame, lights: %s", report.frames, report.seconds_per_frame,
                schedule.description)
    if args.lights_out:
        path = write_npy(args.lights_out, np.stack(used_lights), protect=inputs)
        logger.info("wrote the %d frames' lights to %s", len(used_lights), path)
    if acc is not None and report.frames >= 2:
        res = acc.result()
        data = {"frames": report.frames, "seconds_per_frame": report.seconds_per_frame,
                "temporal_error": res.temporal_error, "warping_error": res.warping_error,
                "light_following": res.light_following, "light_gain": res.light_gain,
                "residual_error": res.residual_error,
                "stabilizer": stabilizer is not None, "dvp": args.dvp}
        with atomic_path(args.metrics, protect=inputs) as tmp:
            tmp.write_text(json.dumps(data, indent=1))
        logger.info("metrics: %s", json.dumps(data))
    for message in source.skipped:  # --skip-bad-frames: the output is kept, the run still fails
        print(f"relight-rt: error: {message}", file=sys.stderr)
    if source.skipped:
        print(f"relight-rt: {source.lost} frame(s) left out, {report.frames} written", file=sys.stderr)
        return 2
    return 0
