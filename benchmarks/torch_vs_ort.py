"""Side by side: the relight_rt runtime (onnxruntime) against PyTorch eager fp32 on the same weights.

    python benchmarks/torch_vs_ort.py --configs 1024x64,256x16 --out runs/bench

For each config RESOLUTIONxWIDTH, random-weight stage-1 and stage-2 networks (``export.networks``,
norm "instance": per-sample statistics, what the reference computes at inference) are made with a
fixed seed, saved as checkpoints and exported with ``export.onnx_export.export_onnx`` (cached in
``OUT/models_RxW``). Then two child processes run one after the other on the same machine, each with
a fresh memory peak:

- ``relight-rt bench``: the runtime as shipped (``Relighter`` on onnxruntime);
- this script with ``--torch``: the same ``relight_rt.cli.bench.run`` sections, with the Relighter's
  two onnxruntime models swapped for the torch networks (eager, fp32, ``torch.inference_mode``) wrapped
  exactly as the export wraps them, so preprocessing, the numpy relight step and compositing are
  shared and only the network executor differs.

The reports are merged into ``OUT/report_RxW.json`` and a markdown table with a ``torch / ort`` ratio
column (above 1: onnxruntime is faster). Needs torch (the export extra). Timings are never asserted.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from relight_rt import RelightError  # noqa: E402
from relight_rt.cli.bench import SECTIONS, run, to_markdown, write_text  # noqa: E402

log = logging.getLogger("torch_vs_ort")
SEEDS = range(1, 9)  # weight seeds tried in turn until the export's 1e-4 parity gate passes


def _parse_config(text: str) -> tuple[int, int]:
    try:
        res, width = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected RESOLUTIONxWIDTH such as 1024x64, got {text!r}") from None
    return res, width


def make_models(folder: Path, resolution: int, width: int, norm: str = "instance") -> dict:
    """Random-weight stage-1/stage-2 checkpoints and ONNX graphs in ``folder`` (reused when present).

    Weights come from ``torch.manual_seed(seed)``; a seed whose export fails the parity gate is skipped
    (logged) and the next one tried. Returns {kind: {"seed", "parity", "tries"}}.
    """
    import torch

    from export.checkpoint import save_checkpoint
    from export.networks import Stage1Net, Stage2Net
    from export.onnx_export import export_onnx

    folder.mkdir(parents=True, exist_ok=True)
    info_path = folder / "models.json"
    files = [folder / f"{k}{s}" for k in ("stage1", "stage2") for s in (".onnx", ".pt")]
    if info_path.is_file() and all(f.is_file() for f in files):
        return json.loads(info_path.read_text())
    info = {}
    for kind, cls in (("stage1", Stage1Net), ("stage2", Stage2Net)):
        tries = []
        for seed in SEEDS:
            torch.manual_seed(seed)
            net = cls(width=width, resolution=resolution, norm=norm)
            source = f"random weights, benchmarks/torch_vs_ort.py, seed {seed}"
            try:
                summary = export_onnx(net, folder / f"{kind}.onnx", source=source, resolution=None)
            except RelightError as exc:
                log.warning("%s seed %d: %s", kind, seed, exc)
                tries.append({"seed": seed, "error": str(exc)})
                continue
            save_checkpoint(folder / f"{kind}.pt", net, seed=seed)
            info[kind] = {"seed": seed, "parity": summary["parity"], "tries": tries}
            break
        else:
            raise RelightError(f"{kind} {resolution}x{width}: no seed in {list(SEEDS)} passed the export parity gate")
    write_text(info_path, json.dumps(info, indent=1) + "\n")
    return info


class TorchModel:
    """A stand-in for ``relight_rt.engine.session.Model`` that runs the torch network eagerly (fp32, CPU)."""

    def __init__(self, checkpoint: Path, model) -> None:
        from export.checkpoint import load_checkpoint
        from export.onnx_export import wrap

        net, _ = load_checkpoint(checkpoint)
        self.wrapper = wrap(net.eval()).eval()
        self.config = model.config
        self.session = None  # the onnxruntime session is dropped, so its memory does not count against torch
        self.name = f"torch:{checkpoint}"
        self.on_cuda = False
        from relight_rt.engine.contract import KINDS

        self._inputs = [t.name for t in KINDS[model.config.kind].inputs]
        self._outputs = [t.name for t in KINDS[model.config.kind].outputs]

    def warm_up(self) -> None:
        pass

    def run(self, feeds: dict) -> dict:
        import torch

        with torch.inference_mode():
            args = [torch.from_numpy(np.ascontiguousarray(feeds[n], dtype=np.float32)) for n in self._inputs]
            out = self.wrapper(*args)
        out = (out,) if isinstance(out, torch.Tensor) else out
        return {n: o.numpy() for n, o in zip(self._outputs, out, strict=True)}


def torch_report(models: Path, args: argparse.Namespace) -> dict:
    """``relight_rt.cli.bench.run`` with the Relighter's networks replaced by torch eager (see module docstring)."""
    import torch

    import relight_rt.relight.relighter as relighter_module

    torch.set_num_threads(args.threads or os.cpu_count() or 1)
    original = relighter_module.Relighter.__init__

    def patched(self, *a, **kw) -> None:  # every Relighter made by bench.run gets the torch networks
        original(self, *a, **kw)
        self.stage1 = TorchModel(models / "stage1.pt", self.stage1)
        if self.stage2 is not None:
            self.stage2 = TorchModel(models / "stage2.pt", self.stage2)

    relighter_module.Relighter.__init__ = patched
    try:
        report = run(models, device="cpu", sections=args.sections, batches=args.batches, n_lights=args.lights,
                     frames=args.frames, repeats=args.repeats, warmup=args.warmup, backend="torch")  # fmt: skip
    finally:
        relighter_module.Relighter.__init__ = original
    report["config"]["torch"] = torch.__version__
    report["config"]["torch_threads"] = torch.get_num_threads()
    report["rows"] = [r for r in report["rows"] if r["backend"] == "torch"]  # numpy rows come from the ort run
    return report


def make_int8(folder: Path, resolution: int) -> dict:
    """``stage1_int8.onnx`` / ``stage2_int8.onnx`` beside the fp32 graphs (``export.quantize``), reused when present.

    No rendered photos here: calibration (4) and held-out (2) inputs are the benchmark's synthetic photos
    (``relight_rt.cli.bench.photo``, smooth random colours) in an ellipse mask; for stage 2 the diffuse input
    is such a photo too. Returns {kind: summary or {"error": message}} (a graph under the gate is not written).
    """
    from export.quantize import quantize
    from relight_rt.cli.bench import person_mask, photo

    info_path = folder / "int8.json"
    if info_path.is_file():
        return json.loads(info_path.read_text())
    mask = person_mask(resolution, resolution)[None, None]
    info = {}
    for kind, first in (("stage1", "image"), ("stage2", "diffuse")):
        feeds = [{first: np.ascontiguousarray(photo(resolution, resolution, seed=100 + i).transpose(2, 0, 1)[None]),
                  "mask": mask} for i in range(6)]  # fmt: skip
        try:
            info[kind] = quantize(folder / f"{kind}.onnx", folder / f"{kind}_int8.onnx", feeds[:4], feeds[4:])
        except RelightError as exc:
            log.warning("%s int8: %s", kind, exc)
            info[kind] = {"error": str(exc)}
    write_text(info_path, json.dumps(info, indent=1) + "\n")
    return info


def _ort(folder: Path, out: Path, args: argparse.Namespace, precision: str) -> dict:
    path = out / f".ort_{folder.name}_{precision}.json"
    cmd = [sys.executable, "-m", "relight_rt", "bench", "--models", str(folder), "--json", str(path)]
    subprocess.run([*cmd, "--precision", precision, *_common(args)], check=True, cwd=REPO, stdout=subprocess.DEVNULL)
    report = json.loads(path.read_text())
    path.unlink()
    return report


def _child(argv: list[str]) -> dict:
    out = subprocess.run([sys.executable, *argv], check=True, capture_output=True, text=True, cwd=REPO)
    if out.stderr.strip():
        log.info("%s", out.stderr.strip())
    return json.loads(out.stdout)


def _common(args: argparse.Namespace) -> list[str]:
    return ["--sections", ",".join(args.sections), "--batches", ",".join(map(str, args.batches)),
            "--lights", str(args.lights), "--frames", str(args.frames), "--repeats", str(args.repeats),
            "--warmup", str(args.warmup)]  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--configs", default="1024x64,256x16", help="comma-separated RESOLUTIONxWIDTH")
    parser.add_argument("--out", default=str(REPO / "runs" / "bench"), help="folder for models and reports")
    parser.add_argument("--sections", default=",".join(SECTIONS))
    parser.add_argument("--batches", default="1,4,8")
    parser.add_argument("--lights", type=int, default=8)
    parser.add_argument("--frames", type=int, default=4)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--warmup", type=int, default=1)
    parser.add_argument("--threads", type=int, default=0, help="torch threads (0: one per core)")
    parser.add_argument("--int8", action="store_true", help="also quantise (export.quantize) and time the int8 graphs")
    parser.add_argument("--no-torch", action="store_true", help="onnxruntime rows only")
    parser.add_argument("--torch", metavar="MODELS", help=argparse.SUPPRESS)  # child: torch rows as JSON on stdout
    args = parser.parse_args(argv)
    args.sections = [s for s in args.sections.split(",") if s]
    args.batches = [int(b) for b in args.batches.split(",") if b]
    logging.basicConfig(level=logging.INFO, format="%(message)s", stream=sys.stderr)
    if args.torch:
        sys.stdout.write(json.dumps(torch_report(Path(args.torch), args)))
        return 0
    out = Path(args.out)
    for text in args.configs.split(","):
        res, width = _parse_config(text)
        folder = out / f"models_{res}x{width}"
        info = make_models(folder, res, width)
        log.info("%dx%d: models in %s (%s)", res, width, folder, {k: v["seed"] for k, v in info.items()})
        ort_report = _ort(folder, out, args, "fp32")
        report = {**ort_report, "models": info}
        rows = list(ort_report["rows"])
        if args.int8:
            report["int8"] = make_int8(folder, res)
            int8_rows = _ort(folder, out, args, "int8")["rows"]
            rows += [r for r in int8_rows if r["backend"] != "numpy"]
        if not args.no_torch:
            torch_child = [str(Path(__file__).resolve()), "--torch", str(folder), "--threads", str(args.threads)]
            torch_rows = _child(torch_child + _common(args))
            report["torch"] = torch_rows["config"]
            rows += torch_rows["rows"]
        order = {s: i for i, s in enumerate(SECTIONS)}
        backends = {"torch": 0, "onnxruntime": 1, "onnxruntime int8": 2}
        report["rows"] = sorted(rows, key=lambda r: (order[r["section"]], r["batch"], backends.get(r["backend"], 3)))
        title = f"{res}² width {width}, {report['system']['cpu']}"
        text = to_markdown(report, title)
        write_text(out / f"report_{res}x{width}.json", json.dumps(report, indent=1) + "\n")
        write_text(out / f"report_{res}x{width}.md", text)
        sys.stdout.write(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
