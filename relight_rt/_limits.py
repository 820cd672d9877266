"""Limits on what is loaded: image sizes read from file headers, .npy headers checked before allocating.

Decoding a 40000 x 40000 PNG allocates 4.8 GB before anyone can say no, and a 100-byte .npy whose header
claims a (10**7, 10**7) array asks numpy for 800 TB. Both are refused here from the first bytes of the file:

- :func:`header_size` reads the width and height from the header of PNG, JPEG, BMP, WebP, TIFF, Radiance
  HDR and OpenEXR files (a few hundred bytes; JPEG: the segments up to the first SOF marker) without
  decoding. OpenCV has no header-only read in its Python API, and PIL is not a dependency, so the formats
  are parsed here, minimally. Any other format (PPM, JPEG 2000, ...) is checked right after decoding,
  where OpenCV's own cap (OPENCV_IO_MAX_IMAGE_PIXELS, 2**30 pixels by default) bounds the allocation.
- :func:`check_pixels` compares a size with :func:`max_pixels` (default 100 megapixels; the CLI's
  ``--max-pixels``; :func:`pixel_limit` changes it for a ``with`` block, per thread/task).
- :func:`load_npy` reads a .npy file with ``allow_pickle=False`` after checking its header: the magic
  string (a zip archive, i.e. an .npz, is named as such), a numeric dtype, and that the data the header
  announces is really in the file and under a size limit.
"""

from __future__ import annotations

import contextlib
import contextvars
import math
import os
import stat
import struct
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from ._errors import RelightError

DEFAULT_MAX_PIXELS = 100_000_000
_MAX_PIXELS = contextvars.ContextVar("relight_rt_max_pixels", default=DEFAULT_MAX_PIXELS)
NPY_MAX_BYTES = 1 << 30  # no light sequence or layer file of this project comes near 1 GiB
HEADER_MAX_BYTES = 1 << 20  # what a header parser may read (a TIFF's largest IFD is 786 KB; seeks are free)
_MAX_ATTRIBUTES = 1000  # OpenEXR header attributes parsed before giving up (real files have ~10-40)


def max_pixels() -> int:
    """The largest image (width x height) that is decoded; 0 means no limit."""
    return _MAX_PIXELS.get()


@contextlib.contextmanager
def pixel_limit(pixels: int) -> Iterator[None]:
    """Set :func:`max_pixels` inside a ``with`` block (0: no limit)."""
    if isinstance(pixels, bool) or not isinstance(pixels, int) or pixels < 0:
        raise RelightError(f"max pixels: expected a whole number >= 0, got {pixels!r}")
    token = _MAX_PIXELS.set(pixels)
    try:
        yield
    finally:
        _MAX_PIXELS.reset(token)


def check_pixels(width: int, height: int, name: str) -> None:
    """Raise RelightError when a width x height image exceeds :func:`max_pixels`."""
    limit = max_pixels()
    if limit and width * height > limit:
        raise RelightError(
            f"{name}: image is {width}x{height} ({width * height / 1e6:.1f} megapixels), more than the limit of "
            f"{limit / 1e6:g} megapixels; raise it with --max-pixels if the machine has the memory"
        )


def check_array_pixels(a: np.ndarray, name: str) -> None:
    """:func:`check_pixels` for an image given as an array (H, W[, C]): a 60000 x 60000 view of one pixel
    costs nothing until it is converted, then 43 GB; it is refused from its shape, before any work."""
    if a.ndim >= 2:
        check_pixels(int(a.shape[1]), int(a.shape[0]), name)


# ------------------------------------------------------------------------------------- image headers


def _png(f) -> tuple[int, int] | None:
    head = f.read(24)
    if len(head) == 24 and head[12:16] == b"IHDR":
        return struct.unpack(">II", head[16:24])
    return None


_SOF = {0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF}


def _jpeg(f) -> tuple[int, int] | None:
    f.seek(2)
    for _ in range(1000):  # segments before the frame header: APPn (EXIF, ICC), DQT, DHT, ...
        byte = f.read(1)
        while byte == b"\xff":  # fill bytes
            marker = f.read(1)
            if marker != b"\xff":
                break
            byte = marker
        else:
            return None
        if not marker:
            return None
        code = marker[0]
        if code in (0x01, *range(0xD0, 0xD9)):  # markers without a length
            continue
        raw = f.read(2)
        if len(raw) < 2:
            return None
        length = struct.unpack(">H", raw)[0]
        if code in _SOF:
            data = f.read(5)
            if len(data) < 5:
                return None
            h, w = struct.unpack(">HH", data[1:5])
            return w, h
        if length < 2:
            return None
        f.seek(length - 2, os.SEEK_CUR)
    return None


def _bmp(f) -> tuple[int, int] | None:
    head = f.read(26)
    if len(head) < 26:
        return None
    w, h = struct.unpack("<ii", head[18:26])
    return abs(w), abs(h)


def _webp(f) -> tuple[int, int] | None:
    head = f.read(30)
    if len(head) < 30 or head[8:12] != b"WEBP":
        return None
    chunk = head[12:16]
    if chunk == b"VP8X":
        w = int.from_bytes(head[24:27], "little") + 1
        h = int.from_bytes(head[27:30], "little") + 1
        return w, h
    if chunk == b"VP8L":
        bits = int.from_bytes(head[21:25], "little")
        return (bits & 0x3FFF) + 1, ((bits >> 14) & 0x3FFF) + 1
    if chunk == b"VP8 ":
        w, h = struct.unpack("<HH", head[26:30])
        return w & 0x3FFF, h & 0x3FFF
    return None


def _tiff(f) -> tuple[int, int] | None:
    order = "<" if f.read(2) == b"II" else ">"
    magic, offset = struct.unpack(order + "HI", f.read(6))
    if magic != 42:  # 43: BigTIFF, not parsed
        return None
    f.seek(offset)
    raw = f.read(2)
    if len(raw) < 2:
        return None
    found = {}
    for _ in range(struct.unpack(order + "H", raw)[0]):
        entry = f.read(12)
        if len(entry) < 12:
            return None
        tag, kind, _count = struct.unpack(order + "HHI", entry[:8])
        if tag in (256, 257):
            value = entry[8:10] if kind == 3 else entry[8:12]  # SHORT or LONG
            found[tag] = struct.unpack(order + ("H" if kind == 3 else "I"), value)[0]
    if 256 in found and 257 in found:
        return found[256], found[257]
    return None


def _radiance(f) -> tuple[int, int] | None:
    for _ in range(200):
        line = f.readline(4096).strip()
        if not line:  # the empty line that ends the header; the resolution line follows
            parts = f.readline(256).split()
            if len(parts) == 4 and parts[0][1:2] in (b"Y", b"X") and parts[2][1:2] in (b"X", b"Y"):
                a, b = int(parts[1]), int(parts[3])
                return (b, a) if parts[0][1:2] == b"Y" else (a, b)
            return None
    return None


def _cstring(f, limit: int) -> bytes | None:
    """A NUL-terminated string of at most ``limit`` bytes; None at EOF or when it runs longer (a damaged or
    forged header: reading on would never end at EOF, or end only after the whole file)."""
    data = f.read(limit + 1)
    end = data.find(b"\x00")
    if end < 0:
        return None
    f.seek(end + 1 - len(data), os.SEEK_CUR)  # back to just after the NUL
    return data[:end]


def _exr(f) -> tuple[int, int] | None:
    f.seek(8)
    for _ in range(_MAX_ATTRIBUTES):
        name = _cstring(f, 255)  # OpenEXR: attribute and type names are at most 255 bytes (31 in old files)
        if not name:  # None (no NUL within the limit, or EOF) or b"" (the end of the header)
            return None
        if _cstring(f, 255) is None:  # the attribute's type name
            return None
        raw = f.read(4)
        if len(raw) < 4:
            return None
        size = struct.unpack("<i", raw)[0]
        if name == b"dataWindow" and size == 16:
            x0, y0, x1, y1 = struct.unpack("<iiii", f.read(16))
            if x1 < x0 or y1 < y0:
                return None
            return x1 - x0 + 1, y1 - y0 + 1
        if size < 0:
            return None
        f.seek(size, os.SEEK_CUR)
    return None


_SIGNATURES = (
    (b"\x89PNG\r\n\x1a\n", _png),
    (b"\xff\xd8", _jpeg),
    (b"BM", _bmp),
    (b"RIFF", _webp),
    (b"II*\x00", _tiff),
    (b"MM\x00*", _tiff),
    (b"#?", _radiance),
    (b"v/1\x01", _exr),
)


class _HeaderTooLong(Exception):
    """A header parser went past its byte budget."""


class _HeaderReader:
    """A binary file seen through a byte budget: every parser reads at most ``budget`` bytes in all (a read
    at EOF counts as one), so no header, however forged, makes a loop run for ever or read a whole file."""

    def __init__(self, f, budget: int) -> None:
        self._f, self._left = f, budget

    def _take(self, data: bytes) -> bytes:
        self._left -= max(len(data), 1)  # a read at EOF counts too: a loop that reads b"" for ever ends
        if self._left < 0:
            raise _HeaderTooLong()
        return data

    def read(self, n: int = -1) -> bytes:
        return self._take(self._f.read(self._left + 1 if n is None or n < 0 else min(n, self._left + 1)))

    def readline(self, n: int = -1) -> bytes:
        return self._take(self._f.readline(self._left + 1 if n is None or n < 0 else min(n, self._left + 1)))

    def seek(self, offset: int, whence: int = os.SEEK_SET) -> int:
        return self._f.seek(offset, whence)

    def tell(self) -> int:
        return self._f.tell()


def header_size(path: str | os.PathLike) -> tuple[int, int] | None:
    """(width, height) from an image file's header without decoding it; None for formats not parsed here
    and for damaged headers (the decoder then says what is wrong). Reads at most HEADER_MAX_BYTES.

    Raises:
        OSError: the file cannot be opened or read.
        RelightError: ``path`` is not a regular file (a FIFO or a device would block or never end), or its
            header goes on past HEADER_MAX_BYTES (no real image's does: refused rather than decoded unchecked).
    """
    require_file(path, "image")
    with open(path, "rb") as f:
        head = f.read(8)
        for magic, parse in _SIGNATURES:
            if head.startswith(magic):
                f.seek(0)
                try:
                    return parse(_HeaderReader(f, HEADER_MAX_BYTES))
                except (struct.error, ValueError, OverflowError):
                    return None  # a damaged header: the decoder will say so
                except _HeaderTooLong:
                    raise RelightError(f"{path}: the image header goes on past {HEADER_MAX_BYTES:,} bytes "
                                       "(a damaged or forged file); not decoded") from None
    return None


def require_file(path: str | os.PathLike, name: str) -> Path:
    """``path`` as a Path when it names a regular file (symlinks followed); else RelightError naming it.

    Reading a FIFO blocks until a writer comes (for ever, in a batch), and a device such as /dev/zero never
    ends: every input file is checked with this before it is opened.
    """
    p = Path(path)
    try:
        st = os.stat(p)
    except FileNotFoundError:
        raise RelightError(f"{name} {p}: not found") from None
    except OSError as exc:
        raise RelightError(f"{name} {p}: cannot read ({exc.strerror or exc})") from None
    if not stat.S_ISREG(st.st_mode):
        what = "a folder" if stat.S_ISDIR(st.st_mode) else "a FIFO" if stat.S_ISFIFO(st.st_mode) else \
            "a device" if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode) else \
            "a socket" if stat.S_ISSOCK(st.st_mode) else "not a file"
        raise RelightError(f"{name} {p}: not a regular file ({what}); expected a file")
    return p


def require_file_or_folder(path: str | os.PathLike, name: str) -> Path:
    """``path`` when it names a regular file or a folder; else RelightError (see :func:`require_file`)."""
    p = Path(path)
    if p.is_dir():
        return p
    return require_file(p, name)


# ------------------------------------------------------------------------------------- .npy


def load_npy(path: str | os.PathLike, name: str = "array", max_bytes: int = NPY_MAX_BYTES) -> np.ndarray:
    """Read a .npy file without pickles, refusing what its header says before anything is allocated.

    Raises:
        RelightError: missing or unreadable file, empty file, an .npz (zip) or another format under a .npy
            name, an object (pickled) or non-numeric dtype, a header announcing more data than the file holds
            (truncated or forged) or more than ``max_bytes``.
    """
    p = Path(path)
    label = f"{name} {p}"
    if p.exists() and not p.is_file():
        raise RelightError(f"{label}: not a regular file")
    try:
        with open(p, "rb") as f:
            size = os.fstat(f.fileno()).st_size
            if size == 0:
                raise RelightError(f"{label}: the file is empty (0 bytes); expected a .npy array")
            head = f.read(6)
            if head.startswith(b"PK"):
                raise RelightError(f"{label}: is a zip archive (an .npz), expected a single-array .npy file")
            if not head.startswith(b"\x93NUMPY"):
                hint = " (it looks like JSON text)" if head.lstrip()[:1] in (b"{", b"[") else ""
                raise RelightError(f"{label}: not a .npy file (no NUMPY header){hint}")
            f.seek(0)
            version = np.lib.format.read_magic(f)
            if version == (1, 0):
                shape, fortran, dtype = np.lib.format.read_array_header_1_0(f)
            elif version == (2, 0):
                shape, fortran, dtype = np.lib.format.read_array_header_2_0(f)
            else:
                raise RelightError(f"{label}: .npy format version {version} is not read here (1.0 and 2.0 are)")
            if dtype.hasobject:
                raise RelightError(f"{label}: holds Python objects (pickled data), which are never loaded")
            if dtype.kind not in "biuf":
                raise RelightError(f"{label}: expected numbers, got dtype {dtype}")
            nbytes = math.prod(shape) * dtype.itemsize
            available = size - f.tell()
            if nbytes > available:
                raise RelightError(
                    f"{label}: the header announces a {shape} {dtype} array ({nbytes:,} bytes) but the file holds "
                    f"{available:,} bytes of data (truncated or corrupt)"
                )
            if nbytes > max_bytes:
                raise RelightError(f"{label}: a {shape} {dtype} array is {nbytes:,} bytes, more than {max_bytes:,}")
            f.seek(0)
            return np.load(f, allow_pickle=False)
    except OSError as exc:
        raise RelightError(f"{label}: cannot read ({exc.strerror or exc})") from None
    except ValueError as exc:
        if isinstance(exc, RelightError):
            raise
        raise RelightError(f"{label}: not a valid .npy file ({exc})") from None
