"""Reading a ``torch.save`` zip checkpoint of tensors without torch, for relight_rt.apps.reference_checkpoints.

A restricted unpickler that resolves only the globals a plain state_dict of tensors needs (the records are
plain objects: nothing from the file runs), an opcode scan of ``data.pkl`` before the unpickler sees it
(:func:`scan_pickle`), and storages read only after every record is known, their declared sizes bounded
(:func:`read_checkpoint`). The relight_rt.apps.reference_checkpoints module docstring says what is accepted and
why.
"""

from __future__ import annotations

import io
import math
import os
import pickle
import re
import zipfile
import zlib
from collections import OrderedDict
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..engine.errors import RelightError

_STORAGE_DTYPES = {
    "FloatStorage": "f4",
    "DoubleStorage": "f8",
    "HalfStorage": "f2",
    "BFloat16Storage": "bf16",
    "LongStorage": "i8",
    "IntStorage": "i4",
    "ShortStorage": "i2",
    "CharStorage": "i1",
    "ByteStorage": "u1",
    "BoolStorage": "b1",
    "UntypedStorage": "u1",
}
_STORAGE_KEY = re.compile(r"[A-Za-z0-9_]{1,64}")
PICKLE_MAX_BYTES = 8 << 20  # a state_dict's data.pkl: names and records, ~60 KB for the reference's 144 tensors
PICKLE_MAX_OPS = 1_000_000  # pickle opcodes (the reference's: ~4,000)
PICKLE_MAX_DEPTH = 32  # nesting of containers (a state_dict's: 4); the C code that hashes or frees them recurses


class _StorageType:
    """What the unpickler returns for ``torch.<Name>Storage``: a name, nothing callable, immutable."""

    __slots__ = ("name",)

    def __init__(self, name: str) -> None:
        object.__setattr__(self, "name", name)

    def __setattr__(self, key, value):
        raise AttributeError("read-only")


class _Storage:
    """One storage record of the archive: its member, element type and count; read later (:func:`_materialise`),
    after every record and the layout were checked."""

    __slots__ = ("code", "info", "key", "numel")

    def __init__(self, key: str, code: str, numel: int, info: zipfile.ZipInfo) -> None:
        for k, v in (("key", key), ("code", code), ("numel", numel), ("info", info)):
            object.__setattr__(self, k, v)

    def __setattr__(self, key, value):
        raise AttributeError("read-only")


class _Tensor:
    """A tensor record: ``size`` elements, contiguous, from ``offset`` in ``storage``; nothing read yet."""

    __slots__ = ("offset", "size", "storage")

    def __init__(self, storage: _Storage, offset: int, size: tuple[int, ...]) -> None:
        for k, v in (("storage", storage), ("offset", offset), ("size", size)):
            object.__setattr__(self, k, v)

    def __setattr__(self, key, value):
        raise AttributeError("read-only")


def is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


class _WeightsUnpickler(pickle.Unpickler):
    """Unpickles a state_dict of tensor records (:class:`_Tensor`, nothing read); refuses every other global
    (module docstring)."""

    def __init__(self, file, archive: zipfile.ZipFile, prefix: str, name: str) -> None:
        super().__init__(file)
        self._zip, self._prefix, self._name = archive, prefix, name
        self._storages: dict[str, _Storage] = {}

    def find_class(self, module: str, name: str):
        if (module, name) == ("collections", "OrderedDict"):
            return OrderedDict
        if (module, name) == ("torch._utils", "_rebuild_tensor_v2"):
            return self._rebuild_tensor
        if (module, name) == ("torch._utils", "_rebuild_parameter"):
            return self._rebuild_parameter
        if module in ("torch", "torch.storage") and name in _STORAGE_DTYPES:
            return _StorageType(name)
        raise RelightError(
            f"{self._name}: refused: the checkpoint's pickle asks for {module}.{name}, which is not a tensor or "
            "storage record; only plain state_dicts of tensors are read (nothing from the file was run)"
        )

    def persistent_load(self, pid):
        if not (isinstance(pid, tuple) and len(pid) == 5 and pid[0] == "storage"):
            raise RelightError(f"{self._name}: refused: unexpected persistent record {_short(pid)}")
        _, stype, key, _location, numel = pid
        if not isinstance(stype, _StorageType) or not isinstance(key, str) or not is_int(numel) or numel < 0:
            raise RelightError(f"{self._name}: refused: malformed storage record {_short(pid)}")
        if not _STORAGE_KEY.fullmatch(key):
            raise RelightError(f"{self._name}: refused: storage key {key[:40]!r} is not a plain name")
        if key in self._storages:
            return self._storages[key]
        code = _STORAGE_DTYPES[stype.name]
        member = f"{self._prefix}/data/{key}"
        try:
            info = self._zip.getinfo(member)
        except KeyError:
            raise RelightError(f"{self._name}: storage {member} is missing from the archive") from None
        itemsize = 2 if code == "bf16" else int(code[1:])
        if info.file_size != numel * itemsize:  # checked before reading: a size lie is never decompressed
            raise RelightError(
                f"{self._name}: storage {member} holds {info.file_size} bytes, expected {numel} x {itemsize} "
                f"({stype.name})"
            )
        storage = _Storage(key, code, numel, info)
        self._storages[key] = storage
        return storage

    def _rebuild_tensor(self, storage, offset, size, stride, requires_grad=False, backward_hooks=None, *rest):
        if not isinstance(storage, _Storage):
            raise RelightError(f"{self._name}: refused: a tensor record without a storage")
        ok = is_int(offset) and offset >= 0 and isinstance(size, tuple) and isinstance(stride, tuple)
        ok = ok and len(size) == len(stride) and all(is_int(v) and v >= 0 for v in (*size, *stride))
        if not ok:
            raise RelightError(f"{self._name}: malformed tensor record (offset {offset!r}, size {size!r})")
        if not _no_hooks(backward_hooks) or len(rest) > 1:
            raise RelightError(f"{self._name}: refused: a tensor record with hooks or extra state")
        count = math.prod(size)
        if count == 0:
            return _Tensor(storage, 0, size)
        contiguous, step = [], 1  # C order; the stride of a dimension of size 1 is free (torch leaves any)
        for n in reversed(size):
            contiguous.append(step)
            step *= n
        contiguous.reverse()
        if any(n > 1 and s != c for n, s, c in zip(size, stride, contiguous, strict=True)):
            raise RelightError(f"{self._name}: refused: a tensor of size {size} with strides {stride}; only "
                               f"contiguous tensors (strides {tuple(contiguous)}) are read")
        if offset + count > storage.numel:
            raise RelightError(f"{self._name}: a tensor reaches past its storage ({offset + count - 1} >= "
                               f"{storage.numel} elements)")
        return _Tensor(storage, offset, size)

    def _rebuild_parameter(self, data, requires_grad=False, backward_hooks=None):
        if not isinstance(data, _Tensor) or not _no_hooks(backward_hooks):
            raise RelightError(f"{self._name}: refused: a malformed parameter record")
        return data


def _materialise(records: dict[str, _Tensor], archive: zipfile.ZipFile, byteorder: str, name: str,
                 max_elements: int) -> dict[str, np.ndarray]:
    """Read the storages the records use and cut each tensor out of its storage (a copy, native byte order).

    Both are bounded by ``max_elements`` before anything is decompressed: the storages' declared sizes (each
    storage once) and the tensors' (each record once: many records can view one storage, and each is copied).
    """
    storages = {id(t.storage): t.storage for t in records.values()}
    hint = "of the network expected (a forged or foreign checkpoint; check --width/--resolution)"
    total = sum(st.numel for st in storages.values())
    if total > max_elements:
        raise RelightError(f"{name}: refused: its storages hold {total:,} elements, more than the {max_elements:,} "
                           + hint)
    copied = sum(math.prod(t.size) for t in records.values())
    if copied > max_elements:
        raise RelightError(f"{name}: refused: its {len(records):,} tensors hold {copied:,} elements together, more "
                           f"than the {max_elements:,} " + hint)
    order = "<" if byteorder == "little" else ">"
    arrays: dict[int, np.ndarray] = {}
    for key, st in storages.items():
        raw = archive.read(st.info)
        if len(raw) != st.info.file_size:
            raise RelightError(f"{name}: storage {st.info.filename} is truncated")
        if st.code == "bf16":
            bits = np.frombuffer(raw, dtype=order + "u2").astype(np.uint32) << 16
            arrays[key] = bits.view(np.float32)
        elif st.code == "b1":
            arrays[key] = np.frombuffer(raw, dtype=np.bool_)
        else:
            arrays[key] = np.frombuffer(raw, dtype=order + st.code).astype(st.code, copy=False)  # tensors copy below
        del raw
    out = {}
    for k, t in records.items():
        flat = arrays[id(t.storage)]
        count = math.prod(t.size)
        out[k] = flat[t.offset : t.offset + count].reshape(t.size).copy() if count else np.zeros(t.size, flat.dtype)
    return out


def _no_hooks(hooks) -> bool:
    return hooks is None or (isinstance(hooks, dict) and not hooks)


def _short(value) -> str:
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def scan_pickle(data: bytes, name: str) -> None:
    """Walk a pickle's opcodes (nothing is built, nothing is run) and refuse one that is not a plain, shallow
    record: more than PICKLE_MAX_OPS opcodes, containers nested deeper than PICKLE_MAX_DEPTH (a tuple key
    nested 200,000 deep crashes the interpreter when the dict hashes it: a segfault, not an exception), a
    container changed after it went into another one (the standard pickler fills each one first, so depths
    stay known), or memo references that were never stored.

    Each stack item is a [depth, inside] pair: depth 0 for scalars, 1 + the deepest part for what is built of
    parts; ``inside`` once it is part of something else.
    """
    import pickletools

    def too_deep(depth: int) -> None:
        if depth > PICKLE_MAX_DEPTH:
            raise RelightError(f"{name}: refused: the pickle nests containers more than {PICKLE_MAX_DEPTH} deep")

    mark = object()
    stack: list = []
    memo: dict[int, list] = {}
    in_place = {"APPEND", "APPENDS", "SETITEM", "SETITEMS", "ADDITEMS", "BUILD"}
    for count, (op, arg, _pos) in enumerate(pickletools.genops(data), start=1):
        if count > PICKLE_MAX_OPS:
            raise RelightError(f"{name}: refused: the pickle has more than {PICKLE_MAX_OPS:,} opcodes")
        before, after = op.stack_before, op.stack_after
        if op.name in ("PUT", "BINPUT", "LONG_BINPUT", "MEMOIZE"):
            if not stack or stack[-1] is mark:
                raise RelightError(f"{name}: malformed pickle (memo of an empty stack)")
            memo[len(memo) if op.name == "MEMOIZE" else arg] = stack[-1]
            continue
        if op.name in ("GET", "BINGET", "LONG_BINGET"):
            if arg not in memo:
                raise RelightError(f"{name}: malformed pickle (memo {arg} read before it was stored)")
            stack.append(memo[arg])
            continue
        if op.name == "DUP":
            stack.append(stack[-1] if stack else [0, False])
            continue
        popped: list = []
        if pickletools.markobject in before:  # everything above the last MARK, then what lies below it
            while stack and stack[-1] is not mark:
                popped.append(stack.pop())
            if not stack:
                raise RelightError(f"{name}: malformed pickle (no MARK)")
            stack.pop()
            popped.reverse()
            below = before[: before.index(pickletools.markobject)]  # APPENDS: the list; OBJ: nothing
        else:
            below = before
        under = []
        for _ in below:
            if not stack or stack[-1] is mark:
                raise RelightError(f"{name}: malformed pickle (stack underflow at {op.name})")
            under.append(stack.pop())
        under.reverse()
        if op.name in in_place:  # container, items: the container changes in place
            container, items = under[0], under[1:] + popped
            if container[1]:
                raise RelightError(f"{name}: refused: the pickle changes a container after putting it into "
                                   "another one (no state_dict does)")
            for item in items:
                item[1] = True
                container[0] = max(container[0], item[0] + 1)
            too_deep(container[0])
            stack.append(container)
            continue
        parts = under + popped
        for item in parts:
            item[1] = True
        for result in after:
            if result is pickletools.markobject:
                stack.append(mark)
            else:
                depth = 1 + max((p[0] for p in parts), default=-1)
                too_deep(depth)
                stack.append([depth, False])
        if op.name == "STOP":
            return
    raise RelightError(f"{name}: malformed pickle (no STOP)")


def read_checkpoint(path: str | os.PathLike, max_elements: int, check=None) -> dict[str, np.ndarray]:
    """:func:`read_torch_checkpoint`; ``check(shapes)`` (name -> a zero-size stand-in of the tensor's shape)
    runs on the records before any storage is read (:func:`import_reference` checks the layout there)."""
    path = Path(path)
    name = str(path)
    if not path.is_file():
        raise RelightError(f"{name}: checkpoint file {'is not a regular file' if path.exists() else 'not found'}")
    if not zipfile.is_zipfile(path):
        raise RelightError(
            f"{name}: not a PyTorch zip checkpoint (torch.save since torch 1.6); an older file can be read "
            "with 'python -m export convert-reference', which needs torch"
        )
    try:
        with zipfile.ZipFile(path) as archive:
            pickles = [n for n in archive.namelist() if re.fullmatch(r"[^/]+/data\.pkl", n)]
            if len(pickles) != 1:
                raise RelightError(f"{name}: expected one PREFIX/data.pkl in the archive, found {len(pickles)}")
            prefix = pickles[0].rsplit("/", 1)[0]
            byteorder = "little"
            if f"{prefix}/byteorder" in archive.namelist():
                record = archive.getinfo(f"{prefix}/byteorder")
                if record.file_size > 16:
                    raise RelightError(f"{name}: byteorder record is {record.file_size:,} bytes, expected a word")
                byteorder = archive.read(record).decode("ascii", "replace").strip()
                if byteorder not in ("little", "big"):
                    raise RelightError(f"{name}: byteorder record is {byteorder!r}, expected 'little' or 'big'")
            info = archive.getinfo(pickles[0])
            if info.file_size > PICKLE_MAX_BYTES:
                raise RelightError(f"{name}: refused: {pickles[0]} is {info.file_size:,} bytes uncompressed, more "
                                   f"than {PICKLE_MAX_BYTES:,} (a state_dict's is tens of KB)")
            data = archive.read(info)
            scan_pickle(data, name)
            obj = _WeightsUnpickler(io.BytesIO(data), archive, prefix, name).load()
            del data
            records = _records(obj, name)
            if check is not None:
                check({k: np.broadcast_to(np.float32(0), t.size) for k, t in records.items()})
            return _materialise(records, archive, byteorder, name, max_elements)
    except RelightError:
        raise
    except (pickle.UnpicklingError, zipfile.BadZipFile, EOFError, TypeError, ValueError, AttributeError,
            IndexError, KeyError, OverflowError, MemoryError, RecursionError, zlib.error) as exc:
        raise RelightError(f"{name}: not a readable torch checkpoint ({type(exc).__name__}: {exc})") from None


def _records(obj, name: str) -> dict[str, _Tensor]:
    """The state_dict's name -> tensor record (a ``{"state_dict": ...}`` wrapper is opened)."""
    if isinstance(obj, Mapping) and isinstance(obj.get("state_dict"), Mapping):
        obj = obj["state_dict"]
    if not isinstance(obj, Mapping):
        raise RelightError(f"{name}: expected a state_dict (mapping of names to tensors), got {type(obj).__name__}")
    out = {}
    for key, value in obj.items():
        if not isinstance(key, str) or not isinstance(value, _Tensor):
            what = "tensor" if isinstance(value, _Tensor) else type(value).__name__
            raise RelightError(f"{name}: entry {_short(key)} is not a named tensor ({what})")
        out[key] = value
    return out
