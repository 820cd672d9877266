"""Process-level behaviour of the command line: interruption and the native libraries' own stderr output.

- :func:`interrupt_handling` turns SIGTERM into an exception (a ``KeyboardInterrupt`` subclass) in the main
  thread, so a terminated run unwinds like Ctrl-C: the atomic writers (relight_rt.engine.files.atomic_path, the video
  sink) remove their temporary files on the way out, and the CLI prints one line.
- :func:`quiet_native_libraries` keeps what libpng, libjpeg, FFmpeg, OpenCV and onnxruntime write straight
  to the process's stderr (file descriptor 2) off the terminal, and numpy's floating-point warnings off it
  too: the CLI's own messages keep the real stderr. Used by the CLI only (``-v`` turns it off); the library
  never touches process-wide state.
- :func:`give_back_freed_memory` hands the C allocator's freed pages back to the system between a photo's relight
  and its encoding (``relight_rt.apps.batch.relight_file``: the CLI's and Ray's photo jobs, not the ``Relighter``
  API, which leaves the process's allocator alone).
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import signal
import sys
import threading
import types
import warnings
from collections.abc import Iterator

_TRIM: list = []  # glibc's malloc_trim once looked up ([None] where there is none)


def give_back_freed_memory() -> None:
    """Hand the memory the C allocator keeps after arrays are freed back to the system (glibc's ``malloc_trim``;
    nothing where there is no glibc). glibc keeps freed arrays under its mmap threshold (which rises to 32 MB as
    large arrays are freed) for reuse, and a group photo's people are many such arrays: after a 16-person 25-MP
    photo's Decomposition is let go it held ~0.7 GB of them, under the full-size temporaries of the image's encoding
    that comes next (issue 50 bug 1). A photo's freed pages are faulted in again when reused: once a photo, not
    measurable."""
    if not _TRIM:
        try:
            _TRIM.append(ctypes.CDLL(None).malloc_trim)
        except (AttributeError, OSError, TypeError):  # no glibc (macOS, Windows, musl)
            _TRIM.append(None)
    if _TRIM[0] is not None:
        _TRIM[0](ctypes.c_size_t(0))


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread by :func:`interrupt_handling` (unwinds as Ctrl-C does)."""


@contextlib.contextmanager
def interrupt_handling() -> Iterator[types.SimpleNamespace]:
    """Inside the block SIGTERM raises :class:`Terminated`; yields a record whose ``reason`` and ``code``
    (exit status: 130 for Ctrl-C, 143 for SIGTERM) say what stopped the run. A second SIGTERM during the
    clean-up is ignored (SIGKILL still ends the process)."""
    state = types.SimpleNamespace(reason=None, code=None)
    if threading.current_thread() is not threading.main_thread():  # signals reach the main thread only
        yield state
        return

    def on_term(signum, frame):
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        state.reason, state.code = "terminated (SIGTERM)", 128 + signal.SIGTERM
        raise Terminated()

    previous = signal.signal(signal.SIGTERM, on_term)
    try:
        yield state
    finally:
        signal.signal(signal.SIGTERM, previous)


@contextlib.contextmanager
def quiet_native_libraries(enabled: bool = True) -> Iterator[None]:
    """Silence native libraries' stderr output and numpy warnings inside the block (see the module docstring).

    The file descriptor 2 is pointed at /dev/null only when ``sys.stderr`` is the process's own stderr (not
    a test's capture); ``sys.stderr`` then writes to a duplicate of the real one.
    """
    if not enabled:
        yield
        return
    import cv2
    import numpy as np
    import onnxruntime as ort

    cv_level = cv2.utils.logging.getLogLevel()
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
    ort.set_default_logger_severity(3)  # errors only (they also arrive as exceptions)
    redirect = sys.stderr is sys.__stderr__ and _fileno(sys.stderr) == 2
    saved = None
    try:
        if redirect:
            sys.stderr.flush()
            saved = os.dup(2)
            null = os.open(os.devnull, os.O_WRONLY)
            os.dup2(null, 2)
            os.close(null)
            encoding = sys.__stderr__.encoding or "utf-8"
            sys.stderr = open(saved, "w", buffering=1, encoding=encoding, errors="backslashreplace", closefd=False)
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            yield
    finally:
        if saved is not None:
            sys.stderr.flush()
            os.dup2(saved, 2)
            sys.stderr = sys.__stderr__
            # ``saved`` stays open: logging's handler may still hold the stream written to it (process exit
            # flushes it); one descriptor per CLI run in a real process, never in a test's capture
        cv2.utils.logging.setLogLevel(cv_level)
        ort.set_default_logger_severity(2)


def _fileno(stream) -> int:
    try:
        return stream.fileno()
    except (AttributeError, OSError, ValueError):
        return -1
