"""``relight-rt import-reference``: the authors' checkpoints to contract graphs, without torch.

The reference implementation (Tajima et al. 2021) saves ``model.state_dict()`` with ``torch.save``:
``model_1st.pth`` (stage 1), ``model_2nd.pth`` (stage 2) and, per video, the deep-video-prior network.
This module turns them into the same format-1 ONNX graphs as ``python -m export convert-reference``
with numpy and the ``onnx`` package only (``pip install "relight-rt[import]"``), so a user of the
runtime does not need torch to run the authors' weights.

Reading (:func:`read_torch_checkpoint`; the reader is relight_rt.apps.torch_checkpoint). A torch checkpoint
is a zip archive: ``PREFIX/data.pkl`` (a pickle of the state_dict), ``PREFIX/data/KEY`` (the raw bytes of
each tensor storage) and ``PREFIX/byteorder``. The pickle is read by a restricted unpickler that resolves
only the globals a plain state_dict of tensors needs, the ones ``torch.load(weights_only=True)`` accepts for that:

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
import logging
import math
import os
import re
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..engine.contract import KINDS, META_OUTPUT_ACTIVATION, ModelConfig
from ..engine.errors import RelightError
from ..engine.files import atomic_path, check_target
from .torch_checkpoint import PICKLE_MAX_BYTES as PICKLE_MAX_BYTES  # re-exported: the reader's bounds
from .torch_checkpoint import PICKLE_MAX_DEPTH as PICKLE_MAX_DEPTH
from .torch_checkpoint import PICKLE_MAX_OPS as PICKLE_MAX_OPS
from .torch_checkpoint import is_int, read_checkpoint

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


def read_torch_checkpoint(path: str | os.PathLike, *, max_elements: int | None = None) -> dict[str, np.ndarray]:
    """Read a ``torch.save`` zip checkpoint of tensors into numpy arrays, without torch.

    Everything is bounded before it is read: ``data.pkl`` by PICKLE_MAX_BYTES (its uncompressed size, from
    the archive's directory) and by an opcode scan (relight_rt.apps.torch_checkpoint.scan_pickle: count and nesting
    depth), the storages together by ``max_elements`` (declared sizes, checked before decompressing), and a
    tensor must be contiguous in its storage (no stride-0 views that a copy would blow up).

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
    return read_checkpoint(path, DEFAULT_MAX_ELEMENTS if max_elements is None else max_elements)


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
    if not is_int(width) or width < 1:
        raise RelightError(f"width: expected a positive int, got {width!r}")
    if not is_int(resolution) or resolution < 64 or resolution % 64:
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

    from ..engine.session import cpu_session_options, validate_session

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

        state = read_checkpoint(path, expected, layout)
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
