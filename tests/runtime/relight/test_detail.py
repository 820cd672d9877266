"""relight_rt.relight.detail.guided_upsample: a and b resampled separately give the same map as one 6-channel stack."""

import cv2
import numpy as np
import pytest

from relight_rt.image.crop import CropGeometry
from relight_rt.relight.detail import GUIDE_EPS, GUIDE_RADIUS, guided_upsample


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
