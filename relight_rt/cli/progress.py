"""Progress of the CLI's long commands (video, folders, masks of a clip): one place, used only by the CLI.

With tqdm installed (a dependency of the package: 80 kB, pure Python, no dependencies of its own) a bar on
stderr shows the count, items per second and the time left; without it, one log line every
``every`` seconds says the same ("frame 50 / 240, 3.1 frame/s, 1 min 13 s left"). Nothing is shown when
INFO is not logged (``-q``). The bar is removed when the work ends: the command's one summary line
follows it.
"""

from __future__ import annotations

import logging
import sys
import time
from collections.abc import Iterable, Iterator

log = logging.getLogger("relight_rt.cli")


def _duration(seconds: float) -> str:
    seconds = int(round(seconds))
    if seconds < 60:
        return f"{seconds} s"
    if seconds < 3600:
        return f"{seconds // 60} min {seconds % 60} s"
    return f"{seconds // 3600} h {seconds % 3600 // 60} min"


class Progress:
    """A progress report for ``total`` items (None when unknown), named ``unit`` ("frame", "image").

    Use as a context manager: ``with Progress(n, "frame") as bar: ... bar.update()``.
    """

    def __init__(self, total: int | None, unit: str, *, enabled: bool = True, every: float = 10.0) -> None:
        self.total = total if total and total > 0 else None
        self.unit, self.every, self.count = unit, every, 0
        self.enabled = enabled and log.isEnabledFor(logging.INFO)
        self._bar = None
        if self.enabled:
            try:
                from tqdm import tqdm
            except ImportError:  # optional: plain log lines instead
                tqdm = None
            # a bar only on a terminal; piped or logged stderr gets the plain lines (a bar there is noise)
            if tqdm is not None and sys.stderr.isatty():
                self._bar = tqdm(total=self.total, unit=unit, file=sys.stderr, leave=False, dynamic_ncols=True)
        self._start = self._last = time.monotonic()

    def update(self, n: int = 1) -> None:
        self.count += n
        if self._bar is not None:
            self._bar.update(n)
            return
        if not self.enabled:
            return
        now = time.monotonic()
        if now - self._last < self.every:
            return
        self._last = now
        rate = self.count / max(now - self._start, 1e-9)
        of = f" / {self.total}" if self.total else ""
        left = ""
        if self.total and self.count < self.total:
            left = f", {_duration((self.total - self.count) / rate)} left"
        log.info("%s %d%s, %.3g %s/s%s", self.unit, self.count, of, rate, self.unit, left)

    def iterate(self, items: Iterable) -> Iterator:
        """Yield ``items``, counting each one when the next is asked for (or the loop ends)."""
        for item in items:
            yield item
            self.update()

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def progress(items: list, unit: str, enabled: bool = True) -> Iterator:
    """Yield ``items`` with a :class:`Progress` report (when ``enabled``), closed when the loop ends."""
    bar = Progress(len(items), unit, enabled=enabled)
    try:
        yield from bar.iterate(items)
    finally:
        bar.close()
