"""Losses of stage-1 and stage-2 training (Tajima et al. 2021, §4; Kanamori & Endo 2018, §5).

Every image-space loss is a mean over the pixels inside the mask: with a soft mask m (N,1,H,W)
in [0, 1] the L1 loss of x, y (N,C,H,W) is ``Σ m·|x − y| / (C · Σ m)``, summed over the whole
batch (a sample with a larger mask counts more, as in a batch of one pixel set). The light loss
is the plain mean over the 27 coefficients.

Shading in the losses is the raw product ``T·L`` without the max(0, ·) clamp (the clamp only
hides a few ringing pixels and would cut their gradient); rendering is ``albedo ⊙ (T·L)``. Both
sides of every comparison are computed the same way, so the clamp would not change the minimum.

Spatial-frequency (SF) loss. For each σ in (0.6, 1.2, 2.4, 4.8, 9.6, 19.2) pixels, with weights
(600, 500, 400, 20, 10, 10), the difference of the two masked images is filtered by a
Laplacian-of-Gaussian kernel K_σ and the squared response is averaged inside the mask. Our
normalisation of K_σ (the paper does not state one):

- K_σ = g''(x)·g(y) + g(x)·g''(y), where g is a sampled 1-D Gaussian of radius ceil(3σ) scaled to
  sum 1 and g'' its sampled second derivative with its sum removed along g (g'' − (Σg'')·g). The
  2-D kernel therefore has zero mean exactly (a flat region gives zero response however the
  Gaussian is truncated). Size 2·ceil(3σ)+1: 5 px at σ = 0.6 up to 117 px at σ = 19.2.
- K_σ is then scaled to unit L1 norm (Σ|K_σ| = 1). An image in [0, 1] then gives responses in
  [−0.5, 0.5] at every σ, so the weights compare bands on one scale.
- Images are zero-padded (outside the mask both images are zero anyway). For an image smaller
  than the kernel, taps further than the image's size from the centre only ever meet padding;
  they are dropped, which is exact, not an approximation (the normalisation is computed on the
  full kernel first).
- Filtering is by FFT on a (2H, 2W) zero-padded grid: one forward transform of the difference
  image and one inverse per band, whatever σ (see :class:`SpatialFrequencyLoss`).

Focal loss (Lin et al. 2017) on the skin mask with γ = 2 and no class weight, on soft labels:
``−[y(1 − p)^γ log p + (1 − y) p^γ log(1 − p)]`` averaged inside the mask.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch

from .shading import shade

SF_SIGMAS: tuple[float, ...] = (0.6, 1.2, 2.4, 4.8, 9.6, 19.2)
SF_WEIGHTS: tuple[float, ...] = (600.0, 500.0, 400.0, 20.0, 10.0, 10.0)

# SH coefficients odd in y (DESIGN.md §3: Y1 ∝ y, Y4 ∝ xy, Y5 ∝ yz) change sign under a horizontal flip.
FLIP_SIGNS: tuple[float, ...] = (1.0, -1.0, 1.0, 1.0, -1.0, -1.0, 1.0, 1.0, 1.0)

_EPS = 1e-6


def masked_l1(pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Mean absolute difference inside the mask.

    Args:
        pred, target: (N, C, H, W) float.
        mask: (N, 1, H, W) float in [0, 1].

    Returns:
        Scalar tensor: Σ m·|pred − target| / (C · Σ m).
    """
    channels = pred.shape[1]
    return (mask * (pred - target).abs()).sum() / (channels * mask.sum() + _EPS)


def masked_mse(pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Mean squared difference inside the mask, shapes as :func:`masked_l1`."""
    channels = pred.shape[1]
    return (mask * (pred - target).square()).sum() / (channels * mask.sum() + _EPS)


def flip_sh(coeffs: torch.Tensor, dim: int) -> torch.Tensor:
    """Flip the sign of the SH coefficients odd in y (k = 1, 4, 5) along dimension ``dim`` (size 9).

    A horizontal image flip mirrors y (+y points to the image's right, DESIGN.md §3); transport
    and light must both get this sign change so that the flipped image is still their product.
    """
    shape = [1] * coeffs.ndim
    shape[dim] = 9
    signs = torch.tensor(FLIP_SIGNS, dtype=coeffs.dtype, device=coeffs.device).reshape(shape)
    return coeffs * signs


# ---------------------------------------------------------------------------------------------
# spatial-frequency loss


def log_kernel(sigma: float) -> torch.Tensor:
    """The normalised LoG kernel of the SF loss (module docstring), float64 (2r+1, 2r+1), r = ceil(3σ).

    Built from separable factors: g (sampled Gaussian, sum 1) and g'' (its sampled second derivative
    minus (Σg'')·g, so that it sums to 0); K = g''(x)g(y) + g(x)g''(y) then sums to exactly 0 and is
    scaled to Σ|K| = 1. Symmetric, so correlation and convolution agree. Its centre is negative.
    """
    radius = max(1, math.ceil(3.0 * sigma))
    x = torch.arange(-radius, radius + 1, dtype=torch.float64)
    g = torch.exp(-(x**2) / (2 * sigma**2))
    g = g / g.sum()
    g2 = (x**2 / sigma**4 - 1.0 / sigma**2) * g
    g2 = g2 - g2.sum() * g
    kernel = g2[:, None] * g[None, :] + g[:, None] * g2[None, :]
    return kernel / kernel.abs().sum()


class SpatialFrequencyLoss(torch.nn.Module):
    """Weighted multi-scale LoG loss of two masked images (see the module docstring).

    Filtering is done by FFT (one forward transform of the difference image, one inverse per band)
    on a grid padded to (2H, 2W), which makes the circular convolution equal to zero-padded linear
    filtering for every output pixel (the kernel radius is capped at H − 1, W − 1, see the module
    docstring). On a CPU at 128² this is about ten times faster than separable 1-D convolutions,
    whose 117-tap kernels at σ = 19.2 dominate the step time. Kernel spectra are cached per image
    size, device and dtype.

    Args:
        sigmas: Gaussian σ in pixels per band.
        weights: weight per band.
    """

    def __init__(self, sigmas: Sequence[float] = SF_SIGMAS, weights: Sequence[float] = SF_WEIGHTS):
        super().__init__()
        if len(sigmas) != len(weights):
            raise ValueError(f"expected one weight per sigma, got {len(sigmas)} sigmas and {len(weights)} weights")
        self.sigmas = tuple(float(s) for s in sigmas)
        self.weights = tuple(float(w) for w in weights)
        self.kernels = [log_kernel(s) for s in self.sigmas]
        self._spectra: dict[tuple, list[torch.Tensor]] = {}

    def spectra(self, h: int, w: int, device: torch.device, dtype: torch.dtype) -> list[torch.Tensor]:
        """rfft2 of each band's kernel, capped and centred at the origin of a (2h, 2w) grid."""
        key = (h, w, str(device), dtype)
        if key not in self._spectra:
            out = []
            for kernel in self.kernels:
                r = (kernel.shape[0] - 1) // 2
                rh, rw = min(r, h - 1), min(r, w - 1)  # taps further out only ever meet padding
                k = kernel[r - rh : r + rh + 1, r - rw : r + rw + 1]
                grid = torch.zeros(2 * h, 2 * w, dtype=torch.float64)
                grid[: 2 * rh + 1, : 2 * rw + 1] = k
                grid = torch.roll(grid, shifts=(-rh, -rw), dims=(0, 1))
                out.append(torch.fft.rfft2(grid.to(dtype)).to(device))
            self._spectra[key] = out
        return self._spectra[key]

    def _responses(self, image: torch.Tensor):
        """Yield (band, LoG response (N, C, H, W)) for every band."""
        h, w = image.shape[-2:]
        spec = torch.fft.rfft2(image, s=(2 * h, 2 * w))
        for band, k in enumerate(self.spectra(h, w, image.device, image.dtype)):
            yield band, torch.fft.irfft2(spec * k, s=(2 * h, 2 * w))[..., :h, :w]

    def filter(self, image: torch.Tensor, band: int) -> torch.Tensor:
        """LoG response of band ``band`` for (N, C, H, W) float32/64 -> (N, C, H, W), zero padding."""
        h, w = image.shape[-2:]
        k = self.spectra(h, w, image.device, image.dtype)[band]
        return torch.fft.irfft2(torch.fft.rfft2(image, s=(2 * h, 2 * w)) * k, s=(2 * h, 2 * w))[..., :h, :w]

    def forward(self, pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """Σ_σ w_σ · masked mean of (K_σ * ((pred − target) ⊙ mask))².

        Args:
            pred, target: (N, C, H, W) float.
            mask: (N, 1, H, W) float in [0, 1].

        Returns:
            Scalar tensor, ≥ 0, zero when pred equals target inside the mask.
        """
        diff = (pred - target) * mask  # the filter is linear: filter the difference once
        if diff.dtype != torch.float64:
            diff = diff.float()
        mask = mask.to(diff.dtype)
        total = diff.new_zeros(())
        zero = torch.zeros((), dtype=diff.dtype, device=diff.device)
        for band, response in self._responses(diff):
            total = total + self.weights[band] * masked_mse(response, zero.expand_as(response), mask)
        return total


def focal_loss(pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor, gamma: float = 2.0) -> torch.Tensor:
    """Binary focal loss of a probability map inside the mask.

    Args:
        pred: (N, 1, H, W) probabilities in [0, 1] (after the sigmoid).
        target: (N, 1, H, W) labels in [0, 1] (soft labels allowed).
        mask: (N, 1, H, W) in [0, 1].
        gamma: focusing parameter.

    Returns:
        Scalar tensor, masked mean.
    """
    p = pred.float().clamp(1e-6, 1.0 - 1e-6)
    y = target.float()
    loss = -(y * (1.0 - p).pow(gamma) * torch.log(p) + (1.0 - y) * p.pow(gamma) * torch.log1p(-p))
    return (mask * loss).sum() / (mask.sum() + _EPS)


# ---------------------------------------------------------------------------------------------
# the stage-1 objective

SH_DEGREES: tuple[slice, ...] = (slice(1, 4), slice(4, 9))  # the degree-1 and degree-2 coefficients (DESIGN.md §3)


def band_magnitudes(transport: torch.Tensor, eps: float = 1e-8) -> torch.Tensor:
    """Per pixel, the magnitude of the degree-1 and of the degree-2 band: (N, 9, H, W) -> (N, 2, H, W).

    ``sqrt(Σ_k T_k² + eps)`` over each degree's coefficients; the eps keeps the gradient finite where a band is zero.
    """
    return torch.stack([(transport[:, s].square().sum(1) + eps).sqrt() for s in SH_DEGREES], dim=1)


def band_magnitude_loss(pred: torch.Tensor, true: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Masked L1 of the degree-1 and degree-2 band magnitudes of two transports (N, 9, H, W), mask (N, 1, H, W).

    Where the network is unsure of a surface's direction, the per-coefficient L1 of the transport is smallest for a
    shrunk band (the median of directions that disagree lies inside the sphere): measured on held-out renders the
    bundled stage 1's degree-1 magnitude was x0.91 of the truth's and degree-2 x0.76, so every new light changed the
    photo too little (docs/RESULTS.md, "Real photos"). This term compares only the magnitudes, whatever their
    direction, so a shrunk band costs here even where its direction is wrong; a rotation inside a band costs nothing.
    """
    return masked_l1(band_magnitudes(pred.float()), band_magnitudes(true.float()), mask)


def direction_loss(pred: torch.Tensor, true: torch.Tensor, mask: torch.Tensor, eps: float = 1e-6) -> torch.Tensor:
    """Masked mean of ``|t₁| · (1 − cos(T̂₁, t₁))`` for two transports (N, 9, H, W): the degree-1 direction's error.

    The degree-1 band of a pixel's transport points along its (visibility-weighted) normal; its direction sets which
    side of a face or body a new light brightens. Weighted by the true band's magnitude (the error's size in
    transport units, zero where the truth has no direction); a scaled band costs nothing here, a rotated one does.
    """
    degree1 = SH_DEGREES[0]
    p, t = pred[:, degree1].float(), true[:, degree1].float()
    t_norm = (t.square().sum(1, keepdim=True) + eps).sqrt()
    p_norm = (p.square().sum(1, keepdim=True) + eps).sqrt()
    cos = (p * t).sum(1, keepdim=True) / (p_norm * t_norm)
    return masked_l1(t_norm * (1.0 - cos), torch.zeros_like(cos), mask)


class Stage1Loss(torch.nn.Module):
    """All stage-1 terms, each with weight 1 (the paper's choice).

    Terms (names as in the returned dict): ``transport``, ``albedo``, ``light`` (unary L1);
    ``shading_TL`` (T̂·L), ``shading_tL`` (T·L̂), ``shading_TLhat`` (T̂·L̂) against T·L; seven
    ``render_*`` terms, one per combination of predicted (upper case letter) and true (lower
    case) albedo, transport and light with at least one predicted, against a ⊙ (t·l); ``skin``
    (focal); ``sf_albedo`` and ``sf_shading`` (SF loss of Â and of T̂·L̂), unless ``use_sf`` is off;
    ``transport_bands`` (:func:`band_magnitude_loss`, ours, not the paper's) times ``band_weight`` when it is > 0;
    ``transport_direction`` (:func:`direction_loss`, ours) times ``direction_weight`` when it is > 0.

    Args:
        use_sf: include the two SF terms (off for the "without SF loss" baseline).
        sf_scale: a common factor on the SF band weights (1 = the paper's 600 … 10). At low training
            resolutions the mask outline is a large share of the pixels and its LoG response makes the
            SF terms dominate (at 128² with scale 1 they were ~75% of the objective after 5 epochs).
        band_weight: weight of the ``transport_bands`` term (0: off, the paper's objective).
        direction_weight: weight of the ``transport_direction`` term (0: off).
    """

    def __init__(self, use_sf: bool = True, sf_scale: float = 1.0, band_weight: float = 0.0,
                 direction_weight: float = 0.0):
        super().__init__()
        if not band_weight >= 0:
            raise ValueError(f"band_weight: expected >= 0, got {band_weight}")
        if not direction_weight >= 0:
            raise ValueError(f"direction_weight: expected >= 0, got {direction_weight}")
        self.use_sf = use_sf
        self.band_weight = float(band_weight)
        self.direction_weight = float(direction_weight)
        self.sf = SpatialFrequencyLoss(weights=[w * sf_scale for w in SF_WEIGHTS])

    def forward(self, pred: dict[str, torch.Tensor], true: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        """Compute every term and their sum.

        Args:
            pred: transport (N,9,H,W), albedo (N,3,H,W), skin (N,1,H,W), light (N,9,3); unmasked
                network outputs are fine (every term is restricted to the mask).
            true: the same keys plus mask (N,1,H,W).

        Returns:
            dict of scalar tensors: each term and ``total``.
        """
        m = true["mask"].float()
        T, A, L = (pred[k].float() for k in ("transport", "albedo", "light"))
        t, a, l = (true[k].float() for k in ("transport", "albedo", "light"))
        terms: dict[str, torch.Tensor] = {
            "transport": masked_l1(T, t, m),
            "albedo": masked_l1(A, a, m),
            "light": (L - l).abs().mean(),
        }
        s_true = shade(t, l)
        s_TL, s_tL, s_hat = shade(T, l), shade(t, L), shade(T, L)
        terms["shading_TL"] = masked_l1(s_TL, s_true, m)
        terms["shading_tL"] = masked_l1(s_tL, s_true, m)
        terms["shading_TLhat"] = masked_l1(s_hat, s_true, m)
        img_true = a * s_true
        shadings = {"tl": s_true, "Tl": s_TL, "tL": s_tL, "TL": s_hat}
        for alb_name, alb in (("a", a), ("A", A)):
            for sh_name, s in shadings.items():
                name = alb_name + sh_name
                if name == "atl":
                    continue
                terms[f"render_{name}"] = masked_l1(alb * s, img_true, m)
        terms["skin"] = focal_loss(pred["skin"], true["skin"], m)
        if self.use_sf:
            terms["sf_albedo"] = self.sf(A, a, m)
            terms["sf_shading"] = self.sf(s_hat, s_true, m)
        if self.band_weight > 0:
            terms["transport_bands"] = self.band_weight * band_magnitude_loss(T, t, m)
        if self.direction_weight > 0:
            terms["transport_direction"] = self.direction_weight * direction_loss(T, t, m)
        terms["total"] = torch.stack(list(terms.values())).sum()
        return terms
