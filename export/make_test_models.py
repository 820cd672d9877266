"""Regenerate the tiny ONNX test graphs in tests/data (random weights; runtime tests never need torch).

``python -m export.make_test_models [OUT_DIR]`` writes, with fixed seeds:

- ``tiny_stage1.onnx``: Stage1Net width 2, resolution 128 (light head: one conv), norm "instance";
- ``tiny_stage2.onnx``: Stage2Net width 2, norm "batch" (running statistics gathered from a few random
  batches), metadata resolution 0 (any size divisible by 64);
- ``tiny_dvp.onnx``: DVPNet width 2, norm "instance", metadata resolution 0.

Width 2 (not 4) keeps the three files near 0.5 MB together; they pass the same checks as any export
(parity torch vs onnxruntime within 1e-4, onnx.checker, contract metadata).
"""

from __future__ import annotations

import logging
import sys
from pathlib import Path

import torch

from .networks import DVPNet, Stage1Net, Stage2Net
from .onnx_export import export_onnx, format_summary

SOURCE = "random weights for tests (export/make_test_models.py, seed {seed})"
DEFAULT_DIR = Path(__file__).resolve().parents[1] / "tests" / "data"


def _gather_running_stats(net: torch.nn.Module, seed: int, steps: int = 8) -> None:
    """Give a norm="batch" network plausible running statistics: a few training-mode passes on noise."""
    gen = torch.Generator().manual_seed(seed)
    net.train()
    with torch.no_grad():
        for _ in range(steps):
            x = torch.rand(2, 3, 128, 128, generator=gen) * 2 - 1
            net(x)
    net.eval()


def make_test_models(out_dir: str | Path = DEFAULT_DIR) -> list[dict]:
    """Write the three tiny graphs into ``out_dir``; returns their export summaries."""
    out_dir = Path(out_dir)
    summaries = []
    torch.manual_seed(0)
    stage1 = Stage1Net(width=2, resolution=128, norm="instance")
    summaries.append(export_onnx(stage1, out_dir / "tiny_stage1.onnx", source=SOURCE.format(seed=0)))
    torch.manual_seed(1)
    stage2 = Stage2Net(width=2, resolution=128, norm="batch")
    _gather_running_stats(stage2, seed=1)
    summaries.append(export_onnx(stage2, out_dir / "tiny_stage2.onnx", source=SOURCE.format(seed=1), resolution=0))
    torch.manual_seed(2)
    dvp = DVPNet(width=2, resolution=128, norm="instance")
    summaries.append(export_onnx(dvp, out_dir / "tiny_dvp.onnx", source=SOURCE.format(seed=2), resolution=0))
    return summaries


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    for summary in make_test_models(argv[0] if argv else DEFAULT_DIR):
        print(format_summary(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main())
