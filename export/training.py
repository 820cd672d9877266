"""The training loop shared by stage 1 and stage 2: device, seeds, resume, time budget, logs.

A run folder holds ``last.pt`` (written at the end of every epoch and when the time budget runs
out), ``best.pt`` (lowest validation loss, or lowest training loss without a validation split),
``log.jsonl`` (one JSON object per line: ``{"event": "step", ...}`` every ``log_every`` steps and
``{"event": "epoch", ...}`` per epoch) and ``args.json``.

Checkpoints are :func:`export.checkpoint.save_checkpoint` files whose extra entries are the
epoch, the step inside the epoch (non-zero only when the time budget stopped a run mid-epoch),
the optimizer and scheduler states and the torch RNG state. The data order and augmentation are
a pure function of (seed, epoch, index) (see :mod:`export.torch_data`), so a resumed run repeats
exactly the steps an uninterrupted run would have taken (on the CPU the weights match bit for bit).

The learning rate follows torch's ``CosineAnnealingWarmRestarts`` stepped with the fractional
epoch ``epoch + i / steps_per_epoch`` at every step.
"""

from __future__ import annotations

import contextlib
import json
import logging
import math
import os
import random
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from relight_rt import RelightError

from .torch_data import epoch_order

log = logging.getLogger(__name__)


def pick_device(name: str = "auto") -> torch.device:
    """``auto`` -> CUDA when available, else CPU; otherwise the named device."""
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    return torch.device(name)


def autocast(device: torch.device, enabled: bool = True):
    """Mixed precision on CUDA (bfloat16 when supported, which needs no gradient scaler), nothing on CPU."""
    if device.type != "cuda" or not enabled:
        return contextlib.nullcontext()
    dtype = torch.bfloat16 if torch.cuda.is_bf16_supported() else torch.float16
    return torch.autocast("cuda", dtype=dtype)


def seed_all(seed: int) -> None:
    """Seed Python, numpy and torch (CPU and CUDA)."""
    random.seed(seed)
    np.random.seed(seed % 2**32)  # noqa: NPY002  (third-party code may draw from the legacy global)
    torch.manual_seed(seed)


def write_json(path: Path, obj) -> None:
    """Write JSON atomically (temporary file beside it, then rename)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    with os.fdopen(fd, "w") as f:
        json.dump(obj, f, indent=2, default=str)
        f.write("\n")
    os.replace(tmp, path)


class JsonlLog:
    """Append-only JSON-lines log (one flushed line per record)."""

    def __init__(self, path: Path):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)

    def write(self, record: dict) -> None:
        with open(self.path, "a") as f:
            f.write(json.dumps(record, default=float) + "\n")


def read_jsonl(path: Path) -> list[dict]:
    """All records of a JSON-lines log."""
    with open(path) as f:
        return [json.loads(line) for line in f if line.strip()]


def collate(items: Sequence[dict]) -> dict:
    """Stack a list of dataset items (tensors stacked, ints as a tensor, other values as a list)."""
    out = {}
    for key in items[0]:
        vals = [it[key] for it in items]
        if isinstance(vals[0], torch.Tensor):
            out[key] = torch.stack(vals)
        elif isinstance(vals[0], int):
            out[key] = torch.tensor(vals)
        else:
            out[key] = vals
    return out


def to_device(batch: dict, device: torch.device) -> dict:
    return {k: v.to(device, non_blocking=True) if isinstance(v, torch.Tensor) else v for k, v in batch.items()}


def add_loop_arguments(parser, *, epochs: int, lr_max: float = 1e-3, lr_min: float = 1e-4) -> None:
    """The flags every training command shares."""
    g = parser.add_argument_group("training loop")
    g.add_argument("--out", required=True, help="run folder (checkpoints, logs)")
    g.add_argument("--epochs", type=int, default=epochs, help="number of epochs (default %(default)s)")
    g.add_argument("--max-minutes", type=float, default=None, help="stop cleanly (and checkpoint) after this time")
    g.add_argument("--max-steps", type=int, default=None, help="stop after this many optimiser steps in this call")
    g.add_argument("--batch-size", type=int, default=1, help="batch size (paper: 1; default %(default)s)")
    g.add_argument("--lr", type=float, default=lr_max, help="peak learning rate (default %(default)s)")
    g.add_argument("--lr-min", type=float, default=lr_min, help="final learning rate (default %(default)s)")
    g.add_argument("--seed", type=int, default=0, help="seed of weights, data order and augmentation")
    g.add_argument("--device", default="auto", help="auto (CUDA when present), cpu, cuda, cuda:1, ...")
    g.add_argument("--no-amp", action="store_true", help="no mixed precision on CUDA")
    g.add_argument("--workers", type=int, default=0,
                   help="data-loader processes (0 is best on a CPU: each keeps its own cache; default %(default)s)")
    g.add_argument("--threads", type=int, default=None, help="torch CPU threads (default: torch's choice)")
    g.add_argument("--log-every", type=int, default=50, help="write a step record every N steps")
    g.add_argument("--resume", action="store_true", help="continue from RUN/last.pt")
    g.add_argument("--export-onnx", action="store_true", help="export best.pt to RUN/<kind>.onnx at the end")


@dataclass(frozen=True, kw_only=True)
class LoopOptions:
    """The settings of :func:`add_loop_arguments`, shared by every training command's config."""

    out: Path
    epochs: int = 60
    max_minutes: float | None = None
    max_steps: int | None = None
    batch_size: int = 1
    lr: float = 1e-3
    lr_min: float = 1e-4
    seed: int = 0
    device: str = "auto"
    no_amp: bool = False
    workers: int = 0
    threads: int | None = None
    log_every: int = 50
    resume: bool = False
    export_onnx: bool = False

    def __post_init__(self) -> None:
        if self.epochs < 1 or self.batch_size < 1:
            raise RelightError(f"--epochs and --batch-size: expected >= 1, got {self.epochs} and {self.batch_size}")


@dataclass
class LoopConfig:
    """Settings of one call of :func:`train_loop` (see :func:`add_loop_arguments`)."""

    out: Path
    epochs: int
    batch_size: int = 1
    lr: float = 1e-3
    lr_min: float = 1e-4
    restart_epochs: int | None = None  # None: one cosine over all epochs
    max_minutes: float | None = None
    max_steps: int | None = None
    seed: int = 0
    workers: int = 0
    log_every: int = 50
    resume: bool = False
    device: torch.device = field(default_factory=lambda: torch.device("cpu"))
    amp: bool = True
    progress: bool = True

    @classmethod
    def from_options(cls, options: LoopOptions, restart_epochs: int | None = None) -> LoopConfig:
        if options.threads:
            torch.set_num_threads(options.threads)
        return cls(
            out=Path(options.out),
            epochs=options.epochs,
            batch_size=options.batch_size,
            lr=options.lr,
            lr_min=options.lr_min,
            restart_epochs=restart_epochs,
            max_minutes=options.max_minutes,
            max_steps=options.max_steps,
            seed=options.seed,
            workers=options.workers,
            log_every=max(1, options.log_every),
            resume=options.resume,
            device=pick_device(options.device),
            amp=not options.no_amp,
        )


def _rng_state() -> dict:
    state = {"torch_rng": torch.get_rng_state()}
    if torch.cuda.is_available():
        state["cuda_rng"] = torch.cuda.get_rng_state_all()
    return state


def _set_rng_state(ckpt: dict) -> None:
    if "torch_rng" in ckpt:
        torch.set_rng_state(ckpt["torch_rng"])
    if "cuda_rng" in ckpt and torch.cuda.is_available():
        with contextlib.suppress(RuntimeError):
            torch.cuda.set_rng_state_all(ckpt["cuda_rng"])


def load_raw_checkpoint(path: Path) -> dict:
    """The whole checkpoint dict (weights_only=True)."""
    try:
        return torch.load(path, map_location="cpu", weights_only=True)
    except (OSError, RuntimeError) as exc:
        raise RelightError(f"could not read checkpoint {path}: {exc}") from None


StepFn = Callable[[torch.nn.Module, dict], dict]  # (model, batch on device) -> dict of scalar tensors incl. "total"


def train_loop(
    model: torch.nn.Module,
    optimizer: torch.optim.Optimizer,
    dataset,
    step_fn: StepFn,
    cfg: LoopConfig,
    *,
    val_fn: Callable[[torch.nn.Module], float] | None = None,
    meta: dict | None = None,
) -> dict:
    """Train ``model`` for ``cfg.epochs`` epochs (or until the time/step budget), checkpointing in ``cfg.out``.

    Args:
        model: the network (already on ``cfg.device``).
        optimizer: its optimizer; its learning rate is driven by a cosine schedule.
        dataset: map-style dataset of dict items with ``set_epoch(epoch)``.
        step_fn: loss of one batch; must return a dict of scalar tensors with key ``total``.
        cfg: loop settings.
        val_fn: validation loss of the model (called in eval mode, no grad) after each epoch.
        meta: extra JSON-able values stored in every checkpoint as ``meta`` (a JSON string).

    Returns:
        Summary dict: epochs_done, steps, stopped ("done" | "time" | "steps"), best, last_loss, seconds,
        steps_per_s.
    """
    from .checkpoint import save_checkpoint

    out = cfg.out
    out.mkdir(parents=True, exist_ok=True)
    last_path, best_path = out / "last.pt", out / "best.pt"
    for group in optimizer.param_groups:
        group["lr"] = cfg.lr
        group["initial_lr"] = cfg.lr
    restart = cfg.restart_epochs or cfg.epochs
    scheduler = torch.optim.lr_scheduler.CosineAnnealingWarmRestarts(optimizer, T_0=restart, eta_min=cfg.lr_min)

    start_epoch, start_step, global_step, best = 0, 0, 0, math.inf
    if last_path.exists():
        if not cfg.resume:
            raise RelightError(f"{out} already holds last.pt: pass --resume to continue it, or choose a new --out")
        ckpt = load_raw_checkpoint(last_path)
        _check_same_activation(model, ckpt, last_path)
        model.load_state_dict(ckpt["state_dict"])
        optimizer.load_state_dict(ckpt["optimizer"])
        scheduler.load_state_dict(ckpt["scheduler"])
        _set_rng_state(ckpt)
        start_epoch, start_step = int(ckpt["epoch"]), int(ckpt["step"])
        global_step, best = int(ckpt["global_step"]), float(ckpt["best"])
        log.info("resuming %s at epoch %d step %d", last_path, start_epoch, start_step)
    else:
        seed_all(cfg.seed)

    logger = JsonlLog(out / "log.jsonl")
    meta_text = json.dumps(meta or {}, default=str)
    n = len(dataset)
    steps_per_epoch = math.ceil(n / cfg.batch_size)
    t0 = time.monotonic()
    steps_here = 0
    stopped = "done"
    last_loss = math.nan

    def save(path: Path, epoch: int, step: int) -> None:
        save_checkpoint(
            path,
            model,
            epoch=epoch,
            step=step,
            global_step=global_step,
            best=best,
            optimizer=optimizer.state_dict(),
            scheduler=scheduler.state_dict(),
            seed=cfg.seed,
            meta=meta_text,
            **_rng_state(),
        )

    tqdm = _tqdm()
    epoch = start_epoch
    for epoch in range(start_epoch, cfg.epochs):
        dataset.set_epoch(epoch)
        order = epoch_order(n, cfg.seed, epoch)
        batches = [order[i : i + cfg.batch_size].tolist() for i in range(0, n, cfg.batch_size)]
        first = start_step if epoch == start_epoch else 0
        loader = torch.utils.data.DataLoader(
            dataset, batch_sampler=batches[first:], num_workers=cfg.workers, collate_fn=collate
        )
        model.train()
        sums: dict[str, float] = {}
        count = 0
        bar = tqdm(loader, total=len(batches) - first, desc=f"epoch {epoch + 1}/{cfg.epochs}", leave=False,
                   disable=not cfg.progress or None)
        step = first
        for step, batch in enumerate(bar, start=first):
            scheduler.step(epoch + step / steps_per_epoch)
            batch = to_device(batch, cfg.device)
            optimizer.zero_grad(set_to_none=True)
            with autocast(cfg.device, cfg.amp):
                terms = step_fn(model, batch)
            loss = terms["total"]
            if not torch.isfinite(loss):
                raise RelightError(f"training diverged: loss {loss.item()} at epoch {epoch} step {step}")
            loss.backward()
            optimizer.step()
            global_step += 1
            steps_here += 1
            values = {k: float(v.detach()) for k, v in terms.items()}
            last_loss = values["total"]
            for k, v in values.items():
                sums[k] = sums.get(k, 0.0) + v
            count += 1
            bar.set_postfix(loss=f"{last_loss:.4f}")
            elapsed = time.monotonic() - t0
            if global_step % cfg.log_every == 0:
                logger.write({"event": "step", "epoch": epoch, "step": step, "global_step": global_step,
                              "lr": optimizer.param_groups[0]["lr"], "elapsed_s": elapsed,
                              "steps_per_s": steps_here / max(elapsed, 1e-9), **values})
            out_of_time = cfg.max_minutes is not None and elapsed > 60.0 * cfg.max_minutes
            out_of_steps = cfg.max_steps is not None and steps_here >= cfg.max_steps
            if (out_of_time or out_of_steps) and step + 1 < len(batches):
                stopped = "time" if out_of_time else "steps"
                save(last_path, epoch, step + 1)
                break
        bar.close()
        if stopped != "done":
            break
        means = {k: v / max(count, 1) for k, v in sums.items()}
        val = None
        if val_fn is not None:
            model.eval()
            with torch.no_grad(), autocast(cfg.device, cfg.amp):
                val = float(val_fn(model))
            model.train()
        score = val if val is not None else means.get("total", math.inf)
        improved = score < best
        if improved:
            best = score
        elapsed = time.monotonic() - t0
        logger.write({"event": "epoch", "epoch": epoch, "global_step": global_step, "elapsed_s": elapsed,
                      "lr": optimizer.param_groups[0]["lr"], "val": val, "best": best,
                      "train": means})
        log.info("epoch %d/%d: train %.4f%s (%.0f s)", epoch + 1, cfg.epochs, means.get("total", math.nan),
                 "" if val is None else f", val {val:.4f}", elapsed)
        save(last_path, epoch + 1, 0)
        if improved:
            save(best_path, epoch + 1, 0)
        out_of_time = cfg.max_minutes is not None and elapsed > 60.0 * cfg.max_minutes
        out_of_steps = cfg.max_steps is not None and steps_here >= cfg.max_steps
        if (out_of_time or out_of_steps) and epoch + 1 < cfg.epochs:
            stopped = "time" if out_of_time else "steps"
            epoch += 1
            break
    else:
        epoch = cfg.epochs
    seconds = time.monotonic() - t0
    if not best_path.exists() and last_path.exists():  # stopped before the first epoch ended
        import shutil

        shutil.copyfile(last_path, best_path)
    summary = {"epochs_done": epoch, "steps": steps_here, "global_step": global_step, "stopped": stopped,
               "best": best, "last_loss": last_loss, "seconds": seconds,
               "steps_per_s": steps_here / max(seconds, 1e-9)}
    logger.write({"event": "end", **summary})
    return summary


def _tqdm():
    try:
        from tqdm import tqdm
    except ImportError:  # progress bars are optional

        class tqdm:  # noqa: N801
            def __init__(self, iterable, **kwargs):
                self.iterable = iterable

            def __iter__(self):
                return iter(self.iterable)

            def set_postfix(self, **kwargs):
                pass

            def close(self):
                pass

    return tqdm


def _check_same_activation(model: torch.nn.Module, ckpt: dict, path: Path) -> None:
    """A resumed run must keep the output activation it was trained with (the weights depend on it)."""
    from .checkpoint import LEGACY_OUTPUT_ACTIVATION

    want = getattr(model, "output_activation", None)
    if want is None:
        return
    config = ckpt.get("config") if isinstance(ckpt.get("config"), dict) else {}
    saved = config.get("output_activation", LEGACY_OUTPUT_ACTIVATION)
    if saved != want:
        raise RelightError(
            f"{path}: this run was trained with output activation {saved!r}; resuming asks for {want!r} "
            f"(pass --output-activation {saved})"
        )


def export_best(out: Path, kind: str, source: str) -> Path:
    """Export ``out/best.pt`` to ``out/<kind>.onnx`` with :func:`export.onnx_export.export_onnx`."""
    from .checkpoint import load_checkpoint
    from .onnx_export import export_onnx

    model, _ = load_checkpoint(out / "best.pt")
    model.eval()
    path = out / f"{kind}.onnx"
    summary = export_onnx(model, path, source=source)
    log.info("exported %s: %s", path, summary)
    return path
