"""``python -m export train-stage2``: train the stage-2 residual network on non-diffuse photos.

Stage 1 is frozen (eval mode). Each photo is decomposed once, its diffuse reconstruction under its
own estimated light, ``D = clip(Â ⊙ max(0, T̂·L̂), 0, 1) ⊙ mask``, is cached in
``RUN/diffuse_cache.npz`` (keyed by the stage-1 checkpoint's path, size and modification time and
the resolution, so a changed checkpoint recomputes it), and the residual network is trained with
the masked L1 loss between ``clip(D + residual, 0, 1) ⊙ mask`` and the masked photo, starting from a
zero residual (the last layer is zero-initialised; ``--random-init`` keeps it random). The residual has
no output activation, as the reference's; ``--output-activation tanh`` bounds it to [-1, 1] (how the
bundled stage 2 was trained), recorded in the checkpoint's config and the graph's metadata. RAdam
(torch's own); learning rate cosine-annealed from ``--lr`` to ``--lr-min`` over ``--epochs``.
Augmentation: random horizontal flips (images only; no SH is involved here).

``--stage1`` takes a torch checkpoint or a stage-1 ONNX graph (the bundled ``relight_rt/models/stage1.onnx``,
a converted reference checkpoint): stage 1 only runs forward here.

Relighting pairs (``--cross-light P``, beyond the paper). The paper trains stage 2 on reconstruction
only, because a real photo is seen under one light. Stage 2 then learns, besides the non-diffuse
residual, to correct stage 1's reconstruction under stage 1's *own* light estimate, and that correction
does not carry over to a new light (see docs/RESULTS.md). The renderer photographs each sample under
several environment maps, so a relighting pair exists: with probability P a training item uses the
diffuse image of photo i relit with the true SH light of photo j of the same sample,
``clip(Â_i ⊙ max(0, T̂_i·L_j), 0, 1) ⊙ mask``, and photo j as the target: exactly what stage 2 sees
at relighting time. P = 0 (the default) is the paper's training. The cache then also keeps every
photo's estimated albedo and transport (float16).

Example::

    python -m export train-stage2 --photos data/photos --stage1 runs/s1/best.pt --out runs/s2 \\
        --width 16 --epochs 30 --max-minutes 20 --export-onnx
"""

from __future__ import annotations

import dataclasses
import json
import logging
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

from relight_rt import RelightError

from .config import as_record, check_fraction, reader
from .losses import masked_l1, masked_mse
from .shading import render_diffuse
from .torch_data import PhotoDataset, decompose, item_rng, subject_of
from .training import (
    LoopConfig,
    LoopOptions,
    add_loop_arguments,
    collate,
    export_best,
    pick_device,
    to_device,
    train_loop,
    write_json,
)

log = logging.getLogger(__name__)

CACHE_NAME = "diffuse_cache.npz"


def add_arguments(parser) -> None:
    parser.add_argument("--photos", required=True,
                        help="folder of rendered photos (SUBJECT__L{j}_photo.png, ...) or of your own photos of people "
                             "(masks: NAME_mask.png, alpha, else the automatic matte)")
    parser.add_argument("--stage1", required=True,
                        help="frozen stage 1: a checkpoint (RUN/best.pt of train-stage1) or a stage-1 .onnx graph")
    parser.add_argument("--resolution", type=int, default=None,
                        help="training size, a multiple of 64 (default: stage 1's resolution)")
    parser.add_argument("--width", type=int, default=64, help="base channel count (default %(default)s)")
    parser.add_argument("--norm", choices=("batch", "instance"), default="batch",
                        help="normalisation layers (default %(default)s)")
    parser.add_argument("--output-activation", choices=("none", "tanh"), default="none",
                        help="the residual's activation: none (the reference's, default) or tanh (bounded to "
                             "[-1, 1]; the bundled stage 2 was trained so); recorded in the checkpoint and graph")
    parser.add_argument("--random-init", action="store_true",
                        help="keep the random last layer (default: zero it, so training starts from residual 0)")
    parser.add_argument("--init", metavar="CHECKPOINT",
                        help="start from this stage-2 checkpoint (.pt, same width/resolution/norm/activation) "
                             "instead of a zero residual: adapts a trained stage 2 to another stage 1")
    parser.add_argument("--cross-light", type=float, default=0.0, metavar="P",
                        help="probability that a training item is a relighting pair (photo i relit with the light "
                             "of photo j of the same sample, target photo j) instead of a reconstruction "
                             "(default %(default)s = the paper's training; see the module docstring)")
    parser.add_argument("--true-diffuse", type=float, default=0.0, metavar="P",
                        help="probability that a training item's input is the renderer's own diffuse image of the "
                             "target photo (NAME_diffuse.png) instead of stage 1's, so that stage 2 learns the "
                             "non-diffuse residual alone (default %(default)s)")
    parser.add_argument("--loss", choices=("l1", "l2"), default="l1",
                        help="l1: the paper's masked L1; l2: masked squared error, whose optimum is the expected "
                             "residual (sparse highlights survive; L1's median drops them) — what RMSE measures "
                             "(default %(default)s)")
    parser.add_argument("--val-fraction", type=float, default=0.1,
                        help="fraction of the subjects held out for validation (default %(default)s)")
    add_loop_arguments(parser, epochs=60)


@dataclass(frozen=True, kw_only=True)
class TrainStage2Config(LoopOptions):
    """The settings of ``train-stage2`` (one field per flag; see :func:`add_arguments`)."""

    photos: Path
    stage1: Path
    resolution: int | None = None
    width: int = 64
    norm: str = "batch"
    output_activation: str = "none"
    random_init: bool = False
    init: Path | None = None
    cross_light: float = 0.0
    true_diffuse: float = 0.0
    loss: str = "l1"
    val_fraction: float = 0.1

    def __post_init__(self) -> None:
        super().__post_init__()
        check_fraction("--cross-light", self.cross_light)
        check_fraction("--true-diffuse", self.true_diffuse)
        if self.init and Path(self.init).suffix.lower() == ".onnx":
            raise RelightError(f"--init {self.init}: stage 2 starts from a .pt checkpoint (its graph's residual "
                               "blocks cannot be unfolded back into the network)")


config_from_args = reader(TrainStage2Config)


def _stage1_id(path: Path, resolution: int) -> str:
    st = Path(path).stat()
    return f"{Path(path).resolve()}|{st.st_size}|{st.st_mtime_ns}|{resolution}"


def diffuse_cache(stage1, photos: PhotoDataset, path: Path, key: str, device: torch.device, batch_size: int = 4,
                  layers: bool = False) -> dict[str, np.ndarray]:
    """Diffuse reconstructions of every photo by a frozen stage 1, computed once and cached in ``path``.

    Args:
        stage1: a frozen stage 1 (:func:`export.frozen.load_frozen`).
        layers: also keep the estimated albedo and transport (for relighting pairs); a cache without
            them is recomputed.

    Returns:
        dict: names (N,) str, diffuse (N,3,R,R) float16 RGB in [0,1] (masked), light (N,9,3) float32
        estimated lights, key (the cache key); with ``layers`` also albedo (N,3,R,R) and transport
        (N,9,R,R), float16, masked.
    """
    if path.exists():
        with np.load(path, allow_pickle=False) as z:
            if (str(z["key"]) == key and list(z["names"]) == photos.names
                    and (not layers or {"albedo", "transport"} <= set(z.files))):
                log.info("using cached diffuse reconstructions %s", path)
                return {k: z[k] for k in z.files}
    stage1.eval()
    parts: dict[str, list[np.ndarray]] = {"diffuse": [], "light": [], "albedo": [], "transport": []}
    for i in range(0, len(photos), batch_size):
        b = to_device(collate([photos[j] for j in range(i, min(i + batch_size, len(photos)))]), device)
        out = decompose(stage1, b["photo"], b["mask"])
        parts["diffuse"].append(render_diffuse(out["albedo"], out["transport"], out["light"], b["mask"]).cpu().numpy())
        parts["light"].append(out["light"].cpu().numpy())
        if layers:
            parts["albedo"].append(out["albedo"].cpu().numpy().astype(np.float16))
            parts["transport"].append(out["transport"].cpu().numpy().astype(np.float16))
    cache = {"names": np.asarray(photos.names), "diffuse": np.concatenate(parts["diffuse"]).astype(np.float16),
             "light": np.concatenate(parts["light"]).astype(np.float32), "key": np.asarray(key)}
    if layers:
        cache.update(albedo=np.concatenate(parts["albedo"]), transport=np.concatenate(parts["transport"]))
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".npz", dir=path.parent)
    with os.fdopen(fd, "wb") as f:
        np.savez(f, **cache)
    os.replace(tmp, path)
    log.info("cached %d diffuse reconstructions in %s", len(photos), path)
    return cache


def relighting_partners(names: list[str]) -> list[list[int]]:
    """For each photo, the indices of the other photos of the same sample (other lights, same view)."""
    by_subject: dict[str, list[int]] = {}
    for i, n in enumerate(names):
        by_subject.setdefault(subject_of(n), []).append(i)
    return [[j for j in by_subject[subject_of(n)] if j != i] for i, n in enumerate(names)]


class Stage2Dataset(torch.utils.data.Dataset):
    """Stage-2 training items from photos and their cached stage-1 results, resized to ``resolution``.

    Each entry of ``pairs`` is ``(i, j)``: the diffuse image of photo i under the light of photo j, and
    photo j as the target. ``i == j`` is a reconstruction (stage 1's cached diffuse image under its own
    estimated light, the paper's training); ``i != j`` a relighting pair (stage 1's albedo and transport
    of photo i under the true SH light of photo j; needs the cache's layers). With ``cross_light`` > 0
    a reconstruction entry becomes, with that probability per epoch, a pair with a random partner. With
    ``true_diffuse`` > 0 the input is, with that probability, the renderer's own diffuse image of the
    target photo instead of stage 1's (the non-diffuse residual alone).

    Items: photo (3,R,R) (the target), mask (1,R,R), diffuse (3,R,R), index. Random flips when ``augment``.
    """

    def __init__(self, photos: PhotoDataset, cache: dict[str, np.ndarray], pairs: list[tuple[int, int]],
                 resolution: int, augment: bool = True, seed: int = 0, cross_light: float = 0.0,
                 true_diffuse: float = 0.0):
        self.photos, self.cache, self.pairs = photos, cache, list(pairs)
        self.resolution, self.augment, self.seed, self.epoch = resolution, augment, seed, 0
        self.cross_light, self.true_diffuse = float(cross_light), float(true_diffuse)
        self.partners = relighting_partners(photos.names) if self.cross_light > 0 else None
        if (self.cross_light > 0 or any(i != j for i, j in self.pairs)) and "transport" not in cache:
            raise RelightError("relighting pairs need the stage-1 albedo and transport in the cache")

    def __len__(self) -> int:
        return len(self.pairs)

    def set_epoch(self, epoch: int) -> None:
        self.epoch = int(epoch)

    def _diffuse(self, i: int, j: int) -> torch.Tensor:
        """Unmasked diffuse image of photo i under photo j's light (i == j: the cached reconstruction)."""
        if i == j:
            return torch.from_numpy(self.cache["diffuse"][i].astype(np.float32))
        albedo = torch.from_numpy(self.cache["albedo"][i][None].astype(np.float32))
        transport = torch.from_numpy(self.cache["transport"][i][None].astype(np.float32))
        return render_diffuse(albedo, transport, self.photos[j]["light"][None], torch.ones(1, 1, 1, 1))[0]

    def __getitem__(self, index: int) -> dict:
        i, j = self.pairs[index]
        rng = item_rng(self.seed, self.epoch, index)
        flip = bool(rng.integers(2))
        if self.partners is not None and i == j and self.partners[i] and rng.random() < self.cross_light:
            j = int(rng.choice(self.partners[i]))
        p = self.photos[j]
        photo, mask = p["photo"], p["mask"] if i == j else p["mask"] * self.photos[i]["mask"]
        if self.true_diffuse > 0 and rng.random() < self.true_diffuse:
            if not p["diffuse"].any():
                raise RelightError(f"--true-diffuse: {self.photos.names[j]} has no diffuse image (NAME_diffuse.png)")
            d = p["diffuse"]
        else:
            d = self._diffuse(i, j)
        if d.shape[-1] != self.resolution:
            d = F.interpolate(d[None], size=(self.resolution,) * 2, mode="bilinear", align_corners=False)[0]
        d = d * mask
        if self.augment and flip:
            photo, mask, d = (t.flip(-1) for t in (photo, mask, d))
        return {"photo": photo, "mask": mask, "diffuse": d, "index": index}


def stage2_step(model: torch.nn.Module, batch: dict, loss: str = "l1") -> dict:
    """Masked L1 (or squared error) between clip(D + residual, 0, 1) ⊙ mask and the masked photo."""
    mask, diffuse = batch["mask"], batch["diffuse"]
    residual = model((2.0 * diffuse - 1.0) * mask).float()
    relit = (diffuse + residual).clamp(0.0, 1.0) * mask
    if loss == "l2":
        value = masked_mse(relit, batch["photo"] * mask, mask)
        return {"l2": value, "total": value}
    value = masked_l1(relit, batch["photo"] * mask, mask)
    return {"l1": value, "total": value}


def zero_residual_init(model: torch.nn.Module) -> None:
    """Zero the last conv of the residual decoder, so stage 1 + 2 starts exactly at stage 1's reconstruction.

    Its weight gradient is not zero (it is the product of its input features and the loss gradient), so
    training moves it at the first step; the rest of the network follows from the second.
    """
    with torch.no_grad():
        model.dc5b.weight.zero_()
        model.dc5b.bias.zero_()


def split_subjects(names: list[str], fraction: float, seed: int) -> tuple[list[int], list[int]]:
    """Indices of (train, val) photos; whole subjects go to validation."""
    subjects = sorted({subject_of(n) for n in names})
    n_val = int(round(len(subjects) * fraction)) if fraction > 0 else 0
    if n_val == 0 or n_val >= len(subjects):
        return list(range(len(names))), []
    order = np.random.default_rng([seed, 11]).permutation(len(subjects))
    val_subjects = {subjects[i] for i in order[:n_val]}
    train = [i for i, n in enumerate(names) if subject_of(n) not in val_subjects]
    val = [i for i, n in enumerate(names) if subject_of(n) in val_subjects]
    return train, val


def _own_photos(config: TrainStage2Config, out: Path) -> Path:
    """``--photos`` as given when it holds rendered photos (SUBJECT__L{j}_photo.png); a folder of one's own photos
    is prepared into OUT/photos first (masks: NAME_mask.png, else alpha, else the automatic person matte)."""
    from . import dataset

    if dataset.list_photos(config.photos):
        return config.photos
    names, failures = dataset.prepare_user_photos(config.photos, out / "photos")
    for line in failures:
        log.warning("left out: %s", line)
    if not names:
        raise RelightError(f"--photos {config.photos}: no photos of people found (rendered SUBJECT__L{{j}}_photo.png, "
                           "or ordinary photos)")
    if config.cross_light > 0 or config.true_diffuse > 0:
        raise RelightError("--cross-light / --true-diffuse need rendered photos (their lights and diffuse parts are "
                           "known); one's own photos train with the paper's recipe only")
    log.info("%d of your photos prepared in %s (%d left out)", len(names), out / "photos", len(failures))
    return out / "photos"


def run(config: TrainStage2Config) -> int:
    from .frozen import load_frozen
    from .networks import Stage2Net

    device = pick_device(config.device)
    stage1 = load_frozen(config.stage1, "stage1", device, threads=config.threads)
    r1 = stage1.resolution
    r2 = config.resolution or r1
    if r2 % 64 or r2 < 64:
        raise RelightError(f"--resolution: expected a positive multiple of 64, got {r2}")
    cfg = LoopConfig.from_options(config)
    out = Path(config.out)
    out.mkdir(parents=True, exist_ok=True)
    config = dataclasses.replace(config, photos=_own_photos(config, out))
    photos_r1 = PhotoDataset(config.photos, r1)
    cache = diffuse_cache(stage1, photos_r1, out / CACHE_NAME, _stage1_id(Path(config.stage1), r1), device,
                          layers=config.cross_light > 0)
    del stage1
    photos = photos_r1 if r2 == r1 else PhotoDataset(config.photos, r2)
    train_idx, val_idx = split_subjects(photos.names, config.val_fraction, config.seed)
    log.info("stage 2: %d training photos, %d validation, %d² px, width %d, norm %s, relighting pairs %.2f",
             len(train_idx), len(val_idx), r2, config.width, config.norm, config.cross_light)
    train_set = Stage2Dataset(photos, cache, [(i, i) for i in train_idx], r2, augment=True, seed=config.seed,
                              cross_light=config.cross_light, true_diffuse=config.true_diffuse)
    torch.manual_seed(config.seed)
    model = Stage2Net(width=config.width, resolution=r2, norm=config.norm,
                      output_activation=config.output_activation).to(cfg.device)
    init = None
    if config.init and not (config.resume and (out / "last.pt").exists()):
        from .warm_start import load_init

        init = load_init(model, config.init)
        log.info("stage 2 starts from %s", init)
    elif not config.random_init:
        zero_residual_init(model)
    optimizer = torch.optim.RAdam(model.parameters(), lr=config.lr)

    def step(m: torch.nn.Module, batch: dict) -> dict:
        return stage2_step(m, batch, config.loss)

    val_fn = None
    if val_idx:
        # validation measures what the training aims at: reconstructions, plus every relighting pair of
        # the held-out subjects when pairs are trained
        val_pairs = [(i, i) for i in val_idx]
        if config.cross_light > 0:
            partners = relighting_partners(photos.names)
            val_pairs += [(i, j) for i in val_idx for j in partners[i]]
        val_set = Stage2Dataset(photos, cache, val_pairs, r2, augment=False)

        def val_fn(m: torch.nn.Module) -> float:
            total = 0.0
            for i in range(len(val_set)):
                total += float(step(m, to_device(collate([val_set[i]]), cfg.device))["total"])
            return total / len(val_set)

    write_json(out / "args.json", {**as_record(config), "command": "train-stage2",
                                   "val_names": [photos.names[i] for i in val_idx]})
    meta = {"command": "train-stage2", "photos": str(config.photos), "stage1": str(config.stage1),
            "cross_light": config.cross_light, "true_diffuse": config.true_diffuse, "loss": config.loss, "init": init}
    summary = train_loop(model, optimizer, train_set, step, cfg, val_fn=val_fn, meta=meta)
    log.info("stage 2 finished: %s", json.dumps(summary))
    if config.export_onnx:
        export_best(out, "stage2", f"relight_rt train-stage2 on {config.photos} ({summary['epochs_done']} epochs)")
    return 0
