"""relight_rt.relight.detail: guided_upsample (a and b resampled separately give the same map as one 6-channel stack)
shadow_texture (the photo's own detail for the deep shadow's fill, held to the lit side's) and masked_blur (a blur in
which only the person's pixels count)."""

import cv2
import numpy as np
import pytest

from relight_rt.image.crop import CropGeometry
from relight_rt.relight.detail import GUIDE_EPS, GUIDE_RADIUS, guided_upsample, masked_blur, shadow_texture


def stacked(geom, src, guide_net, guide, origin):
    """The fast guided filter written out with a and b resampled as one stack (the earlier implementation)."""
    k = 2 * GUIDE_RADIUS + 1
    box = lambda x: cv2.boxFilter(x, -1, (k, k), borderType=cv2.BORDER_REFLECT)  # noqa: E731
    i_net = cv2.cvtColor(guide_net, cv2.COLOR_RGB2GRAY)
    mean_i, mean_p = box(i_net), box(src)
    var_i = box(i_net * i_net) - mean_i * mean_i
    cov = box(src * i_net[..., None]) - mean_i[..., None] * mean_p
    a = cov / (var_i[..., None] + GUIDE_EPS)
    b = mean_p - a * mean_i[..., None]
    ab = geom.to_crop(np.concatenate([box(a), box(b)], axis=2), origin)
    return ab[..., :3] * cv2.cvtColor(guide, cv2.COLOR_RGB2GRAY)[..., None] + ab[..., 3:]


@pytest.mark.parametrize("size", [(300, 200), (130, 90)])
def test_guided_upsample_matches_the_stacked_form(size):
    rng = np.random.default_rng(0)
    mask = np.zeros(size, np.float32)
    mask[10:-10, 20:-20] = 1
    geom = CropGeometry.from_mask(mask, 64)
    y0, y1, x0, x1 = 4, 60, 8, 56
    src = rng.random((y1 - y0, x1 - x0, 3), dtype=np.float32) + 0.5
    guide_net = rng.random((y1 - y0, x1 - x0, 3), dtype=np.float32)
    guide = np.ascontiguousarray(geom.crop(rng.random(size + (3,), dtype=np.float32)))
    got = guided_upsample(geom, src, guide_net, guide, (y0, x0))
    want = stacked(geom, src, guide_net, guide, (y0, x0))
    assert got.shape == guide.shape and got.dtype == np.float32
    # cv2.warpAffine (INTER_LINEAR) weighs with 5-bit fixed-point fractions and takes different paths for 3 and
    # 4 channels, so the two groupings agree to about 1/32 of the local slope, not to float precision
    np.testing.assert_allclose(got, want, atol=5e-3)
    assert np.abs(got - want).mean() < 5e-4


def _textured(h=120, w=160, seed=0):
    """A grey whose left half is a clean texture at 0.5 and whose right half is the same texture at 0.03 with its
    detail multiplied 4x (a deep shadow's noise)."""
    rng = np.random.default_rng(seed)
    grain = cv2.GaussianBlur(rng.normal(0, 1, (h, w)).astype(np.float32), (0, 0), 1.2)
    grain /= grain.std()
    gray = 0.5 * np.exp(0.1 * grain)
    gray[:, w // 2 :] = 0.03 * np.exp(0.4 * grain[:, w // 2 :])
    return gray.astype(np.float32)


def _rms(texture, where):
    return float(np.log(texture)[where].std())


def test_shadow_texture_holds_a_noisy_shadow_to_the_lit_sides_texture():
    gray = _textured()
    lit = np.zeros(gray.shape, bool)
    lit[10:-10, 10:70] = True
    shadow = np.zeros(gray.shape, bool)
    shadow[10:-10, 90:150] = True
    texture = shadow_texture(gray, lit, (1.0, 2.0), 4.0, 0.5)
    assert texture.shape == gray.shape and texture.dtype == np.float32
    assert 0.6 < _rms(texture, shadow) / _rms(texture, lit) < 1.4  # not the shadow's 4x
    free = shadow_texture(gray, lit, (1.0, 2.0), 4.0, 1.0 - 1e-9)  # the hold at the lit side's largest power
    assert _rms(free, shadow) > _rms(texture, shadow)
    assert shadow_texture(gray, np.zeros(gray.shape, bool), (1.0, 2.0), 4.0, 0.5) is None  # nothing lit: none


def test_shadow_texture_on_a_faces_skin_follows_the_skins_own_and_leaves_the_rest():
    """A face's skin is held to the lit skin's texture; off the skin (weight 0) the result is the one without."""
    gray = _textured()
    lit = np.zeros(gray.shape, bool)
    lit[10:-10, 10:70] = True
    smooth_skin = lit.copy()
    smooth_skin[:, 40:] = False
    gray[:, :40] = 0.5 * np.exp(0.25 * np.log(gray[:, :40] / 0.5))  # the lit skin's texture a quarter of the rest's
    weight = np.zeros(gray.shape, np.float32)
    weight[:60, :] = 1.0  # the skin: the upper half
    plain = shadow_texture(gray, lit, (1.0, 2.0), 4.0, 0.5)
    faced = shadow_texture(gray, lit, (1.0, 2.0), 4.0, 0.5, (weight, smooth_skin))
    np.testing.assert_array_equal(faced[60:], plain[60:])
    upper = np.zeros(gray.shape, bool)
    upper[10:50, 90:150] = True
    assert _rms(faced, upper) < 0.6 * _rms(plain, upper)


def test_masked_blur_is_moved_by_the_kept_pixels_only():
    """A flat value on the kept pixels stays flat up to their edge whatever lies beside them (a plain blur drags a
    bright background in), the background's values move nothing anywhere, and where every pixel counts it is a plain
    blur."""
    keep = np.zeros((40, 60), np.float32)
    keep[:, :30] = 1
    values = np.where(keep > 0, 0.3, 5.0).astype(np.float32)
    got = masked_blur(values, keep, 3.0)
    assert got.dtype == np.float32 and got.shape == values.shape
    assert np.allclose(got[:, :30], 0.3, atol=1e-5)
    assert cv2.GaussianBlur(values, (0, 0), 3.0)[:, 29].min() > 1.0  # what it guards against
    other = np.where(keep > 0, 0.3, -7.0).astype(np.float32)
    assert np.array_equal(masked_blur(other, keep, 3.0), got)  # the background's values count nowhere
    rng = np.random.default_rng(0)
    free = rng.random((40, 60), dtype=np.float32)
    assert np.allclose(masked_blur(free, np.ones_like(free), 2.0), cv2.GaussianBlur(free, (0, 0), 2.0), atol=1e-5)
