"""Command line interface: ``relight-rt COMMAND ...``.

Commands: ``relight``, ``decompose``, ``lights list|show|from-envmap``, ``doctor`` (and ``video`` when
relight_rt.video_cli is present). Each command is registered by its own ``add_*`` function; another
module adds one with an ``add_parser(subparsers)`` function that sets ``func`` on its parser.

Errors: bad input is one line on stderr (``relight-rt: error: ...``) and exit code 2; in batch mode
every file is tried and every failure is listed at the end. Outputs are written atomically and never
over an input.
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

from . import __version__, lights, sh
from ._errors import RelightError
from ._io import IMAGE_SUFFIXES, list_images, sibling_mask, write_image, write_npy, write_npz

log = logging.getLogger("relight_rt.cli")


def _add_model_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--models", metavar="DIR", help="model folder (default: $RELIGHT_RT_MODELS, then the bundled models)"
    )
    p.add_argument("--device", choices=("auto", "cpu", "cuda"), default="auto", help="where to run (default: auto)")


def _relighter(args: argparse.Namespace):
    from .relighter import Relighter

    return Relighter(args.models, device=args.device)


# ------------------------------------------------------------------------------------------- relight


def add_relight(subparsers) -> None:
    p = subparsers.add_parser(
        "relight",
        help="relight photos of people",
        description="Relight photos (files or folders). Masks: --mask, else NAME_mask.png beside NAME.jpg, "
        "else the image's alpha channel.",
    )
    p.add_argument("inputs", nargs="+", metavar="INPUT", help="image files or folders of images")
    p.add_argument("--mask", metavar="M", help="mask file (one input) or folder holding NAME_mask.png")
    light = p.add_mutually_exclusive_group(required=True)
    light.add_argument("--light", metavar="L", help="SH light file: .npy (9, 3) RGB or .json")
    light.add_argument("--preset", metavar="NAME", help=f"named light: {', '.join(lights.list_presets())}")
    light.add_argument("--envmap", metavar="HDR", help="equirectangular environment map (.hdr/.exr/.png/.jpg)")
    light.add_argument("--light-from", metavar="PHOTO", help="borrow the light of another photo of a person")
    p.add_argument("--bgr", action="store_true", help="the --light file's columns are B, G, R (reference files)")
    p.add_argument("--rotate", type=float, default=0.0, metavar="DEG", help="turn the light about the vertical axis")
    p.add_argument("--background", default="original", metavar="B", help="original | transparent | IMAGE")
    p.add_argument("-o", "--output", required=True, metavar="OUT", help="output file (one input) or folder")
    _add_model_options(p)
    p.set_defaults(func=cmd_relight)


def _gather_inputs(inputs: list[str]) -> tuple[list[Path], list[tuple[str, str]]]:
    files, failures = [], []
    for item in inputs:
        path = Path(item)
        if path.is_dir():
            found = list_images(path)
            if not found:
                failures.append((item, f"folder {item} holds no images ({', '.join(IMAGE_SUFFIXES)})"))
            files.extend(found)
        elif path.is_file():
            files.append(path)
        else:
            failures.append((item, f"input {item} not found"))
    return files, failures


def _light_from_args(args: argparse.Namespace, relighter) -> np.ndarray:
    if args.light:
        light = sh.load_light(args.light, bgr=args.bgr)
    elif args.preset:
        light = lights.preset(args.preset)
    elif args.envmap:
        light = sh.project_envmap(sh.load_envmap(args.envmap))
    else:
        light = relighter.resolve_light(Path(args.light_from))
    if args.rotate:
        light = sh.rotate_z(light, math.radians(args.rotate))
    return np.asarray(light, dtype=np.float32)


def _mask_for(image: Path, mask_arg: str | None, single: bool) -> Path | None:
    if mask_arg is None:
        return sibling_mask(image)
    m = Path(mask_arg)
    if m.is_dir():
        found = sibling_mask(m / image.name)
        if found is None:
            raise RelightError(f"mask folder {m} has no {image.stem}_mask.png")
        return found
    if not single:
        raise RelightError("--mask FILE works with one input; for several, give a folder with NAME_mask.png files")
    return m


def _progress(items: list, enabled: bool):
    if not enabled:
        return items
    try:
        from tqdm import tqdm
    except ImportError:
        return items
    return tqdm(items, unit="image", file=sys.stderr)


def cmd_relight(args: argparse.Namespace) -> int:
    files, failures = _gather_inputs(args.inputs)
    out = Path(args.output)
    single = len(files) == 1 and len(args.inputs) == 1 and not Path(args.inputs[0]).is_dir()
    to_file = single and out.suffix.lower() in IMAGE_SUFFIXES
    if single and not to_file and out.suffix:
        raise RelightError(f"output {out}: unknown image type {out.suffix!r}; use one of {', '.join(IMAGE_SUFFIXES)}")
    background = args.background
    if background not in ("original", "transparent") and not Path(background).is_file():
        raise RelightError(f"--background {background}: expected original, transparent or an image file")
    relighter = _relighter(args)
    light = _light_from_args(args, relighter)
    protect = set(files)
    protect.update(p for p in (args.mask, args.light, args.envmap, args.light_from, background) if p)
    protect.update(m for m in (sibling_mask(f) for f in files) if m)
    if not to_file and files:
        out.mkdir(parents=True, exist_ok=True)
    written: set[Path] = set()
    show_bar = len(files) > 1
    for path in _progress(files, show_bar):
        target = out if to_file else out / f"{path.stem}_relit.png"
        try:
            if target.resolve() in written:
                raise RelightError(f"two inputs named {path.stem} would both write {target}")
            mask = _mask_for(path, args.mask, single)
            image = relighter.relight(path, light, mask=mask, background=background)
            write_image(target, image, protect=protect)
            written.add(target.resolve())
            if not show_bar:
                log.info("%s -> %s", path, target)
        except (RelightError, OSError) as exc:
            failures.append((str(path), str(exc)))
    for item, message in failures:
        text = message if item in message else f"{item}: {message}"
        print(f"relight-rt: error: {text}", file=sys.stderr)
    if failures and len(files) > 1:
        print(f"relight-rt: {len(failures)} failed, {len(written)} written", file=sys.stderr)
    return 2 if failures else 0


# ------------------------------------------------------------------------------------------- decompose


def add_decompose(subparsers) -> None:
    p = subparsers.add_parser(
        "decompose",
        help="albedo, shading, skin, light and transport of a photo",
        description="Writes albedo.png, shading.png, skin.png (input size), light.npy ((9, 3) RGB SH) and "
        "transport.npz (key T, (H, W, 9) float32, input size) into DIR.",
    )
    p.add_argument("input", metavar="INPUT", help="image file")
    p.add_argument("--mask", metavar="M", help="mask file (default: NAME_mask.png beside it, else alpha)")
    p.add_argument("-o", "--output", required=True, metavar="DIR", help="output folder")
    _add_model_options(p)
    p.set_defaults(func=cmd_decompose)


def cmd_decompose(args: argparse.Namespace) -> int:
    src = Path(args.input)
    mask = Path(args.mask) if args.mask else sibling_mask(src)
    relighter = _relighter(args)
    dec = relighter.decompose(src, mask)
    folder = Path(args.output)
    folder.mkdir(parents=True, exist_ok=True)
    protect = [p for p in (src, mask) if p]
    write_image(folder / "albedo.png", dec.to_input(np.ascontiguousarray(dec.albedo)), protect)
    write_image(folder / "shading.png", dec.to_input(dec.shading()), protect)
    write_image(folder / "skin.png", dec.to_input(dec.skin), protect)
    write_npy(folder / "light.npy", np.asarray(dec.light, np.float64), protect)
    write_npz(folder / "transport.npz", {"T": dec.to_input(np.ascontiguousarray(dec.transport))}, protect)
    log.info("%s -> %s (albedo.png, shading.png, skin.png, light.npy, transport.npz)", src, folder)
    return 0


# ------------------------------------------------------------------------------------------- lights


def add_lights(subparsers) -> None:
    p = subparsers.add_parser("lights", help="list, show and make SH lights")
    sub = p.add_subparsers(dest="lights_command", required=True, metavar="{list,show,from-envmap,from-photo}")
    ls = sub.add_parser("list", help="the named lights, one per line, name first")
    ls.set_defaults(func=cmd_lights_list)
    show = sub.add_parser("show", help="render a light on a diffuse sphere")
    show.add_argument("name", metavar="NAME", help="preset name or light file (.npy/.json)")
    show.add_argument("--size", type=int, default=256, help="sphere image size in pixels (default 256)")
    show.add_argument("-o", "--output", required=True, metavar="PNG")
    show.set_defaults(func=cmd_lights_show)
    env = sub.add_parser("from-envmap", help="project an environment map to a (9, 3) SH light")
    env.add_argument("envmap", metavar="HDR")
    env.add_argument("-o", "--output", required=True, metavar="LIGHT", help=".npy or .json")
    env.set_defaults(func=cmd_lights_from_envmap)
    photo = sub.add_parser("from-photo", help="estimate the light of a photo of a person (stage 1)")
    photo.add_argument("photo", metavar="PHOTO")
    photo.add_argument("--mask", help="mask image (default: the photo's alpha, or PHOTO_mask.png beside it)")
    photo.add_argument("-o", "--output", required=True, metavar="LIGHT", help=".npy or .json")
    photo.set_defaults(func=cmd_lights_from_photo)
    for q in (ls, show, env, photo):  # every command takes them; only from-photo runs a model
        _add_model_options(q)


def cmd_lights_list(args: argparse.Namespace) -> int:
    notes = getattr(lights, "_PRESETS", {})
    for name in lights.list_presets():
        note = notes.get(name, (None, None, ""))[2] if isinstance(notes.get(name), tuple) else ""
        print(f"{name}\t{note}".rstrip())
    return 0


def cmd_lights_show(args: argparse.Namespace) -> int:
    if not 8 <= args.size <= 8192:
        raise RelightError(f"--size is {args.size}, expected 8 to 8192")
    name = Path(args.name)
    light = sh.load_light(name) if name.suffix.lower() in (".npy", ".json") else lights.preset(args.name)
    write_image(args.output, sh.render_sphere(light, size=args.size), protect=[name])
    log.info("%s -> %s", args.name, args.output)
    return 0


def _light_output(output: str, source: str) -> Path:
    """The output light file, checked before any work: .npy or .json, and not the input."""
    out = Path(output)
    if out.suffix.lower() not in (".npy", ".json"):
        raise RelightError(f"output {out}: expected a .npy or .json light file")
    if out.resolve() == Path(source).resolve():
        raise RelightError(f"refusing to overwrite the input {source}")
    return out


def _write_light(out: Path, light: np.ndarray, source: str) -> None:
    if out.suffix.lower() == ".npy":
        write_npy(out, light, protect=[source])
    else:
        sh.save_light(out, light)
    log.info("%s -> %s", source, out)


def cmd_lights_from_envmap(args: argparse.Namespace) -> int:
    out = _light_output(args.output, args.envmap)
    _write_light(out, sh.project_envmap(sh.load_envmap(args.envmap)), args.envmap)
    return 0


def cmd_lights_from_photo(args: argparse.Namespace) -> int:
    out = _light_output(args.output, args.photo)  # before the models load
    photo = Path(args.photo)
    mask = Path(args.mask) if args.mask else sibling_mask(photo)
    light = np.asarray(_relighter(args).decompose(photo, mask).light, dtype=np.float32)
    _write_light(out, light, args.photo)
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
PLUGINS = ["relight_rt.video_cli", "relight_rt.demo", "relight_rt.bench", "relight_rt.reference_import"]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="relight-rt", description="Relight people in photos and videos.")
    parser.add_argument("--version", action="version", version=f"relight-rt {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log details")
    parser.add_argument("-q", "--quiet", action="store_true", help="log warnings and errors only")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for add in COMMANDS:
        add(subparsers)
    for name in PLUGINS:
        if importlib.util.find_spec(name) is not None:
            importlib.import_module(name).add_parser(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; returns the process exit code (0 ok, 1 doctor found problems, 2 bad input)."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # argparse: --help / --version (0) or a usage error (2)
        return int(exc.code or 0)
    level = logging.DEBUG if args.verbose else logging.WARNING if args.quiet else logging.INFO
    logging.basicConfig(level=level, format="%(message)s")
    if args.command is None:
        parser.print_help()
        return 0
    try:
        return int(args.func(args))
    except RelightError as exc:
        print(f"relight-rt: error: {exc}", file=sys.stderr)
        return 2
