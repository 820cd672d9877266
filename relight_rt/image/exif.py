"""The EXIF orientation tag of an image file, and turning decoded pixels the way it says.

A phone stores a photo as its sensor read it and writes in tag 0x0112 how to turn it for display. Every
intake of the runtime (photos, masks, backgrounds, video frames given as files, studio uploads) decodes
with OpenCV's own orientation handling switched off and applies :func:`apply_orientation` here, so the
same rule holds for every flag and channel count (OpenCV applies it for some decode flags and not for
others). Read from JPEG (APP1 ``Exif``), PNG (``eXIf`` chunk) and WebP (``EXIF`` chunk); anything
unreadable counts as "no tag" (1): a damaged tag never stops a photo from loading.
"""

from __future__ import annotations

import struct

import numpy as np

_PNG = b"\x89PNG\r\n\x1a\n"
_TAG_ORIENTATION = 0x0112
_MAX_WALK = 4096  # segments/chunks looked at before giving up (a forged file cannot make this loop long)


def _tiff_orientation(buf: bytes) -> int:
    """The orientation in a TIFF-structured EXIF block (byte order, 42, IFD0 offset, IFD0 entries)."""
    order = {b"II": "<", b"MM": ">"}.get(bytes(buf[:2]))
    if order is None or struct.unpack_from(order + "H", buf, 2)[0] != 42:
        return 1
    ifd = struct.unpack_from(order + "I", buf, 4)[0]
    count = struct.unpack_from(order + "H", buf, ifd)[0]
    for k in range(min(count, _MAX_WALK)):
        tag, kind, n = struct.unpack_from(order + "HHI", buf, ifd + 2 + 12 * k)
        if tag == _TAG_ORIENTATION and kind == 3 and n >= 1:  # SHORT, stored in the entry itself
            value = struct.unpack_from(order + "H", buf, ifd + 2 + 12 * k + 8)[0]
            return value if 1 <= value <= 8 else 1
    return 1


def _jpeg_exif(buf: memoryview) -> memoryview | None:
    pos = 2
    for _ in range(_MAX_WALK):
        if buf[pos] != 0xFF:
            return None
        marker = buf[pos + 1]
        if marker == 0xFF:  # fill byte
            pos += 1
            continue
        if marker in (0xD9, 0xDA):  # end of image, start of scan: no EXIF before the pixels
            return None
        if 0xD0 <= marker <= 0xD7 or marker == 0x01:  # markers without a length
            pos += 2
            continue
        length = struct.unpack_from(">H", buf, pos + 2)[0]
        if marker == 0xE1 and bytes(buf[pos + 4 : pos + 10]) == b"Exif\x00\x00":
            return buf[pos + 10 : pos + 2 + length]
        pos += 2 + length
    return None


def _png_exif(buf: memoryview) -> memoryview | None:
    pos = 8
    for _ in range(_MAX_WALK):
        length = struct.unpack_from(">I", buf, pos)[0]
        kind = bytes(buf[pos + 4 : pos + 8])
        if kind == b"eXIf":
            return buf[pos + 8 : pos + 8 + length]
        if kind == b"IEND":
            return None
        pos += 12 + length
    return None


def _webp_exif(buf: memoryview) -> memoryview | None:
    pos = 12
    for _ in range(_MAX_WALK):
        kind = bytes(buf[pos : pos + 4])
        length = struct.unpack_from("<I", buf, pos + 4)[0]
        if kind == b"EXIF":
            block = buf[pos + 8 : pos + 8 + length]
            return block[6:] if bytes(block[:6]) == b"Exif\x00\x00" else block
        pos += 8 + length + (length & 1)
    return None


def exif_orientation(data: bytes | np.ndarray) -> int:
    """The EXIF orientation (1-8; 1 = as stored) of an encoded JPEG, PNG or WebP file; 1 when absent,
    unreadable or another format."""
    buf = memoryview(np.ascontiguousarray(np.frombuffer(data, np.uint8)) if not isinstance(data, bytes) else data)
    try:
        head = bytes(buf[:12])
        if head[:2] == b"\xff\xd8":
            block = _jpeg_exif(buf)
        elif head[:8] == _PNG:
            block = _png_exif(buf)
        elif head[:4] == b"RIFF" and head[8:12] == b"WEBP":
            block = _webp_exif(buf)
        else:
            return 1
        return _tiff_orientation(block) if block is not None else 1
    except (struct.error, IndexError, ValueError):
        return 1


def apply_orientation(image: np.ndarray, orientation: int) -> np.ndarray:
    """``image`` (H, W[, C]) as stored → as shown, for EXIF orientation 1-8 (a view when nothing moves).

    1 as is; 2 mirrored left-right; 3 turned 180°; 4 mirrored top-bottom; 5 transposed (mirrored about the
    main diagonal); 6 turned 90° clockwise; 7 mirrored about the other diagonal; 8 turned 90° anticlockwise.
    """
    a = image
    if orientation == 2:
        return np.ascontiguousarray(a[:, ::-1])
    if orientation == 3:
        return np.ascontiguousarray(a[::-1, ::-1])
    if orientation == 4:
        return np.ascontiguousarray(a[::-1])
    if orientation == 5:
        return np.ascontiguousarray(a.swapaxes(0, 1))
    if orientation == 6:
        return np.ascontiguousarray(a[::-1].swapaxes(0, 1))
    if orientation == 7:
        return np.ascontiguousarray(a[::-1, ::-1].swapaxes(0, 1))
    if orientation == 8:
        return np.ascontiguousarray(a[:, ::-1].swapaxes(0, 1))
    return a
