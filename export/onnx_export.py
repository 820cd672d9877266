"""ONNX export of our networks following the contract of DESIGN.md §5 (``python -m export onnx``).

The exported graph wraps the network with the input scaling, the masking and the clipping, so a
runtime feeds it [0, 1] RGB images and a mask and gets final values:

- stage1 ``(image, mask) -> (albedo, skin, transport, light)``: ``x = (2 * image - 1) * mask``; albedo,
  skin and transport are the network's outputs times the mask; light (N, 9, 3) is not masked.
- stage2 ``(diffuse, mask) -> (residual, relit)``: ``x = (2 * diffuse - 1) * mask``;
  ``residual = net(x) * mask`` (decoder b's last conv upsampled, no activation, as the reference;
  in [-1, 1] for a network trained with ``output_activation="tanh"``);
  ``relit = clip(diffuse + net(x), 0, 1) * mask`` (the raw output added, then the sum masked, as the
  reference does: at soft mask edges this differs from adding ``residual``).
- dvp ``(frame, mask, light) -> relit``: the network input is ``(2 * frame - 1) * mask`` followed by
  27 channels, channel 3 + 3k + c = ``light[n, k, c]`` at every pixel (not masked, not rescaled);
  ``relit = clip((net(x) + 1) / 2, 0, 1) * mask``. The DVP network is fitted to ``2 * target - 1``
  (as the reference's ``remove_flicker.py`` does), hence ``(out + 1) / 2``.

Stage-2 and DVP graphs also carry ``relight_rt.output_activation`` ("none" | "tanh"): what the network's
output went through, a record for people (the runtime does not read it; the graph computes it).

Every export is checked before it is written: one self-contained file, ``onnx.checker`` full check,
no Dropout / random / training-mode op, metadata per ``relight_rt.contract``, and a parity run
torch vs onnxruntime (CPU) on a random masked input whose relative error ‖ort − torch‖ / ‖torch‖
must not exceed 1e-4 for any output. ``fp16=True`` also writes ``NAME_fp16.onnx`` (fp16 weights
and compute, fp32 inputs and outputs, Cast at the boundaries) unless its PSNR against the fp32
graph on that input is under 40 dB for some output (peak = the largest |value| of that fp32 output).
"""

from __future__ import annotations

import copy
import hashlib
import io
import logging
import math
import os
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch import nn

from relight_rt import RelightError
from relight_rt.engine.contract import KINDS, META_OUTPUT_ACTIVATION, ModelConfig
from relight_rt.engine.files import atomic_path

from .config import reader

__all__ = [
    "DEFAULT_OPSET",
    "FP16_MIN_PSNR",
    "PARITY_TOLERANCE",
    "add_arguments",
    "check_graph",
    "export_onnx",
    "fp16_psnr",
    "parity_errors",
    "run",
    "sample_inputs",
    "to_fp16",
    "wrap",
]

log = logging.getLogger(__name__)

DEFAULT_OPSET = 17
PARITY_TOLERANCE = 1e-4
FP16_MIN_PSNR = 40.0
_FORBIDDEN_OPS = {"Dropout", "RandomNormal", "RandomNormalLike", "RandomUniform", "RandomUniformLike", "Bernoulli"}
_MAX_SINGLE_FILE = 2**31 - 2**20  # protobuf's 2 GiB limit, with room for the graph itself


class _Stage1Graph(nn.Module):
    def __init__(self, net: nn.Module) -> None:
        super().__init__()
        self.net = net

    def forward(self, image, mask):
        transport, albedo, skin, light = self.net((2 * image - 1) * mask)
        return albedo * mask, skin * mask, transport * mask, light


class _Stage2Graph(nn.Module):
    def __init__(self, net: nn.Module) -> None:
        super().__init__()
        self.net = net

    def forward(self, diffuse, mask):
        r = self.net((2 * diffuse - 1) * mask)  # the reference adds r unmasked, then masks the sum (DESIGN.md §5)
        return r * mask, torch.clamp(diffuse + r, 0.0, 1.0) * mask


class _DVPGraph(nn.Module):
    def __init__(self, net: nn.Module) -> None:
        super().__init__()
        self.net = net

    def forward(self, frame, mask, light):
        tiled = light.reshape(-1, 27, 1, 1) + torch.zeros_like(frame[:, :1])
        out = self.net(torch.cat(((2 * frame - 1) * mask, tiled), dim=1))
        return torch.clamp((out + 1) * 0.5, 0.0, 1.0) * mask


_WRAPPERS = {"stage1": _Stage1Graph, "stage2": _Stage2Graph, "dvp": _DVPGraph}


def wrap(model: nn.Module) -> nn.Module:
    """The contract wrapper (module docstring) around a network of ``export.networks``; shares its weights."""
    kind = getattr(model, "kind", None)
    if kind not in _WRAPPERS:
        raise RelightError(f"export: expected a Stage1Net, Stage2Net or DVPNet, got {type(model).__name__}")
    if kind == "dvp" and not getattr(model, "conditioned", True):
        raise RelightError("export: an unconditioned DVPNet has no light input; the dvp contract needs one")
    return _WRAPPERS[kind](model)


def sample_inputs(kind: str, batch: int, height: int, width: int, seed: int = 0) -> dict[str, np.ndarray]:
    """Random contract inputs: images uniform in [0, 1], a soft elliptic mask with zeros and ones, lights.

    Returns:
        name -> float32 array, NCHW (light (N, 9, 3), coefficient 0 in [0.4, 1.4], others in [-0.5, 0.5]).
    """
    rng = np.random.default_rng(seed)
    yy, xx = np.meshgrid(np.linspace(-1, 1, height), np.linspace(-1, 1, width), indexing="ij")
    mask = np.clip((1 - (xx / 0.7) ** 2 - (yy / 0.9) ** 2) * 8, 0, 1).astype(np.float32)
    mask = np.broadcast_to(mask, (batch, 1, height, width)).copy()
    out = {}
    for spec in KINDS[kind].inputs:  # by the contract's spec: a light, a mask, or an image of its channels
        if spec.rank == 3:
            light = rng.uniform(-0.5, 0.5, (batch, 9, 3)).astype(np.float32)
            light[:, 0] = rng.uniform(0.4, 1.4, (batch, 3))
            out[spec.name] = light
        elif spec.name == "mask":
            out[spec.name] = mask
        else:
            out[spec.name] = rng.random((batch, spec.channels or 3, height, width), dtype=np.float32)
    return out


def _dynamic_axes(kind: str) -> dict[str, dict[int, str]]:
    spec = KINDS[kind]
    axes = {}
    for t in (*spec.inputs, *spec.outputs):
        if t.rank == 4 and not spec.fixed_size:
            axes[t.name] = {0: "N", 2: "H", 3: "W"}
        else:
            axes[t.name] = {0: "N"}
    return axes


def _torch_to_onnx(wrapper: nn.Module, inputs: dict[str, np.ndarray], kind: str, opset: int) -> bytes:
    """Trace ``wrapper`` (fp32 inputs) with the TorchScript exporter (deterministic, fast), fold constants.

    Returns the serialized model.
    """
    spec = KINDS[kind]
    args = tuple(torch.from_numpy(inputs[t.name]) for t in spec.inputs)
    buf = io.BytesIO()
    with warnings.catch_warnings(), torch.no_grad():
        warnings.simplefilter("ignore")  # tracer warnings about shape-dependent Python branches
        torch.onnx.export(
            wrapper,
            args,
            buf,
            dynamo=False,
            input_names=[t.name for t in spec.inputs],
            output_names=[t.name for t in spec.outputs],
            dynamic_axes=_dynamic_axes(kind),
            opset_version=opset,
            # torch's own folding deduplicates equal initializers and can leave dangling Identity inputs
            # (seen with freshly initialised norms, all ones); onnxscript's optimizer folds correctly.
            do_constant_folding=False,
        )
    import onnx
    from onnxscript import optimizer

    quiet = [logging.getLogger(name) for name in ("onnxscript", "onnx_ir")]  # they log every folded constant
    levels = [q.level for q in quiet]
    for q in quiet:
        q.setLevel(logging.WARNING)
    try:
        return optimizer.optimize(onnx.load_from_string(buf.getvalue())).SerializeToString()
    finally:
        for q, level in zip(quiet, levels, strict=True):
            q.setLevel(level)


def check_graph(model_bytes: bytes, kind: str, name: str = "graph") -> None:
    """Structural checks of a serialized graph: checker (full), I/O names, no dropout/random/training op.

    Raises:
        RelightError: naming what is wrong.
    """
    import onnx

    if len(model_bytes) > _MAX_SINGLE_FILE:
        raise RelightError(f"{name}: {len(model_bytes)} bytes does not fit one self-contained ONNX file")
    model = onnx.load_from_string(model_bytes)
    try:
        onnx.checker.check_model(model, full_check=True)
    except Exception as exc:  # onnx raises several types (ValidationError, InferenceError)
        raise RelightError(f"{name}: onnx.checker refused the graph: {exc}") from None
    bad = sorted({n.op_type for n in model.graph.node if n.op_type in _FORBIDDEN_OPS})
    training = sorted(
        {n.op_type for n in model.graph.node for a in n.attribute if a.name == "training_mode" and a.i != 0}
    )
    if bad or training or any(n.domain.endswith("training") for n in model.graph.node):
        raise RelightError(f"{name}: training-only ops left in the graph: {bad + training}")
    external = onnx.TensorProto.EXTERNAL
    if any(t.HasField("data_location") and t.data_location == external for t in model.graph.initializer):
        raise RelightError(f"{name}: the graph refers to external data; expected one self-contained file")
    spec = KINDS[kind]
    got_in = [i.name for i in model.graph.input]
    got_out = [o.name for o in model.graph.output]
    if got_in != [t.name for t in spec.inputs] or got_out != [t.name for t in spec.outputs]:
        raise RelightError(f"{name}: I/O {got_in} -> {got_out} do not match the {kind} contract")


def _session(model_bytes: bytes):
    import onnxruntime as ort

    opts = ort.SessionOptions()
    opts.intra_op_num_threads = min(os.cpu_count() or 1, 4)
    opts.log_severity_level = 3
    return ort.InferenceSession(model_bytes, sess_options=opts, providers=["CPUExecutionProvider"])


def _run_ort(model_bytes: bytes, inputs: dict[str, np.ndarray], name: str) -> list[np.ndarray]:
    try:
        return _session(model_bytes).run(None, inputs)
    except Exception as exc:  # onnxruntime raises its own types (Fail, InvalidArgument, NotImplemented...)
        raise RelightError(f"{name}: onnxruntime (CPU) could not run the graph: {exc}") from None


def _run_torch(wrapper: nn.Module, inputs: dict[str, np.ndarray], kind: str) -> list[np.ndarray]:
    with torch.no_grad():
        out = wrapper(*(torch.from_numpy(inputs[t.name]) for t in KINDS[kind].inputs))
    out = (out,) if isinstance(out, torch.Tensor) else out
    return [o.float().numpy() for o in out]


def parity_errors(reference: list[np.ndarray], candidate: list[np.ndarray], names: list[str]) -> dict[str, float]:
    """Relative error ‖candidate − reference‖ / ‖reference‖ per output (absolute error where ‖reference‖ = 0)."""
    errors = {}
    for name, ref, got in zip(names, reference, candidate, strict=True):
        if ref.shape != got.shape:
            errors[name] = math.inf
            continue
        diff = float(np.linalg.norm((got.astype(np.float64) - ref).ravel()))
        norm = float(np.linalg.norm(ref.astype(np.float64).ravel()))
        errors[name] = diff / norm if norm > 0 else diff
        if not np.isfinite(got).all():
            errors[name] = math.inf
    return errors


def fp16_psnr(reference: list[np.ndarray], candidate: list[np.ndarray], names: list[str]) -> dict[str, float]:
    """PSNR in dB per output, peak = max |reference| of that output (inf when identical)."""
    result = {}
    for name, ref, got in zip(names, reference, candidate, strict=True):
        ref64, got64 = ref.astype(np.float64), got.astype(np.float64)
        if ref.shape != got.shape or not np.isfinite(got64).all():
            result[name] = -math.inf
            continue
        mse = float(np.mean((got64 - ref64) ** 2))
        peak = float(np.abs(ref64).max()) or 1.0
        result[name] = math.inf if mse == 0 else 10 * math.log10(peak**2 / mse)
    return result


def to_fp16(model_bytes: bytes) -> bytes:
    """The graph with fp16 weights and compute and fp32 inputs/outputs (a Cast at every boundary).

    Float initializers, Constant/ConstantOfShape values and Cast targets become float16, except the
    ``roi``/``scales`` inputs of Resize, which the operator requires in float32. Metadata is kept.
    """
    import onnx
    from onnx import TensorProto, helper, numpy_helper

    model = onnx.load_from_string(model_bytes)
    graph = model.graph
    keep32 = {name for n in graph.node if n.op_type == "Resize" for name in n.input[1:3] if name}

    def halve(t: onnx.TensorProto) -> None:
        if t.data_type == TensorProto.FLOAT:
            t.CopyFrom(numpy_helper.from_array(numpy_helper.to_array(t).astype(np.float16), t.name))

    for init in graph.initializer:
        if init.name not in keep32:
            halve(init)
    for node in graph.node:
        if node.op_type in ("Constant", "ConstantOfShape") and node.output[0] not in keep32:
            for attr in node.attribute:
                if attr.name == "value":
                    halve(attr.t)
        elif node.op_type == "Cast":
            for attr in node.attribute:
                if attr.name == "to" and attr.i == TensorProto.FLOAT:
                    attr.i = TensorProto.FLOAT16

    def rename_uses(old: str, new: str) -> None:
        for node in graph.node:
            for i, name in enumerate(node.input):
                if name == old:
                    node.input[i] = new

    casts_in = []
    for inp in graph.input:
        if inp.type.tensor_type.elem_type == TensorProto.FLOAT:
            rename_uses(inp.name, inp.name + "_fp16")
            casts_in.append(helper.make_node("Cast", [inp.name], [inp.name + "_fp16"], to=TensorProto.FLOAT16))
    for out in graph.output:
        if out.type.tensor_type.elem_type == TensorProto.FLOAT:
            inner = out.name + "_fp16"
            rename_uses(out.name, inner)
            for node in graph.node:
                for i, name in enumerate(node.output):
                    if name == out.name:
                        node.output[i] = inner
            graph.node.append(helper.make_node("Cast", [inner], [out.name], to=TensorProto.FLOAT))
    for i, cast in enumerate(casts_in):
        graph.node.insert(i, cast)
    del graph.value_info[:]
    return model.SerializeToString()


def _with_metadata(model_bytes: bytes, meta: dict[str, str]) -> bytes:
    import onnx

    model = onnx.load_from_string(model_bytes)
    del model.metadata_props[:]
    onnx.helper.set_model_props(model, meta)
    model.producer_name = "relight_rt.export"
    return model.SerializeToString()




def _write_atomic(path: Path, data: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def _fp16_path(path: Path) -> Path:
    return path.with_name(path.stem + "_fp16" + path.suffix)


def export_onnx(
    model: nn.Module,
    out_path: str | os.PathLike,
    *,
    source: str,
    fp16: bool = False,
    opset: int = DEFAULT_OPSET,
    resolution: int | None = None,
    seed: int = 0,
) -> dict:
    """Export a network as a contract graph (module docstring), checked before it is written.

    Args:
        model: a Stage1Net, Stage2Net or (conditioned) DVPNet; not modified (a copy is exported in eval mode).
        out_path: the .onnx file to write (atomically); with ``fp16`` also ``<stem>_fp16.onnx`` beside it.
        source: free text for the ``relight_rt.source`` metadata (what the weights come from).
        fp16: also write the fp16 graph, refused under 40 dB PSNR against fp32.
        opset: ONNX opset.
        resolution: the ``relight_rt.resolution`` metadata; default the network's resolution. stage2/dvp
            may give 0 ("any size divisible by 64"); stage1 must use its own resolution.
        seed: seed of the random parity input.

    Returns:
        summary: {"path", "kind", "config", "metadata", "bytes", "seconds", "parity": {output: rel. error},
        and with fp16 "fp16": {"path", "bytes", "psnr": {output: dB}}}.

    Raises:
        RelightError: not a network of ours, a graph that fails a check, parity over 1e-4, or fp16 under 40 dB.
    """
    t0 = time.perf_counter()
    out_path = Path(out_path)
    net = copy.deepcopy(model).cpu().float().eval()
    wrapper = wrap(net).eval()
    kind = net.kind
    meta_res = net.resolution if resolution is None else int(resolution)
    if kind == "stage1" and meta_res != net.resolution:
        raise RelightError(f"export: a stage1 graph runs at its own resolution {net.resolution}, not {meta_res}")
    if meta_res and meta_res % 64:
        raise RelightError(f"export: resolution metadata must be 0 or a multiple of 64, got {meta_res}")
    meta = ModelConfig(kind=kind, resolution=meta_res, norm=net.norm, source=source).metadata()
    if kind in ("stage2", "dvp"):
        meta[META_OUTPUT_ACTIVATION] = net.output_activation
    size = net.resolution if kind == "stage1" else max(net.resolution, 128)  # bottleneck >= 2x2 when tracing
    inputs = sample_inputs(kind, 1, size, size, seed)
    names = [t.name for t in KINDS[kind].outputs]

    graph = _with_metadata(_torch_to_onnx(wrapper, inputs, kind, opset), meta)
    check_graph(graph, kind, str(out_path))
    expected = _run_torch(wrapper, inputs, kind)
    parity = parity_errors(expected, _run_ort(graph, inputs, str(out_path)), names)
    log.info("%s parity (relative error, torch vs onnxruntime CPU): %s", out_path.name, _fmt(parity, "{:.2e}"))
    worst = max(parity, key=parity.get)
    if not parity[worst] <= PARITY_TOLERANCE:
        raise RelightError(
            f"{out_path}: parity check failed: output {worst!r} differs from torch by relative error "
            f"{parity[worst]:.3g} > {PARITY_TOLERANCE:g}; nothing written"
        )
    summary = {
        "path": str(out_path),
        "kind": kind,
        "config": dict(net.config),
        "metadata": meta,
        "bytes": len(graph),
        "parity": parity,
    }
    if fp16:
        graph16 = to_fp16(graph)
        path16 = _fp16_path(out_path)
        check_graph(graph16, kind, str(path16))
        psnr = fp16_psnr(expected, _run_ort(graph16, inputs, str(path16)), names)
        log.info("%s PSNR vs fp32 (dB): %s", path16.name, _fmt(psnr, "{:.1f}"))
        worst16 = min(psnr, key=psnr.get)
        if not psnr[worst16] >= FP16_MIN_PSNR:
            raise RelightError(
                f"{path16}: fp16 check failed: output {worst16!r} has PSNR {psnr[worst16]:.1f} dB against fp32, "
                f"under {FP16_MIN_PSNR:g} dB; nothing written"
            )
        summary["fp16"] = {"path": str(path16), "bytes": len(graph16), "psnr": psnr}
    _write_atomic(out_path, graph)
    if fp16:
        _write_atomic(_fp16_path(out_path), graph16)
    summary["seconds"] = time.perf_counter() - t0
    return summary


def _fmt(values: dict[str, float], pattern: str) -> str:
    return ", ".join(f"{k} {pattern.format(v)}" for k, v in values.items())


def file_source(path: str | os.PathLike, what: str) -> str:
    """``"<what> <file name> sha256:<hex>"`` for the ``relight_rt.source`` metadata."""
    path = Path(path)
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return f"{what} {path.name} sha256:{digest.hexdigest()}"


# ----------------------------------------------------------------------------------------------- CLI


def add_arguments(parser) -> None:
    """Arguments of ``python -m export onnx``."""
    parser.add_argument("--checkpoint", required=True, help="a checkpoint written by our training (relight_rt.ckpt/1)")
    parser.add_argument("--kind", required=True, choices=sorted(KINDS), help="the kind the checkpoint must hold")
    parser.add_argument("--out", required=True, help="the .onnx file to write")
    parser.add_argument("--fp16", action="store_true", help="also write OUT_fp16.onnx (refused under 40 dB PSNR)")
    parser.add_argument(
        "--any-size",
        action="store_true",
        help="stage2/dvp: metadata resolution 0 (any size divisible by 64) instead of the training resolution",
    )
    parser.add_argument("--opset", type=int, default=DEFAULT_OPSET, help=f"ONNX opset (default {DEFAULT_OPSET})")


@dataclass(frozen=True, kw_only=True)
class OnnxConfig:
    """The settings of ``onnx`` (one field per flag; see :func:`add_arguments`)."""

    checkpoint: Path
    kind: str
    out: Path
    fp16: bool = False
    any_size: bool = False
    opset: int = 17


config_from_args = reader(OnnxConfig)


def run(config: OnnxConfig) -> int:
    """``python -m export onnx``: load our checkpoint, export it, print the summary."""
    from .checkpoint import load_checkpoint

    model, ckpt = load_checkpoint(config.checkpoint)
    if model.kind != config.kind:
        raise RelightError(f"{config.checkpoint}: holds a {model.kind} network, --kind says {config.kind}")
    if config.any_size and config.kind == "stage1":
        raise RelightError("--any-size: a stage1 graph has a fixed resolution")
    source = file_source(config.checkpoint, "relight_rt checkpoint")
    if "epoch" in ckpt:
        source += f" epoch {ckpt['epoch']}"
    summary = export_onnx(
        model, config.out, source=source, fp16=config.fp16, opset=config.opset,
        resolution=0 if config.any_size else None,
    )
    print(format_summary(summary))
    return 0


def format_summary(summary: dict) -> str:
    """A few human-readable lines about one export."""
    lines = [
        f"wrote {summary['path']} ({summary['kind']}, {summary['config']}, {summary['bytes'] / 1e6:.1f} MB, "
        f"{summary['seconds']:.1f} s)",
        f"  parity torch vs onnxruntime CPU (relative error, limit {PARITY_TOLERANCE:g}): "
        + _fmt(summary["parity"], "{:.2e}"),
    ]
    if "fp16" in summary:
        f16 = summary["fp16"]
        lines.append(
            f"wrote {f16['path']} ({f16['bytes'] / 1e6:.1f} MB); PSNR vs fp32 (limit {FP16_MIN_PSNR:g} dB): "
            + _fmt(f16["psnr"], "{:.1f} dB")
        )
    return "\n".join(lines)
