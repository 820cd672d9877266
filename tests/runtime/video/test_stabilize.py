"""Tests of relight_rt.video.stabilize: less flicker in the layers, the light still moves the shading."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from relight_rt import RelightError
from relight_rt.video import metrics
from relight_rt.video.stabilize import Stabilizer, stabilize

H = W = 64
SQ = 32  # side of the moving square


def _texture(seed: int, size: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    tex = cv2.GaussianBlur(rng.random((size, size, 3)).astype(np.float32), (0, 0), 1.5)
    tex = (tex - tex.min()) / (tex.max() - tex.min())
    return 0.2 + 0.6 * tex


def _moving_square_clip(n: int, noise: float = 0.06, seed: int = 0):
    """A textured square moving 1.5 px right and 1 px down per frame over a grey background.

    Returns per frame: input frame, mask, true albedo, noisy albedo estimate, noisy transport estimate,
    true transport. The transport is smooth and positive; the noise is per frame and per pixel plus a
    per-frame gain (the flicker of a frame-by-frame estimator).
    """
    rng = np.random.default_rng(seed)
    tex = _texture(seed, SQ)
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float32) / H
    true_transport = np.stack([np.full_like(xx, 3.0), xx, yy, xx * yy, xx**2, yy**2, xx - yy, 0 * xx, 0 * xx], -1)
    clip = []
    for t in range(n):
        x0, y0 = 6 + 1.5 * t, 6 + 1.0 * t
        m = np.float32([[1, 0, x0], [0, 1, y0]])
        albedo = cv2.warpAffine(tex, m, (W, H), flags=cv2.INTER_LINEAR, borderValue=(0.5, 0.5, 0.5))
        mask = cv2.warpAffine(np.ones((SQ, SQ), np.float32), m, (W, H), flags=cv2.INTER_LINEAR)
        frame = np.clip(albedo * 0.9, 0, 1)
        gain = rng.uniform(0.9, 1.1)
        noisy_albedo = np.clip(albedo * gain + rng.normal(0, noise, albedo.shape), 0, 1).astype(np.float32)
        noisy_transport = (true_transport * rng.uniform(0.9, 1.1)
                           + rng.normal(0, noise, true_transport.shape)).astype(np.float32)
        clip.append((frame, mask, albedo, noisy_albedo, noisy_transport, true_transport))
    return clip


def _lights(n: int) -> np.ndarray:
    lights = np.zeros((n, 9, 3), np.float32)
    angle = 2 * np.pi * np.arange(n) / n
    lights[:, 0] = 0.25
    lights[:, 1] = 0.2 * np.cos(angle)[:, None]
    lights[:, 2] = 0.2 * np.sin(angle)[:, None]
    return lights


def _relight(albedo, transport, light):
    return np.clip(albedo * np.maximum(transport @ light, 0), 0, 1).astype(np.float32)


def test_stabilised_layers_flicker_less_and_shading_still_moves():
    n = 16
    clip = _moving_square_clip(n)
    lights = _lights(n)
    raw = metrics.TemporalMetrics()
    stab_metrics = metrics.TemporalMetrics()
    raw_albedo = metrics.TemporalMetrics()
    stab_albedo = metrics.TemporalMetrics()
    stab = Stabilizer()
    for t, (frame, mask, _, noisy_a, noisy_t, _) in enumerate(clip):
        a_s, t_s = stab.update(frame, mask, noisy_a, noisy_t)
        raw_albedo.update(noisy_a, mask, frame)
        stab_albedo.update(a_s, mask, frame)
        raw.update(_relight(noisy_a, noisy_t, lights[t]), mask, frame, noisy_a, noisy_t, lights[t])
        stab_metrics.update(_relight(a_s, t_s, lights[t]), mask, frame, noisy_a, noisy_t, lights[t])
    r_alb, s_alb = raw_albedo.result(), stab_albedo.result()
    r, s = raw.result(), stab_metrics.result()
    assert s_alb.warping_error < 0.6 * r_alb.warping_error
    assert s.warping_error < 0.7 * r.warping_error
    # the light turns a full revolution: the stabilised video follows it at least as well
    assert s.light_following > 0.5
    assert s.light_following > r.light_following - 0.05
    assert s.light_gain == pytest.approx(1.0, abs=0.25)


def test_static_light_static_scene_converges_to_mean():
    rng = np.random.default_rng(1)
    frame = _texture(2, W)
    truth = frame.copy()
    stab = Stabilizer(strength=0.9)
    errors = []
    for _ in range(30):
        noisy = np.clip(truth + rng.normal(0, 0.05, truth.shape), 0, 1).astype(np.float32)
        a_s, _ = stab.update(frame, None, noisy, np.zeros((W, W, 9), np.float32))
        errors.append(np.abs(a_s - truth)[4:-4, 4:-4].mean())
    assert errors[-1] < 0.5 * errors[0]


def test_occlusion_and_cut_fall_back_to_estimate():
    frame_a = _texture(3, W)
    frame_b = _texture(4, W)  # a scene cut: nothing matches
    stab = Stabilizer()
    stab.update(frame_a, None, frame_a, np.zeros((W, W, 9), np.float32))
    est = np.full((W, W, 3), 0.3, np.float32)
    a_s, _ = stab.update(frame_b, None, est, np.zeros((W, W, 9), np.float32))
    assert stab.last_weight.mean() < 0.2
    assert np.abs(a_s - est).mean() < 0.05


def test_downscaled_flow_still_stabilises():
    clip = _moving_square_clip(10)
    full, small = Stabilizer(flow_max_side=None), Stabilizer(flow_max_side=32)
    err = {"full": [], "small": []}
    for frame, mask, albedo, noisy_a, noisy_t, _ in clip:
        for name, stab in (("full", full), ("small", small)):
            a_s, _ = stab.update(frame, mask, noisy_a, noisy_t)
            err[name].append(np.abs(a_s - albedo)[mask > 0.5].mean())
    noise = np.mean([np.abs(c[3] - c[2])[c[1] > 0.5].mean() for c in clip[5:]])
    assert np.mean(err["small"][5:]) < 0.8 * noise
    assert np.mean(err["small"][5:]) < 1.5 * np.mean(err["full"][5:])


def test_strength_zero_is_identity_and_inputs_untouched():
    clip = _moving_square_clip(3)
    stab = Stabilizer(strength=0.0)
    for frame, mask, _, noisy_a, noisy_t, _ in clip:
        before = noisy_a.copy()
        a_s, t_s = stab.update(frame, mask, noisy_a, noisy_t)
        np.testing.assert_array_equal(a_s, noisy_a)
        np.testing.assert_array_equal(t_s, noisy_t)
        np.testing.assert_array_equal(noisy_a, before)


def test_stabilize_generator_matches_class():
    clip = _moving_square_clip(4)
    frames, masks, _, albedos, transports, _ = zip(*clip, strict=True)
    out = list(stabilize(frames, masks, albedos, transports))
    stab = Stabilizer()
    for (a, t), args in zip(out, zip(frames, masks, albedos, transports, strict=True), strict=True):
        a2, t2 = stab.update(*args)
        np.testing.assert_array_equal(a, a2)
        np.testing.assert_array_equal(t, t2)


@pytest.mark.parametrize("shape", [(32, 48), (64, 64)])
def test_shapes(shape):
    h, w = shape
    stab = Stabilizer()
    for _ in range(2):
        a, t = stab.update(np.zeros((h, w, 3), np.uint8), np.ones((h, w), np.uint8) * 255,
                           np.zeros((h, w, 3), np.float32), np.zeros((h, w, 9), np.float32))
    assert a.shape == (h, w, 3) and t.shape == (h, w, 9)
    assert a.dtype == np.float32 and t.dtype == np.float32


def test_bad_inputs():
    with pytest.raises(RelightError, match="strength"):
        Stabilizer(strength=1.0)
    with pytest.raises(RelightError, match="flow_max_side"):
        Stabilizer(flow_max_side=4)
    with pytest.raises(RelightError, match="photometric_tolerance"):
        Stabilizer(photometric_tolerance=0)
    stab = Stabilizer()
    with pytest.raises(RelightError, match="transport: expected"):
        stab.update(np.zeros((8, 8, 3)), None, np.zeros((8, 8, 3)), np.zeros((8, 8, 3)))
    with pytest.raises(RelightError, match="albedo: expected"):
        stab.update(np.zeros((8, 8, 3)), None, np.zeros((8, 9, 3)), np.zeros((8, 8, 9)))
