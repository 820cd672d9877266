"""The ``relight-rt`` entry point (``python -m relight_rt`` and the console script): signals are handled from
the first instant.

Loading the runtime (numpy, OpenCV, onnxruntime) takes ~0.3 s; Ctrl-C in that time printed a
KeyboardInterrupt traceback and SIGTERM ended the process without a word (issue 35 item 16). This module
imports the standard library only (``import relight_rt`` itself loads nothing heavy), turns SIGTERM into an
exception before anything heavy is imported, and ends an interrupted start-up as the CLI ends an interrupted
run (relight_rt.cli.main, relight_rt.engine.process): one line, exit 130 (Ctrl-C) or 143 (SIGTERM).
"""

from __future__ import annotations

import signal
import sys


class _Terminated(KeyboardInterrupt):
    """SIGTERM before the CLI's own handling is in place (it unwinds as Ctrl-C does)."""


def _on_term(signum, frame):
    signal.signal(signal.SIGTERM, signal.SIG_IGN)  # a second SIGTERM during the unwinding is ignored
    raise _Terminated()


def main(argv: list[str] | None = None) -> int:
    """Run ``relight-rt`` (relight_rt.cli.main) with Ctrl-C and SIGTERM handled from the start; returns the
    process exit code."""
    try:
        previous = signal.signal(signal.SIGTERM, _on_term)
    except ValueError:  # not the main thread: signals are not ours to handle
        previous = None
    try:
        from .cli import main as cli_main

        return cli_main(argv)
    except KeyboardInterrupt as exc:  # outside the CLI's own handling (loading, parsing): nothing was written
        terminated = isinstance(exc, _Terminated) or type(exc).__name__ == "Terminated"
        print(f"relight-rt: {'terminated (SIGTERM)' if terminated else 'interrupted'}", file=sys.stderr)
        return 128 + (signal.SIGTERM if terminated else signal.SIGINT)
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
