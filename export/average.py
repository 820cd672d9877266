"""``python -m export average``: the weighted mean of checkpoints of one network (a "model soup").

Checkpoints of one lineage (a run and its continuation, say on more data) lie in one basin of the loss; their
weight average is often better than either (Wortsman et al., "Model soups", ICML 2022; Izmailov et al., SWA,
UAI 2018). Every floating-point tensor of the state_dict is averaged, BatchNorm's running statistics included
(an approximation: statistics of the averaged network would have to be measured again); integer tensors
(BatchNorm's step counts) come from the last checkpoint. The result is an ordinary checkpoint without
optimizer state: export it with ``python -m export onnx`` or go on training from it with ``--init``.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import dataclass
from pathlib import Path

from relight_rt import RelightError

from .checkpoint import load_checkpoint, save_checkpoint
from .config import reader


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("checkpoints", nargs="+", type=Path, help="two or more checkpoints of one network")
    parser.add_argument(
        "--weights", nargs="+", type=float, help="one per checkpoint, normalised to sum 1 (default: equal)"
    )
    parser.add_argument("--out", type=Path, required=True, help="the averaged checkpoint to write")


def average(paths: list[Path], weights: list[float] | None = None):
    """(model, meta): the network of ``paths[0]``'s kind and config with the weighted mean of their weights."""
    if len(paths) < 2:
        raise RelightError(f"average: expected two or more checkpoints, got {len(paths)}")
    if weights is None:
        weights = [1.0] * len(paths)
    if len(weights) != len(paths):
        raise RelightError(f"--weights: expected one per checkpoint ({len(paths)}), got {len(weights)}")
    if any(not w >= 0 for w in weights) or sum(weights) <= 0:
        raise RelightError(f"--weights: expected non-negative numbers with a positive sum, got {weights}")
    total = sum(weights)
    weights = [w / total for w in weights]
    model, first = load_checkpoint(paths[0])
    state = {k: v.clone() for k, v in model.state_dict().items()}
    for v in state.values():
        if v.is_floating_point():
            v.mul_(weights[0])
    for path, w in zip(paths[1:], weights[1:], strict=True):
        other, ckpt = load_checkpoint(path)
        if ckpt["kind"] != first["kind"] or dict(ckpt["config"]) != dict(first["config"]):
            raise RelightError(
                f"{path}: a {ckpt['kind']} {dict(ckpt['config'])}, not the "
                f"{first['kind']} {dict(first['config'])} of {paths[0]}"
            )
        for k, v in other.state_dict().items():
            if v.is_floating_point():
                state[k].add_(v, alpha=w)
            else:
                state[k] = v.clone()  # the last checkpoint's counts
    model.load_state_dict(state)
    meta = {"command": "average", "checkpoints": [str(p) for p in paths], "weights": weights}
    return model, meta


@dataclass(frozen=True, kw_only=True)
class AverageConfig:
    """The settings of ``average`` (one field per flag; see :func:`add_arguments`)."""

    checkpoints: tuple[Path, ...]
    out: Path
    weights: tuple[float, ...] | None = None


config_from_args = reader(AverageConfig)


def run(config: AverageConfig) -> int:
    if any(config.out.resolve() == p.resolve() for p in config.checkpoints):
        raise RelightError(
            f"--out {config.out} is one of the checkpoints averaged: give another file (inputs are kept)")
    model, meta = average(config.checkpoints, config.weights)
    save_checkpoint(config.out, model, meta=json.dumps(meta))
    print(
        f"wrote {config.out}: {model.kind} {dict(model.config)}, "
        + ", ".join(f"{w:.3g} x {p}" for p, w in zip(meta["checkpoints"], meta["weights"], strict=True))
    )
    return 0
