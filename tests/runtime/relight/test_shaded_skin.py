"""Skin the new light darkens keeps more of its colour (relight_rt.relight.look.shaded_skin; issue 32)."""

from __future__ import annotations

import cv2
import numpy as np

import relight_rt
from relight_rt import RuntimeConfig, lights
from relight_rt.relight.look import SKIN_CHROMA, shaded_skin, skin_chroma

REC709 = np.array([0.2126, 0.7152, 0.0722], np.float32)


def _lab_chroma(rgb):
    lab = cv2.cvtColor(np.clip(rgb, 0, 1).astype(np.float32).reshape(1, -1, 3), cv2.COLOR_RGB2Lab)[0]
    return np.hypot(lab[:, 1], lab[:, 2]), lab[:, 0]


def test_darkened_skin_keeps_its_luminance_and_more_of_its_chroma():
    photo = np.tile(np.array([0.8, 0.6, 0.5], np.float32), (2, 3, 1))  # skin; row 1 is not skin
    ratio = np.array([[0.3, 0.6, 1.0], [0.3, 0.6, 1.0]], np.float32)
    skin = np.array([[1.0, 1.0, 1.0], [0.0, 0.0, 0.0]], np.float32)
    factor = np.repeat(ratio[..., None], 3, axis=2)  # a white light: the factor is the luminance ratio
    out = shaded_skin(factor, ratio, *skin_chroma(photo, skin))
    relit, plain = photo * out, photo * factor
    np.testing.assert_allclose(relit @ REC709, plain @ REC709, rtol=1e-5)  # the luminance is the light's
    np.testing.assert_array_equal(out[1], factor[1])  # off the skin: unchanged
    np.testing.assert_allclose(out[0, 2], 1.0, atol=1e-6)  # the photo's own light gives the photo back
    c_in, l_in = _lab_chroma(photo[0, :1])
    c_kept, l_kept = _lab_chroma(relit[0, :2])
    c_grey, l_grey = _lab_chroma(plain[0, :2])
    assert (c_kept > 1.3 * c_grey).all()  # a grey dimming loses chroma with lightness, skin much less
    gamma = np.log(c_kept / c_in) / np.log(l_kept / l_in)  # C* ~ L*^gamma: real faces' median 0.33
    assert ((gamma > 0.15) & (gamma < 0.5)).all() and SKIN_CHROMA == 0.5


def test_brightened_skin_and_the_light_colour_are_left_alone():
    photo = np.full((1, 2, 3), (0.5, 0.35, 0.3), np.float32)
    ratio = np.array([[1.8, 0.5]], np.float32)
    warm = np.array([1.2, 0.95, 0.7], np.float32) / (np.array([1.2, 0.95, 0.7], np.float32) @ REC709)
    factor = warm * ratio[..., None]
    out = shaded_skin(factor, ratio, *skin_chroma(photo, np.ones((1, 2), np.float32)))
    np.testing.assert_array_equal(out[0, 0], factor[0, 0])
    # darkened: the gain on the factor is the white light's (the light's colour still multiplies)
    inputs = skin_chroma(photo, np.ones((1, 2), np.float32))
    white = shaded_skin(np.repeat(ratio[..., None], 3, axis=2), ratio, *inputs)
    np.testing.assert_allclose(out[0, 1] / factor[0, 1], white[0, 1] / ratio[0, 1], rtol=1e-5)


def test_deep_shade_never_turns_a_channel_negative():
    photo = np.array([[[0.9, 0.2, 0.1]]], np.float32)  # saturated skin-like red
    ratio = np.array([[0.02]], np.float32)
    out = shaded_skin(np.full((1, 1, 3), 0.02, np.float32), ratio, *skin_chroma(photo, np.ones((1, 1), np.float32)))
    assert (out > 0).all() and (out <= 4 * 0.02 + 1e-6).all()


def test_a_real_face_keeps_its_colour_on_the_shaded_side(dpr_portrait, monkeypatch):
    """DPR's portrait under a white lamp from the image's right and a soft fill: the shaded (left) cheek's skin
    keeps more of its Lab chroma than a grey dimming of the same luminance leaves it."""
    light = lights.directional((0.3, 1.0, 0.2), (1, 1, 1), 1.0, angular_radius=0.3) + lights.ambient(0.3)
    h, w = dpr_portrait.shape[:2]
    box = np.zeros((h, w), bool)
    box[int(0.35 * h) : int(0.65 * h), int(0.2 * w) : int(0.4 * w)] = True  # the face's left cheek
    ycc = cv2.cvtColor((dpr_portrait * 255).astype(np.uint8), cv2.COLOR_RGB2YCrCb)
    skin = box & (ycc[..., 1] >= 135) & (ycc[..., 2] <= 135)
    assert skin.sum() > 1000
    kept = relight_rt.open(RuntimeConfig(device="cpu")).relight(dpr_portrait, light)
    monkeypatch.setattr("relight_rt.relight.factor.shaded_skin", lambda factor, *args: factor)
    grey = relight_rt.open(RuntimeConfig(device="cpu")).relight(dpr_portrait, light)
    c_in, l_in = _lab_chroma(dpr_portrait[skin])
    c_kept, l_kept = _lab_chroma(kept[skin])
    c_grey, l_grey = _lab_chroma(grey[skin])
    assert float(np.mean(l_kept)) < 0.85 * float(np.mean(l_in))  # the cheek is in shade
    assert abs(float(np.mean(l_kept)) - float(np.mean(l_grey))) < 1.5  # the same lightness
    assert float(np.mean(c_kept)) > 1.15 * float(np.mean(c_grey))
