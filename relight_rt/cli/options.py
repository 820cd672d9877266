"""The options every CLI command shares, declared once: runtime configuration, lights, masks, backgrounds, Ray.

Each ``add_*`` function adds a group of options to a command's parser; the matching reader turns
the parsed values into the runtime's typed objects (RuntimeConfig, LightSpec, Background), so every
command spells and checks them the same way.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from ..apps.ray_jobs import EXTRA_HINT as RAY_EXTRA_HINT
from ..apps.ray_jobs import MANIFEST_NAME
from ..engine.config import DEVICES, PRECISIONS, PREPROCESS, RuntimeConfig
from ..engine.errors import RelightError
from ..engine.limits import DEFAULT_MAX_PIXELS
from ..image.compositing import Background, parse_background
from ..light import presets
from ..light.spec import HDR_SUFFIXES, SH_FILE_SUFFIXES, LightSpec

# ------------------------------------------------------------------------------------------- runtime


def add_runtime_options(p: argparse.ArgumentParser, *, device_default: str = "auto") -> None:
    """--models, --device, --precision, --preprocess, --no-detail (a RuntimeConfig)."""
    g = p.add_argument_group("runtime")
    g.add_argument("--models", metavar="DIR",
                   help="model folder (default: $RELIGHT_RT_MODELS, then the bundled models)")
    g.add_argument("--device", choices=DEVICES, default=device_default,
                   help=f"where to run (default: {device_default})")
    g.add_argument("--precision", choices=PRECISIONS, default="fp32",
                   help="graphs to run: stage1.onnx (fp32), stage1_fp16.onnx or stage1_int8.onnx (default fp32)")
    g.add_argument("--preprocess", choices=PREPROCESS, default="quality",
                   help="quality (INTER_AREA when shrinking, default) or reference (the reference's resize)")
    g.add_argument("--no-detail", action="store_true",
                   help="plain upsampling instead of carrying the photo's full-resolution detail")
    add_max_pixels(g)


def add_max_pixels(p) -> None:
    """``--max-pixels N``: refuse images larger than N pixels, read from the file header before decoding."""
    p.add_argument(
        "--max-pixels", type=int, default=DEFAULT_MAX_PIXELS, metavar="N",
        help=f"refuse images of more than N pixels, before decoding them (default {DEFAULT_MAX_PIXELS:,}; 0: no limit)",
    )  # fmt: skip


def add_person_option(p: argparse.ArgumentParser) -> None:
    """``--person largest|all``: whom the automatic matte takes when no mask is given (RuntimeConfig.matting)."""
    p.add_argument("--person", dest="people", choices=("largest", "all"), default="largest",
                   help="whom the automatic matte takes (no mask given): the largest person and those standing with "
                   "them, as tall and in full view (default), or everyone it finds (a group photo; each person is "
                   "then smaller in the network's square)")  # fmt: skip


def runtime_config(args: argparse.Namespace) -> RuntimeConfig:
    """The RuntimeConfig that ``add_runtime_options`` describes (and ``add_person_option``'s ``--person``,
    where a command has it)."""
    matting = "all" if getattr(args, "people", "largest") == "all" else "auto"
    return RuntimeConfig(models=args.models, device=args.device, precision=args.precision,
                         preprocess=args.preprocess, detail=not args.no_detail, matting=matting)


def relighter(args: argparse.Namespace, device: str | None = None):
    """A Relighter as the runtime options say (``device``: another device than --device): the one place a command
    builds one from its arguments."""
    from ..builder import open as open_relighter

    config = runtime_config(args)
    return open_relighter(config if device is None else config.replace(device=device))


# ------------------------------------------------------------------------------------------- lights


def add_light_options(p: argparse.ArgumentParser, *, required: bool = True, group=None):
    """--preset | --light FILE | --envmap MAP | --light-from PHOTO, with --rotate DEG and --bgr.

    Returns the mutually exclusive group, so a command can add its own alternatives (video: --lights).
    """
    light = group if group is not None else p.add_mutually_exclusive_group(required=required)
    light.add_argument("--preset", metavar="NAME", help=f"named light: {', '.join(presets.list_presets())}")
    light.add_argument("--light", metavar="FILE", help="SH light file: .npy (9, 3) or .json, RGB (see --bgr)")
    light.add_argument("--envmap", metavar="MAP", help="equirectangular environment map (.hdr/.exr/.png/.jpg)")
    light.add_argument("--light-from", metavar="PHOTO", help="borrow the light of another photo of a person")
    p.add_argument("--rotate", type=float, default=0.0, metavar="DEG", help="turn the light about the vertical axis")
    p.add_argument("--bgr", action="store_true", help="the --light file's columns are B, G, R (reference files)")
    return light


def light_spec(args: argparse.Namespace) -> LightSpec | None:
    """The LightSpec of ``add_light_options``' values; None when none was given."""
    if args.bgr and not args.light:
        raise RelightError("--bgr: it says how to read a --light file; give one")
    if args.preset:
        return LightSpec.preset(args.preset, rotate=args.rotate)
    if args.light:
        path = Path(args.light)
        suffix = path.suffix.lower()
        if not path.exists() and not suffix and args.light in presets.list_presets():
            raise RelightError(f"--light expects a light file; {args.light!r} is a preset: use --preset {args.light}")
        if not path.is_file():
            raise RelightError(f"--light {args.light}: {'not a regular file' if path.exists() else 'file not found'}")
        if suffix in SH_FILE_SUFFIXES:
            return LightSpec.file(path, bgr=args.bgr, rotate=args.rotate)
        if suffix in HDR_SUFFIXES and not args.bgr:
            return LightSpec.envmap(path, rotate=args.rotate)
        raise RelightError(f"--light {args.light}: expected a .npy or .json SH light file; for an environment map "
                           "use --envmap, for a photo of a person --light-from")
    if args.envmap:
        return LightSpec.envmap(args.envmap, rotate=args.rotate)
    if args.light_from:
        return LightSpec.photo(args.light_from, rotate=args.rotate)
    if args.rotate:
        raise RelightError("--rotate: it turns a light; give one (--preset, --light, --envmap or --light-from)")
    return None


# ------------------------------------------------------------------------------------------- masks, backgrounds


def add_mask_option(p: argparse.ArgumentParser, *, several: bool = True) -> None:
    """--mask M: a file, a folder of NAME_mask.png (``several``), or "auto" (the automatic matte)."""
    what = "mask file (one input) or folder holding NAME_mask.png" if several else "mask file"
    p.add_argument("--mask", metavar="M", help=f"{what}; 'auto': the automatic matte (default: NAME_mask.png "
                                               "beside the photo, else its alpha, else the automatic matte)")


def add_background_option(p: argparse.ArgumentParser, default: str = "original") -> None:
    p.add_argument("--background", default=default, metavar="B",
                   help="original | transparent | a colour (black, white, #RRGGBB) | IMAGE (fitted by cover); "
                        f"default {default}")


def add_exposure_option(p: argparse.ArgumentParser, reference: str = "the input person's") -> None:
    """--exposure auto | EV | physical (relight_rt.light.exposure), one meaning in every command."""
    p.add_argument(
        "--exposure", default="auto", metavar="E",
        help=f"auto (default: scale the light so the person keeps {reference} mean luminance, lowered up to a "
        "stop where that would put much of the person past white), an EV offset from auto (+1 twice as bright, "
        "-0.5) or physical (the light's own intensity)",
    )  # fmt: skip


def fov(text: str) -> float:
    """argparse type of ``--fov DEG`` (its range is checked by relight_rt.light.from_background)."""
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected degrees, got {text!r}") from None


def add_key_light_option(p: argparse.ArgumentParser) -> None:
    """``--key-light AZ,EL`` (relight_rt.light.from_background.parse_key_light reads it)."""
    p.add_argument("--key-light", metavar="AZ,EL", help="where the scene's key light comes from, degrees: azimuth 0 "
                   "from the camera, 90 from the image's right, 180 from behind the person; elevation above the "
                   "horizon (default: the key the background implies)")  # fmt: skip


def add_grade_background_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--grade-background", action="store_true",
                   help="the original background follows the new light: one global grade per channel, the "
                        "person's change of exposure and colour (off by default)")


def background(args: argparse.Namespace) -> Background:
    bg = parse_background(args.background)
    if getattr(args, "grade_background", False):
        if bg.kind != "original":
            raise RelightError(f"--grade-background: grades the original background only, not --background "
                               f"{args.background}")
        bg = Background.original(grade=True)
    return bg


def paths_of(*values) -> list[str]:
    """The file paths among option values (None and non-paths dropped), to protect them from being overwritten."""
    return [os.fspath(v) for v in values if isinstance(v, (str, os.PathLike)) and v]


# ------------------------------------------------------------------------------------------- Ray


def add_ray_options(parser: argparse.ArgumentParser, *, video: bool = False) -> None:
    """Add ``--ray [ADDRESS|local]`` and its options to a command's parser (imports no Ray)."""
    g = parser.add_argument_group(f"Ray cluster (optional extra: {RAY_EXTRA_HINT})")
    g.add_argument("--ray", nargs="?", const="local", metavar="ADDRESS",
                   help="run on Ray: local (a private Ray on this machine; the default without ADDRESS), "
                        "auto (the cluster this machine belongs to) or ray://HOST:10001")  # fmt: skip
    g.add_argument(
        "--ray-gpus",
        type=float,
        metavar="G",
        help="GPUs per " + ("task" if video else "actor") + " (default: 1 when the cluster has GPUs, else 0)",
    )
    g.add_argument(
        "--ray-cpus",
        type=float,
        default=1.0,
        metavar="C",
        help="CPUs per " + ("task" if video else "actor") + " (default 1; the onnxruntime thread count)",
    )
    if not video:
        g.add_argument(
            "--ray-actors",
            type=int,
            metavar="N",
            help="actors, each with one Relighter (default: one per GPU, or per --ray-cpus CPUs)",
        )
        g.add_argument("--ray-batch-size", type=int, default=8, metavar="B", help="photos per actor call (default 8)")
    g.add_argument(
        "--manifest", metavar="JSONL", help=f"manifest of the job (default: {MANIFEST_NAME} in the output folder)"
    )
