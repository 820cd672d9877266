"""export/shading.py, the torch SH shading of training and evaluation, against the runtime's numpy shading."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from export.shading import render_diffuse, shade, shading  # noqa: E402
from relight_rt.light.sh import shading as runtime_shading  # noqa: E402


@pytest.mark.parametrize("shape", [(1, 4, 5), (3, 8, 2)])
def test_torch_shading_is_the_runtimes(shape):
    n, h, w = shape
    rng = np.random.default_rng(0)
    transport = rng.normal(size=(n, 9, h, w)).astype(np.float32)
    light = rng.normal(size=(n, 9, 3)).astype(np.float32)
    got = shading(torch.from_numpy(transport), torch.from_numpy(light)).numpy()
    for i in range(n):
        want = runtime_shading(transport[i].transpose(1, 2, 0), light[i]).transpose(2, 0, 1)
        np.testing.assert_allclose(got[i], want, rtol=1e-5, atol=1e-5)
    raw = shade(torch.from_numpy(transport), torch.from_numpy(light)).numpy()
    assert (raw < 0).any() and np.array_equal(np.maximum(raw, 0), got)  # shade is the unclamped product


def test_render_diffuse_clips_and_masks():
    transport = torch.zeros(1, 9, 2, 2)
    transport[:, 0] = 1.0
    light = torch.zeros(1, 9, 3)
    light[:, 0] = torch.tensor([3.0, 0.5, -1.0])
    mask = torch.tensor([[[[1.0, 0.5], [0.0, 1.0]]]])
    out = render_diffuse(torch.full((1, 3, 2, 2), 0.5), transport, light, mask)
    np.testing.assert_allclose(out[0, :, 0, 0].numpy(), [1.0, 0.25, 0.0])  # clipped above, max(0, .) below
    np.testing.assert_allclose(out[0, :, 0, 1].numpy(), [0.5, 0.125, 0.0])
    assert out[0, :, 1, 0].abs().max() == 0
