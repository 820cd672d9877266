"""A small OpenEXR writer: single-part scanline files of 32-bit float channels, ZIP-compressed.

relight_rt's OpenCV cannot write EXR (its wheels ship no encoder), and the format's single-part scanline
layout is short enough to write here without a dependency (OpenEXR's "Technical Introduction" and "OpenEXR
File Layout"): the magic number and version, a header of attributes (channels, compression, data and display
windows, line order, pixel aspect ratio, screen window), a table of chunk offsets, then the chunks, each
``int32 y, int32 size, data`` with 16 scanlines (ZIP) whose pixels are stored channel by channel, channels in
alphabetical order, little-endian. ZIP compression reorders the bytes (even bytes, then odd bytes), replaces
each by its difference from the previous one (+128, mod 256) and deflates the result with zlib; a chunk that
does not get smaller is stored as it is, as the format allows. tests/runtime/apps/test_render_passes.py reads the files
back with OpenEXR's own Python module.
"""

from __future__ import annotations

import struct
import zlib

import numpy as np

from ..engine.errors import RelightError

_MAGIC = 20000630
_FLOAT = 2  # pixel type: 0 UINT, 1 HALF, 2 FLOAT
_ZIP = 3  # compression: 0 NONE, 3 ZIP (16 scanlines per chunk)
_LINES = 16


def _attribute(name: str, kind: str, value: bytes) -> bytes:
    return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(value)) + value


def _channel_list(names: list[str]) -> bytes:
    # name, pixel type, pLinear (1 byte) + 3 reserved bytes, x and y sampling; the list ends with a null byte
    return b"".join(n.encode() + b"\0" + struct.pack("<iB3xii", _FLOAT, 0, 1, 1) for n in names) + b"\0"


def _zip(raw: bytes) -> bytes:
    data = np.frombuffer(raw, np.uint8)
    reordered = np.concatenate([data[0::2], data[1::2]])
    predicted = reordered.copy()
    predicted[1:] = (reordered[1:].astype(np.int16) - reordered[:-1] + 128).astype(np.uint8)
    packed = zlib.compress(predicted.tobytes(), 6)
    return packed if len(packed) < len(raw) else raw


def encode_exr(channels: dict[str, np.ndarray]) -> bytes:
    """An EXR file holding ``channels`` as 32-bit float.

    Args:
        channels: channel name ("R", "G", "B", "A", "Y", or "layer.R" ...) → (H, W) array, all of one size; stored
            in alphabetical order as the format requires.

    Returns:
        The file's bytes.

    Raises:
        RelightError: no channels, arrays of different or empty sizes, a bad name, values that are not finite.
    """
    if not channels:
        raise RelightError("exr: expected at least one channel")
    names = sorted(channels)
    planes = [np.ascontiguousarray(channels[n], dtype="<f4") for n in names]
    shape = planes[0].shape
    if len(shape) != 2 or 0 in shape or any(p.shape != shape for p in planes):
        raise RelightError(f"exr: expected (H, W) channels of one size, got {[p.shape for p in planes]}")
    for n, p in zip(names, planes, strict=True):
        if not n or "\0" in n or len(n.encode()) > 255:
            raise RelightError(f"exr: bad channel name {n!r}")
        if not np.all(np.isfinite(p)):
            raise RelightError(f"exr: channel {n!r} holds NaN or Inf")
    h, w = shape
    box = struct.pack("<iiii", 0, 0, w - 1, h - 1)
    header = struct.pack("<ii", _MAGIC, 2) + b"".join([
        _attribute("channels", "chlist", _channel_list(names)),
        _attribute("compression", "compression", bytes([_ZIP])),
        _attribute("dataWindow", "box2i", box),
        _attribute("displayWindow", "box2i", box),
        _attribute("lineOrder", "lineOrder", bytes([0])),
        _attribute("pixelAspectRatio", "float", struct.pack("<f", 1.0)),
        _attribute("screenWindowCenter", "v2f", struct.pack("<ff", 0.0, 0.0)),
        _attribute("screenWindowWidth", "float", struct.pack("<f", 1.0)),
    ]) + b"\0"  # fmt: skip
    stacked = np.stack(planes, axis=1)  # (H, C, W): each scanline holds its channels one after another
    chunks = []
    for y in range(0, h, _LINES):
        data = _zip(stacked[y : y + _LINES].tobytes())
        chunks.append(struct.pack("<ii", y, len(data)) + data)
    offsets, position = [], len(header) + 8 * len(chunks)
    for chunk in chunks:
        offsets.append(position)
        position += len(chunk)
    return header + struct.pack(f"<{len(offsets)}Q", *offsets) + b"".join(chunks)
