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
