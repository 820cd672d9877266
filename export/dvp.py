"""``python -m export fit-dvp``: fit an (illumination-conditioned) deep video prior to one video.

A network of stage 2's architecture (``export.networks.DVPNet``) is fitted from scratch to map each
input frame to that frame's per-frame relit result (Lei et al. 2020, "Blind video temporal
consistency via deep video prior"; Tajima et al. 2021 §5). Convolutional networks fit what is
consistent across frames before they fit what is not, so a network stopped in time reproduces
the relighting without its flicker.

- Conditioned (default): input = (2·frame − 1)·mask (3 channels) followed by the frame's light,
  27 channels, channel 3 + 3k + c = light[k, c] at every pixel (DESIGN.md §1). The light is an
  explicit input, so the network can follow a moving light instead of averaging it away.
- Unconditioned (``--unconditioned``): the frame only (3 channels), for comparison; its ONNX graph
  still has the contract's ``light`` input, which it ignores (see :func:`export_dvp`).
- Output: no activation, as the reference's (``--output-activation tanh`` bounds it, a recorded option);
  the relit frame is ``clip((out + 1) / 2, 0, 1)``, masked (as the exported graph computes it), so the
  loss compares ``(out + 1) / 2`` with the target inside the mask.
- Loss: perceptual (L1 + VGG19 features, ``export.vgg``) when ``--vgg-weights`` names a local
  VGG19 file; otherwise the fallback L1 + spatial-frequency loss (``export.losses``, the stage-1
  SF loss, weight ``--sf-weight``). The chosen loss is logged and written to the fit log.
- Optimiser: Adam, lr 1e-4, betas (0.5, 0.999), one frame per step, frames shuffled every epoch.
- Norm layers: per-sample statistics ("instance") by default, the same in fitting and in the graph.

Stopping. After every epoch the network is run on all frames (dropout off) and two numbers are
measured, both as mean absolute differences in [0, 1] units inside the mask: the fit error E
(prediction vs. per-frame relit target) and the flicker W (warping error of the predictions, with
DIS flow of the INPUT frames, non-occluded pixels only; ``relight_rt.video.metrics``). The score is
E + W; fitting stops when it has not improved for ``--patience`` epochs (or at ``--max-epochs`` /
``--max-minutes``, never before ``--min-epochs``), and the epoch with the lowest score is kept.
Every epoch's E, W and score go to the fit log (JSON).

Why E + W: write each target as a temporally consistent relit frame plus per-frame flicker of
mean size a. Fitting the consistent part lowers E and leaves W near the consistent video's own
(which includes the light's real change, the same for every epoch), so the score falls. Fitting
the flicker lowers E by at most about a but raises W by about √2·a (the difference of two
independent per-frame errors is larger than either), so the score rises: its minimum is the point
where the network has taken what is consistent and has not yet taken the flicker, which is the
point the reference picks by eye ("before noise appears"). Both terms are in the same units, so
no weight has to be tuned; E alone would never stop, W alone would prefer an under-fitted (blurry,
or for the unconditioned net light-frozen) result.

Weight average (``--ema DECAY``, off by default, beyond the paper). One frame per step leaves the
weights after any step leaning towards the last frames seen, differently every epoch, so the fit
error swings from epoch to epoch and the stopping rule picks among noisy scores. An exponential
moving average of the weights (decay per step, e.g. 0.95 ≈ the last 20 steps, about one epoch of the
24-frame clip) averages that out; each epoch's prediction, the score and the kept network then come
from the averaged weights, while training goes on with the raw ones. Measured on the reference clip
(docs/RESULTS.md): the swing of the fit error over the last 30 epochs drops 3× and the kept fit error
from 0.0116 to 0.0100, but the prediction's flicker stays at the targets' level, so it does not make
the DVP beat the per-frame result there.

Frames are held in memory at the working size (``--size``, long side; padded with zeros to a
multiple of 64): fitting needs every frame every epoch.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from relight_rt import RelightError
from relight_rt.video import metrics as rt_metrics
from relight_rt.video.job import IMAGE_SUFFIXES, FrameSource, read_frame

from .config import reader

logger = logging.getLogger(__name__)


# ---------------------------------------------------------------------------------------------
# data


def _resize(img: np.ndarray, size: tuple[int, int], interp: int = cv2.INTER_AREA) -> np.ndarray:
    return img if img.shape[:2] == size else cv2.resize(img, (size[1], size[0]), interpolation=interp)


def working_size(shape: tuple[int, int], size: int | None) -> tuple[int, int]:
    """(h, w) after scaling the long side to ``size`` (None: unchanged)."""
    h, w = shape
    if size is None or max(h, w) == size:
        return h, w
    scale = size / max(h, w)
    return max(1, round(h * scale)), max(1, round(w * scale))


def load_clip(frames: str | os.PathLike, relit: str | os.PathLike, lights: str | os.PathLike | np.ndarray,
              masks: str | os.PathLike | None = None, size: int | None = None) -> dict[str, np.ndarray]:
    """Read a video's frames, masks, per-frame relit targets and lights.

    Args:
        frames: folder of input frames or a video file (masks as relight_rt.video.job.FrameSource reads them).
        relit: folder of per-frame relit frames: same stems as the frames, or the same count in sorted order.
        lights: (N, 9, 3) RGB .npy (or array), or a single (9, 3) light used for every frame.
        masks: mask folder or video, see FrameSource.
        size: working size of the long side (None: the frames' own size).

    Returns:
        dict: frames (N, h, w, 3), targets (N, h, w, 3), masks (N, h, w) float32 in [0, 1] and
        lights (N, 9, 3) float32 RGB.
    """
    source = FrameSource(frames, masks)
    relit_dir = Path(relit)
    if not relit_dir.is_dir():
        raise RelightError(f"{relit_dir}: expected a folder of relit frames")
    relit_files = sorted(p for p in relit_dir.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES
                         and not p.stem.endswith("_mask"))
    by_stem = {p.stem: p for p in relit_files}
    xs, ys, ms = [], [], []
    for i, frame in enumerate(source):
        shape = working_size(frame.image.shape[:2], size)
        if frame.name in by_stem:
            target_path = by_stem[frame.name]
        elif i < len(relit_files):
            target_path = relit_files[i]
        else:
            raise RelightError(f"{relit_dir}: no relit frame for input frame {frame.name}")
        target = read_frame(target_path)[..., :3]
        xs.append(_resize(frame.image, shape))
        ys.append(_resize(target, shape))
        ms.append(_resize(frame.mask, shape, cv2.INTER_LINEAR))
    if len(xs) < 2:
        raise RelightError(f"{frames}: expected at least two frames to fit a video prior, got {len(xs)}")
    if len(relit_files) != len(xs):
        raise RelightError(f"{relit_dir}: expected {len(xs)} relit frames (one per input frame), "
                           f"got {len(relit_files)}")
    if isinstance(lights, (str, os.PathLike)):
        try:
            light_arr = np.load(lights, allow_pickle=False)
        except (OSError, ValueError) as exc:
            raise RelightError(f"{lights}: cannot read the lights ({exc})") from None
    else:
        light_arr = np.asarray(lights)
    light_arr = np.asarray(light_arr, np.float32)
    if light_arr.shape == (9, 3):
        light_arr = np.repeat(light_arr[None], len(xs), axis=0)
    if light_arr.shape != (len(xs), 9, 3) or not np.isfinite(light_arr).all():
        raise RelightError(f"lights: expected finite ({len(xs)}, 9, 3) RGB SH lights (one per frame), "
                           f"got {light_arr.shape}")
    return {"frames": np.stack(xs), "targets": np.stack(ys), "masks": np.stack(ms), "lights": light_arr}


def network_input(frames, masks, lights, conditioned: bool):
    """The DVP network input (DESIGN.md §1), torch.

    Args:
        frames: (N, 3, H, W) in [0, 1]; masks (N, 1, H, W); lights (N, 9, 3) RGB.

    Returns:
        (N, 30, H, W) = ((2x − 1)·mask, light tiled with channel 3 + 3k + c = light[k, c]); (N, 3, H, W)
        when not conditioned.
    """
    import torch

    x = (2.0 * frames - 1.0) * masks
    if not conditioned:
        return x
    n, _, h, w = frames.shape
    tiled = lights.reshape(n, 27, 1, 1).expand(n, 27, h, w)
    return torch.cat([x, tiled.to(x.dtype)], dim=1)


def _pad64(arr: np.ndarray) -> np.ndarray:
    """Zero-pad (N, H, W, ...) at the bottom/right to multiples of 64."""
    h, w = arr.shape[1:3]
    pad = [(0, 0), (0, -h % 64), (0, -w % 64)] + [(0, 0)] * (arr.ndim - 3)
    return np.pad(arr, pad)


class _FlickerMeter:
    """Warping error of prediction sequences against fixed DIS flows of the input frames."""

    def __init__(self, frames: np.ndarray, masks: np.ndarray):
        grays = [rt_metrics.to_gray_u8(f) for f in frames]
        self.pairs = []
        for t in range(len(frames) - 1):
            forward = rt_metrics.dis_flow(grays[t], grays[t + 1], "medium")
            backward = rt_metrics.dis_flow(grays[t + 1], grays[t], "medium")
            valid = (rt_metrics.consistent_flow(forward, backward) & (masks[t] >= 0.5)
                     & (rt_metrics.warp(masks[t + 1], forward) >= 0.5))
            self.pairs.append((forward, valid))

    def __call__(self, preds: np.ndarray) -> float:
        errs = [float(np.abs(rt_metrics.warp(preds[t + 1], flow) - preds[t])[valid].mean()) if valid.any() else 0.0
                for t, (flow, valid) in enumerate(self.pairs)]
        return float(np.mean(errs))


# ---------------------------------------------------------------------------------------------
# fitting


def fit_dvp(clip: dict[str, np.ndarray], conditioned: bool = True, width: int = 64, norm: str = "instance",
            vgg_weights: str | os.PathLike | None = None, sf_weight: float = 1.0, lr: float = 1e-4,
            max_epochs: int = 100, min_epochs: int = 3, patience: int = 8, max_seconds: float | None = None,
            seed: int = 0, device: str = "cpu", ema: float | None = None, output_activation: str = "none"):
    """Fit a DVP network to one clip and return the best epoch's network.

    Args:
        clip: as returned by :func:`load_clip`.
        conditioned: light-conditioned (3 + 27 channels) or frame-only (3).
        width, norm: DVPNet constructor arguments.
        vgg_weights: local VGG19 weights for the perceptual loss; None: L1 + sf_weight · SF loss.
        lr: Adam learning rate (betas (0.5, 0.999)).
        max_epochs, min_epochs, patience, max_seconds: stopping (module docstring).
        seed: torch seed (initialisation, shuffling, dropout).
        device: torch device.
        ema: None (the paper): predict and keep the trained weights; a decay in [0, 1): an exponential
            moving average of the weights, updated after every step, is what each epoch's prediction,
            the stopping score and the returned network use (module docstring, "Weight average").
        output_activation: "none" (the reference) or "tanh".

    Returns:
        (model in eval mode with the best weights, history dict: per-epoch fit/flicker/score, best epoch,
        loss used, target flicker, stop reason).
    """
    import torch

    from export.losses import SpatialFrequencyLoss, masked_l1
    from export.networks import DVPNet

    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    n, h, w = clip["frames"].shape[:3]
    frames = torch.from_numpy(_pad64(clip["frames"])).permute(0, 3, 1, 2).contiguous().to(device)
    targets = torch.from_numpy(_pad64(clip["targets"])).permute(0, 3, 1, 2).contiguous().to(device)
    masks = torch.from_numpy(_pad64(clip["masks"]))[:, None].contiguous().to(device)
    lights = torch.from_numpy(clip["lights"]).to(device)
    resolution = max(64, 64 * math.ceil(max(h, w) / 64))
    model = DVPNet(width=width, resolution=resolution, norm=norm, conditioned=conditioned,
                   output_activation=output_activation).to(device)
    optim = torch.optim.Adam(model.parameters(), lr=lr, betas=(0.5, 0.999))
    averaged = None
    if ema is not None:
        if not 0.0 <= ema < 1.0:
            raise RelightError(f"ema: expected a decay in [0, 1), got {ema}")
        from torch.optim.swa_utils import AveragedModel, get_ema_multi_avg_fn

        averaged = AveragedModel(model, multi_avg_fn=get_ema_multi_avg_fn(ema), use_buffers=True)
    net = model if averaged is None else averaged.module  # the weights that predict and are kept
    if vgg_weights is not None:
        from export.vgg import PerceptualLoss

        perceptual = PerceptualLoss(vgg_weights).to(device)
        loss_name = f"perceptual (L1 + VGG19 relu1_2..relu5_4, weights {Path(vgg_weights).name})"

        def loss_fn(pred, target, mask):
            return perceptual(pred, target, mask)
    else:
        sf = SpatialFrequencyLoss().to(device)
        loss_name = f"fallback L1 + {sf_weight:g} x spatial-frequency (no VGG19 weights given)"

        def loss_fn(pred, target, mask):
            return masked_l1(pred, target, mask) + sf_weight * sf(pred, target, mask)

    logger.info("fit-dvp: %d frames at %dx%d, %s, loss: %s", n, w, h,
                "light-conditioned (30 ch)" if conditioned else "unconditioned (3 ch)", loss_name)
    flicker = _FlickerMeter(clip["frames"], clip["masks"])
    target_flicker = flicker(clip["targets"] * clip["masks"][..., None])
    inputs = network_input(frames, masks, lights, conditioned)

    def predict() -> np.ndarray:
        net.eval()
        with torch.no_grad():
            outs = [((net(inputs[i:i + 1]) + 1) / 2).clamp(0, 1) * masks[i:i + 1] for i in range(n)]
        model.train()
        return torch.cat(outs).permute(0, 2, 3, 1)[:, :h, :w].cpu().numpy()

    history: dict = {"loss": loss_name, "conditioned": conditioned, "frames": n, "size": [h, w], "ema": ema,
                     "target_flicker": target_flicker, "epochs": []}
    best_score, best_epoch, best_state = math.inf, -1, None
    start = time.perf_counter()
    stop = "max_epochs"
    model.train()
    from .training import _tqdm

    tqdm = _tqdm()  # a bar per epoch on a terminal (frames/s, time left); nothing without tqdm or a terminal
    for epoch in range(max_epochs):
        total = 0.0
        for i in tqdm(rng.permutation(n), desc=f"epoch {epoch + 1}", unit="frame", leave=False, disable=None):
            pred = (model(inputs[i:i + 1]) + 1) / 2
            loss = loss_fn(pred, targets[i:i + 1], masks[i:i + 1])
            optim.zero_grad(set_to_none=True)
            loss.backward()
            optim.step()
            if averaged is not None:
                averaged.update_parameters(model)
            total += float(loss.detach())
        preds = predict()
        m = clip["masks"][..., None] >= 0.5
        fit = float(np.abs(preds - clip["targets"] * clip["masks"][..., None])[np.broadcast_to(m, preds.shape)].mean())
        flick = flicker(preds)
        score = fit + flick
        history["epochs"].append({"epoch": epoch, "train_loss": total / n, "fit_error": fit, "flicker": flick,
                                  "score": score, "seconds": time.perf_counter() - start})
        logger.info("epoch %d: loss %.4f, fit error %.4f, flicker %.4f (targets %.4f), score %.4f",
                    epoch, total / n, fit, flick, target_flicker, score)
        if score < best_score:
            best_score, best_epoch = score, epoch
            best_state = {k: v.detach().clone() for k, v in net.state_dict().items()}
        if epoch + 1 >= min_epochs and epoch - best_epoch >= patience:
            stop = f"no better score for {patience} epochs"
            break
        if max_seconds is not None and time.perf_counter() - start > max_seconds:
            stop = "time budget"
            break
    net.load_state_dict(best_state)
    net.eval()
    history.update(best_epoch=best_epoch, best_score=best_score, stop=stop)
    logger.info("fit-dvp: kept epoch %d (score %.4f); stopped: %s", best_epoch, best_score, stop)
    return net, history


# ---------------------------------------------------------------------------------------------
# command


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--frames", required=True, help="input frames: a folder (with STEM_mask files) or a video")
    parser.add_argument("--masks", help="mask folder or video (default: STEM_mask files or RGBA frames)")
    parser.add_argument("--relit", required=True, help="folder of the per-frame relit frames (the targets)")
    parser.add_argument("--lights", required=True, help="(N, 9, 3) RGB .npy: each frame's light (or one (9, 3))")
    parser.add_argument("--out", required=True, help="output dvp.onnx")
    parser.add_argument("--unconditioned", action="store_true", help="frame-only input (3 channels), for comparison")
    parser.add_argument("--vgg-weights", help="local torchvision VGG19 weights for the perceptual loss "
                                              "(default: fallback L1 + spatial-frequency loss)")
    parser.add_argument("--sf-weight", type=float, default=1.0, help="weight of the SF term in the fallback loss")
    parser.add_argument("--size", type=int, help="working size of the long side (default: the frames' own)")
    parser.add_argument("--width", type=int, default=64, help="network base width (64 = reference)")
    parser.add_argument("--norm", choices=("instance", "batch"), default="instance")
    parser.add_argument("--output-activation", choices=("none", "tanh"), default="none",
                        help="network output activation: none (the reference's, default) or tanh")
    parser.add_argument("--max-epochs", type=int, default=100)
    parser.add_argument("--min-epochs", type=int, default=3)
    parser.add_argument("--patience", type=int, default=8, help="epochs without a better score before stopping")
    parser.add_argument("--max-minutes", type=float, help="time budget")
    parser.add_argument("--ema", type=float, help="predict with an exponential moving average of the weights, "
                                                 "this decay per step (e.g. 0.95; default: the trained weights)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--device", default="cpu", help="torch device, e.g. cuda")
    parser.add_argument("--checkpoint", help="also save the fitted network as a checkpoint (.pt)")
    parser.add_argument("--fp16", action="store_true", help="export float16 weights")


def _ignore_light(model):
    """Wrap an unconditioned DVPNet so it takes the contract's 30-channel input and ignores channels 3..29.

    export.onnx_export wraps only light-conditioned DVP networks (the dvp contract always has a light
    input); this adapter looks like a conditioned one (kind, conditioned, resolution, norm, config)
    and passes the frame channels alone to the fitted network, so the graph has the ``light`` input
    but its output does not depend on it.
    """
    from torch import nn

    class IgnoreLight(nn.Module):
        kind = "dvp"
        conditioned = True

        def __init__(self, net):
            super().__init__()
            self.net = net
            self.resolution, self.norm = net.resolution, net.norm
            self.output_activation = net.output_activation

        @property
        def config(self) -> dict:
            return {**self.net.config, "ignores_light": True}

        def forward(self, x):
            return self.net(x[:, :3])

    return IgnoreLight(model)


def export_dvp(model, out: str | os.PathLike, source: str, fp16: bool = False) -> dict:
    """Export a fitted DVPNet to ONNX (contract kind dvp, resolution 0 = any size divisible by 64).

    An unconditioned network is exported through :func:`_ignore_light`: its graph has the ``light``
    input of the contract and ignores it.
    """
    from export.onnx_export import export_onnx

    net = model.cpu().eval()
    if not net.conditioned:
        net = _ignore_light(net).eval()
    return export_onnx(net, out, source=source, fp16=fp16, resolution=0)


@dataclass(frozen=True, kw_only=True)
class FitDvpConfig:
    """The settings of ``fit-dvp`` (one field per flag; see :func:`add_arguments`)."""

    frames: Path
    relit: Path
    lights: Path
    out: Path
    masks: Path | None = None
    unconditioned: bool = False
    vgg_weights: Path | None = None
    sf_weight: float = 1.0
    size: int | None = None
    width: int = 64
    norm: str = "instance"
    output_activation: str = "none"
    max_epochs: int = 100
    min_epochs: int = 3
    patience: int = 8
    max_minutes: float | None = None
    ema: float | None = None
    seed: int = 0
    device: str = "cpu"
    checkpoint: Path | None = None
    fp16: bool = False


config_from_args = reader(FitDvpConfig)


def run(config: FitDvpConfig) -> int:
    out = Path(config.out)
    if out.suffix != ".onnx":
        raise RelightError(f"--out: expected a .onnx file name, got {out}")
    clip = load_clip(config.frames, config.relit, config.lights, config.masks, config.size)
    model, history = fit_dvp(clip, conditioned=not config.unconditioned, width=config.width, norm=config.norm,
                             vgg_weights=config.vgg_weights, sf_weight=config.sf_weight, max_epochs=config.max_epochs,
                             min_epochs=config.min_epochs, patience=config.patience,
                             max_seconds=None if config.max_minutes is None else 60 * config.max_minutes,
                             seed=config.seed, device=config.device, ema=config.ema,
                             output_activation=config.output_activation)
    kind = "light-conditioned" if not config.unconditioned else "unconditioned"
    source = (f"fit-dvp {kind} on {Path(config.frames).name} ({history['frames']} frames, "
              f"{history['size'][1]}x{history['size'][0]}), epoch {history['best_epoch']}, loss {history['loss']}")
    out.parent.mkdir(parents=True, exist_ok=True)
    if config.checkpoint:
        from export.checkpoint import save_checkpoint

        save_checkpoint(config.checkpoint, model, epoch=history["best_epoch"], source=source)
    export_dvp(model, out, source, config.fp16)
    log_path = out.with_suffix(".fit.json")
    tmp = log_path.with_name(f".{log_path.name}.tmp")
    tmp.write_text(json.dumps(history, indent=1))
    os.replace(tmp, log_path)
    logger.info("wrote %s (epoch %d, %s); log %s", out, history["best_epoch"], history["stop"], log_path)
    return 0
