"""Optimised ONNX graphs kept between processes, so that a cold run does not optimise every graph again.

onnxruntime optimises a graph each time a session is created (all levels, the NCHWc layout transform included:
relight_rt.engine.session): on the bundled graphs that is most of the session's creation, paid by every cold
``relight-rt relight`` (docs/BENCHMARKS.md). The first creation writes the optimised graph
(``SessionOptions.optimized_model_filepath``) to a temporary file in the cache folder and renames it into place
(atomic: a reader sees a whole file or none); later creations load it with optimisation off, which gives the same
graph and so the same results.

The key names everything the optimised graph depends on: the graph's bytes (BLAKE2b, remembered in the folder's
``digests/`` under the file's identity: ``graph_digest``), onnxruntime's version, the
optimisation level, the providers, the machine and the CPU's features (the layout transform picks kernels for this
CPU: onnxruntime says such a file suits only the machine that wrote it). A file that fails to load is removed and
the graph is optimised again. The folder: ``$RELIGHT_RT_CACHE`` (``off`` turns the cache off), else
``$XDG_CACHE_HOME/relight_rt/graphs``, else ``~/.cache/relight_rt/graphs``; a folder that cannot be written turns
it off for that graph (logged at debug).
"""

from __future__ import annotations

import functools
import hashlib
import logging
import platform
from pathlib import Path

import onnxruntime as ort

from . import environment
from .errors import RelightError
from .files import atomic_path

log = logging.getLogger(__name__)

_CPU = "CPUExecutionProvider"
_FORMAT = "2"  # bump when what is stored or how it is keyed changes


@functools.cache
def _cpu_features() -> str:
    """The CPU's model name and feature flags (Linux), else the platform's processor string (read once a process,
    not once a graph)."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            text = f.read(1 << 16)
    except OSError:
        return platform.processor()
    keep = [line for line in text.splitlines() if line.startswith(("model name", "flags", "Features"))]
    return "\n".join(dict.fromkeys(keep))


def graph_key(path: Path, level, providers: list, folder: str | None = None) -> str:
    """The cache key of ``path`` optimised at ``level`` for ``providers`` on this machine (module docstring); with
    the cache ``folder``, the graph's digest is remembered there (``graph_digest``)."""
    h = hashlib.blake2b(digest_size=20)
    h.update("\0".join([_FORMAT, graph_digest(path, folder), ort.__version__, str(level), repr(providers),
                        platform.machine(), _cpu_features()]).encode())
    return h.hexdigest()


def graph_digest(path: Path, folder: str | None = None) -> str:
    """BLAKE2b of the graph file's bytes. With a cache ``folder`` it is remembered there under the file's identity
    (its path, device, inode, size, and modification and change times in ns: any write to the file changes its
    change time), so a cold process reads a 40-character note per graph instead of hashing them all again (the
    bundled graphs are ~28 MB, ~20 ms of CPU). A note that cannot be read or written is hashed past."""
    st = path.stat()
    identity = "\0".join(map(str, (path.resolve(), st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)))
    note = None
    if folder is not None:
        note = Path(folder) / "digests" / hashlib.blake2b(identity.encode(), digest_size=20).hexdigest()
        try:
            known = note.read_text("ascii").strip()
            if len(known) == 40 and all(c in "0123456789abcdef" for c in known):
                return known
        except (OSError, UnicodeError):
            pass
    h = hashlib.blake2b(digest_size=20)
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 22), b""):
            h.update(block)
    digest = h.hexdigest()
    if note is not None:
        try:
            note.parent.mkdir(parents=True, exist_ok=True)
            with atomic_path(note) as tmp:
                tmp.write_text(digest, "ascii")
        except (OSError, RelightError) as exc:
            log.debug("graph cache: digest of %s not kept (%s)", path, exc)
    return digest


def _usable(opts: ort.SessionOptions, providers: list) -> bool:
    return (opts.graph_optimization_level == ort.GraphOptimizationLevel.ORT_ENABLE_ALL
            and not opts.optimized_model_filepath and list(providers) == [_CPU])


def open_session(path: Path, opts: ort.SessionOptions, providers: list) -> ort.InferenceSession:
    """``ort.InferenceSession(path, opts, providers)``, through the cache of optimised graphs where it applies (CPU,
    all optimisations, no file of the caller's own); errors are onnxruntime's, as without the cache."""
    folder = environment.graph_cache()
    if folder is None or not _usable(opts, providers):
        return ort.InferenceSession(str(path), sess_options=opts, providers=providers)
    try:
        key = graph_key(path, opts.graph_optimization_level, providers, folder)
        target = Path(folder) / f"{path.stem}-{key}.onnx"
    except OSError as exc:
        log.debug("graph cache: %s not keyed (%s)", path, exc)
        return ort.InferenceSession(str(path), sess_options=opts, providers=providers)
    if target.is_file():
        level = opts.graph_optimization_level
        opts.graph_optimization_level = ort.GraphOptimizationLevel.ORT_DISABLE_ALL
        try:
            return ort.InferenceSession(str(target), sess_options=opts, providers=providers)
        except Exception as exc:  # a damaged file: optimise again below
            log.debug("graph cache: %s unusable (%s); optimising %s again", target, exc, path)
            target.unlink(missing_ok=True)
        finally:
            opts.graph_optimization_level = level
    severity = opts.log_severity_level
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(target) as tmp:  # the project's one atomic writer: in place once the session is made
            opts.optimized_model_filepath = str(tmp)
            opts.log_severity_level = 3  # onnxruntime warns that the file suits only this machine: the key says so
            return ort.InferenceSession(str(path), sess_options=opts, providers=providers)
    except (OSError, RelightError) as exc:  # an unwritable cache folder: no cache
        log.debug("graph cache: %s not writable (%s)", target.parent, exc)
    finally:
        opts.optimized_model_filepath = ""
        opts.log_severity_level = severity
    return ort.InferenceSession(str(path), sess_options=opts, providers=providers)
