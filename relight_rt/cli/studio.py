"""``relight-rt studio PHOTO``: the light editor in the browser (relight_rt.apps.studio)."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..engine.errors import RelightError
from .options import add_person_option, add_runtime_options, relighter


def add_parser(subparsers) -> None:
    p = subparsers.add_parser(
        "studio",
        help="light editor in the browser: drag a lamp, see the person relit",
        description="Decompose PHOTO once and serve a page that relights it live while you move a lamp, pick a "
        'preset, an environment map or the light of another photo. Needs: pip install "relight-rt[studio]".',
    )
    p.add_argument("photo", metavar="PHOTO", help="photo of a person (mask: --mask, NAME_mask.png beside it, or alpha)")
    p.add_argument("--mask", metavar="M", help="mask file")
    add_person_option(p)
    p.add_argument("--background", default="original", metavar="BG", help="original | transparent | IMAGE")
    p.add_argument("--panorama", action="append", default=[], metavar="PANO",
                   help="an equirectangular panorama (.hdr/.exr) the page may view as the scene: the plate and the "
                   "person lit by its light turned to the view (repeatable)")  # fmt: skip
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1: this machine only)")
    p.add_argument("--port", type=int, default=8000, help="port (default 8000; 0: any free port)")
    p.add_argument("--open", action="store_true", help="open the page in the default browser")
    p.add_argument(
        "--preview-pixels",
        type=int,
        default=1_000_000,
        metavar="N",
        help="most pixels of the live preview in the browser (default 1000000)",
    )
    add_runtime_options(p)
    p.set_defaults(func=cmd_studio)


def cmd_studio(args: argparse.Namespace) -> int:
    from ..apps import studio

    studio.check_extra()
    if not 0 <= args.port <= 65535:
        raise RelightError(f"--port is {args.port}, expected 0 to 65535")
    if not Path(args.photo).is_file():
        raise RelightError(f"photo {args.photo} not found")
    from ..apps.studio.core import Studio

    rl = relighter(args)  # --models, --device, --precision, --preprocess, --no-detail
    session = Studio(args.photo, args.mask, args.background, rl, args.preview_pixels, models=args.models,
                     panoramas=args.panorama)
    # Ctrl-C and SIGTERM: uvicorn stops serving, then raises the signal again under the CLI's own handlers,
    # so the command ends as every command does (130 / 143, one line; relight_rt.cli)
    studio.serve(session, args.host, args.port, args.open)
    return 0
