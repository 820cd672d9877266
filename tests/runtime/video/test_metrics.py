"""Tests of relight_rt.video.metrics on synthetic clips whose answer is known."""

from __future__ import annotations

import numpy as np
import pytest

from relight_rt import RelightError
from relight_rt.video import metrics

H = W = 48


def _texture(seed: int = 0, size: int = H) -> np.ndarray:
    """Smooth random colour texture (size, size, 3) in [0.2, 0.8]: trackable by optical flow."""
    import cv2

    rng = np.random.default_rng(seed)
    tex = cv2.GaussianBlur(rng.random((size, size, 3)).astype(np.float32), (0, 0), 1.5)
    tex = (tex - tex.min()) / (tex.max() - tex.min())
    return 0.2 + 0.6 * tex


def _layers(seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Albedo (H, W, 3) and a smooth positive transport (H, W, 9) for a static subject."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float32) / H
    basis = np.stack([np.ones_like(xx), xx, yy, xx * yy, xx**2, yy**2, np.sin(3 * xx), np.cos(3 * yy), xx - yy], -1)
    mix = rng.normal(size=(9, 9)).astype(np.float32) * 0.3 + np.eye(9, dtype=np.float32)
    transport = basis @ mix
    transport[..., 0] = 3.0  # a strong DC term keeps shading positive
    return _texture(seed), transport


def _rotating_lights(n: int) -> np.ndarray:
    """(n, 9, 3) lights: constant ambient plus a first-order lobe that turns one revolution."""
    lights = np.zeros((n, 9, 3), np.float32)
    angle = 2 * np.pi * np.arange(n) / n
    lights[:, 0] = 0.25
    lights[:, 1] = 0.15 * np.cos(angle)[:, None]
    lights[:, 3] = 0.15 * np.sin(angle)[:, None]
    return lights


def _relit(albedo, transport, light):
    return np.clip(albedo * np.maximum(transport @ light, 0.0), 0, 1).astype(np.float32)


def test_static_clip_has_zero_errors():
    frame = _texture()
    result = metrics.TemporalMetrics()
    for _ in range(4):
        result.update(frame, None, frame)
    out = result.result()
    assert out.temporal_error == 0.0
    assert out.warping_error < 1e-6
    assert out.pairs == 3


def test_pure_flicker_is_high():
    rng = np.random.default_rng(0)
    frame = _texture()
    frames = [np.clip(frame * rng.uniform(0.7, 1.3), 0, 1) for _ in range(6)]
    flicker = metrics.temporal_error(frames)
    assert flicker > 0.05
    assert metrics.warping_error(frames, [frame] * 6) > 0.05


def test_uint8_and_float_agree():
    frames = [_texture(s) for s in range(3)]
    frames8 = [np.rint(f * 255).astype(np.uint8) for f in frames]
    frames_q = [f.astype(np.float32) / 255 for f in frames8]
    assert metrics.temporal_error(frames8) == pytest.approx(metrics.temporal_error(frames_q), rel=1e-5)


def test_temporal_error_uses_mask_intersection():
    a = np.zeros((H, W, 3), np.float32)
    b = a.copy()
    b[:, : W // 2] = 1.0  # changes only outside the mask
    mask = np.zeros((H, W), np.float32)
    mask[:, W // 2:] = 1.0
    assert metrics.temporal_error([a, b], [mask, mask]) == 0.0
    assert metrics.temporal_error([a, b]) == pytest.approx(0.5)


def test_warping_error_discounts_motion():
    big = _texture(3, size=H + 20)
    frames = [big[10:10 + H, 2 * t:2 * t + W] for t in range(5)]  # the camera pans 2 px per frame
    mask = np.zeros((H, W), np.float32)
    mask[8:-8, 8:-8] = 1
    temporal = metrics.temporal_error(frames, [mask] * 5)
    warping = metrics.warping_error(frames, frames, [mask] * 5)
    assert temporal > 0.02
    assert warping < 0.25 * temporal


@pytest.mark.parametrize("n_frames", [8, 24])
def test_light_following_correct_vs_frozen(n_frames):
    albedo, transport = _layers()
    lights = _rotating_lights(n_frames)
    correct = [_relit(albedo, transport, light) for light in lights]
    frozen = [correct[0]] * n_frames
    rng = np.random.default_rng(0)
    frozen_noisy = [np.clip(correct[0] + rng.normal(0, 0.01, correct[0].shape), 0, 1) for _ in range(n_frames)]
    args = ([albedo] * n_frames, [transport] * n_frames, lights)
    assert metrics.light_following(correct, *args) > 0.98
    assert metrics.light_following(frozen, *args) == 0.0
    assert abs(metrics.light_following(frozen_noisy, *args)) < 0.1


def test_light_gain_catches_damped_light():
    albedo, transport = _layers()
    lights = _rotating_lights(12)
    damped = _rotating_lights(12)
    damped[:, 1:] *= 0.5
    acc_full, acc_half = metrics.TemporalMetrics(), metrics.TemporalMetrics()
    for light, light_half in zip(lights, damped, strict=True):
        acc_full.update(_relit(albedo, transport, light), None, None, albedo, transport, light)
        acc_half.update(_relit(albedo, transport, light_half), None, None, albedo, transport, light)
    assert acc_full.result().light_gain == pytest.approx(1.0, abs=0.02)
    assert acc_full.result().residual_error < 0.2 * acc_half.result().residual_error
    assert acc_half.result().light_gain == pytest.approx(0.5, abs=0.05)
    assert acc_half.result().light_following > 0.95


def test_light_following_with_motion_uses_flow():
    big_albedo = _texture(5, size=H + 20)
    _, transport = _layers()
    lights = _rotating_lights(10)
    inputs, outputs, albedos = [], [], []
    for t in range(10):
        albedo = big_albedo[10:10 + H, 2 * t:2 * t + W]
        inputs.append(albedo)
        albedos.append(albedo)
        outputs.append(_relit(albedo, transport, lights[t]))
    score = metrics.light_following(outputs, albedos, [transport] * 10, lights, None, inputs)
    frozen = metrics.light_following([_relit(a, transport, lights[0]) for a in albedos], albedos, [transport] * 10,
                                     lights, None, inputs)
    assert score > 0.6
    assert score > frozen + 0.4


def test_flow_recovers_translation():
    big = _texture(7, size=H + 20)
    a = metrics.to_gray_u8(big[10:10 + H, 10:10 + W])
    b = metrics.to_gray_u8(big[10:10 + H, 13:13 + W])  # content moves 3 px left
    flow = metrics.dis_flow(a, b, "medium")
    assert np.median(flow[8:-8, 8:-8, 0]) == pytest.approx(-3.0, abs=0.3)
    assert np.median(flow[8:-8, 8:-8, 1]) == pytest.approx(0.0, abs=0.3)


def test_warp_does_not_modify_input():
    img = _texture()
    copy = img.copy()
    flow = np.ones((H, W, 2), np.float32)
    out = metrics.warp(img, flow)
    np.testing.assert_array_equal(img, copy)
    np.testing.assert_allclose(out[:-1, :-1], img[1:, 1:], atol=1e-6)


@pytest.mark.parametrize("channels", [1, 3, 9, 12])
def test_warp_shapes(channels):
    img = np.random.default_rng(0).random((H, W, channels)).astype(np.float32)
    assert metrics.warp(img, np.zeros((H, W, 2), np.float32)).shape == (H, W, channels)


def test_bad_inputs():
    with pytest.raises(RelightError, match=r"expected \(H, W, 3\) image"):
        metrics.temporal_error([np.zeros((4, 4, 4)), np.zeros((4, 4, 4))])
    with pytest.raises(RelightError, match="at least two frames"):
        metrics.temporal_error([np.zeros((4, 4, 3))])
    with pytest.raises(RelightError, match="expected mask of shape"):
        metrics.temporal_error([np.zeros((4, 4, 3))] * 2, [np.zeros((5, 5))] * 2)
    with pytest.raises(RelightError, match="size changed"):
        metrics.temporal_error([np.zeros((4, 4, 3)), np.zeros((5, 5, 3))])
    with pytest.raises(RelightError, match="NaN"):
        metrics.temporal_error([np.full((4, 4, 3), np.nan)] * 2)
    with pytest.raises(RelightError, match="preset"):
        metrics.TemporalMetrics("slowest")


def test_residual_error_penalises_frozen_light_and_flicker():
    albedo, transport = _layers()
    lights = _rotating_lights(12)
    rng = np.random.default_rng(3)
    results = {}
    for name in ("correct", "frozen", "flicker"):
        acc = metrics.TemporalMetrics()
        for light in lights:
            out = _relit(albedo, transport, lights[0] if name == "frozen" else light)
            if name == "flicker":
                out = np.clip(out * rng.uniform(0.9, 1.1), 0, 1)
            acc.update(out, None, None, albedo, transport, light)
        results[name] = acc.result()
    assert results["correct"].residual_error < 1e-3
    assert results["frozen"].residual_error > 0.01
    assert results["flicker"].residual_error > 0.01
    # the paper's temporal error rewards the frozen light; the residual error does not
    assert results["frozen"].temporal_error < results["correct"].temporal_error
