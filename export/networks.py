"""The networks of Tajima et al. (PG 2021): stage 1, stage 2 and the deep video prior.

All three share one module layout (DESIGN.md §1), so that the reference checkpoints
(``model_1st.pth``, ``model_2nd.pth``, the DVP network) load with ``strict=True`` at width 64 and
resolution 1024:

- encoder ``c0 … c5``: 4×4 stride-2 convs, widths w, 2w, 4w, 8w, 8w, 8w (w = ``width``); ``c0`` has a
  bias and no norm, ``c1 … c5`` have norms ``bnc1 … bnc5``; LeakyReLU(0.01) after each;
- residual blocks ``ra`` (transport path) and ``rb`` (albedo path) on the R/64 bottleneck:
  conv3(bias)–norm–ReLU–conv3(bias)–norm, plus the input;
- decoders ``dc0a … dc5a`` (transport, 9 channels) and ``dc0b … dc5b`` (albedo [+ skin] or residual):
  conv3 (no bias)–norm–[dropout 0.5 on dc0–dc2, training only]–ReLU–bilinear ×2 (align_corners=True),
  then concatenation ``(decoder, encoder)`` with the encoder feature of the same size; ``dc5`` is
  conv3 with a bias, then ×2 back to the input size;
- light head ``c0l … c{d-1}l`` on ``concat(bottleneck, ra, rb)`` (24w channels): 4×4 stride-2 convs,
  norm + LeakyReLU on all but the last, which has a bias and 27 outputs at 1×1.

**Light-head depth.** The bottleneck of an R×R input is (R/64)×(R/64); each 4×4 stride-2 conv with
padding 1 maps n to ⌊n/2⌋, so the head has d = ⌊log2(R/64)⌋ convs (4 at R = 1024, exactly the
reference; 3 at 512, 2 at 256, 1 at 128). The hidden widths are 8w, 4w, 2w (then 2w again for
R ≥ 2048); with d = 1 the single conv goes 24w → 27 directly, and at R = 64 (a 1×1 bottleneck, d = 0)
the head is one 1×1 conv ``c0l`` (24w → 27, bias). Key names are the reference's at R = 1024.

**Normalisation.** Every norm layer is an ``nn.BatchNorm2d`` (so state_dict keys are the reference's).
``norm="batch"``: ordinary BatchNorm (batch statistics in training, running statistics in eval).
``norm="instance"``: always per-sample statistics over H×W (biased variance, eps 1e-5, the
BatchNorm's affine weight and bias), in training and in eval; running statistics are neither used
nor updated. That is exactly what the reference code computes at inference, since it never calls
``eval()`` and runs one image at a time ("BatchNorm in training mode on a batch of one"). A 1×1
feature map (the bottleneck of a 64×64 input) normalises to the layer's bias, the limit of that
formula. In ONNX the statistics are explicit ReduceMean/Sub/Mul/Sqrt ops over each image's own H×W
(row means first, then their mean: onnxruntime's InstanceNormalization is not accurate enough at 1024²),
so each image of a batch gives exactly what it gives alone.

**Outputs** (never masked here; callers mask): stage 1 returns the transport raw, albedo and skin
through a sigmoid, and the light (N, 9, 3) with output channel 3k + c → light[k, c]. Stage 2 and the
DVP net return decoder ``b`` as it is (its last conv, upsampled; no activation), as the reference code
does for both (its ``train_baseline = False`` path; DESIGN.md §1). ``output_activation="tanh"`` is a
training option of ours, not the reference's: it bounds the output to [-1, 1]. It is part of the
network's config (so of every checkpoint) and is written into the exported graph's metadata
(``relight_rt.output_activation``); converted reference checkpoints never use it. Checkpoints saved
before the option existed were all trained with tanh, and :func:`export.checkpoint.load_checkpoint`
reads them so. Colour order is that of the weights: RGB for ours, BGR for the reference's
(``export.convert`` permutes those to RGB).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from relight_rt import RelightError
from relight_rt.engine.contract import NORMS, OUTPUT_ACTIVATIONS

__all__ = ["DVPNet", "Stage1Net", "Stage2Net", "build_network", "NETWORKS", "light_head_depth"]

_SLOPE = 0.01  # LeakyReLU negative slope of the encoder and light head
_DROPOUT_LAYERS = 3  # dc0..dc2 use dropout 0.5 in training


def light_head_depth(resolution: int) -> int:
    """Number of convs in the light head of an R×R network: ⌊log2(R/64)⌋ (4 at R = 1024)."""
    return (resolution // 64).bit_length() - 1


class _Norm(nn.BatchNorm2d):
    """BatchNorm2d that can compute per-sample statistics instead (``per_sample=True``).

    Same parameters and buffers as ``nn.BatchNorm2d``. Per-sample mode normalises each image
    over its own H×W (biased variance, ``eps``) with the layer's affine weight and bias.
    """

    def __init__(self, channels: int, per_sample: bool) -> None:
        super().__init__(channels)
        self.per_sample = per_sample

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if not self.per_sample:
            return super().forward(x)
        if torch.onnx.is_in_onnx_export():
            return self._exported_per_sample(x)
        if x.shape[-1] * x.shape[-2] == 1:
            # (x - mean) is exactly zero over a 1×1 map: the output is the bias (F.instance_norm refuses 1×1).
            return x * 0.0 + self.bias.view(1, -1, 1, 1)
        return F.instance_norm(x, weight=self.weight, bias=self.bias, eps=self.eps)

    def _exported_per_sample(self, x: torch.Tensor) -> torch.Tensor:
        """The same per-sample normalisation written for onnxruntime's float32 accuracy.

        onnxruntime's InstanceNormalization and ReduceMean over H×W accumulate one long float32 sum
        (relative error ~1e-5 per layer at 256², ~1e-4 at the end of a 1024² network). Averaging rows
        first and then the row means keeps every sum short (two-pass: mean, then the centred variance).
        """

        def spatial_mean(t: torch.Tensor) -> torch.Tensor:
            return t.mean(dim=3, keepdim=True).mean(dim=2, keepdim=True)

        centred = x - spatial_mean(x)
        var = spatial_mean(centred * centred)
        scale = self.weight.view(1, -1, 1, 1) * torch.rsqrt(var + self.eps)
        return centred * scale + self.bias.view(1, -1, 1, 1)


class _ResidualBlock(nn.Module):
    """conv3–norm–ReLU–conv3–norm plus the input (no activation after the sum)."""

    def __init__(self, channels: int, per_sample: bool) -> None:
        super().__init__()
        self.c1 = nn.Conv2d(channels, channels, 3, padding=1)
        self.c2 = nn.Conv2d(channels, channels, 3, padding=1)
        self.b1 = _Norm(channels, per_sample)
        self.b2 = _Norm(channels, per_sample)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        h = F.relu(self.b1(self.c1(x)))
        return x + self.b2(self.c2(h))


class _RelightNet(nn.Module):
    """The shared encoder, two residual blocks, two decoders and light head (module docstring)."""

    kind = ""

    def __init__(self, in_channels: int, out_b: int, width: int, resolution: int, norm: str) -> None:
        super().__init__()
        if not isinstance(width, int) or width < 1:
            raise RelightError(f"width: expected a positive int, got {width!r}")
        if not isinstance(resolution, int) or resolution < 64 or resolution % 64:
            raise RelightError(f"resolution: expected a positive multiple of 64, got {resolution!r}")
        if norm not in NORMS:
            raise RelightError(f"norm: expected one of {list(NORMS)}, got {norm!r}")
        self.width = width
        self.resolution = resolution
        self.norm = norm
        ps = norm == "instance"
        w = width
        enc = [w, 2 * w, 4 * w, 8 * w, 8 * w, 8 * w]

        self.c0 = nn.Conv2d(in_channels, enc[0], 4, stride=2, padding=1)
        for i in range(1, 6):
            setattr(self, f"c{i}", nn.Conv2d(enc[i - 1], enc[i], 4, stride=2, padding=1, bias=False))
        self.ra = _ResidualBlock(enc[5], ps)
        self.rb = _ResidualBlock(enc[5], ps)

        # decoder i: in -> out channels; after upsampling it is concatenated with encoder feature 4 - i
        dec_out = [8 * w, 8 * w, 4 * w, 2 * w, w]
        for branch, n_out in (("a", 9), ("b", out_b)):
            n_in = enc[5]
            for i, n in enumerate(dec_out):
                setattr(self, f"dc{i}{branch}", nn.Conv2d(n_in, n, 3, padding=1, bias=False))
                n_in = n + enc[4 - i]
            setattr(self, f"dc5{branch}", nn.Conv2d(n_in, n_out, 3, padding=1))

        # registration order = the reference's state_dict order: light convs, then every norm
        depth = light_head_depth(resolution)
        light = [3 * enc[5]] + [max(8 * w >> i, 2 * w) for i in range(depth - 1)] + [27]
        if depth == 0:
            self.c0l = nn.Conv2d(light[0], 27, 1)
        for i in range(depth):
            last = i == depth - 1
            setattr(self, f"c{i}l", nn.Conv2d(light[i], light[i + 1], 4, stride=2, padding=1, bias=last))

        for i in range(1, 6):
            setattr(self, f"bnc{i}", _Norm(enc[i], ps))
        for branch in ("a", "b"):
            for i, n in enumerate(dec_out):
                setattr(self, f"bndc{i}{branch}", _Norm(n, ps))
        for i in range(depth - 1):
            setattr(self, f"bnc{i}l", _Norm(light[i + 1], ps))
        self._light_depth = max(depth, 1)

    @property
    def config(self) -> dict:
        """The constructor arguments (plain ints/strs: safe for ``torch.load(weights_only=True)``)."""
        return {"width": self.width, "resolution": self.resolution, "norm": self.norm}

    def _check_input(self, x: torch.Tensor, channels: int, square: bool) -> None:
        if x.ndim != 4 or x.shape[1] != channels:
            raise RelightError(f"{self.kind} input: expected (N, {channels}, H, W), got {tuple(x.shape)}")
        h, w = x.shape[-2:]
        if square and (h, w) != (self.resolution, self.resolution):
            r = self.resolution
            raise RelightError(f"{self.kind} input: expected (N, {channels}, {r}, {r}), got {tuple(x.shape)}")
        if h % 64 or w % 64 or h == 0 or w == 0:
            raise RelightError(f"{self.kind} input: H and W must be positive multiples of 64, got {tuple(x.shape)}")

    def _encode(self, x: torch.Tensor) -> list[torch.Tensor]:
        feats = [F.leaky_relu(self.c0(x), _SLOPE)]
        for i in range(1, 6):
            conv, bn = getattr(self, f"c{i}"), getattr(self, f"bnc{i}")
            feats.append(F.leaky_relu(bn(conv(feats[-1])), _SLOPE))
        return feats

    def _decode(self, h: torch.Tensor, feats: list[torch.Tensor], branch: str) -> torch.Tensor:
        for i in range(5):
            h = getattr(self, f"bndc{i}{branch}")(getattr(self, f"dc{i}{branch}")(h))
            if i < _DROPOUT_LAYERS:
                h = F.dropout(h, 0.5, training=self.training)
            h = F.interpolate(F.relu(h), scale_factor=2.0, mode="bilinear", align_corners=True)
            h = torch.cat((h, feats[4 - i]), dim=1)
        h = getattr(self, f"dc5{branch}")(h)
        return F.interpolate(h, scale_factor=2.0, mode="bilinear", align_corners=True)

    def _light(self, bottleneck: torch.Tensor, hra: torch.Tensor, hrb: torch.Tensor) -> torch.Tensor:
        h = torch.cat((bottleneck, hra, hrb), dim=1)
        for i in range(self._light_depth - 1):
            h = F.leaky_relu(getattr(self, f"bnc{i}l")(getattr(self, f"c{i}l")(h)), _SLOPE)
        h = getattr(self, f"c{self._light_depth - 1}l")(h)
        return h.reshape(h.shape[0], 9, 3)


class Stage1Net(_RelightNet):
    """Stage 1: diffuse inverse rendering (transport, albedo, skin mask, light).

    Args:
        width: base channel count (64 = reference).
        resolution: the square input size R, a multiple of 64 (1024 = reference); sets the light head.
        norm: "batch" or "instance" (module docstring).
    """

    kind = "stage1"

    def __init__(self, width: int = 64, resolution: int = 1024, norm: str = "batch") -> None:
        super().__init__(3, 4, width, resolution, norm)

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """Run stage 1.

        Args:
            x: (N, 3, R, R) float, ``(2 * image - 1) * mask``, image in [0, 1] in the weights' colour order.

        Returns:
            transport (N, 9, R, R) raw; albedo (N, 3, R, R) in (0, 1); skin (N, 1, R, R) in (0, 1);
            light (N, 9, 3), ``light[n, k, c]`` = SH coefficient k of colour c. None of them masked.
        """
        self._check_input(x, 3, square=True)
        feats = self._encode(x)
        hra, hrb = self.ra(feats[5]), self.rb(feats[5])
        transport = self._decode(hra, feats, "a")
        hb = torch.sigmoid(self._decode(hrb, feats, "b"))
        light = self._light(feats[5], hra, hrb)
        return transport, hb[:, :3], hb[:, 3:4], light


class Stage2Net(_RelightNet):
    """Stage 2: the residual between a photo and its diffuse reconstruction.

    Args:
        width: base channel count (64 = reference).
        resolution: training size (a multiple of 64); the network runs on any H, W divisible by 64.
        norm: "batch" or "instance".
        output_activation: "none" (the reference) or "tanh" (a training option of ours, module docstring).

    The transport decoder and light head exist (the reference checkpoints carry them) but are unused.
    """

    kind = "stage2"

    def __init__(
        self, width: int = 64, resolution: int = 1024, norm: str = "batch", output_activation: str = "none"
    ) -> None:
        super().__init__(3, 3, width, resolution, norm)
        self.output_activation = _check_activation(output_activation)

    @property
    def config(self) -> dict:
        return {**super().config, "output_activation": self.output_activation}

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Run stage 2.

        Args:
            x: (N, 3, H, W) float, ``(2 * diffuse - 1) * mask``, H and W multiples of 64.

        Returns:
            residual (N, 3, H, W), not masked (unbounded as the reference's; in [-1, 1] with tanh);
            relit = clip(diffuse + residual, 0, 1).
        """
        self._check_input(x, 3, square=False)
        feats = self._encode(x)
        return _activate(self._decode(self.rb(feats[5]), feats, "b"), self.output_activation)


class DVPNet(_RelightNet):
    """The illumination-conditioned deep video prior (stage 2's albedo path, 3 + 27 input channels).

    Args:
        width: base channel count (64 = reference).
        resolution: training size (a multiple of 64); runs on any H, W divisible by 64.
        norm: "batch" or "instance".
        conditioned: True: input = frame (3) + tiled light (27); False: the frame only.
        output_activation: "none" (the reference) or "tanh" (a training option of ours, module docstring).
    """

    kind = "dvp"

    def __init__(
        self,
        width: int = 64,
        resolution: int = 1024,
        norm: str = "batch",
        conditioned: bool = True,
        output_activation: str = "none",
    ) -> None:
        self.conditioned = bool(conditioned)
        super().__init__(30 if self.conditioned else 3, 3, width, resolution, norm)
        self.output_activation = _check_activation(output_activation)

    @property
    def config(self) -> dict:
        return {**super().config, "conditioned": self.conditioned, "output_activation": self.output_activation}

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Run the DVP network.

        Args:
            x: (N, 30, H, W) (or (N, 3, H, W) unconditioned): channels 0–2 ``(2 * frame - 1) * mask``,
               channel 3 + 3k + c = light[k, c] at every pixel (not masked, not rescaled).

        Returns:
            (N, 3, H, W) (no activation as the reference's; in [-1, 1] with tanh); the relit frame is
            ``clip((out + 1) / 2, 0, 1)``, i.e. the network is fitted to ``2 * target - 1`` as in the reference.
        """
        self._check_input(x, 30 if self.conditioned else 3, square=False)
        feats = self._encode(x)
        return _activate(self._decode(self.rb(feats[5]), feats, "b"), self.output_activation)


def _check_activation(name: str) -> str:
    if name not in OUTPUT_ACTIVATIONS:
        raise RelightError(f"output_activation: expected one of {list(OUTPUT_ACTIVATIONS)}, got {name!r}")
    return name


def _activate(h: torch.Tensor, name: str) -> torch.Tensor:
    return torch.tanh(h) if name == "tanh" else h


NETWORKS: dict[str, type[_RelightNet]] = {"stage1": Stage1Net, "stage2": Stage2Net, "dvp": DVPNet}


def build_network(kind: str, config: dict) -> _RelightNet:
    """Make a network of one kind from its ``.config`` dict.

    Raises:
        RelightError: unknown kind (the message lists the known ones) or a bad config.
    """
    if kind not in NETWORKS:
        raise RelightError(f"network kind {kind!r} is unknown; known kinds: {sorted(NETWORKS)}")
    allowed = {"width", "resolution", "norm"}
    allowed |= {"stage1": set(), "stage2": {"output_activation"}, "dvp": {"conditioned", "output_activation"}}[kind]
    extra = set(config) - allowed
    if extra:
        raise RelightError(f"{kind} config: unexpected keys {sorted(extra)}; allowed: {sorted(allowed)}")
    return NETWORKS[kind](**config)
