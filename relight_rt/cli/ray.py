"""``--ray`` of ``relight-rt relight`` and ``relight-rt video``: the same work on a Ray cluster, with a manifest
(relight_rt.distributed: ``relight_folder`` for photos, ``relight_videos`` for clips, one task each)."""

from __future__ import annotations

import argparse
import logging
import os
from pathlib import Path

from .._errors import RelightError
from .options import background, light_spec, runtime_config
from .report import finish_batch

log = logging.getLogger("relight_rt.distributed")


def _quiet_ray_data() -> None:
    """Ray Data's progress lines only with -v (the manifest is the record)."""
    if not log.isEnabledFor(logging.DEBUG):
        os.environ.setdefault("RAY_DATA_LOG_LEVEL", "WARNING")


def _finish(report, many: bool) -> int:
    log.info("manifest: %s (%d ok, %d skipped, %d failed)", report.manifest, report.written, report.skipped,
             report.count("failed"))  # fmt: skip
    return finish_batch(report.failures, report.written, many)


def cmd_relight_ray(args: argparse.Namespace) -> int:
    """``relight-rt relight ... --ray``: as the single-process command, with a manifest."""
    from ..distributed import relight_folder
    from ..exposure import parse_exposure

    _quiet_ray_data()
    spec = light_spec(args)
    config = runtime_config(args)
    if spec.source == "photo":  # the light of a photo: estimated once, here
        from ..relighter import Relighter

        light = Relighter.from_config(config.replace(device="cpu")).resolve_light(spec)
    else:
        light = spec.resolve()
    report = relight_folder(
        args.inputs, args.output, light, ray_address=args.ray, models=args.models, mask=args.mask,
        background=background(args), device=args.device, actors=args.ray_actors, gpus_per_actor=args.ray_gpus,
        cpus_per_actor=args.ray_cpus, batch_size=args.ray_batch_size, manifest=args.manifest,
        protect=list(spec.paths), config=config, exposure=parse_exposure(args.exposure),
    )  # fmt: skip
    return _finish(report, many=report.inputs > 1)


def plan_videos(args: argparse.Namespace) -> tuple[list[dict], list[tuple[str, str]]]:
    """Per-clip settings (relight_rt.video.relight_clip's keyword arguments) for ``relight-rt video SRC...
    --ray``: -o DST/ gives DST/STEM_relit.mp4; --frames-out, --lights-out and --metrics name folders that get
    STEM/, STEM_lights.npy and STEM_metrics.json. Returns (settings per clip, failures)."""
    from .video import clip_settings

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
    from ..distributed import MANIFEST_NAME, import_ray, relight_videos

    import_ray()  # missing: say so before anything is written
    clips, failures = plan_videos(args)
    for folder in (args.output, args.frames_out, args.lights_out, args.metrics):
        if folder:
            Path(folder).mkdir(parents=True, exist_ok=True)
    manifest = Path(args.manifest) if args.manifest else Path(args.output or args.frames_out) / MANIFEST_NAME
    report = relight_videos(clips, manifest, ray_address=args.ray, gpus_per_task=args.ray_gpus,
                            cpus_per_task=args.ray_cpus, failures=failures)  # fmt: skip
    return _finish(report, many=len(args.input) > 1)
