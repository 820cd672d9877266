"""``relight-rt import-reference``: the authors' checkpoints to contract graphs, without torch.

The reference implementation (Tajima et al. 2021) saves ``model.state_dict()`` with ``torch.save``:
``model_1st.pth`` (stage 1), ``model_2nd.pth`` (stage 2) and, per video, the deep-video-prior network.
This module turns them into the same format-1 ONNX graphs as ``python -m export convert-reference``
with numpy and the ``onnx`` package only (``pip install "relight-rt[import]"``), so a user of the
runtime does not need torch to run the authors' weights.

Reading (:func:`read_torch_checkpoint`). A torch checkpoint is a zip archive: ``PREFIX/data.pkl`` (a
pickle of the state_dict), ``PREFIX/data/KEY`` (the raw bytes of each tensor storage) and
``PREFIX/byteorder``. The pickle is read by a restricted unpickler that resolves only the globals a
plain state_dict of tensors needs, the ones ``torch.load(weights_only=True)`` accepts for that:

- ``collections.OrderedDict``;
- ``torch._utils._rebuild_tensor_v2`` and ``torch._utils._rebuild_parameter`` (tensor records: a storage,
  an offset and a size; only the contiguous strides are accepted, and the record must lie inside its
  storage);
- the storage classes ``torch.FloatStorage``, ``torch.DoubleStorage``, ... and ``torch.UntypedStorage``,
  which only appear inside the persistent-id records ``("storage", TYPE, KEY, LOCATION, NUMEL)`` that
  name a storage file of the archive.

Any other global (``os.system``, ``builtins.eval``, a class, ...) is refused with a RelightError before it
is looked up: no code from the file runs. The legacy (pre-1.6, non-zip) torch format is not read.

Nothing is read unbounded (issue 35): ``data.pkl`` is refused past PICKLE_MAX_BYTES (its size from the
archive's directory) and its opcodes are scanned before the unpickler sees them (count, and the nesting of
containers: a dict key nested 200,000 deep crashed the interpreter); the storages are read only after all
records are known (and, when importing, the layout checked on their shapes), their declared sizes together
at most the expected network's element count.

Conversion (:func:`import_reference`), as ``export.convert``: every key and shape is checked against
the reference layout (DESIGN.md §1) at the given width and resolution (64 / 1024 for the real files),
all problems in one error; BGR is folded into RGB weights (the input channels of ``c0`` — for the DVP
also the colour of each tiled light coefficient, channels 3 + 3k + c —, the output rows 0–2 of
``dc5b``, and the light columns of the light head's last conv); the normalisation layers compute
per-sample statistics (biased variance, eps 1e-5), which is what the reference computes with its
BatchNorm layers left in training mode on a batch of one; stage 2 and the DVP end without an output
activation (decoder b's last conv, upsampled), as the reference's. Graphs are built with
``onnx.helper`` op for op as the torch exporter writes ``export.networks`` (so both give the same
numbers), checked (``onnx.checker``, the runtime's contract check, one onnxruntime run with finite
outputs) and written only when every requested file passed.
"""

from __future__ import annotations

import hashlib
import io
import logging
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

from ._errors import RelightError
from ._io import atomic_path, check_target
from .contract import KINDS, META_OUTPUT_ACTIVATION, ModelConfig

__all__ = [
    "REFERENCE_KINDS",
    "bgr_to_rgb",
    "build_graph",
    "check_layout",
    "import_reference",
    "read_torch_checkpoint",
    "reference_layout",
    "reference_source",
]

log = logging.getLogger(__name__)

REFERENCE_KINDS = ("stage1", "stage2", "dvp")
OPSET = 17
_EPS = 1e-5
_SLOPE = 0.01
_IMPORT_HINT = 'the torch-free importer needs the onnx package: pip install "relight-rt[import]"'

# --------------------------------------------------------------------------------------- reading


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


def _is_int(v) -> bool:
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
        if not isinstance(stype, _StorageType) or not isinstance(key, str) or not _is_int(numel) or numel < 0:
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
        ok = _is_int(offset) and offset >= 0 and isinstance(size, tuple) and isinstance(stride, tuple)
        ok = ok and len(size) == len(stride) and all(_is_int(v) and v >= 0 for v in (*size, *stride))
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


def _scan_pickle(data: bytes, name: str) -> None:
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


def read_torch_checkpoint(path: str | os.PathLike, *, max_elements: int | None = None) -> dict[str, np.ndarray]:
    """Read a ``torch.save`` zip checkpoint of tensors into numpy arrays, without torch.

    Everything is bounded before it is read: ``data.pkl`` by PICKLE_MAX_BYTES (its uncompressed size, from
    the archive's directory) and by an opcode scan (:func:`_scan_pickle`: count and nesting depth), the
    storages together by ``max_elements`` (declared sizes, checked before decompressing), and a tensor must be
    contiguous in its storage (no stride-0 views that a copy would blow up).

    Args:
        path: a ``.pth`` file written by ``torch.save`` (torch >= 1.6, zip format) holding a state_dict
            (a mapping of names to tensors), or a mapping whose ``"state_dict"`` entry is one.
        max_elements: the most storage elements read in all (default: the largest reference network at
            width 64, :data:`DEFAULT_MAX_ELEMENTS`); :func:`import_reference` passes its layout's count.

    Returns:
        name -> array (the tensor's dtype, C order), in the file's order.

    Raises:
        RelightError: missing file, not a zip checkpoint, a pickle that asks for anything but tensor and
            storage records (refused before anything runs), malformed or out-of-range records, or a
            top level that is not a mapping of tensors, storages larger than ``max_elements``.
    """
    return _read_checkpoint(path, DEFAULT_MAX_ELEMENTS if max_elements is None else max_elements)


def _read_checkpoint(path: str | os.PathLike, max_elements: int, check=None) -> dict[str, np.ndarray]:
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
            _scan_pickle(data, name)
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


# ---------------------------------------------------------------------------------------- layout


def _light_head_depth(resolution: int) -> int:
    return (resolution // 64).bit_length() - 1


def reference_layout(kind: str, width: int = 64, resolution: int = 1024) -> dict[str, tuple[int, ...]]:
    """Every state_dict key and shape of the reference network (DESIGN.md §1), in the reference's order.

    Args:
        kind: "stage1" (3 in, albedo decoder 4 out), "stage2" (3 in, 3 out) or "dvp" (30 in, 3 out).
        width: base channel count (64 = reference).
        resolution: the square input size (1024 = reference); sets the light head's depth
            ⌊log2(R / 64)⌋ (a single 1×1 conv at R = 64).
    """
    if kind not in REFERENCE_KINDS:
        raise RelightError(f"kind: expected one of {list(REFERENCE_KINDS)}, got {kind!r}")
    if not _is_int(width) or width < 1:
        raise RelightError(f"width: expected a positive int, got {width!r}")
    if not _is_int(resolution) or resolution < 64 or resolution % 64:
        raise RelightError(f"resolution: expected a positive multiple of 64, got {resolution!r}")
    w = width
    enc = [w, 2 * w, 4 * w, 8 * w, 8 * w, 8 * w]
    c_in, out_b = {"stage1": (3, 4), "stage2": (3, 3), "dvp": (30, 3)}[kind]
    lay: dict[str, tuple[int, ...]] = {"c0.weight": (enc[0], c_in, 4, 4), "c0.bias": (enc[0],)}
    for i in range(1, 6):
        lay[f"c{i}.weight"] = (enc[i], enc[i - 1], 4, 4)

    def norm(prefix: str, n: int) -> None:
        for leaf in ("weight", "bias", "running_mean", "running_var"):
            lay[f"{prefix}.{leaf}"] = (n,)
        lay[f"{prefix}.num_batches_tracked"] = ()

    for block in ("ra", "rb"):
        for conv in ("c1", "c2"):
            lay[f"{block}.{conv}.weight"] = (enc[5], enc[5], 3, 3)
            lay[f"{block}.{conv}.bias"] = (enc[5],)
        norm(f"{block}.b1", enc[5])
        norm(f"{block}.b2", enc[5])
    dec_out = [8 * w, 8 * w, 4 * w, 2 * w, w]
    for branch, n_out in (("a", 9), ("b", out_b)):
        n_in = enc[5]
        for i, n in enumerate(dec_out):
            lay[f"dc{i}{branch}.weight"] = (n, n_in, 3, 3)
            n_in = n + enc[4 - i]
        lay[f"dc5{branch}.weight"] = (n_out, n_in, 3, 3)
        lay[f"dc5{branch}.bias"] = (n_out,)
    depth = _light_head_depth(resolution)
    light = [3 * enc[5]] + [max(8 * w >> i, 2 * w) for i in range(depth - 1)] + [27]
    if depth == 0:
        lay["c0l.weight"], lay["c0l.bias"] = (27, light[0], 1, 1), (27,)
    for i in range(depth):
        lay[f"c{i}l.weight"] = (light[i + 1], light[i], 4, 4)
        if i == depth - 1:
            lay[f"c{i}l.bias"] = (27,)
    for i in range(1, 6):
        norm(f"bnc{i}", enc[i])
    for branch in ("a", "b"):
        for i, n in enumerate(dec_out):
            norm(f"bndc{i}{branch}", n)
    for i in range(depth - 1):
        norm(f"bnc{i}l", light[i + 1])
    return lay


# the storage elements read_torch_checkpoint reads by default: the largest reference network (width 64)
DEFAULT_MAX_ELEMENTS = max(sum(math.prod(s) for s in reference_layout(k).values()) for k in REFERENCE_KINDS)


LISTED_KEYS = 12  # the most unexpected keys an error names (a forged file can hold tens of thousands)


def _listed(keys: list[str]) -> str:
    """``keys`` joined, the first LISTED_KEYS of them, each cut to 100 characters, then how many more."""
    shown = ", ".join(k if len(k) <= 100 else k[:100] + "..." for k in keys[:LISTED_KEYS])
    return shown + (f" and {len(keys) - LISTED_KEYS:,} more" if len(keys) > LISTED_KEYS else "")


def check_layout(state: Mapping[str, np.ndarray], kind: str, width: int, resolution: int, name: str) -> None:
    """Check that ``state`` has exactly the reference layout's keys and shapes.

    Raises:
        RelightError: listing every missing and mis-shaped key in one message, and the first LISTED_KEYS
            unexpected ones (a forged file's names are as many and as long as it likes).
    """
    expected = reference_layout(kind, width, resolution)
    missing = [k for k in expected if k not in state]
    unexpected = [k for k in state if k not in expected]
    misshaped = [
        f"{k} {list(np.shape(v))} (expected {list(expected[k])})"
        for k, v in state.items()
        if k in expected and tuple(np.shape(v)) != expected[k]
    ]
    problems = []
    if missing:
        problems.append(f"missing keys: {', '.join(missing)}")
    if unexpected:  # the file's own names, as many as it likes: the first few
        problems.append(f"unexpected keys: {_listed(unexpected)}")
    if misshaped:
        problems.append(f"mis-shaped: {', '.join(misshaped)}")
    if problems:
        size = f"width {width}, resolution {resolution}"
        what = f"{name}: state_dict does not match the reference {kind} network ({size})"
        raise RelightError(f"{what}: " + "; ".join(problems))


_BGR = [2, 1, 0]


def bgr_to_rgb(state: Mapping[str, np.ndarray], kind: str) -> dict[str, np.ndarray]:
    """A float32 copy of a reference (BGR) state_dict whose network reads and writes RGB.

    Permuted: the input channels 0–2 of ``c0`` (the image), and for the DVP its channels 3 + 3k + c (the
    tiled light, colour c); the output rows 0–2 of ``dc5b`` (albedo / residual; a stage-1 skin row 3
    stays); the rows 3k + c of the light head's last conv (its only one with a bias; stage 2 and DVP do
    not use it, it is permuted the same way, harmlessly). The transport decoder is colour-free.
    """
    sd = {k: np.asarray(v, np.float32).copy() for k, v in state.items()}
    c0 = sd["c0.weight"].copy()
    c0[:, 0:3] = state["c0.weight"][:, _BGR]
    if kind == "dvp":
        for k in range(9):
            c0[:, 3 + 3 * k : 6 + 3 * k] = state["c0.weight"][:, [3 + 3 * k + c for c in _BGR]]
    sd["c0.weight"] = c0
    for key in ("dc5b.weight", "dc5b.bias"):
        sd[key][0:3] = np.asarray(state[key], np.float32)[_BGR]
    rows = [3 * k + c for k in range(9) for c in _BGR]
    for key in [k for k in state if re.fullmatch(r"c\d+l\.bias", k)]:
        prefix = key[: -len(".bias")]
        for leaf in (f"{prefix}.weight", f"{prefix}.bias"):
            sd[leaf] = np.asarray(state[leaf], np.float32)[rows].copy()
    return sd


def reference_source(path: str | os.PathLike, kind: str) -> str:
    """The ``relight_rt.source`` of a converted reference checkpoint (the same for both converters)."""
    path = Path(path)
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    what = f"reference {kind} checkpoint (Tajima et al. 2021), BGR folded to RGB,"
    return f"{what} {path.name} sha256:{digest.hexdigest()}"


# ------------------------------------------------------------------------------------------ graph


class _Builder:
    """Nodes and initializers of one graph, op for op as torch's exporter writes export.networks."""

    def __init__(self, onnx_mod, state: Mapping[str, np.ndarray]) -> None:
        self.onnx = onnx_mod
        self.helper, self.numpy_helper = onnx_mod.helper, onnx_mod.numpy_helper
        self.state = state
        self.nodes: list = []
        self.inits: dict[str, object] = {}
        self._count = 0

    def const(self, name: str, value: np.ndarray) -> str:
        if name not in self.inits:
            self.inits[name] = self.numpy_helper.from_array(np.ascontiguousarray(value), name)
        return name

    def weight(self, key: str, shape: tuple[int, ...] | None = None) -> str:
        value = np.asarray(self.state[key], np.float32)
        return self.const(key, value if shape is None else value.reshape(shape))

    def op(self, op_type: str, inputs: list[str], **attrs) -> str:
        self._count += 1
        out = f"{op_type.lower()}_{self._count}"
        self.nodes.append(self.helper.make_node(op_type, inputs, [out], name=f"n{self._count}", **attrs))
        return out

    def rename_output(self, name: str) -> None:
        """Make the last node write ``name`` (a graph output)."""
        self.nodes[-1].output[0] = name

    # layers

    def conv(self, x: str, key: str, kernel: int, stride: int, pad: int) -> str:
        inputs = [x, self.weight(f"{key}.weight")]
        if f"{key}.bias" in self.state:
            inputs.append(self.weight(f"{key}.bias"))
        return self.op(
            "Conv", inputs, dilations=[1, 1], group=1, kernel_shape=[kernel, kernel],
            pads=[pad] * 4, strides=[stride, stride],
        )

    def norm(self, x: str, key: str) -> str:
        """Per-sample statistics over H×W: row means first, then their mean; biased variance; eps 1e-5."""

        def spatial_mean(t: str) -> str:
            return self.op("ReduceMean", [self.op("ReduceMean", [t], axes=[3], keepdims=1)], axes=[2], keepdims=1)

        centred = self.op("Sub", [x, spatial_mean(x)])
        var = spatial_mean(self.op("Mul", [centred, centred]))
        std = self.op("Sqrt", [self.op("Add", [var, self.const("eps", np.array(_EPS, np.float32))])])
        inv = self.op("Div", [self.const("one", np.array(1.0, np.float32)), std])
        n = int(np.shape(self.state[f"{key}.weight"])[0])
        scale = self.op("Mul", [self.weight(f"{key}.weight", (1, n, 1, 1)), inv])
        return self.op("Add", [self.op("Mul", [centred, scale]), self.weight(f"{key}.bias", (1, n, 1, 1))])

    def leaky(self, x: str) -> str:
        return self.op("LeakyRelu", [x], alpha=_SLOPE)

    def up2(self, x: str) -> str:
        scales = self.const("scales_x2", np.array([1, 1, 2, 2], np.float32))
        return self.op(
            "Resize", [x, "", scales], coordinate_transformation_mode="align_corners", cubic_coeff_a=-0.75,
            mode="linear", nearest_mode="floor",
        )

    # the network (DESIGN.md §1)

    def encode(self, x: str) -> list[str]:
        feats = [self.leaky(self.conv(x, "c0", 4, 2, 1))]
        for i in range(1, 6):
            feats.append(self.leaky(self.norm(self.conv(feats[-1], f"c{i}", 4, 2, 1), f"bnc{i}")))
        return feats

    def residual_block(self, x: str, key: str) -> str:
        h = self.op("Relu", [self.norm(self.conv(x, f"{key}.c1", 3, 1, 1), f"{key}.b1")])
        return self.op("Add", [x, self.norm(self.conv(h, f"{key}.c2", 3, 1, 1), f"{key}.b2")])

    def decode(self, h: str, feats: list[str], branch: str) -> str:
        for i in range(5):
            h = self.norm(self.conv(h, f"dc{i}{branch}", 3, 1, 1), f"bndc{i}{branch}")
            h = self.up2(self.op("Relu", [h]))
            h = self.op("Concat", [h, feats[4 - i]], axis=1)
        return self.up2(self.conv(h, f"dc5{branch}", 3, 1, 1))

    def light_head(self, bottleneck: str, hra: str, hrb: str, resolution: int) -> str:
        h = self.op("Concat", [bottleneck, hra, hrb], axis=1)
        depth = _light_head_depth(resolution)
        for i in range(depth - 1):
            h = self.leaky(self.norm(self.conv(h, f"c{i}l", 4, 2, 1), f"bnc{i}l"))
        last = max(depth, 1) - 1
        h = self.conv(h, f"c{last}l", 1, 1, 0) if depth == 0 else self.conv(h, f"c{last}l", 4, 2, 1)
        return self.op("Reshape", [h, self.const("light_shape", np.array([-1, 9, 3], np.int64))], allowzero=0)

    def scaled_input(self, image: str, mask: str) -> str:
        two = self.const("two", np.array(2.0, np.float32))
        one = self.const("one", np.array(1.0, np.float32))
        return self.op("Mul", [self.op("Sub", [self.op("Mul", [image, two]), one]), mask])


def build_graph(state: Mapping[str, np.ndarray], kind: str, resolution: int, source: str):
    """The format-1 contract graph (``onnx.ModelProto``) of an RGB state_dict in the reference layout.

    Args:
        state: RGB weights (after :func:`bgr_to_rgb`), keys and shapes as :func:`reference_layout`.
        kind: "stage1", "stage2" or "dvp".
        resolution: the network's resolution (stage 1's fixed input size; metadata for all kinds).
        source: the ``relight_rt.source`` metadata.
    """
    try:
        import onnx
    except ImportError:
        raise RelightError(_IMPORT_HINT) from None
    from onnx import TensorProto

    helper = onnx.helper
    b = _Builder(onnx, state)
    one, zero = np.array(1.0, np.float32), np.array(0.0, np.float32)
    spatial = [resolution, resolution] if kind == "stage1" else ["H", "W"]

    def value(name: str, channels: int) -> object:
        return helper.make_tensor_value_info(name, TensorProto.FLOAT, ["N", channels, *spatial])

    light_value = helper.make_tensor_value_info("light", TensorProto.FLOAT, ["N", 9, 3])
    if kind == "stage1":
        inputs = [value("image", 3), value("mask", 1)]
        feats = b.encode(b.scaled_input("image", "mask"))
        hra, hrb = b.residual_block(feats[5], "ra"), b.residual_block(feats[5], "rb")
        transport = b.decode(hra, feats, "a")
        hb = b.op("Sigmoid", [b.decode(hrb, feats, "b")])
        b.light_head(feats[5], hra, hrb, resolution)
        b.rename_output("light")
        starts = [b.const(f"slice_{v}", np.array([v], np.int64)) for v in (0, 3, 4)]
        axis1 = b.const("slice_axis1", np.array([1], np.int64))
        step = b.const("slice_step", np.array([1], np.int64))
        albedo = b.op("Slice", [hb, starts[0], starts[1], axis1, step])
        skin = b.op("Slice", [hb, starts[1], starts[2], axis1, step])
        for src, name in ((albedo, "albedo"), (skin, "skin"), (transport, "transport")):
            b.op("Mul", [src, "mask"])
            b.rename_output(name)
        outputs = [value("albedo", 3), value("skin", 1), value("transport", 9), light_value]
    elif kind == "stage2":
        inputs = [value("diffuse", 3), value("mask", 1)]
        feats = b.encode(b.scaled_input("diffuse", "mask"))
        out = b.decode(b.residual_block(feats[5], "rb"), feats, "b")
        b.op("Mul", [out, "mask"])
        b.rename_output("residual")
        # the reference adds the raw residual and masks the sum (DESIGN.md §5): clip(diffuse + r, 0, 1) * mask
        clipped = b.op("Clip", [b.op("Add", ["diffuse", out]), b.const("zero", zero), b.const("one", one)])
        b.op("Mul", [clipped, "mask"])
        b.rename_output("relit")
        outputs = [value("residual", 3), value("relit", 3)]
    elif kind == "dvp":
        inputs = [value("frame", 3), value("mask", 1), light_value]
        shape = b.const("light_tile_shape", np.array([-1, 27, 1, 1], np.int64))
        lights = b.op("Reshape", ["light", shape], allowzero=0)
        starts = [b.const(f"slice_{v}", np.array([v], np.int64)) for v in (0, 1)]
        step = b.const("slice_step", np.array([1], np.int64))
        first = b.op("Slice", ["frame", starts[0], starts[1], starts[1], step])
        zeros = b.op("ConstantOfShape", [b.op("Shape", [first])],
                     value=helper.make_tensor("zero_value", TensorProto.FLOAT, [1], [0.0]))
        tiled = b.op("Add", [lights, zeros])
        x = b.op("Concat", [b.scaled_input("frame", "mask"), tiled], axis=1)
        feats = b.encode(x)
        out = b.decode(b.residual_block(feats[5], "rb"), feats, "b")
        half = b.const("half", np.array(0.5, np.float32))
        relit = b.op("Add", [out, b.const("one", one)])
        relit = b.op("Clip", [b.op("Mul", [relit, half]), b.const("zero", zero), b.const("one", one)])
        b.op("Mul", [relit, "mask"])
        b.rename_output("relit")
        outputs = [value("relit", 3)]
    else:
        raise RelightError(f"kind: expected one of {list(REFERENCE_KINDS)}, got {kind!r}")
    graph = helper.make_graph(b.nodes, f"relight_rt_{kind}", inputs, outputs, initializer=list(b.inits.values()))
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", OPSET)], producer_name="relight_rt.import")
    model.ir_version = 8
    meta = ModelConfig(kind=kind, resolution=resolution, norm="instance", source=source).metadata()
    if kind in ("stage2", "dvp"):
        meta[META_OUTPUT_ACTIVATION] = "none"
    helper.set_model_props(model, meta)
    return model


# ------------------------------------------------------------------------------------------ checks


def _sample_feeds(kind: str, size: int, seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    yy, xx = np.meshgrid(np.linspace(-1, 1, size), np.linspace(-1, 1, size), indexing="ij")
    mask = np.clip((1 - (xx / 0.7) ** 2 - (yy / 0.9) ** 2) * 8, 0, 1).astype(np.float32)[None, None]
    first = KINDS[kind].inputs[0].name
    feeds = {first: rng.random((1, 3, size, size), dtype=np.float32), "mask": mask}
    if kind == "dvp":
        light = rng.uniform(-0.5, 0.5, (1, 9, 3)).astype(np.float32)
        light[:, 0] = rng.uniform(0.4, 1.4, (1, 3))
        feeds["light"] = light
    return feeds


def _check_graph(data: bytes, kind: str, resolution: int, name: str) -> None:
    """onnx.checker (full), the runtime's contract check, and one run with finite outputs."""
    import onnx
    import onnxruntime as ort

    from .session import cpu_session_options, validate_session

    try:
        onnx.checker.check_model(onnx.load_from_string(data), full_check=True)
    except Exception as exc:  # onnx raises several types (ValidationError, InferenceError)
        raise RelightError(f"{name}: onnx.checker refused the built graph: {exc}") from None
    session = ort.InferenceSession(data, sess_options=cpu_session_options(), providers=["CPUExecutionProvider"])
    validate_session(session, name, kind)
    size = resolution if kind == "stage1" else 128
    outputs = session.run(None, _sample_feeds(kind, size))
    bad = [o.name for o, v in zip(session.get_outputs(), outputs, strict=True) if not np.isfinite(v).all()]
    if bad:
        raise RelightError(f"{name}: the imported graph gives non-finite {bad} on a test input; the weights are broken")


# ---------------------------------------------------------------------------------------------- API


def import_reference(
    out_dir: str | os.PathLike,
    *,
    stage1: str | os.PathLike | None = None,
    stage2: str | os.PathLike | None = None,
    dvp: str | os.PathLike | None = None,
    width: int = 64,
    resolution: int = 1024,
) -> list[dict]:
    """Convert reference checkpoints to ``out_dir/stage1.onnx``, ``stage2.onnx``, ``dvp.onnx`` (torch-free).

    Every file is read, checked and converted, and every graph built and checked, before anything is
    written; outputs are written atomically and never over an input.

    Returns:
        one summary per graph: {"kind", "path", "source", "bytes"}.

    Raises:
        RelightError: no checkpoint given, an unreadable or refused file, a layout mismatch, a graph that
            fails its checks, or the onnx package missing.
    """
    jobs = [(k, p) for k, p in (("stage1", stage1), ("stage2", stage2), ("dvp", dvp)) if p is not None]
    if not jobs:
        raise RelightError("import-reference: give --stage1, --stage2 and/or --dvp")
    try:
        import onnx  # noqa: F401
    except ImportError:
        raise RelightError(_IMPORT_HINT) from None
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise RelightError(f"--out: {out} exists and is not a folder")
    inputs = [Path(p) for _, p in jobs]
    built = []
    for kind, path in jobs:
        target = out / f"{kind}.onnx"
        check_target(target, inputs)
        expected = sum(math.prod(shape) for shape in reference_layout(kind, width, resolution).values())

        def layout(shapes, kind=kind, path=path):  # before any storage is read
            check_layout(shapes, kind, width, resolution, f"{path} ({kind})")

        state = _read_checkpoint(path, expected, layout)
        source = reference_source(path, kind)
        data = build_graph(bgr_to_rgb(state, kind), kind, resolution, source).SerializeToString()
        del state
        _check_graph(data, kind, resolution, str(target))
        built.append({"kind": kind, "path": str(target), "source": source, "bytes": len(data), "data": data})
        log.info("built %s from %s (%.1f MB)", target.name, path, len(data) / 1e6)
    out.mkdir(parents=True, exist_ok=True)
    for item in built:
        with atomic_path(item["path"], protect=inputs) as tmp:
            tmp.write_bytes(item.pop("data"))
    return built
