"""Writing files atomically, never over an input: the one writer every file of the project goes through.

Every writer goes through a temporary file in the destination folder and ``os.replace``, so an interrupted run
never leaves a half-written file, and refuses to write over any path in ``protect`` (the inputs, compared
resolved and by inode). ``write_all`` writes several files as one: all of them or none.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path

import numpy as np

from .errors import RelightError


def current_umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def same_file(a: str | os.PathLike, b: str | os.PathLike) -> bool:
    """True when ``a`` and ``b`` name the same file: equal resolved paths (symlinks followed) or, when both
    exist, the same inode (hard links, bind mounts, case-insensitive file systems)."""
    pa, pb = Path(a), Path(b)
    if pa.resolve() == pb.resolve():
        return True
    try:
        return os.path.samefile(pa, pb)
    except OSError:
        return False


class ProtectedPaths:
    """Input files that outputs must never replace, resolved once: each check is O(1), so a batch of N
    files does not cost N² path resolutions. Iterating gives the paths as they were named."""

    def __init__(self, paths: Iterable[str | os.PathLike] = ()) -> None:
        self._resolved: dict[Path, Path] = {}
        self._inodes: dict[tuple[int, int], Path] = {}
        for p in paths:
            self.add(p)

    def add(self, path: str | os.PathLike) -> None:
        named = Path(path)
        resolved = named.resolve()
        self._resolved.setdefault(resolved, named)
        with contextlib.suppress(OSError):
            st = os.stat(resolved)
            self._inodes.setdefault((st.st_dev, st.st_ino), named)

    def find(self, path: str | os.PathLike) -> Path | None:
        """The protected input that ``path`` names (resolved, or the same inode), or None."""
        resolved = Path(path).resolve()
        if resolved in self._resolved:
            return self._resolved[resolved]
        try:
            st = os.stat(resolved)
        except OSError:
            return None
        return self._inodes.get((st.st_dev, st.st_ino))

    def __iter__(self) -> Iterator[Path]:
        return iter(self._resolved.values())

    def __len__(self) -> int:
        return len(self._resolved)


def check_target(path: str | os.PathLike, protect: Iterable[str | os.PathLike]) -> None:
    """Raise RelightError when ``path`` is one of the ``protect`` inputs (an output must never replace one).

    Paths are compared resolved (a symlink, ``./x`` or ``dir/../x`` is the file it names) and, for files
    that exist, by inode (hard links). Pass a :class:`ProtectedPaths` when checking many outputs.
    """
    found = (protect if isinstance(protect, ProtectedPaths) else ProtectedPaths(protect)).find(path)
    if found is not None:
        raise RelightError(f"refusing to overwrite the input {found}; choose another output path")


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, protect: Iterable[str | os.PathLike] = ()) -> Iterator[Path]:
    """A temporary path beside ``path`` (same suffix, so writers that go by it work) that replaces
    ``path`` when the ``with`` block succeeds and is removed when it fails: readers never see a
    half-written file. The one atomic writer of the project; everything that writes files uses it.

    Raises:
        RelightError: ``path`` is one of ``protect`` (an input), or its folder does not exist.
    """
    path = Path(path)
    check_target(path, protect)
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        what = "is not a folder" if folder.exists() or _under_a_file(folder) else "does not exist"
        raise RelightError(f"cannot write {path}: {folder} {what}")
    if path.is_dir():
        raise RelightError(f"cannot write {path}: it is a folder")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=f".tmp{path.suffix}", dir=folder)
    except OSError as exc:
        raise RelightError(f"cannot write {path}: {exc.strerror or exc} (folder {folder})") from None
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, 0o666 & ~current_umask())  # mkstemp makes 0600; give the file the usual permissions
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _under_a_file(folder: Path) -> bool:
    """True when some parent of ``folder`` is a file (``-o photo.png/sub``)."""
    return any(p.is_file() for p in (folder, *folder.parents))


def _write_to(tmp: Path, path: Path, write: Callable[[object], None]) -> None:
    """``write(fileobj)`` into ``tmp``; a failure of the file system (a full disk) names ``path``."""
    try:
        with open(tmp, "wb") as f:
            write(f)
    except OSError as exc:
        raise RelightError(f"cannot write {path}: {exc.strerror or exc}") from None


def atomic_write(path: str | os.PathLike, protect: Iterable[str | os.PathLike],
                 write: Callable[[object], None]) -> Path:
    """Write through ``write(fileobj)`` into a temporary file beside ``path``, then rename it into place."""
    with atomic_path(path, protect) as tmp:
        _write_to(tmp, Path(path), write)
    return Path(path)


# What each kind of file is written with: ``write(fileobj)``, for one file (``write_npy``, ...) or for several
# written as one (``write_all``). The arrays are taken, and an image encoded, when the writer is made.
def bytes_writer(data: bytes) -> Callable[[object], None]:
    """A writer of ``data`` as it is."""
    return lambda f: f.write(data)


def npy_writer(array: np.ndarray) -> Callable[[object], None]:
    """A writer of one array as .npy (never pickled)."""
    arr = np.asarray(array)
    return lambda f: np.save(f, arr, allow_pickle=False)


def npz_writer(arrays: dict[str, np.ndarray], compressed: bool = True) -> Callable[[object], None]:
    """A writer of named arrays as .npz (compressed by default)."""
    save = np.savez_compressed if compressed else np.savez
    named = {k: np.asarray(v) for k, v in arrays.items()}
    return lambda f: save(f, **named)


def write_bytes(path: str | os.PathLike, data: bytes, protect: Iterable[str | os.PathLike] = ()) -> Path:
    """Write ``data`` to ``path`` atomically (a temporary file beside it, then a rename), never over ``protect``."""
    return atomic_write(path, protect, bytes_writer(data))


def write_all(files: Sequence[tuple[str | os.PathLike, Callable[[object], None]]],
              protect: Iterable[str | os.PathLike] = ()) -> list[Path]:
    """Write several files as one: all of them or none.

    Every target is checked against ``protect`` before anything is written; each file is written through
    ``write(fileobj)`` into its own temporary file; only when every one is complete are they renamed into
    place. A failure (an input among the targets, a full disk, an encoder error) leaves none of them.

    Args:
        files: (path, write) pairs.
        protect: inputs no target may replace.
    """
    protect = protect if isinstance(protect, ProtectedPaths) else ProtectedPaths(protect)
    paths = [Path(p) for p, _ in files]
    for path in paths:
        check_target(path, protect)
    with contextlib.ExitStack() as stack:
        temps = [stack.enter_context(atomic_path(path, protect)) for path in paths]
        for (_, write), tmp, path in zip(files, temps, paths, strict=True):
            _write_to(tmp, path, write)
    return paths


def write_npy(path: str | os.PathLike, array: np.ndarray, protect: Iterable[str | os.PathLike] = ()) -> Path:
    """Save one array as .npy atomically (never pickled)."""
    return atomic_write(path, protect, npy_writer(array))


def write_npz(
    path: str | os.PathLike,
    arrays: dict[str, np.ndarray],
    protect: Iterable[str | os.PathLike] = (),
    compressed: bool = True,
) -> Path:
    """Save named arrays as .npz atomically (compressed by default)."""
    return atomic_write(path, protect, npz_writer(arrays, compressed))
