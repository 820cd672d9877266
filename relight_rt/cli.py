"""Command line interface: ``relight-rt COMMAND ...``."""

from __future__ import annotations

import argparse
import logging
import sys

from . import __version__
from ._errors import RelightError


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="relight-rt", description="Relight people in photos and videos.")
    parser.add_argument("--version", action="version", version=f"relight-rt {__version__}")
    parser.add_subparsers(dest="command")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; returns the process exit code (0 ok, 2 bad input)."""
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    try:
        return int(args.func(args))
    except RelightError as exc:
        print(f"relight-rt: error: {exc}", file=sys.stderr)
        return 2
