"""Frozen networks for training stage 2 and for evaluation: a torch checkpoint or an ONNX graph.

Stage 1 is frozen while stage 2 trains, and evaluation only runs networks forward, so neither needs
the torch weights: the graphs that the runtime ships (``relight_rt/models``), graphs converted from
the reference checkpoints, or any graph that meets the contract work as well. :func:`load_frozen`
returns a torch ``nn.Module`` for a ``.pt`` checkpoint and an :class:`OnnxStage` for an ``.onnx``
file; :func:`export.torch_data.decompose` and :func:`apply_stage2` accept either.

An ONNX stage runs on onnxruntime's CPU provider (the same code path as the runtime), one batch at a
time, with tensors moved to and from the host.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import torch

from relight_rt import RelightError


class OnnxStage:
    """A contract-checked stage-1 or stage-2 ONNX graph with the few attributes the trainers read.

    Attributes:
        kind: "stage1" or "stage2" (from the graph's metadata).
        resolution: the graph's native size (0 = any size divisible by 64).
        path: the file it was loaded from.
    """

    def __init__(self, path: str | os.PathLike, kind: str, threads: int | None = None):
        from relight_rt.engine.session import cpu_session_options, load_model

        opts = cpu_session_options()
        if threads:
            opts.intra_op_num_threads = int(threads)
        self.path = Path(path)
        self._model = load_model(self.path, kind, device="cpu", sess_options=opts, warmup=False)
        self.kind = self._model.config.kind
        self.resolution = self._model.config.resolution

    # the nn.Module calls that train_stage2 and evaluate make on a frozen network
    def to(self, *_args, **_kwargs) -> OnnxStage:
        return self

    def eval(self) -> OnnxStage:
        return self

    def parameters(self):
        return iter(())

    def run(self, feeds: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        """Run on torch tensors (any device); returns float32 tensors on the first input's device."""
        device = next(iter(feeds.values())).device
        out = self._model.run({k: v.detach().float().cpu().numpy() for k, v in feeds.items()})
        return {k: torch.from_numpy(np.asarray(v, np.float32)).to(device) for k, v in out.items()}


def load_frozen(path: str | os.PathLike, kind: str, device: torch.device | str = "cpu",
                threads: int | None = None) -> torch.nn.Module | OnnxStage:
    """A network of ``kind`` for inference only, from a torch checkpoint (``.pt``) or an ONNX graph (``.onnx``).

    Raises:
        RelightError: the file is missing, unreadable or of another kind.
    """
    path = Path(path)
    if not path.is_file():
        raise RelightError(f"{path}: no such file (expected a {kind} checkpoint .pt or graph .onnx)")
    if path.suffix.lower() == ".onnx":
        return OnnxStage(path, kind, threads=threads)
    from .checkpoint import load_checkpoint

    model, _ = load_checkpoint(path)
    if model.kind != kind:
        raise RelightError(f"{path}: expected a {kind} checkpoint, got {model.kind}")
    model = model.to(device).eval()
    for p in model.parameters():
        p.requires_grad_(False)
    return model


def apply_stage2(model: torch.nn.Module | OnnxStage, diffuse: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """clip(diffuse + residual, 0, 1) ⊙ mask for (N,3,H,W) diffuse images in [0,1] and (N,1,H,W) masks."""
    if isinstance(model, OnnxStage):
        return model.run({"diffuse": diffuse, "mask": mask})["relit"]
    with torch.no_grad():
        return (diffuse + model((2.0 * diffuse - 1.0) * mask).float()).clamp(0.0, 1.0) * mask


__all__ = ["OnnxStage", "apply_stage2", "load_frozen"]
