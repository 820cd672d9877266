"""The environment variables relight_rt reads, each through one reader that checks it.

- ``RELIGHT_RT_THREADS``: onnxruntime's intra-op threads (:func:`threads`);
- ``RELIGHT_RT_MODELS``: the models folder used when none is given (:func:`models`);
- ``RELIGHT_RT_TENSORRT``: TensorRT's engine cache folder, opt-in (:func:`tensorrt_cache`);
- ``RELIGHT_RT_CACHE``: where optimised graphs are kept, or ``off`` (:func:`graph_cache`,
relight_rt.engine.graph_cache);
- ``OPENCV_IO_ENABLE_OPENEXR``: whether OpenCV's .exr reader was switched on (:func:`openexr_enabled`; OpenCV
  reads it itself, relight_rt only to say why an .exr did not decode).

Nothing else in the package reads ``os.environ`` for these names; a value out of range is one RelightError that
names the variable, raised before any work starts (issue 50 bugs 7 and 8: ``RELIGHT_RT_THREADS=1000000`` made
onnxruntime start threads until the process died with SIGSEGV, and a value of 2**31 or more a traceback).
"""

from __future__ import annotations

import os

from .errors import RelightError

THREADS = "RELIGHT_RT_THREADS"
MODELS = "RELIGHT_RT_MODELS"
TENSORRT = "RELIGHT_RT_TENSORRT"
CACHE = "RELIGHT_RT_CACHE"
OPENEXR = "OPENCV_IO_ENABLE_OPENEXR"


def _text(name: str) -> str | None:
    """The variable's value, stripped; None when it is unset or blank."""
    return os.environ.get(name, "").strip() or None


def max_threads() -> int:
    """The most intra-op threads accepted: four per core, at least 64 (more only wait on one another; a million
    made onnxruntime create threads until the process crashed)."""
    return max(64, 4 * (os.cpu_count() or 1))


def threads() -> int | None:
    """$RELIGHT_RT_THREADS as a whole number from 0 (onnxruntime's default) to :func:`max_threads`; None when
    unset or blank.

    Raises:
        RelightError: anything else, naming the variable and the range.
    """
    text = _text(THREADS)
    if text is None:
        return None
    top = max_threads()
    n = int(text) if text.isascii() and text.isdigit() and len(text) <= 9 else -1
    if not 0 <= n <= top:
        shown = text if len(text) <= 40 else text[:40] + "..."
        raise RelightError(f"${THREADS} is {shown!r}, expected a whole number from 0 (onnxruntime's default) to "
                           f"{top}")  # fmt: skip
    return n


def models() -> str | None:
    """$RELIGHT_RT_MODELS, stripped; None when unset or blank (the callers check that the folder holds models)."""
    return _text(MODELS)


def tensorrt_cache() -> str | None:
    """$RELIGHT_RT_TENSORRT (TensorRT's engine cache folder), stripped; None when unset or blank."""
    return _text(TENSORRT)


def graph_cache() -> str | None:
    """The folder of optimised graphs (relight_rt.engine.graph_cache): $RELIGHT_RT_CACHE (None when it is ``off``, ``0``
    or ``none``), else ``$XDG_CACHE_HOME/relight_rt/graphs``, else ``~/.cache/relight_rt/graphs`` (None when there
    is no home)."""
    text = _text(CACHE)
    if text is not None:
        return None if text.lower() in ("off", "0", "none") else text
    base = _text("XDG_CACHE_HOME")
    if base is None:
        home = os.path.expanduser("~")
        if home == "~":
            return None
        base = os.path.join(home, ".cache")
    return os.path.join(base, "relight_rt", "graphs")


def openexr_enabled() -> bool:
    """Whether $OPENCV_IO_ENABLE_OPENEXR switches OpenCV's .exr reader on (1, true or on, any case)."""
    return (_text(OPENEXR) or "").lower() in ("1", "true", "on")
