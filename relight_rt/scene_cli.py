"""``relight-rt composite`` (put a person into a scene, lit like it) and ``lights from-background``.

``relight-rt composite PERSON [--mask M] --background BG -o OUT [--preset P | --light L | --envmap E]
[--key-light AZ,EL] [--position X,Y] [--height H] [--horizon Y] [--no-shadow] [--exposure auto|EV|physical]
[--meter frame|background] [--no-match-camera] [--fov 60]``

``relight-rt lights from-background BG -o light.npy [--fov 60] [--key-light AZ,EL] [--preview sheet.png]``
(registered by ``relight_rt.cli.add_lights`` through ``add_from_background``).
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import numpy as np

from . import sh
from ._errors import RelightError
from ._io import IMAGE_SUFFIXES, check_target, write_image
from .exposure import parse_exposure

log = logging.getLogger("relight_rt.cli")


def _fov(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected degrees, got {text!r}") from None


def _add_key_light(p) -> None:
    p.add_argument("--key-light", metavar="AZ,EL", help="where the scene's key light comes from, degrees: azimuth 0 "
                   "from the camera, 90 from the image's right, 180 from behind the person; elevation above the "
                   "horizon (default: the key the background implies)")  # fmt: skip


def add_parser(subparsers) -> None:
    from ._options import add_exposure_option, add_light_options, add_mask_option, add_runtime_options

    p = subparsers.add_parser(
        "composite",
        help="put a person into a background photo, relit by the background's light, standing on its ground",
        description="Relight the person of PERSON for the scene of --background and composite it there. Without "
        "a light option the light is estimated from the background (relight_rt.scene_light). The person "
        "is matched to the background's exposure, white balance, blur and noise, stands on the ground at the size "
        "perspective gives (a cut-off person on the bottom edge), casts a shadow along the key light and is laid over "
        "it with its soft matte. The output has the background's size.",
    )
    p.add_argument("person", metavar="PERSON", help="photo of the person")
    add_mask_option(p, several=False)
    p.add_argument("--background", required=True, metavar="BG", help="the scene photo (RGB, >= 64 px a side)")
    p.add_argument("-o", "--output", required=True, metavar="OUT", help="output image (.png, .jpg, ...)")
    add_light_options(p, required=False)
    _add_key_light(p)
    p.add_argument("--position", metavar="X,Y", help="where the feet (bottom centre) go, fractions of the background "
                   "(default: a full body stands at y = 0.92, a cut-off one on the bottom edge)")  # fmt: skip
    p.add_argument("--height", type=float, metavar="H", help="the person's height, fraction of the background's "
                   "(default: from perspective for a full body, as in its own photo for a cut-off one)")  # fmt: skip
    p.add_argument("--horizon", type=float, default=0.5, metavar="Y",
                   help="the horizon's row, fraction of the background's height (0.5: a level camera)")  # fmt: skip
    p.add_argument("--shadow", action=argparse.BooleanOptionalAction, default=True,
                   help="contact and cast shadows on the ground (default: on)")  # fmt: skip
    add_exposure_option(p, "the brightness the background's light gives it, as")
    p.add_argument("--meter", choices=("frame", "background"), default="frame",
                   help="frame: expose the composed frame as a camera metering it would (default); "
                   "background: keep the background's pixels as they are")  # fmt: skip
    p.add_argument("--match-camera", action=argparse.BooleanOptionalAction, default=True,
                   help="match the background's blur and noise (default: on)")  # fmt: skip
    p.add_argument("--fov", type=_fov, default=60.0, metavar="DEG", help="background's horizontal field of view")
    add_runtime_options(p)
    p.set_defaults(func=cmd_composite)


def cmd_composite(args: argparse.Namespace) -> int:
    from ._options import light_spec, relighter
    from .masks import find_mask_file
    from .scene import composite, parse_position
    from .scene_light import _check_fov, parse_key_light

    out = Path(args.output)
    if out.suffix.lower() not in IMAGE_SUFFIXES:
        raise RelightError(f"output {out}: expected an image file ({', '.join(IMAGE_SUFFIXES)})")
    person = Path(args.person)
    if not person.is_file():
        raise RelightError(f"person {person}: file not found")
    if not Path(args.background).is_file():
        raise RelightError(f"--background {args.background}: file not found")
    mask = find_mask_file(person, args.mask)
    exposure = parse_exposure(args.exposure)  # checked before the models load
    position = parse_position(args.position) if args.position is not None else None
    key = parse_key_light(args.key_light)
    _check_fov(args.fov)
    spec = light_spec(args)
    protect = [p for p in (person, mask if mask != "auto" else None, args.background, *(spec.paths if spec else ()))
               if p]  # fmt: skip
    check_target(out, protect)  # before any work
    rl = relighter(args)
    light = None if spec is None else rl.resolve_light(spec)
    image = composite(rl, person, args.background, mask=mask, light=light, position=position, height=args.height,
                      shadow=args.shadow, exposure=exposure, fov=args.fov, key_light=key, horizon=args.horizon,
                      meter=args.meter, match_camera=args.match_camera)  # fmt: skip
    write_image(out, image, protect=protect)
    log.info("%s + %s -> %s", person, args.background, out)
    return 0


# ------------------------------------------------------------------------------------ lights from-background


def add_from_background(sub) -> argparse.ArgumentParser:
    """Add ``from-background`` to the ``lights`` subcommands (called by relight_rt.cli.add_lights)."""
    p = sub.add_parser("from-background", help="estimate a scene's SH light from one ordinary photo of it")
    p.add_argument("background", metavar="BG", help="the scene photo (RGB, >= 64 px a side)")
    p.add_argument("-o", "--output", required=True, metavar="LIGHT", help=".npy or .json")
    p.add_argument("--fov", type=_fov, default=60.0, metavar="DEG", help="horizontal field of view (default 60)")
    _add_key_light(p)
    p.add_argument("--preview", metavar="PNG", help="also write a sheet: background | filled env map | sphere")
    p.set_defaults(func=cmd_from_background)
    return p


def preview_sheet(background: np.ndarray, env: np.ndarray, light: np.ndarray, height: int = 256) -> np.ndarray:
    """(height, W, 3) sRGB sheet: the background, its filled env map, a white sphere under the light."""
    import cv2

    from .color import linear_to_srgb

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
    from .cli import _light_output, _write_light
    from .scene_light import light_from_background, parse_key_light, read_background

    key = parse_key_light(args.key_light)
    out = _light_output(args.output, args.background)
    if args.preview and Path(args.preview).suffix.lower() not in IMAGE_SUFFIXES:
        raise RelightError(f"--preview {args.preview}: expected an image file ({', '.join(IMAGE_SUFFIXES)})")
    if args.preview:
        check_target(Path(args.preview), [args.background, out])
    photo = read_background(args.background)
    light, env = light_from_background(photo, args.fov, key_light=key)
    _write_light(out, light.astype(np.float64), args.background)
    if args.preview:
        write_image(args.preview, preview_sheet(photo, env, light), protect=[args.background, out])
        log.info("preview -> %s", args.preview)
    return 0
