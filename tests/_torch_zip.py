"""Write PyTorch's zip checkpoint format by hand (no torch): for tests of the torch-free importer.

``write_state_dict`` lays out what ``torch.save(OrderedDict of tensors)`` writes: ``PREFIX/data.pkl``
(protocol-2 pickle: an OrderedDict whose values are ``torch._utils._rebuild_tensor_v2`` records, each
storage a persistent id ``("storage", torch.<Type>Storage, KEY, "cpu", NUMEL)``), ``PREFIX/data/KEY``
(raw storage bytes), ``PREFIX/byteorder`` and ``PREFIX/version``. The pickle opcodes are emitted one by
one, so any pickle (a malicious one too) can be packed with :func:`write_archive`.
"""

from __future__ import annotations

import struct
import zipfile
import zlib
from pathlib import Path

import numpy as np

_STORAGE = {
    np.dtype("float32"): "FloatStorage",
    np.dtype("float64"): "DoubleStorage",
    np.dtype("float16"): "HalfStorage",
    np.dtype("int64"): "LongStorage",
    np.dtype("int32"): "IntStorage",
    np.dtype("uint8"): "ByteStorage",
    np.dtype("bool"): "BoolStorage",
}


def op_global(module: str, name: str) -> bytes:
    return b"c" + module.encode() + b"\n" + name.encode() + b"\n"


def op_str(text: str) -> bytes:
    data = text.encode("utf-8")
    return b"X" + struct.pack("<I", len(data)) + data


def op_int(value: int) -> bytes:
    return b"J" + struct.pack("<i", value)


def op_tuple(items: list[bytes]) -> bytes:
    return b"(" + b"".join(items) + b"t"


def tensor_record(key: str, storage_type: str, numel: int, offset: int, size, stride) -> bytes:
    """The pickle of one tensor: _rebuild_tensor_v2(storage, offset, size, stride, False, OrderedDict())."""
    pid = op_tuple([op_str("storage"), op_global("torch", storage_type), op_str(key), op_str("cpu"), op_int(numel)])
    args = [
        pid + b"Q",  # BINPERSID
        op_int(offset),
        op_tuple([op_int(v) for v in size]),
        op_tuple([op_int(v) for v in stride]),
        b"\x89",  # NEWFALSE
        op_global("collections", "OrderedDict") + b")R",
    ]
    return op_global("torch._utils", "_rebuild_tensor_v2") + op_tuple(args) + b"R"


def write_archive(path: str | Path, pickle_bytes: bytes, storages: dict[str, bytes], prefix: str = "archive",
                  byteorder: str = "little") -> Path:
    path = Path(path)
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_STORED) as z:
        z.writestr(f"{prefix}/data.pkl", pickle_bytes)
        z.writestr(f"{prefix}/byteorder", byteorder)
        for key, data in storages.items():
            z.writestr(f"{prefix}/data/{key}", data)
        z.writestr(f"{prefix}/version", "3\n")
    return path


def write_state_dict(path: str | Path, state: dict[str, np.ndarray], prefix: str = "archive",
                     byteorder: str = "little") -> Path:
    """``state`` (name -> array) as torch.save would write it; arrays are stored C-contiguous."""
    order = "<" if byteorder == "little" else ">"
    body = [b"\x80\x02", op_global("collections", "OrderedDict"), b")R", b"("]
    storages = {}
    for i, (name, value) in enumerate(state.items()):
        a = np.array(value, order="C")  # (ascontiguousarray would make a 0-d array 1-d)
        stride = [int(s // a.itemsize) for s in a.strides] if a.ndim else []
        body.append(op_str(name))
        body.append(tensor_record(str(i), _STORAGE[a.dtype], a.size, 0, a.shape, stride))
        storages[str(i)] = a.astype(a.dtype.newbyteorder(order)).tobytes()
    body.append(b"u.")  # SETITEMS, STOP
    return write_archive(path, b"".join(body), storages, prefix, byteorder)


# ------------------------------------------------------------------------------------------- bombs


def deflated_zeros(n_bytes: int, head: bytes = b"", tail: bytes = b"") -> bytes:
    """A raw deflate stream of ``head`` + ``n_bytes`` zero bytes + ``tail``, made in milliseconds: one 16 MiB
    block of zeros is compressed once (full flush, so it stands alone) and repeated. 2 GiB of zeros: ~2 MB."""
    chunk = 1 << 24
    if n_bytes % chunk:
        raise ValueError("n_bytes: a multiple of 16 MiB")
    flush = zlib.Z_FULL_FLUSH

    def block(data: bytes) -> bytes:
        c = zlib.compressobj(9, zlib.DEFLATED, -15)
        return c.compress(data) + c.flush(flush)

    final = zlib.compressobj(9, zlib.DEFLATED, -15)
    return block(head) + block(bytes(chunk)) * (n_bytes // chunk) + final.compress(tail) + final.flush()


def write_raw_zip(path: str | Path, members: list[tuple[str, bytes, int, int]]) -> Path:
    """A zip archive written field by field: (name, data as stored, method (0 stored, 8 deflated), declared
    uncompressed size). A deflated member's CRC is left 0: those are the bombs, refused (or blowing up) before
    any check of it; a stored member gets its real CRC."""
    path = Path(path)
    body, central = b"", b""
    for name, data, method, size in members:
        raw_name = name.encode()
        crc = zlib.crc32(data) if method == 0 else 0
        fields = struct.pack("<HHHHHIII", 20, 0, method, 0, 0x21, crc, len(data), size)
        central += b"PK\x01\x02" + struct.pack("<H", 20) + fields + struct.pack("<HHHHHII", len(raw_name), 0, 0, 0,
                                                                               0, 0, len(body)) + raw_name
        body += b"PK\x03\x04" + fields + struct.pack("<HH", len(raw_name), 0) + raw_name + data
    end = b"PK\x05\x06" + struct.pack("<HHHHIIH", 0, 0, len(members), len(members), len(central), len(body), 0)
    path.write_bytes(body + central + end)
    return path
