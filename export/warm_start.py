"""Start training from existing weights: a checkpoint of this project or a shipped ONNX graph.

Fine-tuning (``train-stage1 --init``) needs the weights of the model it starts
from. A ``.pt`` checkpoint holds them as trained. A shipped ``.onnx`` graph of a ``norm="batch"`` network
holds them with every BatchNorm folded into the convolution before it (the exporter's ``weight_bias``
initialisers): :func:`load_init` puts the folded weights back into the convolutions and turns every norm
layer into the identity plus that bias, which reproduces the graph exactly in eval mode (checked
against onnxruntime). The original normalisation statistics are gone from the graph, so they are
measured again.

Why measure them: in training mode a BatchNorm normalises by the statistics of the batch, not by its
running ones. A network whose norm layers are "identity in eval mode" would be rescaled by its first
training step. :func:`calibrate_norms` runs a few batches of the training data, records the mean and
(biased) variance each norm layer sees, and rewrites the layer so that eval mode is unchanged and
training mode is the same function on batches with those statistics. Training then starts from the
shipped model's behaviour instead of a jolt.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Iterable
from pathlib import Path

import numpy as np
import torch
from torch import nn

from relight_rt import RelightError

log = logging.getLogger(__name__)


def load_init(model: nn.Module, path: str | os.PathLike) -> str:
    """Load the weights of ``path`` (``.pt`` checkpoint or ``.onnx`` graph) into ``model``.

    Args:
        model: a freshly built network of the same kind and configuration (width, resolution, norm).
        path: the weights to start from.

    Returns:
        A one-line description of what was loaded (for the run's log and meta).

    Raises:
        RelightError: unreadable file, another kind, or weights whose names/shapes do not fit.
    """
    path = Path(path)
    if not path.is_file():
        raise RelightError(f"--init {path}: no such file")
    if path.suffix.lower() == ".onnx":
        return _load_onnx(model, path)
    from .checkpoint import load_checkpoint

    source, ckpt = load_checkpoint(path)
    if source.kind != model.kind:
        raise RelightError(f"--init {path}: a {source.kind} checkpoint, this run trains {model.kind}")
    if source.config != model.config:
        raise RelightError(f"--init {path}: network {source.config} differs from this run's {model.config}")
    model.load_state_dict(source.state_dict())
    return f"{path} (checkpoint, epoch {ckpt.get('epoch')})"


def _load_onnx(model: nn.Module, path: Path) -> str:
    import onnx
    from onnx import numpy_helper

    try:
        graph = onnx.load(str(path))
    except Exception as exc:  # onnx raises its own DecodeError and plain ValueErrors
        raise RelightError(f"--init {path}: not a readable ONNX graph ({exc})") from None
    meta = {p.key: p.value for p in graph.metadata_props}
    kind = meta.get("relight_rt.kind")
    if kind != model.kind:
        raise RelightError(f"--init {path}: a {kind!r} graph, this run trains {model.kind}")
    if meta.get("relight_rt.norm", "batch") != "batch" or getattr(model, "norm", "batch") != "batch":
        raise RelightError(f"--init {path}: only norm='batch' graphs can be unfolded into a network")
    weights = {t.name: numpy_helper.to_array(t) for t in graph.graph.initializer}

    convs = {name: m for name, m in model.named_modules() if isinstance(m, nn.Conv2d)}
    norms = {name: m for name, m in model.named_modules() if isinstance(m, nn.BatchNorm2d)}
    with torch.no_grad():
        for norm in norms.values():
            norm.weight.fill_(1.0)
            norm.bias.zero_()
            norm.running_mean.zero_()
            norm.running_var.fill_(1.0 - norm.eps)  # (x - 0) / sqrt(var + eps) = x exactly
        for name, conv in convs.items():
            key = f"net.{name}"
            w = weights.get(f"{key}.weight")
            if w is None or tuple(w.shape) != tuple(conv.weight.shape):
                got = None if w is None else tuple(w.shape)
                raise RelightError(f"--init {path}: {key}.weight is {got}, the network needs "
                                   f"{tuple(conv.weight.shape)} (another width or resolution?)")
            conv.weight.copy_(torch.from_numpy(w.copy()))
            bias = weights.get(f"{key}.bias", weights.get(f"{key}.weight_bias"))
            if bias is None:
                raise RelightError(f"--init {path}: no bias for {key} in the graph")
            bias = torch.from_numpy(bias.copy())
            if conv.bias is not None:
                conv.bias.copy_(bias)
            else:
                _norm_after(name, norms).bias.copy_(bias)
    _check_parity(model, path)
    return f"{path} (ONNX, norm layers unfolded; {meta.get('relight_rt.source', 'no source recorded')})"


def _norm_after(conv_name: str, norms: dict[str, nn.BatchNorm2d]) -> nn.BatchNorm2d:
    """The norm layer that follows a bias-free conv (the networks' naming: c3 -> bnc3, dc1a -> bndc1a)."""
    head, _, leaf = conv_name.rpartition(".")
    name = f"{head}.bn{leaf}" if head else f"bn{leaf}"
    if name not in norms:
        raise RelightError(f"the network has no norm layer {name!r} after conv {conv_name!r}")
    return norms[name]


def _check_parity(model: nn.Module, path: Path) -> None:
    """The unfolded network must compute what the graph computes (eval mode, one random input).

    The graph runs through :class:`export.frozen.OnnxStage` (the contract-checked loader every frozen stage
    uses); its inputs and outputs are named by the kind registry, in the contract wrapper's order.
    """
    from relight_rt.engine.contract import kind_spec

    from .frozen import OnnxStage
    from .onnx_export import wrap

    spec = kind_spec(model.kind)
    res = model.resolution
    rng = np.random.default_rng(0)
    image = rng.uniform(0, 1, (1, model.c0.in_channels, res, res)).astype(np.float32)
    mask = (rng.uniform(0, 1, (1, 1, res, res)) > 0.2).astype(np.float32)
    feeds = dict(zip((t.name for t in spec.inputs), (torch.from_numpy(image), torch.from_numpy(mask)), strict=True))
    want = OnnxStage(path, model.kind).run(feeds)
    was_training = model.training
    graph = wrap(model).eval()
    with torch.no_grad():
        got = graph(*feeds.values())
    model.train(was_training)
    got = got if isinstance(got, (tuple, list)) else (got,)
    for tensor, g in zip(spec.outputs, got, strict=True):
        w = want[tensor.name]
        err = float((g - w).abs().max() / (w.abs().max() + 1e-6))
        if g.shape != w.shape or err > 1e-3:
            raise RelightError(f"--init {path}: the unfolded network's {tensor.name} differs from the graph's "
                               f"(relative error {err:.2e}, shapes {tuple(g.shape)} vs {tuple(w.shape)})")


def calibrate_norms(model: nn.Module, inputs: Iterable[torch.Tensor]) -> int:
    """Re-measure every BatchNorm's statistics on ``inputs`` without changing the eval-mode function.

    Each norm layer computes ``A·x + B`` per channel in eval mode. With the mean ``m`` and biased variance
    ``v`` its input has over ``inputs`` (network in eval mode), it becomes running statistics (m, v),
    weight ``A·sqrt(v + eps)`` and bias ``A·m + B``: still ``A·x + B`` in eval mode, and the same in
    training mode on a batch whose statistics are (m, v).

    Returns:
        The number of norm layers rewritten.
    """
    norms = [m for m in model.modules() if isinstance(m, nn.BatchNorm2d)]
    sums = {id(n): [0.0, 0.0, 0] for n in norms}

    def hook(module, args, _out):
        x = args[0].detach().double()
        s = sums[id(module)]
        s[0] = s[0] + x.sum(dim=(0, 2, 3))
        s[1] = s[1] + (x * x).sum(dim=(0, 2, 3))
        s[2] += x.shape[0] * x.shape[2] * x.shape[3]

    handles = [n.register_forward_hook(hook) for n in norms]
    was_training = model.training
    model.eval()
    try:
        with torch.no_grad():
            for x in inputs:
                model(x)
    finally:
        for h in handles:
            h.remove()
        model.train(was_training)
    with torch.no_grad():
        for n in norms:
            s0, s1, count = sums[id(n)]
            if count == 0:
                raise RelightError("calibrate_norms: no input reached a norm layer")
            mean = s0 / count
            var = (s1 / count - mean * mean).clamp_min(0.0)
            a = n.weight.double() / torch.sqrt(n.running_var.double() + n.eps)
            b = n.bias.double() - a * n.running_mean.double()
            n.running_mean.copy_(mean.float())
            n.running_var.copy_(var.float())
            n.weight.copy_((a * torch.sqrt(var + n.eps)).float())
            n.bias.copy_((a * mean + b).float())
    log.info("re-measured the statistics of %d norm layers", len(norms))
    return len(norms)
