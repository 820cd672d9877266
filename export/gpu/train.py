"""``python -m export gpu-train``: render stage-1 samples from a bank and train stage 1 on them until a deadline.

Made for a lent GPU that starts bare (torch, numpy, onnx, onnxruntime and OpenCV; no anny, no embree) and is
held for minutes: everything it needs is the checkout and a bank folder (``python -m export gpu-bank``).
It renders samples on the training device (:mod:`export.gpu.render`) into a pool that every step refreshes
in part (up to ``--fresh-per-step`` samples, while rendering has taken at most ``--render-share`` of the
time: whichever of rendering and training is faster on the device, neither starves the other), trains
on random batches of the pool, each sample under a random training light of the bank and flipped at random
(as export.torch_data does), with the loss of ``train-stage1`` (by default with the shipped stage 1's band and
direction terms, ``--band-weight 2 --direction-weight 5``; with ``--albedo-anchor W`` also W times the mean
absolute difference, over the person, between the albedo and that of the frozen warm start on the same batch) and
Adam, the learning rate falling along one cosine from ``--lr`` to ``--lr-min`` over the time there is. It starts
from the shipped stage 1 (export.warm_start) unless told otherwise. The last ``--val-people`` people of the bank
are held out of training (:mod:`export.gpu.validate`): their relit RMSE and loss are measured before the first
step and every ``--val-every`` seconds, and the weights of the lowest ``--val-metric`` are the ones exported
(``best.pt``; ``last.pt`` holds the last).

Whatever happens, the run folder ends with ``stage1.onnx`` (the best weights on the held-out people, or the
last ones without any, exported with the usual checks), ``last.pt`` and ``best.pt`` (weights only: under 16 MiB
each, so they come back from the device), ``log.jsonl`` and ``summary.json`` (which step won): training stops
``--export-reserve`` seconds before ``--deadline`` (counted from the start of the command) to leave time for
that, and a SIGTERM or an error stops it early the same way.
A checkpoint is written every ``--checkpoint-every`` seconds.

Example (CPU rehearsal; the device call is in docs/GPU.md)::

    python -m export gpu-train --bank data/gpu_bank --out runs/gpu --deadline 60 --dirs 16 --shadow-size 64
"""

from __future__ import annotations

import argparse
import copy
import hashlib
import json
import logging
import math
import signal
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from relight_rt import RelightError

from .validate import Best, HeldOut, split_people

log = logging.getLogger(__name__)

DEFAULT_FRAMINGS = "full=0.4,knees-up=0.15,waist-up=0.15,head-shoulders=0.15,face=0.15"
SHIPPED_STAGE1 = Path(__file__).resolve().parents[2] / "relight_rt" / "models" / "stage1.onnx"


@dataclass(frozen=True)
class GpuTrainConfig:
    """Settings of one ``gpu-train`` run (see add_arguments for each)."""

    out: Path
    bank: Path = Path("data/gpu_bank")
    deadline: float = 540.0
    init: Path | None = SHIPPED_STAGE1
    resolution: int = 256
    width: int = 16
    batch_size: int = 16
    pool: int = 512
    fresh_per_step: int = 4
    render_share: float = 0.5
    dirs: int = 128
    shadow_size: int = 256
    framings: str = DEFAULT_FRAMINGS
    max_yaw: float = 45.0
    lr: float = 3e-4
    lr_min: float = 3e-5
    sf_scale: float = 0.2
    band_weight: float = 2.0  # the shipped stage 1's recipe (models/README.md): without them the bands shrink
    direction_weight: float = 5.0
    albedo_anchor: float = 0.0  # 0: off (the second lend's objective exactly)
    val_people: int = 4
    val_samples: int = 32
    val_every: float = 30.0
    val_metric: str = "relit_rmse"
    seed: int = 0
    device: str = "auto"
    checkpoint_every: float = 60.0
    export_reserve: float = 45.0
    max_steps: int | None = None
    log_every: int = 10
    amp: bool = True


def add_arguments(parser: argparse.ArgumentParser) -> None:
    d = GpuTrainConfig(out=Path())
    parser.add_argument("--bank", type=Path, default=d.bank,
                        help="bank folder (python -m export gpu-bank; default %(default)s)")
    parser.add_argument("--out", type=Path, required=True, help="run folder: stage1.onnx, last.pt, log.jsonl, "
                                                                  "summary.json")
    parser.add_argument("--deadline", type=float, default=d.deadline,
                        help="seconds from the start until everything is written (default %(default)s)")
    parser.add_argument("--init", default=str(d.init),
                        help="start from these weights (.onnx or .pt); 'none' starts from random weights "
                             "(default: the shipped stage 1)")
    parser.add_argument("--resolution", type=int, default=d.resolution, help="sample and network size (k·64)")
    parser.add_argument("--width", type=int, default=d.width, help="network base width (shipped: 16)")
    parser.add_argument("--batch-size", type=int, default=d.batch_size)
    parser.add_argument("--pool", type=int, default=d.pool, help="rendered samples kept on the device")
    parser.add_argument("--fresh-per-step", type=int, default=d.fresh_per_step,
                        help="at most this many samples rendered into the pool before each step")
    parser.add_argument("--render-share", type=float, default=d.render_share,
                        help="a step renders fresh samples only while rendering has taken at most this share of "
                             "the time spent rendering and training (1: always; default %(default)s)")
    parser.add_argument("--dirs", type=int, default=d.dirs, help="visibility directions per sample")
    parser.add_argument("--shadow-size", type=int, default=d.shadow_size, help="depth-map side per direction")
    parser.add_argument("--framings", default=d.framings, help="framings and weights (as render --framings)")
    parser.add_argument("--max-yaw", type=float, default=d.max_yaw, help="largest turn of a subject, degrees")
    parser.add_argument("--lr", type=float, default=d.lr, help="first learning rate")
    parser.add_argument("--lr-min", type=float, default=d.lr_min, help="learning rate at the deadline")
    parser.add_argument("--sf-scale", type=float, default=d.sf_scale, help="factor on the SF loss bands")
    parser.add_argument("--band-weight", type=float, default=d.band_weight,
                        help="weight of the transport band-magnitude loss (as train-stage1; default %(default)s, the "
                             "shipped stage 1's: without it the degree-2 band shrinks)")
    parser.add_argument("--direction-weight", type=float, default=d.direction_weight,
                        help="weight of the degree-1 direction loss (as train-stage1; default %(default)s)")
    parser.add_argument("--albedo-anchor", type=float, default=d.albedo_anchor,
                        help="W: add W * mean |albedo - the warm start's albedo| over the person, the warm start "
                             "frozen and run on the same batch (the second lend's albedo lost on real faces while "
                             "its transport gained; 0: off, default %(default)s)")
    parser.add_argument("--val-people", type=int, default=d.val_people,
                        help="the bank's last N people are never trained on: the exported weights are those of "
                             "their lowest --val-metric (0: none held out, the last weights exported; default "
                             "%(default)s)")
    parser.add_argument("--val-samples", type=int, default=d.val_samples,
                        help="validation samples of the held-out people, rendered once (default %(default)s)")
    parser.add_argument("--val-every", type=float, default=d.val_every,
                        help="seconds between validations (default %(default)s)")
    parser.add_argument("--val-metric", choices=("relit_rmse", "loss"), default=d.val_metric,
                        help="the held-out figure whose lowest value picks the exported weights (default "
                             "%(default)s: the first lend lowered the loss on new people without relighting them "
                             "better)")
    parser.add_argument("--seed", type=int, default=d.seed)
    parser.add_argument("--device", default=d.device, help="auto (CUDA when present), cpu, cuda, ...")
    parser.add_argument("--checkpoint-every", type=float, default=d.checkpoint_every, help="seconds")
    parser.add_argument("--export-reserve", type=float, default=d.export_reserve,
                        help="seconds kept before the deadline for the ONNX export and the summary")
    parser.add_argument("--max-steps", type=int, default=None, help="stop after this many steps (tests)")
    parser.add_argument("--log-every", type=int, default=d.log_every, help="a log.jsonl record every N steps")
    parser.add_argument("--no-amp", dest="amp", action="store_false", help="no mixed precision on CUDA")


def config_from_args(args: argparse.Namespace) -> GpuTrainConfig:
    init = None if str(args.init).lower() == "none" else Path(args.init)
    return GpuTrainConfig(
        bank=Path(args.bank), out=Path(args.out), deadline=args.deadline, init=init, resolution=args.resolution,
        width=args.width, batch_size=args.batch_size, pool=args.pool, fresh_per_step=args.fresh_per_step,
        render_share=args.render_share,
        dirs=args.dirs, shadow_size=args.shadow_size, framings=args.framings, max_yaw=args.max_yaw, lr=args.lr,
        lr_min=args.lr_min, sf_scale=args.sf_scale, band_weight=args.band_weight,
        direction_weight=args.direction_weight, albedo_anchor=args.albedo_anchor, val_people=args.val_people,
        val_samples=args.val_samples,
        val_every=args.val_every, val_metric=args.val_metric, seed=args.seed, device=args.device,
        checkpoint_every=args.checkpoint_every, export_reserve=args.export_reserve, max_steps=args.max_steps,
        log_every=max(1, args.log_every), amp=args.amp,
    )


POOL_MAX_BYTES = 96 << 30  # the rendered samples kept on the device (an H200 holds 139 GiB)


def _check(config: GpuTrainConfig) -> None:
    if config.resolution < 64 or config.resolution % 64:
        raise RelightError(f"--resolution: expected a positive multiple of 64, got {config.resolution}")
    for name in ("batch_size", "pool", "fresh_per_step", "dirs", "width"):
        if getattr(config, name) < 1:
            raise RelightError(f"--{name.replace('_', '-')}: expected >= 1, got {getattr(config, name)}")
    from export.render.cli import parse_framings

    from .render import RenderSettings

    try:
        parse_framings(config.framings)
    except argparse.ArgumentTypeError as exc:
        raise RelightError(f"--framings: {exc}") from None
    RenderSettings(resolution=config.resolution, dirs=config.dirs, shadow_size=config.shadow_size, dir_chunk=128)
    pool_bytes = config.pool * 14 * config.resolution**2 * 2  # _Pool: float16
    if pool_bytes > POOL_MAX_BYTES:
        raise RelightError(f"--pool {config.pool} at --resolution {config.resolution} would hold "
                           f"{pool_bytes / 2**30:.0f} GiB, more than {POOL_MAX_BYTES >> 30} GiB; lower one")
    if config.batch_size > config.pool or config.fresh_per_step > config.pool:
        raise RelightError(f"--batch-size {config.batch_size} and --fresh-per-step {config.fresh_per_step}: "
                           f"expected at most --pool {config.pool}")
    if config.pool < config.batch_size:
        raise RelightError(f"--pool {config.pool} must hold at least one batch (--batch-size {config.batch_size})")
    if not 0 < config.render_share <= 1:
        raise RelightError(f"--render-share: expected a share in (0, 1], got {config.render_share}")
    if config.shadow_size < 8:
        raise RelightError(f"--shadow-size: expected >= 8, got {config.shadow_size}")
    if not (config.deadline > 0 and 0 <= config.export_reserve < config.deadline):
        raise RelightError(f"expected --deadline > --export-reserve >= 0, got {config.deadline} and "
                           f"{config.export_reserve}")
    for name in ("lr", "lr_min", "max_yaw", "sf_scale", "checkpoint_every", "export_reserve", "band_weight",
                 "direction_weight", "albedo_anchor", "val_every"):
        if not math.isfinite(getattr(config, name)):
            raise RelightError(f"--{name.replace('_', '-')}: expected a finite number, got {getattr(config, name)}")
    if not (config.checkpoint_every > 0 and config.sf_scale >= 0 and 0 <= config.max_yaw <= 180):
        raise RelightError(f"expected --checkpoint-every > 0, --sf-scale >= 0 and 0 <= --max-yaw <= 180, got "
                           f"{config.checkpoint_every}, {config.sf_scale} and {config.max_yaw}")
    if not (config.band_weight >= 0 and config.direction_weight >= 0):
        raise RelightError(f"expected --band-weight >= 0 and --direction-weight >= 0, got {config.band_weight} and "
                           f"{config.direction_weight}")
    if not config.albedo_anchor >= 0:
        raise RelightError(f"--albedo-anchor: expected a weight >= 0, got {config.albedo_anchor}")
    if config.albedo_anchor > 0 and config.init is None:
        raise RelightError("--albedo-anchor needs a warm start (--init): the albedo is held near the network it "
                           "starts from")
    if config.val_metric not in ("relit_rmse", "loss"):
        raise RelightError(f"--val-metric: expected relit_rmse or loss, got {config.val_metric!r}")
    if config.val_people < 0 or config.val_samples < 1 or not config.val_every > 0:
        raise RelightError(f"expected --val-people >= 0, --val-samples >= 1 and --val-every > 0, got "
                           f"{config.val_people}, {config.val_samples} and {config.val_every}")
    if not (config.lr > 0 and 0 <= config.lr_min <= config.lr):
        raise RelightError(f"expected --lr > 0 and 0 <= --lr-min <= --lr, got {config.lr} and {config.lr_min}")
    out, bank = Path(config.out), Path(config.bank)
    if out.exists() and not out.is_dir():
        raise RelightError(f"--out {out}: a file, not a run folder")
    if out.resolve() == bank.resolve():
        raise RelightError(f"--out {out}: the bank folder itself; give the run a folder of its own")
    if config.init is not None and not config.init.is_file():
        raise RelightError(f"--init {config.init}: no such file")


class _Stop(Exception):
    """Raised by the SIGTERM handler: stop training, then export as at the deadline."""


def _on_sigterm(signum, frame):  # noqa: ARG001  (signal handler signature)
    raise _Stop("SIGTERM")


class _Pool:
    """Rendered samples on the training device: a ring of ``size`` slots, float16, channels
    albedo 3, mask 1, skin 1, transport 9."""

    def __init__(self, size: int, resolution: int, device):
        import torch

        from .render import SAMPLE_CHANNELS

        self.data = torch.zeros((size, SAMPLE_CHANNELS, resolution, resolution), dtype=torch.float16, device=device)
        self.count = 0
        self.next = 0

    def add(self, sample: dict) -> None:
        from .render import pack

        self.data[self.next] = pack(sample)
        self.next = (self.next + 1) % len(self.data)
        self.count = min(self.count + 1, len(self.data))

    def batch(self, index, lights, flips) -> dict:
        """Samples ``index`` with lights (N, 9, 3), flipped where ``flips`` (N,) bool (export.torch_data's flip)."""
        import torch

        from export.losses import FLIP_SIGNS

        from .render import unpack

        x = self.data[index].float()
        x = torch.where(flips[:, None, None, None], x.flip(-1), x)
        signs = torch.tensor(FLIP_SIGNS, device=x.device)
        sign = torch.where(flips[:, None], signs[None], torch.ones_like(signs)[None])
        maps = unpack(x)
        return {**maps, "transport": maps["transport"] * sign[:, :, None, None], "light": lights * sign[:, :, None]}


class _Sampler:
    """Draws (subject, framing, yaw) and renders one sample on the device."""

    def __init__(self, config: GpuTrainConfig, subjects: list, device):
        import torch

        from export.render.cli import parse_framings

        from .render import RenderSettings

        try:
            framings = parse_framings(config.framings)
        except argparse.ArgumentTypeError as exc:
            raise RelightError(f"--framings: {exc}") from None
        self.names = sorted(framings)
        self.weights = np.array([framings[n] for n in self.names])
        self.subjects = subjects
        self.config = config
        cuda = device.type == "cuda"  # room for every direction's depth map at once, and large raster chunks
        self.settings = RenderSettings(resolution=config.resolution, dirs=config.dirs, shadow_size=config.shadow_size,
                                       max_candidates=(1 << 25) if cuda else (1 << 21),
                                       dir_chunk=128 if cuda else 32)
        self.rng = np.random.default_rng([config.seed, 0x6B7])
        self.generator = torch.Generator().manual_seed(config.seed)
        self.rendered = 0
        self.seconds = 0.0
        self.by_framing: dict[str, list[float]] = {n: [0, 0.0] for n in self.names}  # count, seconds

    def __call__(self) -> dict:
        import torch

        from .render import render_sample

        t0 = time.monotonic()
        subject = self.subjects[int(self.rng.integers(len(self.subjects)))]
        framing = str(self.rng.choice(self.names, p=self.weights))
        yaw = float(self.rng.uniform(-self.config.max_yaw, self.config.max_yaw))
        with torch.no_grad():
            sample = render_sample(subject, self.settings, framing=framing, yaw_deg=yaw, generator=self.generator)
        if sample["albedo"].is_cuda:
            torch.cuda.synchronize()
        took = time.monotonic() - t0
        self.rendered += 1
        self.seconds += took
        self.by_framing[framing][0] += 1
        self.by_framing[framing][1] += took
        return sample


def frozen_teacher(model, weight: float):
    """The albedo anchor's teacher: a copy of ``model`` as it is now (the warm start, its norms calibrated), in eval
    mode and without gradients; None when ``weight`` is 0 (no anchor: nothing copied, nothing run)."""
    if not weight > 0:
        return None
    teacher = copy.deepcopy(model).eval()
    teacher.requires_grad_(False)
    return teacher


def step_terms(model, loss_fn, batch: dict, teacher=None, anchor: float = 0.0) -> dict:
    """The training loss of one batch: ``loss_fn``'s terms and, with a teacher, ``albedo_anchor`` = ``anchor`` ·
    mean |Â − Â_teacher| over the person (export.losses.masked_l1; the teacher runs on the same input without
    gradients), added to ``total``. Without a teacher the terms are ``loss_fn``'s alone, as before the anchor."""
    import torch

    from export.losses import masked_l1
    from export.torch_data import render_input

    x = (2.0 * render_input(batch) - 1.0) * batch["mask"]
    transport, albedo, skin, light = model(x)
    terms = loss_fn({"transport": transport, "albedo": albedo, "skin": skin, "light": light}, batch)
    if teacher is not None:
        with torch.no_grad():
            kept = teacher(x)[1]
        terms["albedo_anchor"] = anchor * masked_l1(albedo.float(), kept.float(), batch["mask"].float())
        terms["total"] = terms["total"] + terms["albedo_anchor"]
    return terms


def _load_bank(root: Path, device):
    from . import bank
    from .render import DeviceSubject

    index = bank.read_index(root)
    template = bank.read_template(root)
    subjects = [DeviceSubject.from_data(bank.read_subject(root / f"{n}.npz", template), device)
                for n in index["subjects"]]
    return index, subjects, bank.read_lights(root, index)


def run(config: GpuTrainConfig) -> int:
    """Run ``gpu-train``; returns the exit status (0, or 1 when training stopped on an error)."""
    start = time.monotonic()
    _check(config)
    import torch

    from export.checkpoint import save_checkpoint
    from export.losses import Stage1Loss
    from export.networks import Stage1Net
    from export.torch_data import render_input
    from export.training import JsonlLog, autocast, pick_device

    out = Path(config.out)
    device = pick_device(config.device)
    torch.manual_seed(config.seed)
    index, subjects, lights_np = _load_bank(Path(config.bank), device)
    trained, held = split_people(index["subjects"], config.val_people)  # before the run folder: one error
    subjects, held_subjects = subjects[: len(trained)], subjects[len(trained) :]  # the index's order
    model = Stage1Net(width=config.width, resolution=config.resolution, norm="batch")
    init = None
    if config.init is not None:  # before the run folder, as the bank: a bad --init is one error, not a failed run
        from .. import warm_start

        # on the CPU: load_init checks the unfolded network against onnxruntime with CPU tensors
        init = warm_start.load_init(model, config.init)
    out.mkdir(parents=True, exist_ok=True)
    lights = torch.as_tensor(lights_np, device=device)
    # which training lights: the bank's lights.npy can be swapped (gpu-bank --lights-only); its digest names them
    lights_id = f"{len(lights_np)} lights, sha256 {hashlib.sha256(lights_np.tobytes()).hexdigest()[:12]}"
    logger = JsonlLog(out / "log.jsonl")
    device_name = torch.cuda.get_device_name(device) if device.type == "cuda" else "cpu"
    logger.write({"event": "start", "device": device_name, "torch": torch.__version__, "subjects": len(subjects),
                  "val_people": held, "lights": len(lights_np), "lights_id": lights_id,
                  "config": {k: str(v) for k, v in asdict(config).items()}})
    log.info("gpu-train on %s: %d subjects (%d more held out), %d lights, %d² px, %d directions, depth maps %d²",
             device_name, len(subjects), len(held), len(lights_np), config.resolution, config.dirs, config.shadow_size)

    sampler = _Sampler(config, subjects, device)
    pool = _Pool(config.pool, config.resolution, device)
    loss_fn = Stage1Loss(sf_scale=config.sf_scale, band_weight=config.band_weight,
                         direction_weight=config.direction_weight).to(device)
    rng = torch.Generator(device="cpu").manual_seed(config.seed + 1)

    def draw(n: int) -> dict:
        idx = torch.randint(pool.count, (n,), generator=rng)
        light_idx = torch.randint(len(lights), (n,), generator=rng)
        flips = torch.randint(2, (n,), generator=rng).bool()
        return pool.batch(idx.to(device), lights[light_idx.to(device)], flips.to(device))

    state = {"step": 0, "stopped": "deadline", "losses": [], "train_s": 0.0, "init": init, "error": None,
             "lights_id": lights_id,
             "val": None, "best": Best(), "val_s": 0.0, "val_error": None}

    def validate() -> None:
        """Measure the held-out figures now; keep (and write) the weights when theirs is the lowest so far. A check
        that fails turns the checks off and training goes on (it has never run on the device before a lend: a
        failure there must not cost the run; the weights of the best check so far, or the last, are exported)."""
        t0 = time.monotonic()
        try:
            figures = state["val"].measure(model, loss_fn, config.batch_size, config.amp)
        except _Stop:
            raise
        except Exception as exc:  # noqa: BLE001  (whatever broke, training and its export are worth more)
            state["val_error"] = f"{type(exc).__name__}: {exc}"
            log.error("held-out check failed at step %d, checks off: %s", state["step"], exc)
            return
        if state["best"].offer(model, state["step"], figures[config.val_metric], sampler.rendered):
            meta = {"command": "gpu-train", **{f"val_{k}": v for k, v in figures.items()}}
            save_checkpoint(out / "best.pt", model, step=state["step"], meta=json.dumps(meta))
        state["val_s"] += time.monotonic() - t0
        logger.write({"event": "val", "step": state["step"], "elapsed_s": time.monotonic() - start,
                      **{f"val_{k}": v for k, v in figures.items()}, "best_step": state["best"].step})

    previous = signal.signal(signal.SIGTERM, _on_sigterm)
    stop_at = start + config.deadline - config.export_reserve
    try:
        while pool.count < config.batch_size:
            pool.add(sampler())
        model.to(device)
        if config.init is not None:
            from .. import warm_start

            batches = [draw(config.batch_size) for _ in range(4)]
            warm_start.calibrate_norms(model, ((2.0 * render_input(b) - 1.0) * b["mask"] for b in batches))
            log.info("stage 1 starts from %s", state["init"])
        teacher = frozen_teacher(model, config.albedo_anchor)  # after the calibration: the warm start's function
        if held_subjects:
            t0 = time.monotonic()
            try:
                state["val"] = HeldOut(held_subjects, lights, sampler.settings, sampler.names, config.val_samples,
                                       config.max_yaw, config.seed)
            except _Stop:
                raise
            except Exception as exc:  # noqa: BLE001  (as a failed check: training goes on without)
                state["val_error"] = f"{type(exc).__name__}: {exc}"
                log.error("held-out samples failed, checks off: %s", exc)
            else:
                log.info("%d validation samples of %s rendered in %.1f s", len(state["val"]), ", ".join(held),
                         time.monotonic() - t0)
                validate()
        optimizer = torch.optim.Adam(model.parameters(), lr=config.lr, betas=(0.5, 0.999))
        train_start = time.monotonic()
        last_ckpt = last_val = train_start
        model.train()
        while True:
            now = time.monotonic()
            if now >= stop_at:
                break
            if config.max_steps is not None and state["step"] >= config.max_steps:
                state["stopped"] = "steps"
                break
            for _ in range(config.fresh_per_step):  # keep rendering's share of the time near --render-share
                if sampler.seconds > config.render_share * (sampler.seconds + state["train_s"]):
                    break
                pool.add(sampler())
            if time.monotonic() >= stop_at:  # rendering can be slow (a CPU): no step that would eat the reserve
                break
            frac = min(1.0, (now - train_start) / max(stop_at - train_start, 1e-9))
            for group in optimizer.param_groups:
                group["lr"] = config.lr_min + 0.5 * (config.lr - config.lr_min) * (1.0 + math.cos(math.pi * frac))
            t0 = time.monotonic()
            batch = draw(config.batch_size)
            optimizer.zero_grad(set_to_none=True)
            with autocast(device, config.amp):
                terms = step_terms(model, loss_fn, batch, teacher, config.albedo_anchor)
            loss = terms["total"]
            if not torch.isfinite(loss):
                raise RelightError(f"training diverged: loss {float(loss)} at step {state['step']}")
            loss.backward()
            optimizer.step()
            value = float(loss.detach())
            state["train_s"] += time.monotonic() - t0
            state["step"] += 1
            state["losses"].append(value)
            if state["step"] % config.log_every == 0:
                logger.write({"event": "step", "step": state["step"], "elapsed_s": time.monotonic() - start,
                              "lr": optimizer.param_groups[0]["lr"], "total": value,
                              "rendered": sampler.rendered, "render_s": sampler.seconds, "train_s": state["train_s"],
                              **{k: float(terms[k].detach()) for k in ("transport_bands", "transport_direction",
                                                                       "albedo_anchor") if k in terms}})
            if time.monotonic() - last_ckpt >= config.checkpoint_every:
                save_checkpoint(out / "last.pt", model, step=state["step"], meta=json.dumps({"command": "gpu-train"}))
                logger.write({"event": "checkpoint", "step": state["step"], "elapsed_s": time.monotonic() - start})
                last_ckpt = time.monotonic()
            checking = state["val"] is not None and state["val_error"] is None
            if checking and time.monotonic() - last_val >= config.val_every:
                validate()
                last_val = time.monotonic()
    except (_Stop, KeyboardInterrupt) as exc:
        state["stopped"] = f"interrupted ({type(exc).__name__})"
    except Exception as exc:  # noqa: BLE001  (whatever stopped it, the weights there are still exported)
        state["stopped"] = "error"
        state["error"] = f"{type(exc).__name__}: {exc}"
        log.error("gpu-train stopped: %s", exc)
    finally:
        signal.signal(signal.SIGTERM, previous)
    if state["val"] is not None and state["val_error"] is None and state["best"].last_step != state["step"]:
        try:  # the last weights are a candidate too (within the export reserve: one pass over a few samples)
            validate()
        except Exception as exc:  # noqa: BLE001  (keeping the best, not the check, failed: the export still comes)
            state["val_error"] = f"{type(exc).__name__}: {exc}"
            log.error("the last held-out check failed: %s", exc)
    return _finish(config, model, sampler, state, start, index, device_name, logger)


def _finish(config, model, sampler, state, start, index, device_name, logger) -> int:
    """Write last.pt, stage1.onnx and summary.json, whatever stopped the run."""
    import torch

    from export.checkpoint import save_checkpoint
    from export.onnx_export import export_onnx
    from export.training import write_json

    out = Path(config.out)
    model.eval()
    save_checkpoint(out / "last.pt", model, step=state["step"], meta=json.dumps({"command": "gpu-train"}))
    best = state["best"]
    chosen = "last"
    if state["val_error"] is not None:  # the checks broke off: they judged only part of the run, whose weights are
        chosen = "last (the held-out checks failed)"  # the last ones; best.pt (if any) stays beside, to compare here
    elif best.state is not None:  # the held-out people's choice (best.pt was written when it was reached)
        model.load_state_dict(best.state)
        chosen = f"best (step {best.step})"
    losses = state["losses"]
    k = max(1, min(20, len(losses) // 4)) if losses else 1
    steps, rendered = state["step"], sampler.rendered  # what the exported weights had seen: the last ones', ...
    if state["val_error"] is None and best.state is not None:  # ... or the best's (at step 0: nothing trained on)
        steps, rendered = best.step, best.rendered if best.step else 0
    source = (f"relight_rt gpu-train: {steps} steps on {rendered} samples rendered from "
              f"{len(sampler.subjects)} bank people "
              f"({len(index['subjects']) - len(sampler.subjects)} more held out) under its {state['lights_id']} "
              f"on {device_name}, from "
              f"{state['init'] or 'random weights'}"
              + (f", albedo anchored to it (weight {config.albedo_anchor:g})" if config.albedo_anchor > 0 else ""))
    exported = None
    export_error = None
    if all(torch.isfinite(p).all() for p in model.parameters()):
        try:
            exported = export_onnx(model, out / "stage1.onnx", source=source)
        except RelightError as exc:
            export_error = str(exc)
    else:
        export_error = "weights hold NaN or Inf: nothing exported"
    elapsed = time.monotonic() - start
    summary = {
        "stopped": state["stopped"], "error": state["error"], "export_error": export_error,
        "device": device_name, "torch": torch.__version__, "steps": state["step"],
        "samples_rendered": sampler.rendered, "render_s": round(sampler.seconds, 2),
        "samples_per_s": round(sampler.rendered / max(sampler.seconds, 1e-9), 3),
        "render_s_per_sample_by_framing": {n: round(s / c, 3) for n, (c, s) in sampler.by_framing.items() if c},
        "peak_gpu_memory_gb": round(torch.cuda.max_memory_allocated() / 2**30, 2) if device_name != "cpu" else None,
        "train_s": round(state["train_s"], 2), "steps_per_s": round(state["step"] / max(state["train_s"], 1e-9), 3),
        "loss_first": float(np.mean(losses[:k])) if losses else None,
        "loss_last": float(np.mean(losses[-k:])) if losses else None,
        "elapsed_s": round(elapsed, 1), "init": state["init"], "onnx": exported["path"] if exported else None,
        "subjects": len(index["subjects"]), "trained_people": len(sampler.subjects), "exported": chosen,
        "lights": state["lights_id"],
        "val_error": state["val_error"],
        "val": None if state["val"] is None else {**best.summary(), "metric": config.val_metric,
                                                  "people": state["val"].names,
                                                  "samples": len(state["val"]), "seconds": round(state["val_s"], 2)},
        "config": {k2: str(v) for k2, v in asdict(config).items()},
    }
    write_json(out / "summary.json", summary)
    logger.write({"event": "end", **{k2: v for k2, v in summary.items() if k2 != "config"}})
    log.info("gpu-train: %s after %d steps, %d samples rendered (%.2f/s), loss %s -> %s, %.0f s; held-out %s "
             "%s -> best %s at step %s; onnx (%s weights): %s", state["stopped"], state["step"], sampler.rendered,
             summary["samples_per_s"], summary["loss_first"], summary["loss_last"], elapsed, config.val_metric,
             best.first, None if best.step is None else best.loss, best.step, chosen, summary["onnx"] or export_error)
    return 0 if state["error"] is None and exported is not None else 1
