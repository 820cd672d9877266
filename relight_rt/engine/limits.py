"""Limits on what is loaded: image sizes read from file headers, .npy headers checked before allocating.

Decoding a 40000 x 40000 PNG allocates 4.8 GB before anyone can say no, and a 100-byte .npy whose header
claims a (10**7, 10**7) array asks numpy for 800 TB. Both are refused here from the first bytes of the file:

- :func:`header_size` reads the width and height from the header of PNG, JPEG, BMP, WebP, TIFF, Radiance
  HDR and OpenEXR files (a few hundred bytes; JPEG: the segments up to the first SOF marker) without
  decoding. OpenCV has no header-only read in its Python API, and PIL is not a dependency, so the formats
  are parsed here, minimally, the way their decoders read them (JPEG: libjpeg's marker search, fill
  bytes and damage skipped; Radiance: OpenCV's 127-byte line reads), so that the size checked is the size
  decoded. Every parser is bounded in bytes and loops; a header that does not end within the bounds is
  refused (RelightError), never left to the decoder. This is the one header parser of the project (the
  studio's uploads go through it too). Any other format (PPM, JPEG 2000, ...) is checked right after
  decoding, where OpenCV's own cap (OPENCV_IO_MAX_IMAGE_PIXELS, 2**30 pixels by default) bounds the
  allocation.
- :func:`check_pixels` compares a size with :func:`max_pixels` (default 100 megapixels; the CLI's
  ``--max-pixels``; :func:`pixel_limit` changes it for a ``with`` block, per thread/task).
- :func:`load_npy` reads a .npy file with ``allow_pickle=False`` after checking its header: the magic
  string (a zip archive, i.e. an .npz, is named as such), a numeric dtype, and that the data the header
  announces is really in the file and under a size limit.
"""

from __future__ import annotations

import contextlib
import contextvars
import io
import math
import os
import re
import stat
import struct
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from .errors import RelightError

DEFAULT_MAX_PIXELS = 100_000_000
_MAX_PIXELS = contextvars.ContextVar("relight_rt_max_pixels", default=DEFAULT_MAX_PIXELS)
NPY_MAX_BYTES = 1 << 30  # no light sequence or layer file of this project comes near 1 GiB
# what a header parser may read in all (a TIFF's largest IFD is 786 KB, a Radiance header is read up to 1 MiB,
# a JPEG's stray bytes are skipped up to 1 MiB; seeks are free)
HEADER_MAX_BYTES = 4 << 20
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


def shrink(image: np.ndarray, max_pixels: int) -> np.ndarray:
    """``image`` as decoded (any depth, 1-4 channels), shrunk by area averaging to at most ``max_pixels`` with its
    aspect kept; the image itself when it is that small. A width that is a whole multiple of the height stays that
    multiple (an equirectangular panorama stays 2:1: the largest (h, 2h) within ``max_pixels``). The studio's
    uploads and a panorama read for a preview (relight_rt.light.envmap) are held to their size this way, before any
    full-size float copy."""
    import cv2

    h, w = image.shape[:2]
    if h * w <= max_pixels:
        return image
    if w % h == 0:
        small_h = max(1, math.isqrt(max_pixels // (w // h)))
        size = (w // h * small_h, small_h)
    else:
        s = math.sqrt(max_pixels / (h * w))
        size = (max(1, math.floor(w * s)), max(1, math.floor(h * s)))
    return cv2.resize(image, size, interpolation=cv2.INTER_AREA)


# ------------------------------------------------------------------------------------- image headers


def _png(f) -> tuple[int, int] | None:
    head = f.read(24)
    if len(head) == 24 and head[12:16] == b"IHDR":
        return struct.unpack(">II", head[16:24])
    return None


_SOF = {0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF}
JPEG_MAX_SEGMENTS = 4096  # segments before the frame header (a real JPEG has a dozen; metadata: a few hundred)
JPEG_MAX_STRAY = 1 << 20  # stray bytes (fill 0xFF, damage) skipped between segments, in all
_JPEG_CHUNK = 4096  # stray and fill bytes are scanned this many at a time


class _Unbounded(RelightError):
    """A header that does not end within the parser's bounds: refused, never left to the decoder."""


def _jpeg_marker(f, budget: list[int]) -> int | None:
    """The next marker code, found as libjpeg finds it (jdmarker.c, next_marker): bytes other than 0xFF
    are skipped (damage), then any 0xFF fill bytes, and 0xFF 0x00 is not a marker; None at the end of
    the file. ``budget``: stray bytes still allowed (shared over the whole header). Runs of stray and fill
    bytes are scanned a chunk at a time and the budget is checked as they go."""

    def spend(n: int) -> None:
        budget[0] -= n
        if budget[0] < 0:
            raise _Unbounded(f"more than {JPEG_MAX_STRAY} stray bytes between the JPEG header's segments")

    while True:
        step = 1  # a marker usually follows at once: read little, more only while skipping stray bytes
        while True:  # to the next 0xFF
            chunk = f.read(min(step, budget[0] + 2))
            step = _JPEG_CHUNK
            if not chunk:
                return None
            at = chunk.find(b"\xff")
            if at >= 0:
                spend(at + 1)
                f.seek(at + 1 - len(chunk), os.SEEK_CUR)
                break
            spend(len(chunk))
        step = 1
        while True:  # past the fill bytes
            chunk = f.read(min(step, budget[0] + 2))
            step = _JPEG_CHUNK
            if not chunk:
                return None
            fill = len(chunk) - len(chunk.lstrip(b"\xff"))
            spend(fill)
            if fill < len(chunk):
                f.seek(fill + 1 - len(chunk), os.SEEK_CUR)  # just past the byte after the fill
                code = chunk[fill]
                break
        if code != 0:
            return code
        spend(1)  # 0xFF 0x00: a stuffed byte, not a marker


def _jpeg(f) -> tuple[int, int] | None:
    """(width, height) of the first SOF segment, reached as libjpeg reaches it, so that the size checked
    is the size decoded; None where libjpeg stops before one (end of file, SOS or EOI first)."""
    if f.read(2) != b"\xff\xd8":
        return None
    budget = [JPEG_MAX_STRAY]
    for _ in range(JPEG_MAX_SEGMENTS):  # segments before the frame header: APPn (EXIF, ICC), DQT, DHT, ...
        code = _jpeg_marker(f, budget)
        if code is None or code in (0xD8, 0xD9, 0xDA):  # end of file, a second SOI, EOI, SOS: no frame
            return None
        if code == 0x01 or 0xD0 <= code <= 0xD7:  # TEM, RSTn: no length field
            continue
        raw = f.read(2)
        if len(raw) < 2:
            return None
        if code in _SOF:
            data = f.read(5)
            if len(data) < 5:
                return None
            h, w = struct.unpack(">HH", data[1:5])
            return w, h
        f.seek(max(struct.unpack(">H", raw)[0] - 2, 0), os.SEEK_CUR)  # libjpeg skips length - 2 (none if < 2)
    raise _Unbounded(f"no JPEG frame header within its first {JPEG_MAX_SEGMENTS} segments")


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


HDR_MAX_HEADER = 1 << 20  # a Radiance header is a few hundred bytes; a longer one is refused
_HDR_LINE = 127  # OpenCV reads the header with fgets into a 128-byte buffer: at most 127 bytes at a time
_WS = rb"[ \t\n\v\f\r]*"
_HDR_SIZE = re.compile(rb"-Y" + _WS + rb"([+-]?[0-9]+)" + _WS + rb"\+X" + _WS + rb"([+-]?[0-9]+)")  # "-Y %d +X %d"
_HDR_ANY = re.compile(rb"\s*[+-]([XY])\s+([0-9]+)\s+[+-]([XY])\s+([0-9]+)")  # other orientations


def _radiance(f) -> tuple[int, int] | None:
    """(width, height) from a Radiance header, read as OpenCV reads it (rgbe.cpp, RGBE_ReadHeader): the
    file in pieces of at most 127 bytes, each ending at a newline; the header ends at a piece that starts
    with a newline, and the next piece holds the size. The whole header is read, up to HDR_MAX_HEADER
    bytes; a longer one is refused."""
    head = f.read(HDR_MAX_HEADER + 1)
    pos = 0

    def piece() -> bytes | None:  # C's fgets(buf, 128, fp)
        nonlocal pos
        if pos >= len(head):
            if len(head) > HDR_MAX_HEADER:
                raise _Unbounded(f"the Radiance header is longer than {HDR_MAX_HEADER >> 20} MiB")
            return None
        end = head.find(b"\n", pos, pos + _HDR_LINE)
        start, pos = pos, (end + 1 if end >= 0 else min(pos + _HDR_LINE, len(head)))
        return head[start:pos]

    piece()  # "#?RADIANCE" (checked by the caller)
    while True:
        line = piece()
        if line is None:
            return None
        if line.startswith(b"\n"):
            break
    line = piece()
    if line is None:
        return None
    line = line.split(b"\x00", 1)[0]  # sscanf reads a C string
    found = _HDR_SIZE.match(line)
    if found:
        h, w = int(found[1]), int(found[2])
    else:  # OpenCV refuses other orientations; another reader may not
        found = _HDR_ANY.match(line)
        if not found or found[1] == found[3]:
            return None
        a, b = int(found[2]), int(found[4])
        w, h = (b, a) if found[1] == b"Y" else (a, b)
    if not (-(2**31) < w < 2**31 and -(2**31) < h < 2**31):  # C's int would wrap to a size no one checked
        raise _Unbounded(f"the Radiance header's size {w}x{h} does not fit a 32-bit integer")
    return (w, h) if w > 0 and h > 0 else None


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


class _HeaderReader:
    """A binary file seen through a byte budget: every parser reads at most ``budget`` bytes in all (a read
    at EOF counts as one), so no header, however forged, makes a loop run for ever or read a whole file."""

    def __init__(self, f, budget: int) -> None:
        self._f, self._left, self._budget = f, budget, budget

    def _take(self, data: bytes) -> bytes:
        self._left -= max(len(data), 1)  # a read at EOF counts too: a loop that reads b"" for ever ends
        if self._left < 0:
            raise _Unbounded(f"the image header goes on past {self._budget:,} bytes (a damaged or forged file)")
        return data

    def read(self, n: int = -1) -> bytes:
        return self._take(self._f.read(self._left + 1 if n is None or n < 0 else min(n, self._left + 1)))

    def seek(self, offset: int, whence: int = os.SEEK_SET) -> int:
        return self._f.seek(offset, whence)


def header_size(src: str | os.PathLike | bytes, name: str | None = None) -> tuple[int, int] | None:
    """(width, height) from an image's header without decoding it; None for formats not parsed here, or a
    header the decoder will refuse too (truncated, damaged).

    Args:
        src: an image file, or its bytes (an upload).
        name: what to call it in an error (default: the path, or "image").

    Raises:
        RelightError: ``src`` is a path but not a regular file (a FIFO or a device would block or never end),
            or a header that does not end within the parsers' bounds (HEADER_MAX_BYTES read in all, a JPEG
            frame header after thousands of segments, a Radiance header over 1 MiB, ...): refused, since the
            decoder would find a size that was never checked.
        OSError: the file cannot be opened or read.
    """
    data = isinstance(src, (bytes, bytearray, memoryview))
    if not data:
        require_file(src, "image")
    with io.BytesIO(src) if data else open(src, "rb") as f:
        head = f.read(8)
        for magic, parse in _SIGNATURES:
            if head.startswith(magic):
                f.seek(0)
                try:
                    return parse(_HeaderReader(f, HEADER_MAX_BYTES))
                except _Unbounded as exc:
                    raise RelightError(f"{name or ('image' if data else src)}: {exc}; refused") from None
                except (struct.error, ValueError, OverflowError):
                    return None  # a damaged header: the decoder will say so
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
