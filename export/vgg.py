"""VGG19 features for a perceptual loss, in plain torch, from a weights file the user supplies.

Nothing is downloaded. The file is torchvision's ImageNet VGG19 ``state_dict`` (keys
``features.N.weight`` / ``features.N.bias``, e.g. ``vgg19-dcbb9e9d.pth``), or the same keys without
the ``features.`` prefix; the classifier's keys are ignored. It is read with
``torch.load(weights_only=True)``.

The perceptual loss compares the activations after ``relu1_2, relu2_2, relu3_4, relu4_4, relu5_4``
(L1, layer weights 1/2.6, 1/4.8, 1/3.7, 1/5.6, 10/1.5 as in Chen & Koltun's cascaded refinement
networks, which the deep video prior of Lei et al. 2020 follows) plus an L1 term on the pixels.
Inputs are RGB in [0, 1], normalised with the ImageNet mean and standard deviation inside.
"""

from __future__ import annotations

import logging
import os

import torch
import torch.nn.functional as F
from torch import nn

from relight_rt import RelightError

logger = logging.getLogger(__name__)

# torchvision's "E" configuration: conv widths, "M" = 2x2 max pooling
_CFG = (64, 64, "M", 128, 128, "M", 256, 256, 256, 256, "M", 512, 512, 512, 512, "M", 512, 512, 512, 512, "M")
# indices in `features` of relu1_2, relu2_2, relu3_4, relu4_4, relu5_4
FEATURE_LAYERS = (3, 8, 17, 26, 35)
LAYER_WEIGHTS = (1 / 2.6, 1 / 4.8, 1 / 3.7, 1 / 5.6, 10 / 1.5)
_MEAN = (0.485, 0.456, 0.406)
_STD = (0.229, 0.224, 0.225)


def _build_features() -> nn.Sequential:
    layers: list[nn.Module] = []
    channels = 3
    for item in _CFG:
        if item == "M":
            layers.append(nn.MaxPool2d(2, 2))
        else:
            layers += [nn.Conv2d(channels, int(item), 3, padding=1), nn.ReLU(inplace=False)]
            channels = int(item)
    return nn.Sequential(*layers[: FEATURE_LAYERS[-1] + 1])  # nothing after relu5_4 is needed


class VGG19Features(nn.Module):
    """Frozen VGG19 trunk returning the five feature maps of :data:`FEATURE_LAYERS`.

    Args:
        weights: path to the VGG19 weights (see module docstring), or None for random weights
            (tests only: random features are not a perceptual measure).
    """

    def __init__(self, weights: str | os.PathLike | None):
        super().__init__()
        self.features = _build_features()
        if weights is not None:
            self.load(weights)
        self.register_buffer("mean", torch.tensor(_MEAN).view(1, 3, 1, 1), persistent=False)
        self.register_buffer("std", torch.tensor(_STD).view(1, 3, 1, 1), persistent=False)
        self.requires_grad_(False)
        self.eval()

    def load(self, path: str | os.PathLike) -> None:
        """Load torchvision-layout VGG19 weights from ``path`` (weights_only)."""
        try:
            state = torch.load(path, map_location="cpu", weights_only=True)
        except Exception as exc:  # torch raises many types (pickle, struct, zip) for a bad file
            raise RelightError(f"{path}: cannot read VGG19 weights ({exc})") from None
        if not isinstance(state, dict):
            raise RelightError(f"{path}: expected a state_dict (a dict of tensors), got {type(state).__name__}")
        state = {k.removeprefix("features."): v for k, v in state.items() if not k.startswith("classifier.")}
        own = self.features.state_dict()
        missing = sorted(set(own) - set(state))
        if missing:
            raise RelightError(f"{path}: not VGG19 weights; missing keys {missing[:4]}...")
        for key, value in own.items():
            if tuple(state[key].shape) != tuple(value.shape):
                got = tuple(state[key].shape)
                raise RelightError(f"{path}: {key} has shape {got}, VGG19 needs {tuple(value.shape)}")
        self.features.load_state_dict({k: state[k] for k in own})
        logger.info("VGG19 weights loaded from %s", path)

    def train(self, mode: bool = True) -> VGG19Features:  # always frozen, always eval
        return super().train(False)

    def forward(self, x: torch.Tensor) -> list[torch.Tensor]:
        """x (N, 3, H, W) RGB in [0, 1] -> the five activations (relu1_2 … relu5_4)."""
        h = (x - self.mean) / self.std
        out = []
        for i, layer in enumerate(self.features):
            h = layer(h)
            if i in FEATURE_LAYERS:
                out.append(h)
        return out


class PerceptualLoss(nn.Module):
    """L1 on pixels plus weighted L1 on VGG19 activations of the masked images.

    Args:
        weights: VGG19 weights path (see module docstring).
    """

    def __init__(self, weights: str | os.PathLike | None):
        super().__init__()
        self.vgg = VGG19Features(weights)

    def forward(self, pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """pred, target (N, 3, H, W) RGB [0, 1]; mask (N, 1, H, W) -> scalar."""
        p, t = pred * mask, target * mask
        loss = F.l1_loss(p, t)
        for w, fp, ft in zip(LAYER_WEIGHTS, self.vgg(p), self.vgg(t), strict=True):
            loss = loss + w * F.l1_loss(fp, ft)
        return loss
