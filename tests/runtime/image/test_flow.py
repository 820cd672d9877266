"""relight_rt.image.flow: the one home of DIS optical flow and its warps (metrics, the stabiliser and the video matter
use it)."""

import numpy as np
import pytest

from relight_rt import RelightError
from relight_rt.image import flow
from relight_rt.video import metrics

H, W = 96, 128


def _texture(seed: int = 0, h: int = H + 20, w: int = W + 20) -> np.ndarray:
    rng = np.random.default_rng(seed)
    import cv2

    return cv2.GaussianBlur(rng.random((h, w, 3)).astype(np.float32), (0, 0), 2.0)


def test_metrics_keeps_its_flow_names():
    """metrics' flow functions moved here; the old names (export/dvp.py uses them) are the same objects."""
    for name in ("dis_flow", "warp", "consistent_flow", "to_gray_u8"):
        assert getattr(metrics, name) is getattr(flow, name)


@pytest.mark.parametrize("preset", sorted(flow.PRESETS))
def test_flow_finds_a_shift(preset):
    big = _texture()
    a = flow.to_gray_u8(big[10:10 + H, 10:10 + W])
    b = flow.to_gray_u8(big[10:10 + H, 13:13 + W])  # content moves 3 px left: a[p] = b[p - (3, 0)]
    f = flow.dis_flow(a, b, preset)
    assert f.shape == (H, W, 2) and f.dtype == np.float32
    inner = np.s_[16:-16, 16:-16]
    assert np.median(f[inner][..., 0]) == pytest.approx(-3.0, abs=0.3)
    assert np.median(f[inner][..., 1]) == pytest.approx(0.0, abs=0.3)


def test_flow_on_shrunk_frames_is_scaled_back():
    """max_side: the flow runs on smaller frames and comes back at full size, in full-size pixels."""
    big = _texture(1, 2 * H + 40, 2 * W + 40)
    a = flow.to_gray_u8(big[20:20 + 2 * H, 20:20 + 2 * W])
    b = flow.to_gray_u8(big[20:20 + 2 * H, 26:26 + 2 * W])  # 6 px at full size, 3 px on the half-size frames
    f = flow.dis_flow(a, b, "medium", max_side=W)
    assert f.shape == (2 * H, 2 * W, 2)
    assert np.median(f[32:-32, 32:-32, 0]) == pytest.approx(-6.0, abs=0.6)
    np.testing.assert_array_equal(flow.dis_flow(a, b, "medium", max_side=4 * W), flow.dis_flow(a, b, "medium"))


def test_warp_borders():
    """A flow pointing past the frame: zeros (or a given value) by default, the edge pixel with None."""
    img = np.arange(H * W, dtype=np.float32).reshape(H, W)
    f = np.zeros((H, W, 2), np.float32)
    f[..., 0] = -5.0  # sample 5 px to the left
    const = flow.warp(img, f)
    edge = flow.warp(img, f, border_value=None)
    np.testing.assert_array_equal(const[:, 5:], img[:, :-5])
    np.testing.assert_array_equal(edge[:, 5:], img[:, :-5])
    assert (const[:, :5] == 0).all()
    np.testing.assert_array_equal(edge[:, :5], np.repeat(img[:, :1], 5, axis=1))
    np.testing.assert_array_equal(flow.warp(img, f, border_value=7.0)[:, :5], 7.0)


@pytest.mark.parametrize("channels", [1, 3, 6, 16])
def test_warp_by_zero_flow_is_identity(channels):
    img = np.random.default_rng(channels).random((H, W, channels)).astype(np.float32)
    np.testing.assert_array_equal(flow.warp(img, np.zeros((H, W, 2), np.float32), border_value=None), img)


def test_consistency_check_flags_disagreement():
    f = np.zeros((H, W, 2), np.float32)
    b = np.zeros((H, W, 2), np.float32)
    b[:, W // 2:, 0] = 4.0  # the backward flow disagrees on the right half
    ok = flow.consistent_flow(f, b)
    # (the last row and column sample the NaN border with weight 0, which is NaN: they never count as consistent)
    assert ok[:-1, : W // 2 - 1].all() and not ok[:, W // 2 + 1:].any()


def test_bad_input():
    g = np.zeros((H, W), np.uint8)
    with pytest.raises(RelightError, match="preset: expected one of"):
        flow.dis_flow(g, g, "slow")
    with pytest.raises(RelightError, match="flow_preset: expected one of"):
        flow.check_preset("slow", "flow_preset")
    with pytest.raises(RelightError, match="uint8 frames"):
        flow.dis_flow(g, g.astype(np.float32))
    with pytest.raises(RelightError, match="uint8 frames"):
        flow.dis_flow(g, g[:, :-1])
