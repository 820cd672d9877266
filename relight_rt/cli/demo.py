"""``relight-rt demo``: relight the bundled example person under a preset (relight_rt.demo)."""

from __future__ import annotations

import argparse
import logging

from ..demo import run_demo
from ..light import presets as lights
from .options import add_runtime_options, runtime_config

log = logging.getLogger("relight_rt.demo")


def add_parser(subparsers) -> None:
    p = subparsers.add_parser(
        "demo",
        help="relight the bundled example person under a preset",
        description="Relight the bundled example (a rendered person) and write the photo, the relit photo and "
        "the light on a sphere side by side.",
    )
    p.add_argument("--preset", default="golden-hour", metavar="NAME", help=f"one of {', '.join(lights.list_presets())}")
    p.add_argument("-o", "--output", default="demo.png", metavar="OUT", help="image to write (default demo.png)")
    add_runtime_options(p)
    p.set_defaults(func=cmd_demo)


def cmd_demo(args: argparse.Namespace) -> int:
    path = run_demo(args.output, args.preset, config=runtime_config(args))  # every runtime option, as relight
    log.info("wrote %s (photo | relit under %s | the light on a sphere)", path, args.preset)
    return 0
