"""Command line interface: ``relight-rt COMMAND ...`` (``python -m relight_rt``, the console script).

One module per command or family of commands, each with ``add_parser(subparsers)`` (argparse) and the
``cmd_*`` functions it sets as ``func``; the work itself is done by the library (relight_rt.apps.batch,
relight_rt.video.job, relight_rt.apps.scene, relight_rt.apps.ray_jobs, ...). Shared options and the one place
that builds a Relighter from them: relight_rt.cli.options; how every command ends (error lines, counts, exit
codes): relight_rt.cli.report.

Errors: bad input, a malformed file or one that cannot be read or written (any OSError) is one line on
stderr (``relight-rt: error: ...``) and exit code 2, never a traceback; in batch mode every file is tried
and every failure is listed at the end. Ctrl-C exits 130 and SIGTERM 143, with one line, after the
atomic writers removed their temporary files. Outputs are written atomically and never over a file the
command reads (relight_rt.engine.files.ProtectedPaths). Native libraries' own stderr output is silenced unless
``-v`` (relight_rt.engine.process).
"""

from __future__ import annotations

import argparse
import importlib
import logging
import re
import sys

from .. import __version__
from ..engine.errors import RelightError
from ..engine.limits import DEFAULT_MAX_PIXELS, pixel_limit
from ..engine.process import interrupt_handling, quiet_native_libraries
from .report import error, os_error_text

# every command, in the order ``relight-rt -h`` lists them: its name, its module in relight_rt.cli and the function
# there that adds it to the subparsers. A run of one command imports that command's module only (``build_parser``):
# the others' imports (the bench's harness, video, the studio, ...) cost a one-photo run ~30 ms of CPU.
COMMANDS = (
    ("relight", "relight", "add_relight"),
    ("decompose", "relight", "add_decompose"),
    ("lights", "lights", "add_parser"),
    ("doctor", "doctor", "add_parser"),
    ("video", "video", "add_parser"),
    ("demo", "demo", "add_parser"),
    ("bench", "bench", "add_parser"),
    ("composite", "composite", "add_parser"),
    ("mask", "mask", "add_parser"),
    ("studio", "studio", "add_parser"),
    ("import-reference", "import_reference", "add_parser"),
)


class Parser(argparse.ArgumentParser):
    """argparse, with a usage error as one line (``relight-rt: error: ...; see relight-rt CMD -h``), not the
    whole usage block; every subcommand's parser is one of these (add_subparsers makes its own class).

    A word that starts with "-" and a digit (or "-." and a digit) is a value, never an option: ``--key-light
    -90,30`` (the documented "from the image's left"), ``--exposure -1e-05``. argparse before Python 3.13 took
    only plain negative numbers (``-5``, ``-0.5``) for values, and refused these as a missing argument (issue 50
    bug 12); no option of relight-rt starts with a digit. This is Python 3.13's own rule."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = re.compile(r"^-\.?\d")

    def error(self, message: str):
        self.exit(2, f"relight-rt: error: {message}; see {self.prog} -h\n")


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser of every command, or of ``command`` alone (a name in ``COMMANDS``: only its module is imported)."""
    parser = Parser(prog="relight-rt", description="Relight people in photos and videos.")
    parser.add_argument("--version", action="version", version=f"relight-rt {__version__}")
    _add_log_options(parser)
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, module, adder in COMMANDS:
        if command is None or name == command:
            getattr(importlib.import_module(f"{__name__}.{module}"), adder)(subparsers)
    _remember_parsers(parser)
    return parser


def _command_named(argv: list[str]) -> str | None:
    """The command ``argv`` runs when its first word that is not an option names one (the top level's options take
    no value), else None (help, a misspelt command: every command's parser is built)."""
    word = next((a for a in argv if not a.startswith("-")), None)
    return word if any(word == name for name, _, _ in COMMANDS) else None


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


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; returns the process exit code (0 ok, 1 doctor found problems, 2 bad input or a file that
    cannot be read or written, 130 Ctrl-C, 143 SIGTERM). Every failure is one line on stderr, never a
    traceback; SIGTERM and Ctrl-C unwind through the atomic writers, which remove their temporary files."""
    parser = build_parser(_command_named(sys.argv[1:] if argv is None else list(argv)))
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
        error(message)
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
            return fail(os_error_text(exc))
        except KeyboardInterrupt:
            print(f"relight-rt: {interrupted.reason or 'interrupted'}; partial files removed", file=sys.stderr)
            return interrupted.code or 130


__all__ = ["COMMANDS", "build_parser", "main"]
