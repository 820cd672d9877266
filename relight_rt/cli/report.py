"""How every command ends: one line per failure on stderr (``relight-rt: error: ...``), a count when several
items were tried, and the exit code (0 all done, 2 something failed)."""

from __future__ import annotations

import sys
from collections.abc import Iterable

PROG = "relight-rt"


def error(message: str) -> None:
    """One ``relight-rt: error: MESSAGE`` line on stderr."""
    print(f"{PROG}: error: {message}", file=sys.stderr)


def os_error_text(exc: OSError) -> str:
    """One line for an OSError: the file and the reason, as a person reads it."""
    where = f"{exc.filename}: " if exc.filename else ""
    return f"{where}{exc.strerror or exc}"


def finish(failures: Iterable[tuple[str, str]], summary: str | None = None) -> int:
    """Print each failure ``(item, message)`` as one error line (the item is put in front unless the message
    names it already), then ``summary`` (when given and something failed); returns the exit code: 2 when
    anything failed, else 0."""
    failures = list(failures)
    for item, message in failures:
        error(message if item in message else f"{item}: {message}")
    if failures and summary:
        print(f"{PROG}: {summary}", file=sys.stderr)
    return 2 if failures else 0


def finish_batch(failures: Iterable[tuple[str, str]], written: int, many: bool) -> int:
    """``finish`` for a command that went through several files: with more than one, the count of failed and
    written ones follows the failures."""
    failures = list(failures)
    return finish(failures, f"{len(failures)} failed, {written} written" if many else None)
