"""``relight-rt bench`` (also ``python -m relight_rt.bench``): time the models on this machine (relight_rt.timing)."""

from __future__ import annotations

import argparse
import json
import logging
import sys

from .. import timing
from ..engine.errors import RelightError


def _ints(text: str) -> list[int]:
    try:
        values = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated whole numbers, got {text!r}") from None
    if not values or min(values) < 1:
        raise argparse.ArgumentTypeError(f"expected positive whole numbers, got {text!r}")
    return values


def _add_arguments(p: argparse.ArgumentParser) -> None:
    sections = timing.SECTIONS
    p.add_argument("--models", metavar="DIR", help="model folder (default: $RELIGHT_RT_MODELS, then bundled models)")
    p.add_argument("--device", choices=("auto", "cpu", "cuda"), default="cpu", help="where to run (default: cpu)")
    p.add_argument("--precision", choices=("fp32", "fp16", "int8"), default="fp32",
                   help="graphs to run: stage1.onnx (fp32), stage1_fp16.onnx or stage1_int8.onnx (default fp32)")
    p.add_argument("--sections", default=",".join(sections), help=f"comma-separated, of {','.join(sections)}")
    p.add_argument("--batches", type=_ints, default=[1, 4, 8], help="batch sizes, e.g. 1,4,8 (default)")
    p.add_argument("--lights", type=int, default=8, help="K lights for shade/sweep (default 8)")
    p.add_argument("--frames", type=int, default=4, help="frames for the video section (default 4)")
    p.add_argument("--repeats", type=int, default=5, help="timed calls per figure (default 5)")
    p.add_argument("--warmup", type=int, default=1, help="untimed calls first (default 1)")
    p.add_argument("--json", metavar="FILE", help="write the report as JSON")
    p.add_argument("--markdown", metavar="FILE", help="write the markdown table")


def add_parser(subparsers) -> None:
    """Register ``relight-rt bench`` on the CLI's subparsers."""
    p = subparsers.add_parser("bench", help="time the models on this machine (JSON + markdown)")
    _add_arguments(p)
    p.set_defaults(func=cmd_bench)


def cmd_bench(args: argparse.Namespace) -> int:
    """Run the benchmark from parsed arguments; print the markdown table; write the files asked for."""
    from ..engine.session import find_models

    models = find_models(args.models)
    sections = [s.strip() for s in args.sections.split(",") if s.strip()]
    report = timing.run(models, device=args.device, sections=sections, batches=args.batches, n_lights=args.lights,
                       frames=args.frames, repeats=args.repeats, warmup=args.warmup,
                       precision=args.precision)  # fmt: skip
    text = timing.to_markdown(report)
    if args.json:
        timing.write_text(args.json, json.dumps(report, indent=1) + "\n")
    if args.markdown:
        timing.write_text(args.markdown, text)
    sys.stdout.write(text)
    return 0


def main(argv: list[str] | None = None) -> int:
    """``python -m relight_rt.bench``."""
    parser = argparse.ArgumentParser(prog="python -m relight_rt.bench", description=timing.__doc__.splitlines()[0])
    _add_arguments(parser)
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    try:
        return cmd_bench(args)
    except RelightError as exc:
        sys.stderr.write(f"relight-rt bench: error: {exc}\n")
        return 2
