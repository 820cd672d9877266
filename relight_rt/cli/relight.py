"""``relight-rt relight`` (photos, files or folders; ``--ray`` spreads them over a Ray cluster) and
``relight-rt decompose`` (a photo's albedo, shading, skin, light and transport)."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import numpy as np

from ..apps import batch
from ..engine.errors import RelightError
from ..engine.files import ProtectedPaths, npy_writer, npz_writer, write_all
from ..image.io import image_writer, sibling_mask
from ..light.exposure import for_light, parse_exposure
from ..person.masks import find_mask_file
from ..relight.transport_file import transport_arrays
from .options import (
    add_background_option,
    add_exposure_option,
    add_grade_background_option,
    add_light_options,
    add_mask_option,
    add_person_option,
    add_ray_options,
    add_runtime_options,
    background,
    light_spec,
    paths_of,
    relighter,
    runtime_config,
)
from .progress import progress
from .ray import finish_job, quiet_ray_data
from .report import finish_batch, os_error_text

log = logging.getLogger("relight_rt.cli")

# ------------------------------------------------------------------------------------------- relight


def add_relight(subparsers) -> None:
    p = subparsers.add_parser(
        "relight",
        help="relight photos of people",
        description="Relight photos (files or folders). Masks: --mask, else NAME_mask.png beside NAME.jpg, "
        "else the image's alpha channel, else the automatic matte.",
    )
    p.add_argument("inputs", nargs="+", metavar="INPUT", help="image files or folders of images")
    add_mask_option(p)
    add_person_option(p)
    add_light_options(p)
    add_background_option(p)
    add_grade_background_option(p)
    add_exposure_option(p)
    p.add_argument("-o", "--output", required=True, metavar="OUT", help="output file (one input) or folder")
    p.add_argument("--skip-existing", action="store_true", help="leave outputs that exist alone (resume a batch)")
    add_runtime_options(p)
    add_ray_options(p)  # --ray [ADDRESS|local] and its options (Ray itself is imported only with --ray)
    p.set_defaults(func=cmd_relight)


def _read_inputs(args: argparse.Namespace, files: list[Path], relighter, spec, bg) -> ProtectedPaths:
    """Every file ``relight`` reads, never to be written over: images, masks (beside them or anywhere in a
    --mask folder), light files, the background and the model graphs."""
    protect = set(files)
    mask_arg = args.mask if args.mask != "auto" else None
    named = [Path(p) for p in (mask_arg, *spec.paths, bg.path) if p]
    protect.update(p for p in named if p.is_file())
    protect.update(m for m in (sibling_mask(f) for f in (*files, *(p for p in named if p.is_file()))) if m)
    for folder in (Path(mask_arg),) if mask_arg and Path(mask_arg).is_dir() else ():
        protect.update(p for p in folder.iterdir() if p.is_file())
    protect.update(Path(relighter.models_dir).glob("*.onnx"))
    return ProtectedPaths(protect)


def _mask_note(path: Path, mask_arg: str | None) -> str:
    """" (mask: NAME_mask.png beside it)" when a mask file was picked up without --mask: a stale mask left
    beside the photo changes the result, and the user should see that it was used."""
    if mask_arg is not None:
        return ""
    found = batch.mask_for(path, None, single=True)
    return f" (mask: {found.name} beside it; --mask auto for the automatic matte)" if found else ""


def cmd_relight(args: argparse.Namespace) -> int:
    if getattr(args, "ray", None):  # the same work on a Ray cluster (relight_rt.apps.ray_jobs)
        return cmd_relight_ray(args)
    plan = batch.plan(args.inputs, args.output)
    files, failures, single = plan.inputs, plan.failures, plan.single
    out = Path(args.output)
    spec = light_spec(args)
    bg = background(args)
    rl = relighter(args)
    light = rl.resolve_light(spec)
    exposure = for_light(parse_exposure(args.exposure), spec)  # a preset may ask for its own (night: darker)
    protect = _read_inputs(args, files, rl, spec, bg)
    if not plan.to_file and files:
        out.mkdir(parents=True, exist_ok=True)
    written = 0
    show_bar = len(files) > 1
    for path, target in progress(plan.pairs, "image", show_bar):
        try:
            if args.skip_existing and target.exists():
                log.info("%s exists, skipped (--skip-existing)", target)
                continue
            batch.relight_file(rl, path, target, light, mask_arg=args.mask, single=single, background=bg,
                               protect=protect, exposure=exposure)
            written += 1
            if not show_bar:
                log.info("%s -> %s%s", path, target, _mask_note(path, args.mask))
        except (RelightError, OSError, MemoryError) as exc:  # the batch goes on past any bad file
            reason = os_error_text(exc) if isinstance(exc, OSError) else str(exc) or "out of memory"
            failures.append((str(path), reason))
    return finish_batch(failures, written, many=len(files) > 1)


def cmd_relight_ray(args: argparse.Namespace) -> int:
    """``relight-rt relight ... --ray``: as the single-process command, with a manifest."""
    from ..apps.ray_jobs import relight_folder

    quiet_ray_data()
    spec = light_spec(args)
    config = runtime_config(args)
    if spec.source == "photo":  # the light of a photo: estimated once, here
        light = relighter(args, device="cpu").resolve_light(spec)
    else:
        light = spec.resolve()
    report = relight_folder(
        args.inputs, args.output, light, ray_address=args.ray, models=args.models, mask=args.mask,
        background=background(args), device=args.device, actors=args.ray_actors, gpus_per_actor=args.ray_gpus,
        cpus_per_actor=args.ray_cpus, batch_size=args.ray_batch_size, manifest=args.manifest,
        protect=list(spec.paths), config=config, exposure=for_light(parse_exposure(args.exposure), spec),
    )  # fmt: skip
    return finish_job(report, many=report.inputs > 1)


# ------------------------------------------------------------------------------------------- decompose


def add_decompose(subparsers) -> None:
    p = subparsers.add_parser(
        "decompose",
        help="albedo, shading, skin, light and transport of a photo",
        description="Writes albedo.png, shading.png, skin.png (the photo's size and detail, see "
        "relight_rt.relight.decomposition.intrinsic_layers), light.npy ((9, 3) RGB SH) and transport.npz (the "
        "(R, R, 9) transport at the network's resolution, float16, with the crop geometry; "
        "relight_rt.relight.transport_file.load_transport brings it to the photo's size) into DIR. With --format "
        "exr or png16: render passes for compositors instead (relight_rt.apps.render_passes: albedo, shading under "
        "the photo's light and under the new light, diffuse, residual, beauty, foreground, alpha, a normal map "
        "read off the "
        "transport, light.json, passes.json), relit under the light given (default: the photo's own).",
    )
    p.add_argument("input", metavar="INPUT", help="image file")
    add_mask_option(p, several=False)
    add_person_option(p)
    p.add_argument("-o", "--output", required=True, metavar="DIR", help="output folder")
    p.add_argument("--format", choices=("png", "exr", "png16"), default="png",
                   help="png (default: the layers above, 8-bit), exr (float passes) or png16 (16-bit passes)")
    add_light_options(p, required=False)
    add_exposure_option(p)
    add_runtime_options(p)
    p.set_defaults(func=cmd_decompose)


def cmd_decompose(args: argparse.Namespace) -> int:
    src = Path(args.input)
    mask = find_mask_file(src, args.mask)
    spec = light_spec(args)
    exposure = parse_exposure(args.exposure)
    if args.format == "png" and (spec is not None or exposure != "auto"):
        raise RelightError("a light and --exposure are for the passes: add --format exr or --format png16")
    rl = relighter(args)
    dec = rl.decompose(src, mask)
    folder = Path(args.output)
    protect = [src, *paths_of(mask if mask != "auto" else None), *Path(rl.models_dir).glob("*.onnx")]
    if args.format != "png":
        from ..apps.render_passes import compute_passes, write_passes

        passes = compute_passes(rl, dec, spec, exposure=exposure)
        written = write_passes(folder, passes, args.format, protect=[*protect, *(spec.paths if spec else ())])
        log.info("%s -> %s (%d files: %s passes, light.json, passes.json)", src, folder, len(written), args.format)
        return 0
    folder.mkdir(parents=True, exist_ok=True)
    from ..relight.decomposition import intrinsic_layers

    layers = intrinsic_layers(dec)  # at the photo's resolution, with its detail in the albedo
    pngs = [(folder / f"{name}.png", image_writer(layers[name], folder / f"{name}.png"))
            for name in ("albedo", "shading", "skin")]  # encoded before anything is written
    write_all([  # the five layers or none of them (an input among them, a full disk)
        *pngs,
        # the photo's own light as the runtime takes it (white): albedo x shading = photo
        (folder / "light.npy", npy_writer(np.asarray(dec.white_light, np.float64))),
        # network size, float16, with its crop geometry: the arrays of transport_file.save_transport
        (folder / "transport.npz", npz_writer(transport_arrays(dec.transport, dec.geometry))),
    ], protect)  # fmt: skip
    log.info("%s -> %s (albedo.png, shading.png, skin.png, light.npy, transport.npz)", src, folder)
    return 0
