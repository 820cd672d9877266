"""``relight-rt lights``: ``list``, ``show``, ``from-envmap``, ``from-photo`` and ``from-background``.

``relight-rt lights from-background BG -o light.npy [--fov 60] [--key-light AZ,EL] [--preview sheet.png]``
estimates a scene's light from one ordinary photo of it (relight_rt.light.from_background).
"""

from __future__ import annotations

import argparse
import logging
import math
from pathlib import Path

import numpy as np

from ..engine.errors import RelightError
from ..engine.files import atomic_path, check_target, write_npy
from ..image.io import IMAGE_SUFFIXES, sibling_mask, write_image
from ..light import envmap, presets, sh
from ..light.files import save_light
from ..light.spec import LightSpec, parse_light
from ..person.masks import find_mask_file
from .options import add_key_light_option, add_mask_option, add_runtime_options, fov, paths_of, relighter

log = logging.getLogger("relight_rt.cli")


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("lights", help="list, show and make SH lights")
    metavar = "{list,show,from-envmap,from-photo,from-background}"
    sub = p.add_subparsers(dest="lights_command", required=True, metavar=metavar)
    ls = sub.add_parser("list", help="the named lights, one per line, name first")
    ls.set_defaults(func=cmd_list)
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
    show.set_defaults(func=cmd_show)
    env = sub.add_parser("from-envmap", help="project an environment map to a (9, 3) SH light")
    env.add_argument("envmap", metavar="HDR")
    env.add_argument("-o", "--output", required=True, metavar="LIGHT", help=".npy or .json")
    env.set_defaults(func=cmd_from_envmap)
    photo = sub.add_parser("from-photo", help="estimate the light of a photo of a person (stage 1)")
    photo.add_argument("photo", metavar="PHOTO")
    add_mask_option(photo, several=False)
    photo.add_argument("-o", "--output", required=True, metavar="LIGHT", help=".npy or .json")
    photo.set_defaults(func=cmd_from_photo)
    scene = sub.add_parser("from-background", help="estimate a scene's SH light from one ordinary photo of it")
    scene.add_argument("background", metavar="BG", help="the scene photo (RGB, >= 64 px a side)")
    scene.add_argument("-o", "--output", required=True, metavar="LIGHT", help=".npy or .json")
    scene.add_argument("--fov", type=fov, default=60.0, metavar="DEG", help="horizontal field of view (default 60)")
    add_key_light_option(scene)
    scene.add_argument("--preview", metavar="PNG", help="also write a sheet: background | filled env map | sphere")
    scene.set_defaults(func=cmd_from_background)
    for q in (ls, show, env, photo, scene):  # every command takes them; only from-photo runs a model
        add_runtime_options(q)


def cmd_list(args: argparse.Namespace) -> int:
    for name in presets.list_presets():
        print(f"{name}\t{presets.describe_preset(name)}".rstrip())
    return 0


def cmd_show(args: argparse.Namespace) -> int:
    if not 8 <= args.size <= 8192:
        raise RelightError(f"--size is {args.size}, expected 8 to 8192")
    from ..light import preview

    name = Path(args.name)
    spec = parse_light(args.name)  # the one rule: preset, light file, environment map or photo
    if args.bgr and spec.source != "file":
        raise RelightError("--bgr: it says how to read a light file; a preset or a map has no colour order to choose")
    spec = LightSpec.file(name, bgr=True) if args.bgr else spec
    spec = spec.rotated(args.rotate)
    protect = [name, *spec.paths]
    if spec.source == "envmap":
        env = envmap.load_envmap(spec.value)  # decoded once, for the light and for the sheet
        light = sh.rotate_z(envmap.project_envmap(env), math.radians(spec.rotate))
        light = sh.check_light(light, "light").astype(np.float32)
        image, notes = preview.envmap_sheet(env, light, args.rotate, args.size)
    else:
        light = relighter(args).resolve_light(spec) if spec.source == "photo" else spec.resolve()
        image, notes = sh.render_sphere(light, size=args.size), preview.notes(light, args.rotate)
    check_target(args.output, protect)
    for line in notes:
        log.warning("%s", line)
    write_image(args.output, image, protect=protect)
    log.info("%s -> %s", args.name, args.output)
    return 0


def light_output(output: str, source: str) -> Path:
    """The output light file, checked before any work: .npy or .json, and not the input."""
    out = Path(output)
    if out.suffix.lower() not in (".npy", ".json"):
        raise RelightError(f"output {out}: expected a .npy or .json light file")
    check_target(out, [source, *filter(None, [sibling_mask(source)])])
    return out


def write_light(out: Path, light: np.ndarray, source: str, protect: tuple = ()) -> None:
    """Write ``light`` to ``out`` (.npy, or .json by save_light), atomically and never over ``source`` or
    ``protect``, once it passed the rule every command reads a light by (sh.check_light)."""
    light = sh.check_light(light, f"{source}: its light")  # what every command reads back: checked before writing
    protect = [source, *protect]
    if out.suffix.lower() == ".npy":
        write_npy(out, light, protect=protect)
    else:
        with atomic_path(out, protect) as tmp:  # checked against the inputs first, then save_light's format
            save_light(tmp, light)
    log.info("%s -> %s", source, out)


def cmd_from_envmap(args: argparse.Namespace) -> int:
    out = light_output(args.output, args.envmap)
    write_light(out, envmap.project_envmap(envmap.load_envmap(args.envmap)), args.envmap)
    return 0


def cmd_from_photo(args: argparse.Namespace) -> int:
    out = light_output(args.output, args.photo)  # before the models load
    photo = Path(args.photo)
    mask = find_mask_file(photo, args.mask)
    rl = relighter(args)
    light = rl.resolve_light(rl.decompose(photo, mask))  # the photo's light, white as the runtime takes it
    write_light(out, light, args.photo, (*paths_of(mask if mask != "auto" else None),
                                         *Path(rl.models_dir).glob("*.onnx")))
    return 0


def preview_sheet(background: np.ndarray, env: np.ndarray, light: np.ndarray, height: int = 256) -> np.ndarray:
    """(height, W, 3) sRGB sheet: the background, its filled env map, a white sphere under the light."""
    import cv2

    from ..image.color import linear_to_srgb

    bg = background.astype(np.float32) / 255 if background.dtype == np.uint8 else background.astype(np.float32)
    panels = [cv2.resize(bg, (max(1, round(bg.shape[1] * height / bg.shape[0])), height), interpolation=cv2.INTER_AREA)]
    # the env map and the sphere share one exposure: the env map's 99th percentile at display white
    level = float(np.percentile(env, 99)) or 1.0
    env_big = cv2.resize(env, (2 * height, height), interpolation=cv2.INTER_LINEAR)
    panels.append(linear_to_srgb(np.clip(env_big / level, 0, 1)))
    sphere = sh.render_sphere(light, size=height) / np.float32(level)  # the light's scale: uniform v shades v
    panels.append(linear_to_srgb(np.clip(sphere, 0, 1)))
    gap = np.full((height, 4, 3), 1.0, np.float32)
    return np.concatenate([panels[0], gap, panels[1], gap, panels[2]], axis=1)


def cmd_from_background(args: argparse.Namespace) -> int:
    from ..light.from_background import light_from_background, parse_key_light, read_background

    key = parse_key_light(args.key_light)
    out = light_output(args.output, args.background)
    if args.preview and Path(args.preview).suffix.lower() not in IMAGE_SUFFIXES:
        raise RelightError(f"--preview {args.preview}: expected an image file ({', '.join(IMAGE_SUFFIXES)})")
    if args.preview:
        check_target(Path(args.preview), [args.background, out])
    photo = read_background(args.background)
    light, env = light_from_background(photo, args.fov, key_light=key)
    write_light(out, light.astype(np.float64), args.background)
    if args.preview:
        write_image(args.preview, preview_sheet(photo, env, light), protect=[args.background, out])
        log.info("preview -> %s", args.preview)
    return 0
