"""``relight-rt bench``: time the runtime on this machine, per stage, the numpy relight step, end to end, light
sweeps and video.

The command and its harness (``run``, ``to_markdown``, ...: benchmarks/ import them). It times, on random inputs of
the models' own resolution R:

- ``stage1``: the stage-1 graph alone, batch 1/4/8 (``--batches``);
- ``stage2``: the stage-2 graph alone, same batches;
- ``shade``: the numpy relight step, ``diffuse_batch`` (T·L, ReLU, albedo product, clip) for K lights;
- ``compose``: putting one relit network image back into the photo (unpremultiply, resize, composite);
- ``decompose``: ``Relighter.decompose`` on an R x R photo (preprocessing + stage 1);
- ``end_to_end``: ``Relighter.relight`` on that photo (decompose, shade, stage 2, compose);
- ``sweep``: ``relight_many`` of one decomposition under K lights (``--lights``), per light;
- ``video``: ``relight`` of F different frames (``--frames``), frames per second.

Each timing runs ``--warmup`` untimed calls, then ``--repeats`` timed calls, and reports the median,
min and max (ms), per-image time and throughput, and the peak resident memory of the process while
the section ran (Linux: VmHWM, reset before each section; elsewhere the process's peak so far).
Results are a JSON-able dict (``run``) and a markdown table (``to_markdown``); rows carry a
``backend`` so other harnesses (benchmarks/torch_vs_ort.py) can add their own rows for ratios.
Timings are never asserted anywhere: tests only check that the harness runs.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import platform
import statistics
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import onnxruntime as ort

from .. import __version__
from ..engine import environment
from ..engine.errors import RelightError
from ..light import presets

log = logging.getLogger(__name__)

SECTIONS = ("stage1", "stage2", "shade", "compose", "decompose", "end_to_end", "sweep", "video")
_CLEAR_REFS = Path("/proc/self/clear_refs")
_STATUS = Path("/proc/self/status")


# ------------------------------------------------------------------------------------------- timing


def reset_peak_memory() -> bool:
    """Reset the process's peak resident memory (Linux VmHWM); False where that is not possible."""
    try:
        _CLEAR_REFS.write_text("5")
        return True
    except OSError:
        return False


def peak_memory_mb() -> float:
    """Peak resident memory of this process in MiB (since the last reset where supported)."""
    try:
        for line in _STATUS.read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    import resource

    scale = 1 if sys.platform == "darwin" else 1024  # ru_maxrss: bytes on macOS, KiB on Linux
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * scale / 2**20


def time_call(fn: Callable[[], object], repeats: int, warmup: int) -> dict:
    """Call ``fn`` ``warmup`` times untimed, then ``repeats`` times timed.

    Returns:
        {"median_ms", "min_ms", "max_ms", "repeats", "peak_mb"}; peak_mb covers the warm-up and the timed calls.
    """
    if repeats < 1 or warmup < 0:
        raise RelightError(f"repeats/warmup: expected repeats >= 1 and warmup >= 0, got {repeats}/{warmup}")
    reset_peak_memory()
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append((time.perf_counter() - t0) * 1e3)
    return {
        "median_ms": statistics.median(times),
        "min_ms": min(times),
        "max_ms": max(times),
        "repeats": repeats,
        "peak_mb": peak_memory_mb(),
    }


def row(section: str, backend: str, timing: dict, *, batch: int = 1, items: int | None = None, **extra) -> dict:
    """One result row; ``items`` = images produced per call (default ``batch``) for per-image figures."""
    items = batch if items is None else items
    per = timing["median_ms"] / items
    return {"section": section, "backend": backend, "batch": batch, "items": items, **timing,
            "per_item_ms": per, "items_per_s": 1e3 / per if per > 0 else float("inf"), **extra}  # fmt: skip


# ------------------------------------------------------------------------------------------- inputs


def person_mask(height: int, width: int) -> np.ndarray:
    """(H, W) float32 soft ellipse standing in for a person, in [0, 1], about 85 % of the height."""
    yy, xx = np.meshgrid(np.linspace(-1, 1, height), np.linspace(-1, 1, width), indexing="ij")
    return np.clip((1 - (xx / 0.45) ** 2 - (yy / 0.85) ** 2) * 8, 0, 1).astype(np.float32)


def photo(height: int, width: int, seed: int = 0) -> np.ndarray:
    """(H, W, 3) float32 RGB in [0, 1]: smooth random colours plus a little noise (not a real person)."""
    rng = np.random.default_rng(seed)
    small = rng.random((8, 8, 3), dtype=np.float32)
    import cv2

    smooth = cv2.resize(small, (width, height), interpolation=cv2.INTER_CUBIC)
    return np.clip(smooth + rng.normal(0, 0.02, (height, width, 3)).astype(np.float32), 0, 1)


def sweep_lights(k: int) -> np.ndarray:
    """(K, 9, 3) float32: a light preset turned K times about the vertical axis."""
    return presets.rotation_sequence(presets.preset(presets.list_presets()[0]), k).astype(np.float32)


def network_inputs(kind: str, batch: int, resolution: int, seed: int = 0) -> dict[str, np.ndarray]:
    """Contract inputs for a stage-1 or stage-2 graph: (N, 3, R, R) image/diffuse and (N, 1, R, R) mask."""
    rng = np.random.default_rng(seed)
    mask = np.broadcast_to(person_mask(resolution, resolution), (batch, 1, resolution, resolution)).copy()
    image = rng.random((batch, 3, resolution, resolution), dtype=np.float32)
    return {"image" if kind == "stage1" else "diffuse": image, "mask": mask}


# ------------------------------------------------------------------------------------------- runs


def system_info() -> dict:
    """Machine and library versions for the report."""
    import cv2

    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {
        "cpu": cpu,
        "cpu_count": os.cpu_count(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "onnxruntime": ort.__version__,
        "opencv": cv2.__version__,
        "relight_rt": __version__,
        "providers": ort.get_available_providers(),
        "load_average": list(os.getloadavg()) if hasattr(os, "getloadavg") else None,
        "date_utc": time.strftime("%Y-%m-%d %H:%M:%S", time.gmtime()),
    }


def run(
    models: str | os.PathLike,
    *,
    device: str = "cpu",
    sections: Sequence[str] = SECTIONS,
    batches: Sequence[int] = (1, 4, 8),
    n_lights: int = 8,
    frames: int = 4,
    repeats: int = 5,
    warmup: int = 1,
    precision: str = "fp32",
    backend: str | None = None,
) -> dict:
    """Time the runtime on the models in ``models`` (stage1.onnx, optionally stage2.onnx).

    Args:
        models: model folder (as for ``Relighter``).
        device: "cpu", "cuda" or "auto".
        sections: which of ``SECTIONS`` to run.
        batches: batch sizes for the per-stage sections (and the sweep's stage-2 batch).
        n_lights: K, lights in the ``shade`` and ``sweep`` sections.
        frames: F, frames in the ``video`` section.
        repeats, warmup: timed and untimed calls per measurement.
        precision: the Relighter's precision ("fp32", "fp16", "int8": which graphs of the folder run).
        backend: the label of the rows; default "onnxruntime" (+ the precision unless fp32). The torch harness
            runs this function under its own label.

    Returns:
        {"system", "config", "rows"}: rows as made by ``row``; JSON-serialisable.

    Raises:
        RelightError: unknown section, bad counts, or models that do not load.
    """
    from ..engine.config import RuntimeConfig
    from ..relight.relighter import Relighter, compose_step, diffuse_batch

    unknown = sorted(set(sections) - set(SECTIONS))
    if unknown:
        raise RelightError(f"sections: unknown {unknown}; known: {list(SECTIONS)}")
    if not batches or min(batches) < 1 or n_lights < 1 or frames < 1:
        raise RelightError(f"batches/lights/frames: expected positive counts, got {list(batches)}/{n_lights}/{frames}")
    if backend is None:
        backend = "onnxruntime" if precision == "fp32" else f"onnxruntime {precision}"
    t0 = time.perf_counter()
    relighter = Relighter(RuntimeConfig(models=models, device=device, warmup=True, precision=precision))
    load_ms = (time.perf_counter() - t0) * 1e3
    r = relighter.resolution
    rows: list[dict] = []
    timed = lambda fn: time_call(fn, repeats, warmup)  # noqa: E731

    for kind, model in (("stage1", relighter.stage1), ("stage2", relighter.stage2)):
        if kind not in sections or model is None:
            continue
        for b in batches:
            feeds = network_inputs(kind, b, r)
            rows.append(row(kind, backend, timed(lambda m=model, f=feeds: m.run(f)), batch=b))

    img, mask = photo(r, r), person_mask(r, r)
    dec = relighter.decompose(img, mask)
    sweep = sweep_lights(n_lights)
    if "shade" in sections:
        for k in sorted({1, n_lights}):
            t = timed(lambda k=k: diffuse_batch(dec.albedo_chw, dec.transport_chw, sweep[:k]))
            rows.append(row("shade", "numpy", t, batch=k))
    if "compose" in sections:
        lit = sweep[0]
        rows.append(row("compose", "numpy", timed(compose_step(relighter, dec, lit))))
    if "decompose" in sections:
        rows.append(row("decompose", backend, timed(lambda: relighter.decompose(img, mask))))
    if "end_to_end" in sections:
        rows.append(row("end_to_end", backend, timed(lambda: relighter.relight(img, sweep[0], mask=mask))))
    if "sweep" in sections and relighter.stage2 is not None:
        for b in batches:
            t = timed(lambda b=b: relighter.relight_many(dec, sweep, batch_size=b))
            rows.append(row("sweep", backend, t, batch=b, items=n_lights, lights=n_lights))
    if "video" in sections:
        clip = [(photo(r, r, seed=i), mask) for i in range(frames)]
        light = sweep[0]

        def video() -> None:
            for frame, m in clip:
                relighter.relight(frame, light, mask=m)

        rows.append(row("video", backend, timed(video), items=frames, frames=frames))

    config = {
        "models": str(models),
        "device": device,
        "precision": precision,
        "graphs": [m.name for m in (relighter.stage1, relighter.stage2) if m is not None],
        "providers": relighter.stage1.session.get_providers() if relighter.stage1.session is not None else None,
        "resolution": r,
        "stage1_source": relighter.stage1.config.source,
        "diffuse_only": relighter.diffuse_only,
        "batches": list(batches),
        "lights": n_lights,
        "frames": frames,
        "repeats": repeats,
        "warmup": warmup,
        "load_ms": load_ms,
        "threads": environment.threads() or "default",
    }
    return {"system": system_info(), "config": config, "rows": rows}


# ------------------------------------------------------------------------------------------- report


def _key(r: dict) -> tuple:
    return r["section"], r["batch"], r["items"]


def to_markdown(report: dict, title: str | None = None) -> str:
    """A markdown table of a report's rows; when some rows have backend "torch", a speed-up column.

    The speed-up of a row is (torch's median) / (this row's median) for the same section, batch and items:
    above 1 means this backend is faster than torch.
    """
    rows = report["rows"]
    lines = [f"### {title}", ""] if title else []
    cfg = report.get("config", {})
    if cfg:
        lines += [f"resolution {cfg.get('resolution')}, device {cfg.get('device')}, repeats {cfg.get('repeats')} "
                  f"after {cfg.get('warmup')} warm-up, threads {cfg.get('threads')}", ""]  # fmt: skip
    ref = {_key(r): r for r in rows if r["backend"] == "torch"}
    has_ratio = any(r["backend"] not in ("torch", "numpy") and _key(r) in ref for r in rows)
    head = "| section | batch | items | backend | median ms | min–max ms | ms / item | items / s | peak RSS MiB |"
    sep = "|---|---:|---:|---|---:|---:|---:|---:|---:|"
    if has_ratio:
        head += " speed-up vs torch |"
        sep += "---:|"
    lines += [head, sep]
    for r in rows:
        cells = [r["section"], str(r["batch"]), str(r["items"]), r["backend"], f"{r['median_ms']:.1f}",
                 f"{r['min_ms']:.1f}–{r['max_ms']:.1f}", f"{r['per_item_ms']:.1f}", f"{r['items_per_s']:.2f}",
                 f"{r['peak_mb']:.0f}"]  # fmt: skip
        if has_ratio:
            other = ref.get(_key(r))
            ratio = other["median_ms"] / r["median_ms"] if other is not None and r["backend"] != "torch" else None
            cells.append(f"{ratio:.2f}×" if ratio is not None else "")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------------------------------- files


def write_text(path: str | os.PathLike, text: str) -> Path:
    """Write a text file atomically (temporary file beside it, then rename)."""
    from ..engine.files import write_bytes

    return write_bytes(path, text.encode())


# ------------------------------------------------------------------------------------------- the command


def _ints(text: str) -> list[int]:
    try:
        values = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated whole numbers, got {text!r}") from None
    if not values or min(values) < 1:
        raise argparse.ArgumentTypeError(f"expected positive whole numbers, got {text!r}")
    return values


def _add_arguments(p: argparse.ArgumentParser) -> None:
    sections = SECTIONS
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
    report = run(models, device=args.device, sections=sections, batches=args.batches, n_lights=args.lights,
                 frames=args.frames, repeats=args.repeats, warmup=args.warmup, precision=args.precision)
    text = to_markdown(report)
    if args.json:
        write_text(args.json, json.dumps(report, indent=1) + "\n")
    if args.markdown:
        write_text(args.markdown, text)
    sys.stdout.write(text)
    return 0
