"""Stage-1/2 losses: masked L1, the spatial-frequency (LoG) loss, focal loss, SH flip signs."""

from __future__ import annotations

import math

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from _train_fixtures import sh_basis, sphere, sphere_transport  # noqa: E402

from export.losses import (  # noqa: E402
    FLIP_SIGNS,
    SF_SIGMAS,
    SpatialFrequencyLoss,
    Stage1Loss,
    band_magnitude_loss,
    direction_loss,
    flip_sh,
    focal_loss,
    log_kernel,
    masked_l1,
)
from export.shading import shade  # noqa: E402


def _sf() -> SpatialFrequencyLoss:
    return SpatialFrequencyLoss()


def test_masked_l1_hand_value():
    pred = torch.zeros(1, 2, 2, 2)
    true = torch.ones(1, 2, 2, 2)
    true[0, :, 1, 1] = 5.0  # outside the mask: ignored
    mask = torch.tensor([[[[1.0, 1.0], [0.5, 0.0]]]])
    # inside: weights 1 + 1 + 0.5 = 2.5 per channel, |diff| = 1 -> mean 1
    assert masked_l1(pred, true, mask).item() == pytest.approx(1.0)


@pytest.mark.parametrize("size", [8, 33, 64])
@pytest.mark.parametrize("channels", [1, 3])
def test_sf_zero_for_identical_images_and_positive_otherwise(size, channels):
    g = torch.Generator().manual_seed(0)
    a = torch.rand(2, channels, size, size, generator=g, dtype=torch.float64)
    b = a + 0.05 * torch.randn(a.shape, generator=g, dtype=torch.float64)
    mask = torch.ones(2, 1, size, size, dtype=torch.float64)
    sf = _sf()
    assert sf(a, a.clone(), mask).item() == 0.0
    assert sf(a, b, mask).item() > 0.0


def test_sf_ignores_differences_outside_the_mask():
    a = torch.rand(1, 3, 32, 32, dtype=torch.float64)
    b = a.clone()
    b[..., :, 20:] += 1.0
    mask = torch.zeros(1, 1, 32, 32, dtype=torch.float64)
    mask[..., :, :20] = 1.0
    assert _sf()(a, b, mask).item() == 0.0


@pytest.mark.parametrize("band", range(len(SF_SIGMAS)))
def test_log_kernels_are_zero_mean_with_unit_l1_norm(band):
    sigma = SF_SIGMAS[band]
    kernel = log_kernel(sigma)
    radius = math.ceil(3 * sigma)
    assert kernel.shape == (2 * radius + 1, 2 * radius + 1)
    assert kernel.sum().item() == pytest.approx(0.0, abs=1e-12)
    assert kernel.abs().sum().item() == pytest.approx(1.0, rel=1e-12)
    assert kernel[radius, radius] < 0  # centre of a LoG is negative (a bright blob gives a negative response)
    torch.testing.assert_close(kernel, kernel.T)


@pytest.mark.parametrize("band", [0, 3, 5])
@pytest.mark.parametrize("shape", [(24, 20), (40, 33), (7, 70)])
def test_fft_filter_equals_direct_zero_padded_convolution(band, shape):
    """FFT filtering with the capped kernel equals a direct zero-padded 2-D convolution with the full kernel."""
    sf = SpatialFrequencyLoss()
    full = log_kernel(SF_SIGMAS[band])
    radius = (full.shape[0] - 1) // 2
    image = torch.rand(1, 2, *shape, dtype=torch.float64)
    direct = torch.nn.functional.conv2d(image.reshape(2, 1, *shape), full[None, None], padding=radius)
    torch.testing.assert_close(sf.filter(image, band), direct.reshape(1, 2, *shape), atol=1e-12, rtol=0)


def test_sf_flat_regions_give_no_response():
    sf = _sf()
    image = torch.full((1, 1, 80, 80), 0.7, dtype=torch.float64)
    for band in range(3):  # the kernel fits inside, away from the borders
        assert sf.filter(image, band)[..., 30:50, 30:50].abs().max().item() < 1e-12


def test_focal_loss_values():
    mask = torch.ones(1, 1, 1, 1)
    half = torch.full((1, 1, 1, 1), 0.5)
    one = torch.ones(1, 1, 1, 1)
    # y = 1, p = 0.5, gamma 2: (1 - p)^2 * -log p = 0.25 * ln 2
    assert focal_loss(half, one, mask).item() == pytest.approx(0.25 * math.log(2), rel=1e-5)
    assert focal_loss(one, one, mask).item() < 1e-6
    assert focal_loss(torch.full((1, 1, 1, 1), 0.9), one, mask) < focal_loss(half, one, mask)


def _sphere_batch(size=32, seed=0):
    rng = np.random.default_rng(seed)
    mask, normals = sphere(size, 0.4)
    t = torch.from_numpy(sphere_transport(normals, mask)).permute(2, 0, 1)[None]
    albedo = torch.from_numpy(rng.uniform(0.2, 0.8, (1, 3, size, size)).astype(np.float32))
    light = torch.from_numpy(rng.normal(0, 0.3, (1, 9, 3)).astype(np.float32))
    light[0, 0] += 0.8
    m = torch.from_numpy(mask)[None, None]
    skin = (m * (torch.rand(m.shape) > 0.5)).float()
    return {"transport": t, "albedo": albedo * m, "light": light, "skin": skin, "mask": m}


def test_stage1_loss_has_every_paper_term_and_vanishes_at_the_truth():
    true = _sphere_batch()
    terms = Stage1Loss()(dict(true), true)
    renders = [k for k in terms if k.startswith("render_")]
    shadings = [k for k in terms if k.startswith("shading_")]
    assert len(renders) == 7 and len(shadings) == 3
    assert {"transport", "albedo", "light", "skin", "sf_albedo", "sf_shading", "total"} <= set(terms)
    assert terms["total"].item() < 1e-4
    assert "sf_albedo" not in Stage1Loss(use_sf=False)(dict(true), true)


def test_stage1_loss_grows_with_a_wrong_light():
    true = _sphere_batch()
    pred = dict(true)
    pred["light"] = true["light"] * 1.3
    terms = Stage1Loss()(pred, true)
    assert terms["light"] > 0 and terms["render_atL"] > 0 and terms["render_aTl"] == 0


def test_band_term_is_off_by_default_and_vanishes_at_the_truth():
    true = _sphere_batch()
    assert "transport_bands" not in Stage1Loss()(dict(true), true)
    terms = Stage1Loss(band_weight=2.0)(dict(true), true)
    assert terms["transport_bands"].item() < 1e-6
    with pytest.raises(ValueError):
        Stage1Loss(band_weight=-1.0)


def test_band_term_prices_a_shrunk_band_not_a_rotated_one():
    """The sphere's transport with its degree-1 and degree-2 bands shrunk (what a regression does where it is unsure)
    costs in proportion to the shrinkage; the same bands rotated (left-right mirror: k = 1, 4, 5 change sign, every
    band's magnitude kept) cost nothing here, although the per-coefficient transport L1 sees them."""
    true = _sphere_batch()
    t, m = true["transport"], true["mask"]
    gains = torch.tensor([1.0, 0.9, 0.9, 0.9, 0.75, 0.75, 0.75, 0.75, 0.75]).reshape(1, 9, 1, 1)
    shrunk = t * gains
    inside = m[0, 0] > 0
    mag1 = t[0, 1:4].norm(dim=0)[inside].mean()
    mag2 = t[0, 4:9].norm(dim=0)[inside].mean()
    expected = (0.1 * mag1 + 0.25 * mag2) / 2
    assert band_magnitude_loss(shrunk, t, m).item() == pytest.approx(expected.item(), rel=1e-3)
    rotated = flip_sh(t, dim=1)
    assert band_magnitude_loss(rotated, t, m).item() < 1e-6
    assert masked_l1(rotated, t, m).item() > 1e-2
    pred = dict(true, transport=shrunk)
    weighted = Stage1Loss(band_weight=3.0)(pred, true)
    assert weighted["transport_bands"].item() == pytest.approx(3.0 * expected.item(), rel=1e-3)
    # its gradient asks the shrunk bands to grow
    shrunk = shrunk.clone().requires_grad_(True)
    band_magnitude_loss(shrunk, t, m).backward()
    step = -shrunk.grad[0, 1:9] * shrunk.detach()[0, 1:9]
    assert step.sum(0)[inside].mean() > 0


def test_direction_term_prices_a_rotated_band_not_a_shrunk_one():
    """The degree-1 direction's error: zero at the truth and for a shrunk band; for the sphere's transport mirrored
    left-right (the degree-1 y component negated) it is the truth's magnitude times (1 - cos) of the mirrored
    direction, by hand."""
    true = _sphere_batch()
    t, m = true["transport"], true["mask"]
    assert "transport_direction" not in Stage1Loss()(dict(true), true)
    assert Stage1Loss(direction_weight=1.0)(dict(true), true)["transport_direction"].item() < 1e-5
    gains = torch.tensor([1.0, 0.8, 0.8, 0.8, 0.5, 0.5, 0.5, 0.5, 0.5]).reshape(1, 9, 1, 1)
    assert direction_loss(t * gains, t, m).item() < 1e-5
    rotated = flip_sh(t, dim=1)
    t1 = t[0, 1:4].double()
    norm = t1.norm(dim=0)
    cos = (t1 * rotated[0, 1:4].double()).sum(0) / norm.clamp_min(1e-12) ** 2
    inside = m[0, 0] > 0
    expected = (norm * (1 - cos))[inside].mean()
    assert direction_loss(rotated, t, m).item() == pytest.approx(expected.item(), rel=1e-3)
    assert expected > 1e-2
    terms = Stage1Loss(direction_weight=4.0)(dict(true, transport=rotated), true)
    assert terms["transport_direction"].item() == pytest.approx(4.0 * expected.item(), rel=1e-3)
    with pytest.raises(ValueError):
        Stage1Loss(direction_weight=-0.5)


def test_flip_signs_follow_the_basis():
    """Y_k(x, −y, z) = sign_k · Y_k(x, y, z) for the DESIGN.md §3 basis (k = 1, 4, 5 odd in y)."""
    n = np.random.default_rng(3).normal(size=(50, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    mirrored = n * np.array([1, -1, 1])
    np.testing.assert_allclose(sh_basis(mirrored), sh_basis(n) * np.asarray(FLIP_SIGNS), atol=1e-12)
    assert [k for k, s in enumerate(FLIP_SIGNS) if s < 0] == [1, 4, 5]


def test_flipped_render_equals_render_of_the_mirrored_scene():
    """Physical check: an off-centre sphere under an asymmetric light, flipped left-right, equals the
    mirrored sphere (analytic transport) under the flipped light; and the flip of the transport map
    with the k = 1, 4, 5 sign change is that mirrored sphere's transport."""
    size = 48
    mask, normals = sphere(size, 0.3, shift=(2.0, 7.0))
    mask_m, normals_m = sphere(size, 0.3, shift=(2.0, -7.0))
    t = torch.from_numpy(sphere_transport(normals, mask)).permute(2, 0, 1)[None].double()
    t_m = torch.from_numpy(sphere_transport(normals_m, mask_m)).permute(2, 0, 1)[None].double()
    light = torch.tensor(np.random.default_rng(5).normal(0, 0.4, (1, 9, 3)))
    light[0, 0] += 1.0
    image = shade(t, light).clamp_min(0)
    flipped_t = flip_sh(t.flip(-1), dim=1)
    torch.testing.assert_close(flipped_t, t_m, atol=1e-5, rtol=0)
    torch.testing.assert_close(image.flip(-1), shade(t_m, flip_sh(light, dim=1)).clamp_min(0), atol=1e-5, rtol=0)
    # and the unflipped light does not give the mirrored image (the test can fail)
    assert (image.flip(-1) - shade(t_m, light).clamp_min(0)).abs().max() > 1e-2
