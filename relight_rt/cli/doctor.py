"""``relight-rt doctor``: versions, providers, models and install problems (relight_rt.doctor)."""

from __future__ import annotations

import argparse

from .options import add_runtime_options


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("doctor", help="versions, providers, models and install problems")
    add_runtime_options(p)
    p.set_defaults(func=cmd_doctor)


def cmd_doctor(args: argparse.Namespace) -> int:
    """Print the report; exit 1 when it found problems."""
    from ..doctor import report

    lines, problems = report(args.models, args.device)
    for line in lines:
        print(line)
    for problem in problems:
        print(f"problem: {problem}")
    print("ok" if not problems else f"{len(problems)} problem(s) found")
    return 1 if problems else 0
