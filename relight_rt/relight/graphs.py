"""The Relighter's ONNX graphs: each kind's file in the chosen precision (fp32 where that one is absent), stage 1 and
stage 2 loaded, warmed up and checked against each other (relight_rt.engine.session loads one)."""

from __future__ import annotations

import logging
from pathlib import Path

from ..engine.config import RuntimeConfig
from ..engine.contract import kind_spec
from ..engine.errors import RelightError
from ..engine.session import Model, load_model

log = logging.getLogger(__name__)


def graph_file(models_dir: Path, kind: str, precision: str) -> Path:
    """The file of ``kind`` in ``precision`` in ``models_dir``, falling back to fp32 (logged) when absent."""
    fp32 = models_dir / kind_spec(kind).filename
    if precision == "fp32":
        return fp32
    path = fp32.with_name(f"{fp32.stem}_{precision}{fp32.suffix}")
    if path.is_file() or not fp32.is_file():
        return path
    log.warning("%s: no %s, running %s in fp32", models_dir, path.name, kind)
    return fp32


def load_stages(models_dir: Path, config: RuntimeConfig, session_args: dict) -> tuple[Model, Model | None]:
    """Stage 1 and stage 2 (None without ``stage2.onnx``: results are diffuse-only, logged) of ``models_dir`` in
    ``config``'s precision, warmed up as ``config.warmup`` says (None: on CUDA), with ``session_args`` (device,
    device_id, providers) for ``load_model``.

    Raises:
        RelightError: a graph unreadable or breaking the contract; stage 2's resolution neither stage 1's nor 0.
    """
    stage1 = load_model(graph_file(models_dir, "stage1", config.precision), "stage1", warmup=False, **session_args)
    warmup = config.warmup
    if warmup is None:
        warmup = stage1.on_cuda
    if warmup:
        stage1.warm_up()
    stage2_path = graph_file(models_dir, "stage2", config.precision)
    if not stage2_path.is_file():
        log.warning("%s has no stage2.onnx: results are diffuse-only (no residual/specular)", models_dir)
        return stage1, None
    stage2 = load_model(stage2_path, "stage2", warmup=warmup, **session_args)
    res1, res2 = stage1.config.resolution, stage2.config.resolution
    if res2 not in (0, res1):
        raise RelightError(f"{stage2_path}: resolution {res2} does not match stage 1's {res1} (or 0 for any size)")
    return stage1, stage2
