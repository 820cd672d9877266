"""The SH shading of DESIGN.md §3 in torch, for training and evaluation: the one place ``T·L`` is typed in export/.

The runtime's numpy counterpart is :func:`relight_rt.sh.shading` (channel-last) and ``shading_chw``; these are the
same formula on batched channel-first tensors, differentiable.
"""

from __future__ import annotations

import torch


def shade(transport: torch.Tensor, light: torch.Tensor) -> torch.Tensor:
    """Raw SH shading T·L, not clamped (the losses compare it so: the clamp has no gradient below 0).

    Args:
        transport: (N, 9, H, W).
        light: (N, 9, 3), column c = colour channel c (RGB).

    Returns:
        (N, 3, H, W) shading.
    """
    return torch.einsum("nkhw,nkc->nchw", transport, light)


def shading(transport: torch.Tensor, light: torch.Tensor) -> torch.Tensor:
    """max(0, T·L) for (N, 9, H, W) and (N, 9, 3) -> (N, 3, H, W): what a camera's diffuse image holds."""
    return shade(transport, light).clamp_min(0.0)


def render_diffuse(
    albedo: torch.Tensor, transport: torch.Tensor, light: torch.Tensor, mask: torch.Tensor
) -> torch.Tensor:
    """clip(albedo ⊙ max(0, T·L), 0, 1) ⊙ mask for (N,3,H,W), (N,9,H,W), (N,9,3), (N,1,H,W) -> (N,3,H,W)."""
    return (albedo * shading(transport, light)).clamp(0.0, 1.0) * mask
