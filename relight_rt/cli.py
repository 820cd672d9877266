"""Command line interface: ``relight-rt COMMAND ...``.

Commands: ``relight``, ``decompose``, ``lights list|show|from-envmap``, ``doctor`` (and ``video`` when
relight_rt.video_cli is present). Each command is registered by its own ``add_*`` function; another
module adds one with an ``add_parser(subparsers)`` function that sets ``func`` on its parser.

Errors: bad input, a malformed file or one that cannot be read or written (any OSError) is one line on
stderr (``relight-rt: error: ...``) and exit code 2, never a traceback; in batch mode every file is tried
and every failure is listed at the end. Ctrl-C exits 130 and SIGTERM 143, with one line, after the
atomic writers removed their temporary files. Outputs are written atomically and never over a file the
command reads (relight_rt._io.ProtectedPaths). Native libraries' own stderr output is silenced unless
``-v`` (relight_rt._process).
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import logging
import math
import sys
from pathlib import Path

import numpy as np

from . import __version__, batch, lights, sh
from ._errors import RelightError
from ._io import (
    ProtectedPaths,
    atomic_path,
    check_target,
    encode_image,
    sibling_mask,
    write_all,
    write_image,
    write_npy,
)
from ._limits import DEFAULT_MAX_PIXELS, pixel_limit
from ._options import (
    add_background_option,
    add_exposure_option,
    add_light_options,
    add_mask_option,
    add_runtime_options,
    background,
    light_spec,
    paths_of,
    relighter,
)
from ._process import interrupt_handling, quiet_native_libraries
from ._progress import progress
from .distributed import add_ray_options
from .exposure import parse_exposure
from .lightspec import LightSpec, parse_light
from .masks import find_mask_file
from .transport_file import transport_arrays

log = logging.getLogger("relight_rt.cli")


def _add_model_options(p: argparse.ArgumentParser) -> None:
    """The runtime options (kept under this name for plugins written against it)."""
    add_runtime_options(p)


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
    add_light_options(p)
    add_background_option(p)
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


def cmd_relight(args: argparse.Namespace) -> int:
    if getattr(args, "ray", None):  # relight_rt.distributed: the same work on a Ray cluster
        from .distributed import cmd_relight_ray

        return cmd_relight_ray(args)
    plan = batch.plan(args.inputs, args.output)
    files, failures, single = plan.inputs, plan.failures, plan.single
    out = Path(args.output)
    spec = light_spec(args)
    bg = background(args)
    rl = relighter(args)
    light = rl.resolve_light(spec)
    exposure = parse_exposure(args.exposure)
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
                log.info("%s -> %s", path, target)
        except (RelightError, OSError, MemoryError) as exc:  # the batch goes on past any bad file
            failures.append((str(path), _os_error(exc) if isinstance(exc, OSError) else str(exc) or "out of memory"))
    for item, message in failures:
        text = message if item in message else f"{item}: {message}"
        print(f"relight-rt: error: {text}", file=sys.stderr)
    if failures and len(files) > 1:
        print(f"relight-rt: {len(failures)} failed, {written} written", file=sys.stderr)
    return 2 if failures else 0


# ------------------------------------------------------------------------------------------- decompose


def add_decompose(subparsers) -> None:
    p = subparsers.add_parser(
        "decompose",
        help="albedo, shading, skin, light and transport of a photo",
        description="Writes albedo.png, shading.png, skin.png (the photo's size and detail, see "
        "Relighter.layers), light.npy ((9, 3) RGB SH) and transport.npz (the (R, R, 9) transport at the network's "
        "resolution, float16, with the crop geometry; relight_rt.load_transport brings it to the photo's size) "
        "into DIR.",
    )
    p.add_argument("input", metavar="INPUT", help="image file")
    add_mask_option(p, several=False)
    p.add_argument("-o", "--output", required=True, metavar="DIR", help="output folder")
    add_runtime_options(p)
    p.set_defaults(func=cmd_decompose)


def cmd_decompose(args: argparse.Namespace) -> int:
    src = Path(args.input)
    mask = find_mask_file(src, args.mask)
    rl = relighter(args)
    dec = rl.decompose(src, mask)
    folder = Path(args.output)
    folder.mkdir(parents=True, exist_ok=True)
    protect = [src, *paths_of(mask if mask != "auto" else None), *Path(rl.models_dir).glob("*.onnx")]
    layers = rl.layers(dec)  # at the photo's resolution, with its detail in the albedo
    pngs = {name: encode_image(layers[name], ".png", name=str(folder / f"{name}.png"))
            for name in ("albedo", "shading", "skin")}
    transport = transport_arrays(dec.transport, dec.geometry)  # network size, float16, with its crop geometry
    write_all([  # the five layers or none of them (an input among them, a full disk)
        *((folder / f"{name}.png", lambda f, data=data: f.write(data)) for name, data in pngs.items()),
        # the photo's own light as the runtime takes it (white): albedo x shading = photo
        (folder / "light.npy", lambda f: np.save(f, np.asarray(dec.white_light, np.float64), allow_pickle=False)),
        (folder / "transport.npz", lambda f: np.savez_compressed(f, **transport)),
    ], protect)  # fmt: skip
    log.info("%s -> %s (albedo.png, shading.png, skin.png, light.npy, transport.npz)", src, folder)
    return 0


# ------------------------------------------------------------------------------------------- lights


def add_lights(subparsers) -> None:
    p = subparsers.add_parser("lights", help="list, show and make SH lights")
    metavar = "{list,show,from-envmap,from-photo,from-background}"
    sub = p.add_subparsers(dest="lights_command", required=True, metavar=metavar)
    ls = sub.add_parser("list", help="the named lights, one per line, name first")
    ls.set_defaults(func=cmd_lights_list)
    show = sub.add_parser(
        "show", help="render a light on a diffuse sphere; an environment map with the subject's axes",
        description="Render a light on a white diffuse sphere as the camera sees it. An environment map "
        "(.hdr/.exr, or an equirectangular .png/.jpg) is drawn with the subject's axes (the camera, what is "
        "behind the subject, left and right) beside the sphere it gives, with how --rotate turns it; when most "
        "of its light comes from behind the subject the sheet says so and which --rotate turns it to the face.",
    )
    show.add_argument("name", metavar="LIGHT",
                      help="preset name, light file (.npy/.json), environment map or photo of a person")  # fmt: skip
    show.add_argument("--size", type=int, default=256,
                      help="sphere image size in pixels (a map: the height of the map and the sphere; default 256)")
    show.add_argument("--rotate", type=float, default=0.0, metavar="DEG",
                      help="turn the light about the vertical axis; 90 brings the light on the left round to the face")
    show.add_argument("--bgr", action="store_true", help="the light file's columns are B, G, R (reference files)")
    show.add_argument("-o", "--output", required=True, metavar="PNG")
    show.set_defaults(func=cmd_lights_show)
    env = sub.add_parser("from-envmap", help="project an environment map to a (9, 3) SH light")
    env.add_argument("envmap", metavar="HDR")
    env.add_argument("-o", "--output", required=True, metavar="LIGHT", help=".npy or .json")
    env.set_defaults(func=cmd_lights_from_envmap)
    photo = sub.add_parser("from-photo", help="estimate the light of a photo of a person (stage 1)")
    photo.add_argument("photo", metavar="PHOTO")
    add_mask_option(photo, several=False)
    photo.add_argument("-o", "--output", required=True, metavar="LIGHT", help=".npy or .json")
    photo.set_defaults(func=cmd_lights_from_photo)
    extra = []  # lights from-background, when relight_rt.scene_cli is present
    if importlib.util.find_spec("relight_rt.scene_cli") is not None:
        extra.append(importlib.import_module("relight_rt.scene_cli").add_from_background(sub))
    for q in (ls, show, env, photo, *extra):  # every command takes them; only from-photo runs a model
        add_runtime_options(q)


def cmd_lights_list(args: argparse.Namespace) -> int:
    notes = getattr(lights, "_PRESETS", {})
    for name in lights.list_presets():
        note = notes.get(name, (None, None, ""))[2] if isinstance(notes.get(name), tuple) else ""
        print(f"{name}\t{note}".rstrip())
    return 0


def cmd_lights_show(args: argparse.Namespace) -> int:
    if not 8 <= args.size <= 8192:
        raise RelightError(f"--size is {args.size}, expected 8 to 8192")
    from . import _light_sheet

    name = Path(args.name)
    spec = parse_light(args.name)  # the one rule: preset, light file, environment map or photo
    if args.bgr and spec.source != "file":
        raise RelightError("--bgr: it says how to read a light file; a preset or a map has no colour order to choose")
    spec = LightSpec.file(name, bgr=True) if args.bgr else spec
    spec = spec.rotated(args.rotate)
    protect = [name, *spec.paths]
    if spec.source == "envmap":
        env = sh.load_envmap(spec.value)  # decoded once, for the light and for the sheet
        light = sh.rotate_z(sh.project_envmap(env), math.radians(spec.rotate))
        light = sh.check_light(light, "light").astype(np.float32)
        image, notes = _light_sheet.envmap_sheet(env, light, args.rotate, args.size)
    else:
        light = relighter(args).resolve_light(spec) if spec.source == "photo" else spec.resolve()
        image, notes = sh.render_sphere(light, size=args.size), _light_sheet.notes(light, args.rotate)
    check_target(args.output, protect)
    for line in notes:
        log.warning("%s", line)
    write_image(args.output, image, protect=protect)
    log.info("%s -> %s", args.name, args.output)
    return 0


def _light_output(output: str, source: str) -> Path:
    """The output light file, checked before any work: .npy or .json, and not the input."""
    out = Path(output)
    if out.suffix.lower() not in (".npy", ".json"):
        raise RelightError(f"output {out}: expected a .npy or .json light file")
    check_target(out, [source, *filter(None, [sibling_mask(source)])])
    return out


def _write_light(out: Path, light: np.ndarray, source: str, protect: tuple = ()) -> None:
    protect = [source, *protect]
    if out.suffix.lower() == ".npy":
        write_npy(out, light, protect=protect)
    else:
        with atomic_path(out, protect) as tmp:  # checked against the inputs first, then sh.save_light's format
            sh.save_light(tmp, light)
    log.info("%s -> %s", source, out)


def cmd_lights_from_envmap(args: argparse.Namespace) -> int:
    out = _light_output(args.output, args.envmap)
    _write_light(out, sh.project_envmap(sh.load_envmap(args.envmap)), args.envmap)
    return 0


def cmd_lights_from_photo(args: argparse.Namespace) -> int:
    out = _light_output(args.output, args.photo)  # before the models load
    photo = Path(args.photo)
    mask = find_mask_file(photo, args.mask)
    rl = relighter(args)
    light = rl.resolve_light(rl.decompose(photo, mask))  # the photo's light, white as the runtime takes it
    _write_light(out, light, args.photo, (*paths_of(mask if mask != "auto" else None),
                                          *Path(rl.models_dir).glob("*.onnx")))
    return 0


# ------------------------------------------------------------------------------------------- doctor


def add_doctor(subparsers) -> None:
    p = subparsers.add_parser("doctor", help="versions, providers, models and install problems")
    _add_model_options(p)
    p.set_defaults(func=cmd_doctor)


def cmd_doctor(args: argparse.Namespace) -> int:
    from .doctor import report

    lines, problems = report(args.models, args.device)
    for line in lines:
        print(line)
    for problem in problems:
        print(f"problem: {problem}")
    print("ok" if not problems else f"{len(problems)} problem(s) found")
    return 1 if problems else 0


# ------------------------------------------------------------------------------------------- main

COMMANDS = [add_relight, add_decompose, add_lights, add_doctor]
# modules with add_parser(subparsers), added when present
PLUGINS = ["relight_rt.video_cli", "relight_rt.demo", "relight_rt.bench", "relight_rt.scene_cli", "relight_rt.mask_cli",
           "relight_rt.studio", "relight_rt.reference_import"]


class _Parser(argparse.ArgumentParser):
    """argparse, with a usage error as one line (``relight-rt: error: ...; see relight-rt CMD -h``), not the
    whole usage block; every subcommand's parser is one of these (add_subparsers makes its own class)."""

    def error(self, message: str):
        self.exit(2, f"relight-rt: error: {message}; see {self.prog} -h\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="relight-rt", description="Relight people in photos and videos.")
    parser.add_argument("--version", action="version", version=f"relight-rt {__version__}")
    _add_log_options(parser)
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for add in COMMANDS:
        add(subparsers)
    for name in PLUGINS:
        if importlib.util.find_spec(name) is not None:
            importlib.import_module(name).add_parser(subparsers)
    _remember_parsers(parser)
    return parser


def _remember_parsers(parser: argparse.ArgumentParser) -> None:
    """Give every (sub)command's parsed arguments its own parser, so a usage error shows that command's usage,
    and its own -v/-q, so they work before or after the command."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                sub.set_defaults(_parser=sub)
                _add_log_options(sub, default=argparse.SUPPRESS)  # unset here: the top level's value stays
                _remember_parsers(sub)


def _add_log_options(p: argparse.ArgumentParser, default=False) -> None:
    p.add_argument("-v", "--verbose", action="store_true", default=default, help="log details")
    p.add_argument("-q", "--quiet", action="store_true", default=default, help="log warnings and errors only")


def _os_error(exc: OSError) -> str:
    """One line for an OSError: the file and the reason, as a person reads it."""
    where = f"{exc.filename}: " if exc.filename else ""
    return f"{where}{exc.strerror or exc}"


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; returns the process exit code (0 ok, 1 doctor found problems, 2 bad input or a file that
    cannot be read or written, 130 Ctrl-C, 143 SIGTERM). Every failure is one line on stderr, never a
    traceback; SIGTERM and Ctrl-C unwind through the atomic writers, which remove their temporary files."""
    parser = build_parser()
    try:
        args, extra = parser.parse_known_args(argv)
        if extra:  # an unrecognised argument: the subcommand's usage, not the top-level one
            getattr(args, "_parser", parser).error(f"unrecognized arguments: {' '.join(extra)}")
    except SystemExit as exc:  # argparse: --help / --version (0) or a usage error (2)
        return int(exc.code or 0)
    if args.command is None:
        parser.print_help()
        return 0
    with quiet_native_libraries(enabled=not args.verbose):
        level = logging.DEBUG if args.verbose else logging.WARNING if args.quiet else logging.INFO
        logging.basicConfig(level=level, format="%(message)s")
        return _run(args)


def _run(args: argparse.Namespace) -> int:
    def fail(message: str) -> int:
        print(f"relight-rt: error: {message}", file=sys.stderr)
        return 2

    with interrupt_handling() as interrupted:
        try:
            with pixel_limit(getattr(args, "max_pixels", DEFAULT_MAX_PIXELS)):
                return int(args.func(args))
        except RelightError as exc:
            return fail(str(exc))
        except RecursionError:
            return fail("an input is nested too deeply to read (a malformed file?)")
        except MemoryError:
            return fail("out of memory; lower --max-pixels or the batch size, or use a machine with more memory")
        except OSError as exc:
            return fail(_os_error(exc))
        except KeyboardInterrupt:
            print(f"relight-rt: {interrupted.reason or 'interrupted'}; partial files removed", file=sys.stderr)
            return interrupted.code or 130
