"""``relight-rt composite``: put a person into a scene, lit like it.

``relight-rt composite PERSON [--mask M] --background BG -o OUT [--preset P | --light L | --envmap E]
[--key-light AZ,EL] [--position X,Y] [--height H] [--horizon Y] [--camera-height M] [--no-shadow]
[--exposure auto|EV|physical] [--meter frame|background] [--no-match-camera] [--no-light-wrap]
[--rim | --rim-auto | --no-rim] [--fov 60]``

``relight-rt composite PERSON --background PANO.hdr --view AZ,EL[,FOV] [--size WxH] -o OUT [...]``: the scene is
an equirectangular panorama, seen in that direction, lighting the person with its own light (relight_rt.apps.panorama).
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from ..engine.errors import RelightError
from ..engine.files import check_target
from ..image.io import IMAGE_SUFFIXES, write_image
from ..light.exposure import parse_exposure
from .options import (
    add_exposure_option,
    add_key_light_option,
    add_light_options,
    add_mask_option,
    add_runtime_options,
    fov,
    light_spec,
    relighter,
)

log = logging.getLogger("relight_rt.cli")


def add_parser(subparsers) -> None:
    p = subparsers.add_parser(
        "composite",
        help="put a person into a background photo, relit by the background's light, standing on its ground",
        description="Relight the person of PERSON for the scene of --background and composite it there. Without "
        "a light option the light is estimated from the background (relight_rt.light.from_background). The person "
        "is matched to the background's exposure, white balance, blur and noise, stands on the ground at the size "
        "perspective gives (a cut-off person on the bottom edge), casts a shadow along the key light and is laid over "
        "it with its soft matte. The output has the background's size.",
    )
    p.add_argument("person", metavar="PERSON", help="photo of the person")
    add_mask_option(p, several=False)
    p.add_argument("--background", required=True, metavar="BG", help="the scene photo (RGB, >= 64 px a side), or an "
                   "equirectangular panorama (.hdr/.exr, width = 2 x height) with --view")  # fmt: skip
    p.add_argument("--view", metavar="AZ,EL[,FOV]", help="BG is a panorama: render the background looking this way "
                   "(degrees: azimuth 0 = the panorama's centre, positive to the right; elevation up; horizontal "
                   "field of view, default 60; a negative azimuth as --view=-30,0) and light the person with the "
                   "panorama's own light")  # fmt: skip
    p.add_argument("--size", metavar="WxH", help="with --view: the output's size (default: the person photo's)")
    p.add_argument("-o", "--output", required=True, metavar="OUT", help="output image (.png, .jpg, ...)")
    add_light_options(p, required=False)
    add_key_light_option(p)
    p.add_argument("--position", metavar="X,Y", help="where the feet (a cut-off person's bottom centre) go, fractions "
                   "of the background (default: a full body stands at y = 0.92 or below a low horizon, off the people "
                   "there, a cut-off one on the borders its photo cut it by)")  # fmt: skip
    p.add_argument("--height", type=float, metavar="H", help="the person's height, fraction of the background's "
                   "(default: from perspective for a full body, as in its own photo for a cut-off one)")  # fmt: skip
    p.add_argument("--horizon", type=float, default=None, metavar="Y",
                   help="the horizon's row, fraction of the background's height (default: where the background's "
                   "verticals and the people standing in it put it, else 0.5, a level camera's; with --view, where "
                   "the view's elevation puts it)")  # fmt: skip
    p.add_argument("--camera-height", default=None, metavar="M",
                   help="the background camera's height above the ground in metres, which with the horizon sets a "
                   "full body's size (default 1.5: a standing camera; lower it for a camera held low)")  # fmt: skip
    p.add_argument("--shadow", action=argparse.BooleanOptionalAction, default=True,
                   help="contact and cast shadows on the ground (default: on)")  # fmt: skip
    add_exposure_option(p, "the brightness the background's light gives it, as")
    p.add_argument("--meter", choices=("frame", "background"), default="frame",
                   help="frame: expose the composed frame as a camera metering it would (default); "
                   "background: keep the background's pixels as they are")  # fmt: skip
    p.add_argument("--match-camera", action=argparse.BooleanOptionalAction, default=True,
                   help="match the background's blur and noise (default: on)")  # fmt: skip
    p.add_argument("--light-wrap", action=argparse.BooleanOptionalAction, default=True,
                   help="a brighter background's light wraps over the person's edge (default: on)")  # fmt: skip
    p.add_argument("--rim", dest="rim", action="store_const", const="on", default=None,
                   help="a sun, window or lamp behind the person puts a rim of light on its side of the outline "
                   "(default: on with --view, where the panorama holds the source; off for a photo)")  # fmt: skip
    p.add_argument("--rim-auto", dest="rim", action="store_const", const="auto",
                   help="a rim only where a clipped source is in the photo and it reads as back-lit")  # fmt: skip
    p.add_argument("--no-rim", dest="rim", action="store_const", const="off", help="no rim, with --view too")
    p.add_argument(
        "--fov",
        type=fov,
        default=None,
        metavar="DEG",
        help="background's horizontal field of view (default 60; with --view, the view's third number)",
    )
    add_runtime_options(p)
    p.set_defaults(func=cmd_composite)


def cmd_composite(args: argparse.Namespace) -> int:
    from ..apps.scene import composite, parse_position
    from ..light.from_background import check_fov, hdr_background_error, parse_key_light
    from ..person.masks import find_mask_file

    out = Path(args.output)
    if out.suffix.lower() not in IMAGE_SUFFIXES:
        raise RelightError(f"output {out}: expected an image file ({', '.join(IMAGE_SUFFIXES)})")
    person = Path(args.person)
    if not person.is_file():
        raise RelightError(f"person {person}: file not found")
    if not Path(args.background).is_file():
        raise RelightError(f"--background {args.background}: file not found")
    if args.view is not None:
        return _composite_panorama(args, out, person)
    if args.size is not None:
        raise RelightError("--size: only with --view (a background photo gives the output its own size)")
    err = hdr_background_error(args.background, "--background")
    if err is not None:
        raise err
    mask = find_mask_file(person, args.mask)
    exposure = parse_exposure(args.exposure)  # checked before the models load
    position = parse_position(args.position) if args.position is not None else None
    camera = _camera_height(args)
    key = parse_key_light(args.key_light)
    args.fov = 60.0 if args.fov is None else args.fov
    check_fov(args.fov)
    spec = light_spec(args)
    protect = [p for p in (person, mask if mask != "auto" else None, args.background, *(spec.paths if spec else ()))
               if p]  # fmt: skip
    check_target(out, protect)  # before any work
    rl = relighter(args)
    light = None if spec is None else rl.resolve_light(spec)
    image = composite(rl, person, args.background, mask=mask, light=light, position=position, height=args.height,
                      shadow=args.shadow, exposure=exposure, fov=args.fov, key_light=key,
                      horizon=args.horizon,
                      meter=args.meter, match_camera=args.match_camera, light_wrap=args.light_wrap,
                      rim={"on": True, "auto": "auto"}.get(args.rim, False), camera_height=camera)  # fmt: skip
    write_image(out, image, protect=protect)
    log.info("%s + %s -> %s", person, args.background, out)
    return 0


def _composite_panorama(args: argparse.Namespace, out: Path, person: Path) -> int:
    """``--view``: the background is a panorama seen that way (relight_rt.apps.panorama.composite_panorama)."""
    from ..apps.panorama import composite_panorama, load_panorama, parse_size, parse_view
    from ..apps.scene import parse_position
    from ..person.masks import find_mask_file

    options = (("--preset/--light/--envmap", light_spec(args)), ("--key-light", args.key_light), ("--fov", args.fov))
    given = [name for name, value in options if value is not None]
    if given:
        raise RelightError(f"--view: the panorama gives the light and the view; drop {', '.join(given)}")
    view = parse_view(args.view)
    size = parse_size(args.size) if args.size is not None else None
    mask = find_mask_file(person, args.mask)
    exposure = parse_exposure(args.exposure)
    position = parse_position(args.position) if args.position is not None else None
    camera = _camera_height(args)
    protect = [p for p in (person, mask if mask != "auto" else None, args.background) if p]
    check_target(out, protect)
    pano = load_panorama(args.background, "--background")  # before the models load
    rl = relighter(args)
    image = composite_panorama(rl, person, pano, view, size=size, mask=mask, exposure=exposure,
                               position=position, height=args.height, horizon=args.horizon, shadow=args.shadow,
                               meter=args.meter, match_camera=args.match_camera,
                               light_wrap=args.light_wrap, rim=args.rim != "off", camera_height=camera)  # fmt: skip
    write_image(out, image, protect=protect)
    log.info("%s + %s (view %g,%g,%g) -> %s", person, args.background, *view, out)
    return 0


def _camera_height(args: argparse.Namespace) -> float:
    """--camera-height, checked (metres; default the standing camera of relight_rt.apps.scene_place)."""
    from ..apps.scene_place import CAMERA_M, check_camera_height

    return CAMERA_M if args.camera_height is None else check_camera_height(args.camera_height)
