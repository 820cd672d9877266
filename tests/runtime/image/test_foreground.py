"""relight_rt.image.foreground.estimate_foreground: colour decontamination of a matte's soft edge."""

from __future__ import annotations

import numpy as np
import pytest

from relight_rt import RelightError
from relight_rt.image.foreground import estimate_foreground, nearest_colours
from relight_rt.person import matting


def scene(h: int = 160, w: int = 200, soft: float = 6.0, seed: int = 0):
    """A disc of smoothly varying foreground colour over a different smooth background, soft-edged."""
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    f = np.stack([0.8 + 0 * xx, 0.3 + 0.2 * np.sin(xx / 17), 0.2 + 0.1 * np.cos(yy / 23)], -1)
    b = np.stack([0.1 + 0.05 * np.sin(yy / 11), 0.6 + 0 * xx, 0.9 - 0.2 * xx / w], -1)
    r = np.hypot(yy - h / 2, xx - w / 2)
    alpha = np.clip((min(h, w) / 3 - r) / soft + 0.5, 0, 1).astype(np.float32)
    rgb = alpha[..., None] * f + (1 - alpha[..., None]) * b
    return rgb.astype(np.float32), alpha, f.astype(np.float32), b.astype(np.float32)


def test_recovers_the_foreground_colour_of_soft_pixels():
    rgb, alpha, f, b = scene()
    fe, be = estimate_foreground(rgb, alpha, return_background=True)
    soft = (alpha > 0.05) & (alpha < 0.95)
    before = np.abs(rgb - f)[soft].mean()  # the photo's own colour carries the background
    after = np.abs(fe - f)[soft].mean()
    assert before > 0.15
    assert after < 0.1 * before
    assert np.abs(be - b)[soft].mean() < 0.1 * np.abs(rgb - b)[soft].mean()
    # the model holds: alpha F + (1 - alpha) B reproduces the photo
    model = alpha[..., None] * fe + (1 - alpha[..., None]) * be
    assert np.abs(model - rgb)[soft].max() < 0.02


def test_composite_over_a_new_backdrop_carries_no_old_background():
    rgb, alpha, f, _ = scene(soft=10.0)
    green = np.zeros_like(rgb)
    green[..., 1] = 1.0
    truth = alpha[..., None] * f + (1 - alpha[..., None]) * green
    naive = alpha[..., None] * rgb + (1 - alpha[..., None]) * green
    clean = alpha[..., None] * estimate_foreground(rgb, alpha) + (1 - alpha[..., None]) * green
    soft = (alpha > 0.05) & (alpha < 0.95)
    assert np.abs(clean - truth)[soft].mean() < 0.2 * np.abs(naive - truth)[soft].mean()


@pytest.mark.parametrize("shape", [(1, 1), (1, 7), (9, 1), (17, 33), (300, 40)])
def test_shapes_and_solid_pixels_unchanged(shape):
    rng = np.random.default_rng(1)
    rgb = rng.random(shape + (3,), dtype=np.float32)
    alpha = np.clip(rng.random(shape, dtype=np.float32) * 1.4 - 0.2, 0, 1)
    out = estimate_foreground(rgb, alpha)
    assert out.shape == shape + (3,) and out.dtype == np.float32
    assert np.isfinite(out).all() and out.min() >= 0 and out.max() <= 1
    np.testing.assert_array_equal(out[alpha >= 1], rgb[alpha >= 1])
    assert out is not rgb


def test_empty_and_full_mattes_return_the_photo():
    rgb, _, _, _ = scene(40, 50)
    for alpha in (np.zeros((40, 50), np.float32), np.ones((40, 50), np.float32)):
        np.testing.assert_array_equal(estimate_foreground(rgb, alpha), rgb)


def test_uint8_inputs_and_arguments_left_alone():
    rgb, alpha, _, _ = scene(60, 70)
    rgb8 = np.round(rgb * 255).astype(np.uint8)
    a8 = np.round(alpha * 255).astype(np.uint8)
    keep = rgb8.copy(), a8.copy()
    out = estimate_foreground(rgb8, a8[..., None])
    np.testing.assert_array_equal(rgb8, keep[0])
    np.testing.assert_array_equal(a8, keep[1])
    ref = estimate_foreground(rgb8.astype(np.float32) / 255, a8.astype(np.float32) / 255)
    np.testing.assert_allclose(out, ref, atol=1e-6)


def test_exposed_through_matting():
    assert matting.estimate_foreground is estimate_foreground


@pytest.mark.parametrize(
    "rgb, alpha, match",
    [
        (np.zeros((8, 8)), np.zeros((8, 8)), r"expected an \(H, W, 3\) RGB image, got \(8, 8\)"),
        (np.zeros((8, 8, 3)), np.zeros((8, 9)), r"alpha is \(8, 9\), the image \(8, 8\)"),
        (np.zeros((8, 8, 3)), np.zeros((8, 8, 2)), r"expected an \(H, W\) alpha, got \(8, 8, 2\)"),
        (np.zeros((8, 8, 3), np.int32), np.zeros((8, 8)), "image: expected uint8 or float in \\[0, 1\\], got int32"),
        (np.zeros((8, 8, 3)), np.full((8, 8), np.nan), "alpha: expected finite values"),
        ("photo.png", np.zeros((8, 8)), "got str"),
    ],
)
def test_bad_input(rgb, alpha, match):
    with pytest.raises(RelightError, match=match):
        estimate_foreground(rgb, alpha)


def test_clean_edge_colour_keeps_the_relighting_and_drops_the_old_background():
    from relight_rt.image.compositing import clean_edge_colour

    rgb, alpha, f, _ = scene(40, 50, soft=8.0)
    fg = estimate_foreground(rgb, alpha)
    relit = np.clip(rgb * np.array([1.2, 0.9, 0.7], np.float32), 0, 1)  # a relighting: a colour per channel
    out = clean_edge_colour(relit, rgb, fg, alpha)
    soft = (alpha > 0.05) & (alpha < 0.95)
    want = np.clip(f * np.array([1.2, 0.9, 0.7], np.float32), 0, 1)
    assert np.abs(out - want)[soft].mean() < 0.2 * np.abs(relit - want)[soft].mean()
    solid = (alpha == 0) | (alpha == 1)
    np.testing.assert_array_equal(out[solid], relit[solid])


def test_video_composite_over_a_new_backdrop_is_decontaminated():
    """The DVP path (premultiplied frames) composites through relight_rt.video.job.composite."""
    from relight_rt.video.job import composite

    rgb, alpha, f, _ = scene(60, 80, soft=8.0)
    green = np.zeros_like(rgb)
    green[..., 1] = 1.0
    truth = alpha[..., None] * f + (1 - alpha[..., None]) * green
    naive = alpha[..., None] * rgb + (1 - alpha[..., None]) * green
    out = composite(rgb * alpha[..., None], rgb, alpha, "green", premultiplied=True)
    soft = (alpha > 0.05) & (alpha < 0.95)
    assert np.abs(out - truth)[soft].mean() < 0.3 * np.abs(naive - truth)[soft].mean()
    same = composite(rgb * alpha[..., None], rgb, alpha, "original", premultiplied=True)
    np.testing.assert_allclose(same, rgb, atol=1e-5)  # over its own background: the photo again


def test_nearest_colours_recover_a_thin_edge():
    """A 1.5-px anti-aliased edge: each side's colour from the solid pixels beside it, the photo given back."""
    rgb, alpha, f, b = scene(soft=1.5)
    fe, be = nearest_colours(rgb, alpha)
    soft = (alpha > 0.05) & (alpha < 0.95)
    assert soft.sum() > 100
    assert np.abs(fe - f)[soft].mean() < 0.1 * np.abs(rgb - f)[soft].mean()
    assert np.abs(be - b)[soft].mean() < 0.1 * np.abs(rgb - b)[soft].mean()
    model = alpha[..., None] * fe + (1 - alpha[..., None]) * be
    assert np.abs(model - rgb)[soft].max() < 1e-5
    solid = (alpha <= 0) | (alpha >= 1)
    np.testing.assert_array_equal(fe[solid], rgb[solid])
    np.testing.assert_array_equal(be[solid], rgb[solid])


def test_nearest_colours_of_a_hard_mask_and_of_a_lone_soft_pixel():
    rgb, alpha, _, _ = scene()
    hard = (alpha > 0.5).astype(np.float32)
    fe, be = nearest_colours(rgb, hard)
    np.testing.assert_array_equal(fe, rgb)
    np.testing.assert_array_equal(be, rgb)
    lone = np.zeros((5, 5), np.float32)
    lone[2, 2] = 0.3  # no solid person anywhere: its F is the photo, and so is the B that leaves
    fe, be = nearest_colours(rgb[:5, :5], lone)
    np.testing.assert_allclose(fe[2, 2], rgb[2, 2], atol=1e-6)
    np.testing.assert_allclose(be[2, 2], rgb[2, 2], atol=1e-6)
