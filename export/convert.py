"""Convert the reference checkpoints to contract graphs (``python -m export convert-reference``).

The reference code (Tajima et al.) saves ``model.state_dict()`` of one network class for every network
(``model_1st.pth``: stage 1, 4 albedo-decoder channels; ``model_2nd.pth``: stage 2, 3 channels; the
deep video prior: 30 input channels, 3 out), works in OpenCV's BGR order, and never switches its
BatchNorm layers to eval mode. The conversion:

1. reads each file with ``torch.load(weights_only=True)`` (a file with other pickled objects is refused);
2. checks every key and shape against our network at width 64 / resolution 1024, all problems in one error;
3. folds BGR → RGB into the weights: the input channels of ``c0`` (for the DVP also the colour c of each
   tiled light coefficient, channels 3 + 3k + c); the albedo (stage 1, output rows 0–2 of ``dc5b``; the
   skin row 3 stays) or residual / frame (stage 2 / DVP, rows 0–2 of ``dc5b``) output channels; and the
   light's colour columns (rows 3k + c of ``c3l``, c reversed within each triple). The transport is
   colour-free and stays as is;
4. builds the network with ``norm="instance"`` (per-sample statistics, biased variance, eps 1e-5: what
   the reference computes with batch-of-one training-mode BatchNorm) and, for stage 2 and the DVP,
   ``output_activation="none"`` (the reference returns decoder b's last conv, upsampled), and exports it
   with :func:`export.onnx_export.export_onnx`; ``relight_rt.source`` names the file and its sha256.

``relight-rt import-reference`` (:mod:`relight_rt.apps.reference_checkpoints`) does the same without torch and
writes graphs with the same outputs and metadata.
"""

from __future__ import annotations

import logging
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import torch

from relight_rt import RelightError
from relight_rt.apps.reference_checkpoints import reference_source

from .checkpoint import check_state_dict, read_weights
from .config import reader
from .networks import DVPNet, Stage1Net, Stage2Net
from .onnx_export import DEFAULT_OPSET, export_onnx, format_summary

__all__ = ["add_arguments", "bgr_to_rgb_state_dict", "convert_reference", "load_reference", "run"]

log = logging.getLogger(__name__)

_BGR_TO_RGB = [2, 1, 0]
_NETS = {"stage1": Stage1Net, "stage2": Stage2Net, "dvp": DVPNet}


def _rows_permuted(t: torch.Tensor, rows: list[int]) -> torch.Tensor:
    out = t.clone()
    out[: len(rows)] = t[rows]
    return out


def bgr_to_rgb_state_dict(state_dict: Mapping[str, torch.Tensor], kind: str) -> dict[str, torch.Tensor]:
    """A copy of a reference (BGR) state_dict whose network reads and writes RGB.

    Args:
        state_dict: the reference's keys (``c0.weight``, ``dc5b.*``, ``c3l.*``, ...); not modified.
        kind: "stage1" (albedo rows 0–2 swapped, skin row 3 kept, light columns swapped),
            "stage2" (residual rows 0–2 swapped; the unused light head is swapped too, harmlessly) or
            "dvp" (as stage2, and the input channels 3 + 3k + c of the tiled light reversed in c).

    Returns:
        new dict of tensors. Feeding the result an RGB image gives exactly the reference's outputs
        for the BGR image, with colour channels (albedo / residual / light columns) in RGB.
    """
    if kind not in _NETS:
        raise RelightError(f"bgr_to_rgb_state_dict: kind must be one of {sorted(_NETS)}, got {kind!r}")
    sd = {k: v.clone() for k, v in state_dict.items()}
    channels = list(_BGR_TO_RGB)
    if kind == "dvp":
        channels += [3 + 3 * k + c for k in range(9) for c in _BGR_TO_RGB]
    sd["c0.weight"] = state_dict["c0.weight"][:, channels].clone()
    for key in ("dc5b.weight", "dc5b.bias"):
        sd[key] = _rows_permuted(state_dict[key], _BGR_TO_RGB)
    # the light head's last conv is its only one with a bias (c3l at resolution 1024)
    rows = [3 * k + c for k in range(9) for c in _BGR_TO_RGB]
    for key in [k for k in state_dict if re.fullmatch(r"c\d+l\.bias", k)]:
        prefix = key[: -len(".bias")]
        for name in (f"{prefix}.weight", f"{prefix}.bias"):
            sd[name] = state_dict[name][rows].clone()
    return sd


def load_reference(path: str | os.PathLike, kind: str, width: int = 64, resolution: int = 1024):
    """Read a reference checkpoint into our network (norm="instance"), BGR folded to RGB.

    Args:
        path: ``model_1st.pth`` (kind "stage1"), ``model_2nd.pth`` (kind "stage2") or a DVP network (kind "dvp").
        width, resolution: the network size (64 / 1024 for the real files; smaller ones for tests).

    Returns:
        the network in eval mode, reading and writing RGB; stage 2 and DVP without an output activation.

    Raises:
        RelightError: unreadable or pickle-bearing file, or keys/shapes that differ from the layout.
    """
    cls = _NETS.get(kind)
    if cls is None:
        raise RelightError(f"load_reference: kind must be one of {sorted(_NETS)}, got {kind!r}")
    state = read_weights(path)
    if isinstance(state, Mapping) and "state_dict" in state and isinstance(state["state_dict"], Mapping):
        state = state["state_dict"]
    extra = {} if kind == "stage1" else {"output_activation": "none"}
    net = cls(width=width, resolution=resolution, norm="instance", **extra)
    check_state_dict(net, state, f"{path} ({kind})")
    net.load_state_dict(bgr_to_rgb_state_dict(state, kind), strict=True)
    return net.eval()


def convert_reference(
    stage1: str | os.PathLike | None,
    out_dir: str | os.PathLike,
    *,
    stage2: str | os.PathLike | None = None,
    dvp: str | os.PathLike | None = None,
    fp16: bool = False,
    width: int = 64,
    resolution: int = 1024,
    opset: int = DEFAULT_OPSET,
) -> list[dict]:
    """Convert reference checkpoints to ``out_dir/stage1.onnx`` (and ``stage2.onnx``, ``dvp.onnx``).

    Every file is read and checked before anything is written. Returns the export summaries.
    """
    jobs = [(kind, p) for kind, p in (("stage1", stage1), ("stage2", stage2), ("dvp", dvp)) if p is not None]
    if not jobs:
        raise RelightError("convert-reference: give --stage1, --stage2 and/or --dvp")
    nets = [(kind, path, load_reference(path, kind, width, resolution)) for kind, path in jobs]
    summaries = []
    for kind, path, net in nets:
        source = reference_source(path, kind)
        summaries.append(export_onnx(net, Path(out_dir) / f"{kind}.onnx", source=source, fp16=fp16, opset=opset))
    return summaries


def add_arguments(parser) -> None:
    """Arguments of ``python -m export convert-reference``."""
    parser.add_argument("--stage1", help="the reference's model_1st.pth")
    parser.add_argument("--stage2", help="the reference's model_2nd.pth")
    parser.add_argument("--dvp", help="a reference deep-video-prior network (state_dict)")
    parser.add_argument("--out", required=True, help="output folder for stage1.onnx / stage2.onnx / dvp.onnx")
    parser.add_argument("--fp16", action="store_true", help="also write *_fp16.onnx (refused under 40 dB PSNR)")
    parser.add_argument("--width", type=int, default=64, help="base width (64 = reference)")
    parser.add_argument("--resolution", type=int, default=1024, help="network resolution (1024 = reference)")
    parser.add_argument("--opset", type=int, default=DEFAULT_OPSET, help=f"ONNX opset (default {DEFAULT_OPSET})")


@dataclass(frozen=True, kw_only=True)
class ConvertConfig:
    """The settings of ``convert-reference`` (one field per flag; see :func:`add_arguments`)."""

    out: Path
    stage1: Path | None = None
    stage2: Path | None = None
    dvp: Path | None = None
    fp16: bool = False
    width: int = 64
    resolution: int = 1024
    opset: int = 17


config_from_args = reader(ConvertConfig)


def run(config: ConvertConfig) -> int:
    """``python -m export convert-reference``."""
    summaries = convert_reference(
        config.stage1,
        config.out,
        stage2=config.stage2,
        dvp=config.dvp,
        fp16=config.fp16,
        width=config.width,
        resolution=config.resolution,
        opset=config.opset,
    )
    for summary in summaries:
        print(format_summary(summary))
    return 0
