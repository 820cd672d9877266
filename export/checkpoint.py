"""Our checkpoint format ("relight_rt.ckpt/1") and state_dict checks shared with the reference import.

A checkpoint is one ``torch.save`` file holding only plain containers, tensors, numbers and
strings, so that it loads with ``torch.load(weights_only=True)``::

    {"format": "relight_rt.ckpt/1", "kind": "stage1" | "stage2" | "dvp",
     "config": model.config, "state_dict": model.state_dict(), **extra}

``extra`` is whatever the training loop adds (epoch, optimizer state, losses, ...).

Stage-2 and DVP configs carry ``output_activation`` ("none" | "tanh"); a checkpoint written before that
key existed holds a network that ended in tanh and is loaded as one.
"""

from __future__ import annotations

import logging
import os
import pickle
import re
from collections.abc import Mapping
from pathlib import Path

import torch
from torch import nn

from relight_rt import RelightError
from relight_rt.engine.files import atomic_path

from .networks import build_network

__all__ = ["FORMAT", "check_state_dict", "load_checkpoint", "read_weights", "save_checkpoint"]

log = logging.getLogger(__name__)

FORMAT = "relight_rt.ckpt/1"
LEGACY_OUTPUT_ACTIVATION = "tanh"  # stage2/dvp checkpoints whose config has no "output_activation"
_RESERVED = ("format", "kind", "config", "state_dict")


def save_checkpoint(path: str | os.PathLike, model: nn.Module, **extra) -> Path:
    """Write ``model`` (a network of ``export.networks``) and ``extra`` atomically (temporary file + rename).

    Args:
        path: destination file (parent folders are created).
        model: a Stage1Net, Stage2Net or DVPNet (anything with ``.kind`` and ``.config``).
        **extra: more entries (epoch, optimizer state dict, ...); plain tensors/numbers/strs/containers.

    Returns:
        The path written.
    """
    clash = sorted(set(extra) & set(_RESERVED))
    if clash:
        raise RelightError(f"save_checkpoint: extra keys {clash} are reserved")
    if not getattr(model, "kind", "") or not hasattr(model, "config"):
        raise RelightError(f"save_checkpoint: expected a network from export.networks, got {type(model).__name__}")
    payload = {
        "format": FORMAT,
        "kind": model.kind,
        "config": dict(model.config),
        "state_dict": {k: v.detach().cpu() for k, v in model.state_dict().items()},
        **extra,
    }
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        torch.save(payload, tmp)
    return path




def read_weights(path: str | os.PathLike, map_location: str | torch.device = "cpu") -> object:
    """``torch.load(path, weights_only=True)`` with every failure turned into a RelightError.

    Raises:
        RelightError: the file is missing, not a torch file, or holds pickled objects other than
            tensors and plain containers (refused: unpickling could run arbitrary code).
    """
    path = Path(path)
    if not path.is_file():
        raise RelightError(f"{path}: checkpoint file not found")
    try:
        return torch.load(path, map_location=map_location, weights_only=True)
    except pickle.UnpicklingError as exc:
        text = str(exc)
        found = re.search(r"Unsupported global: GLOBAL ([\w.]+)", text)
        if found:
            raise RelightError(
                f"{path}: refused: the checkpoint holds pickled objects that are not plain tensors/containers "
                f"({found.group(1)}); torch.load(weights_only=True) does not unpickle arbitrary objects"
            ) from None
        detail = re.search(r"WeightsUnpickler error:\s*(.+)", text)
        why = detail.group(1).strip() if detail else type(exc).__name__
        raise RelightError(f"{path}: not a readable torch checkpoint ({why})") from None
    except (RuntimeError, EOFError, OSError, ValueError) as exc:
        raise RelightError(f"{path}: not a readable torch checkpoint ({type(exc).__name__}: {exc})") from None


def check_state_dict(model: nn.Module, state_dict: Mapping, name: str) -> None:
    """Check that ``state_dict`` has exactly ``model``'s keys and shapes.

    Raises:
        RelightError: listing every missing, unexpected and mis-shaped key in one message.
    """
    if not isinstance(state_dict, Mapping):
        got = type(state_dict).__name__
        raise RelightError(f"{name}: expected a state_dict (mapping of names to tensors), got {got}")
    expected = model.state_dict()
    missing = [k for k in expected if k not in state_dict]
    unexpected = [k for k in state_dict if k not in expected]
    misshaped = []
    for k, v in state_dict.items():
        if k in expected:
            if not isinstance(v, torch.Tensor):
                misshaped.append(f"{k} (not a tensor: {type(v).__name__})")
            elif tuple(v.shape) != tuple(expected[k].shape):
                misshaped.append(f"{k} {list(v.shape)} (expected {list(expected[k].shape)})")
    problems = []
    if missing:
        problems.append(f"missing keys: {', '.join(missing)}")
    if unexpected:
        problems.append(f"unexpected keys: {', '.join(unexpected)}")
    if misshaped:
        problems.append(f"mis-shaped: {', '.join(misshaped)}")
    if problems:
        what = f"{name}: state_dict does not match the {model.kind} network {model.config}"
        raise RelightError(f"{what}: " + "; ".join(problems))


def load_checkpoint(path: str | os.PathLike, map_location: str | torch.device = "cpu") -> tuple[nn.Module, dict]:
    """Read a checkpoint written by :func:`save_checkpoint`.

    Returns:
        (model, checkpoint): the network rebuilt from its kind and config with the weights loaded
        (left in training mode, as constructed), and the whole checkpoint dict (extra entries included).

    Raises:
        RelightError: unreadable or pickle-bearing file, wrong format, unknown kind, bad config, or a
            state_dict whose keys/shapes do not match the network.
    """
    ckpt = read_weights(path, map_location)
    if not isinstance(ckpt, dict) or ckpt.get("format") != FORMAT:
        got = ckpt.get("format") if isinstance(ckpt, dict) else type(ckpt).__name__
        raise RelightError(
            f"{path}: expected a {FORMAT!r} checkpoint (format key), got {got!r}; "
            f"reference checkpoints go through 'python -m export convert-reference'"
        )
    kind, config = ckpt.get("kind"), ckpt.get("config")
    if not isinstance(config, dict):
        raise RelightError(f"{path}: 'config' must be a dict, got {type(config).__name__}")
    if kind in ("stage2", "dvp") and "output_activation" not in config:
        # written before the option existed, when every stage-2 and DVP network ended in tanh
        config = {**config, "output_activation": LEGACY_OUTPUT_ACTIVATION}
        log.info("%s: a %s checkpoint from before output_activation was recorded: read as 'tanh'", path, kind)
    try:
        model = build_network(str(kind), config)
    except TypeError as exc:
        raise RelightError(f"{path}: bad config {config}: {exc}") from None
    check_state_dict(model, ckpt.get("state_dict"), str(path))
    model.load_state_dict(ckpt["state_dict"], strict=True)
    log.info("loaded %s checkpoint %s (%s)", kind, path, config)
    return model, ckpt
