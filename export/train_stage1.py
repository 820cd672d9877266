"""``python -m export train-stage1``: train the stage-1 inverse-rendering network.

Every step renders its own input from a sample and a random training light (see
:mod:`export.torch_data`), runs the network on ``(2·image − 1)·mask`` and minimises the sum of
the terms of :class:`export.losses.Stage1Loss` (all weight 1). Adam with betas (0.5, 0.999);
learning rate cosine-annealed from ``--lr`` to ``--lr-min`` with warm restarts every
``--restart-epochs`` epochs (the paper: 1e-3 → 1e-4, every 20 epochs).

Normalisation (``--norm``): "batch" trains with batch statistics and exports running statistics
(fast, standard, but with the paper's batch size of 1 the running statistics average over very
different single images, so eval-mode outputs can drift from training-mode ones); "instance"
uses per-sample statistics in training and at inference (what the reference effectively did at
inference; robust at batch size 1, a little slower, and every image is normalised on its own,
which removes some absolute-brightness information the light head could use). Use "instance"
with --batch-size 1, "batch" with batches of 4 or more.

Example::

    python -m export train-stage1 --data data/train --lights data/lights --out runs/s1 \\
        --resolution 128 --width 16 --epochs 40 --max-minutes 60 --export-onnx
"""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from relight_rt import RelightError

from .config import as_record, reader
from .losses import Stage1Loss
from .torch_data import Stage1Dataset, render_input
from .training import (
    LoopConfig,
    LoopOptions,
    add_loop_arguments,
    collate,
    export_best,
    to_device,
    train_loop,
    write_json,
)

log = logging.getLogger(__name__)


def add_arguments(parser) -> None:
    parser.add_argument("--data", required=True, help="folder of stage-1 samples (NAME_tex.png, ...)")
    parser.add_argument("--lights", required=True, help="folder of training lights (NAME.npy, BGR (9,3))")
    parser.add_argument("--resolution", type=int, default=256, help="training size, k·64 (default %(default)s)")
    parser.add_argument("--width", type=int, default=64, help="base channel count (reference: 64; default %(default)s)")
    parser.add_argument("--norm", choices=("batch", "instance"), default="batch",
                        help="normalisation layers (see the module docs for the tradeoff; default %(default)s)")
    parser.add_argument("--no-sf", action="store_true", help="drop the spatial-frequency loss (the ablation baseline)")
    parser.add_argument("--sf-scale", type=float, default=1.0,
                        help="factor on the SF band weights (1 = paper's 600…10; default %(default)s)")
    parser.add_argument("--band-weight", type=float, default=0.0,
                        help="weight of a loss on the transport's degree-1 and degree-2 band magnitudes, per pixel "
                             "(export.losses.band_magnitude_loss; 0: off, the paper's objective; default %(default)s)")
    parser.add_argument("--direction-weight", type=float, default=0.0,
                        help="weight of a loss on the direction of the transport's degree-1 band, per pixel "
                             "(export.losses.direction_loss; 0: off; default %(default)s)")
    parser.add_argument("--no-flip", action="store_true", help="no horizontal-flip augmentation")
    parser.add_argument("--restart-epochs", type=int, default=20, help="cosine restart period (default %(default)s)")
    parser.add_argument("--val-fraction", type=float, default=0.05,
                        help="fraction of the samples held out for validation (0: none; default %(default)s)")
    parser.add_argument("--no-cache", action="store_true", help="re-read samples from disk every epoch")
    parser.add_argument("--init", help="start from these weights (a .pt checkpoint or a shipped stage-1 .onnx; "
                                       "fine-tuning, see export.warm_start); ignored when resuming")
    add_loop_arguments(parser, epochs=60)


@dataclass(frozen=True, kw_only=True)
class TrainStage1Config(LoopOptions):
    """The settings of ``train-stage1`` (one field per flag; see :func:`add_arguments`)."""

    data: Path
    lights: Path
    resolution: int = 256
    width: int = 64
    norm: str = "batch"
    no_sf: bool = False
    sf_scale: float = 1.0
    band_weight: float = 0.0
    direction_weight: float = 0.0
    no_flip: bool = False
    restart_epochs: int = 20
    val_fraction: float = 0.05
    no_cache: bool = False
    init: Path | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.resolution % 64 or self.resolution < 64:
            raise RelightError(f"--resolution: expected a positive multiple of 64, got {self.resolution}")
        if not self.band_weight >= 0:
            raise RelightError(f"--band-weight: expected a weight >= 0, got {self.band_weight}")
        if not self.direction_weight >= 0:
            raise RelightError(f"--direction-weight: expected a weight >= 0, got {self.direction_weight}")


config_from_args = reader(TrainStage1Config)


def split_names(names: list[str], fraction: float, seed: int) -> tuple[list[str], list[str]]:
    """Deterministic (train, val) split of sample names; val is empty when fraction is 0 or too few samples."""
    n_val = int(round(len(names) * fraction)) if fraction > 0 else 0
    if n_val == 0 or n_val >= len(names):
        return list(names), []
    order = np.random.default_rng([seed, 7]).permutation(len(names))
    val = sorted(names[i] for i in order[:n_val])
    return [n for n in names if n not in set(val)], val


def stage1_step(loss_fn: Stage1Loss):
    """The loss of one batch: render the input, run the network, all Stage1Loss terms."""

    def step(model: torch.nn.Module, batch: dict) -> dict:
        mask = batch["mask"]
        image = render_input(batch)
        transport, albedo, skin, light = model((2.0 * image - 1.0) * mask)
        pred = {"transport": transport, "albedo": albedo, "skin": skin, "light": light}
        return loss_fn(pred, batch)

    return step


def validation_fn(dataset: Stage1Dataset, loss_fn: Stage1Loss, device: torch.device, batch_size: int):
    """Mean total loss over a fixed-light, unflipped validation set."""
    step = stage1_step(loss_fn)

    def val(model: torch.nn.Module) -> float:
        total, count = 0.0, 0
        for i in range(0, len(dataset), batch_size):
            batch = to_device(collate([dataset[j] for j in range(i, min(i + batch_size, len(dataset)))]), device)
            total += float(step(model, batch)["total"]) * len(batch["index"])
            count += len(batch["index"])
        return total / max(count, 1)

    return val


def warm_start(model: torch.nn.Module, path: str, dataset: Stage1Dataset, device: torch.device,
               batch_size: int, batches: int = 8) -> str:
    """Load ``path`` into ``model`` and re-measure its norm statistics on training inputs (export.warm_start)."""
    from .warm_start import calibrate_norms, load_init

    source = load_init(model, path)
    dataset.set_epoch(0)
    n = min(len(dataset), batches * batch_size)

    def inputs():
        for i in range(0, n, batch_size):
            batch = to_device(collate([dataset[j] for j in range(i, min(i + batch_size, n))]), device)
            yield (2.0 * render_input(batch) - 1.0) * batch["mask"]

    calibrate_norms(model, inputs())
    log.info("stage 1 starts from %s", source)
    return source


def run(config: TrainStage1Config) -> int:
    from . import dataset
    from .networks import Stage1Net

    cfg = LoopConfig.from_options(config, restart_epochs=config.restart_epochs)
    lights = dataset.read_lights(config.lights)
    names = dataset.list_samples(config.data)
    if not names:
        raise RelightError(f"--data {config.data}: no stage-1 samples found")
    train_names, val_names = split_names(names, config.val_fraction, config.seed)
    log.info("stage 1: %d training samples, %d validation, %d lights, %d² px, width %d, norm %s, SF %s",
             len(train_names), len(val_names), len(lights), config.resolution, config.width, config.norm,
             "off" if config.no_sf else "on")
    cache = not config.no_cache
    train_set = Stage1Dataset(config.data, lights, config.resolution, train_names, augment=True, seed=config.seed,
                              cache=cache, flip=not config.no_flip)
    torch.manual_seed(config.seed)
    model = Stage1Net(width=config.width, resolution=config.resolution, norm=config.norm).to(cfg.device)
    init = None
    if config.init and not (config.resume and (Path(config.out) / "last.pt").exists()):
        init = warm_start(model, config.init, train_set, cfg.device, max(config.batch_size, 2))
    loss_fn = Stage1Loss(use_sf=not config.no_sf, sf_scale=config.sf_scale, band_weight=config.band_weight,
                         direction_weight=config.direction_weight).to(cfg.device)
    optimizer = torch.optim.Adam(model.parameters(), lr=config.lr, betas=(0.5, 0.999))
    val_fn = None
    if val_names:
        val_set = Stage1Dataset(config.data, lights, config.resolution, val_names, augment=False, seed=config.seed,
                                cache=cache)
        val_fn = validation_fn(val_set, loss_fn, cfg.device, max(config.batch_size, 1))
    out = Path(config.out)
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "args.json", {**as_record(config), "command": "train-stage1", "val_names": val_names})
    meta = {"command": "train-stage1", "data": str(config.data), "sf": not config.no_sf, "sf_scale": config.sf_scale,
            "band_weight": config.band_weight, "direction_weight": config.direction_weight, "init": init}
    summary = train_loop(model, optimizer, train_set, stage1_step(loss_fn), cfg, val_fn=val_fn, meta=meta)
    log.info("stage 1 finished: %s", json.dumps(summary))
    if config.export_onnx:
        source = f"relight_rt train-stage1 on {config.data} ({summary['epochs_done']} epochs, width {config.width})"
        export_best(out, "stage1", source)
    return 0
