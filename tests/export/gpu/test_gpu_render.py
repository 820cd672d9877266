"""The plain-PyTorch sample renderer (export.gpu.render) against the analytic lobe and the embree renderer."""

from __future__ import annotations

import math

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from export.gpu import bank  # noqa: E402
from export.gpu.render import DeviceSubject, RenderSettings, render_sample, sh_basis, sphere_directions  # noqa: E402
from export.render.scene import Subject  # noqa: E402
from export.render.shapes import plane, sphere  # noqa: E402
from relight_rt.light.sh import basis  # noqa: E402


def _device_subject(parts, tmp_path, name="s"):
    data = bank.read_subject(bank.write_subject(tmp_path, Subject(parts, name)), None)
    return data, DeviceSubject.from_data(data, torch.device("cpu"))


def test_sh_basis_is_relight_rt_s():
    d = sphere_directions(50, torch.Generator().manual_seed(0), torch.device("cpu"))
    assert np.allclose(sh_basis(d).numpy(), basis(d.numpy().astype(np.float64)), atol=1e-5)
    assert np.allclose(np.linalg.norm(d.numpy(), axis=1), 1.0, atol=1e-6)


def test_a_lone_sphere_gets_the_unoccluded_lobe(tmp_path):
    _, subject = _device_subject([sphere((0, 0, 1.0), 0.4, (0.5, 0.5, 0.5), rows=32)], tmp_path)
    s = render_sample(subject, RenderSettings(resolution=48, dirs=32, shadow_size=48), generator=torch.Generator())
    mask = s["mask"][0] > 0
    assert 0.6 < mask.float().mean() < 0.8  # a disc with the framing's margin
    t = s["transport"].permute(1, 2, 0)[mask]
    # unoccluded, the degree-1 coefficients (y, z, x order) point along the normal
    n = torch.nn.functional.normalize(t[:, [3, 1, 2]], dim=-1)
    lobe = torch.tensor([math.pi] + [2 * math.pi / 3] * 3 + [math.pi / 4] * 5)
    assert torch.allclose(t, lobe * sh_basis(n), atol=0.03)
    assert (s["transport"][:, ~mask] == 0).all()


@pytest.mark.parametrize("framing, yaw", [("full", 0.0), ("waist-up", 30.0)])
def test_it_agrees_with_the_embree_renderer(tmp_path, framing, yaw):
    pytest.importorskip("embreex")
    from export.render.camera import fit_camera
    from export.render.cli import turn_subject
    from export.render.transport import render_sample as embree_sample

    parts = [sphere((0, 0, 1.0), 0.3, (0.7, 0.3, 0.2), rows=24, name="torso"),
             sphere((0.0, 0.0, 1.42), 0.13, (0.8, 0.6, 0.5), rows=16, name="head", skin=1.0),
             sphere((0.05, 0.3, 1.0), 0.1, (0.2, 0.6, 0.3), rows=16, name="hand"),
             plane(0.5, (0.3, 0.3, 0.8), x=-0.35, cells=2)]
    data, subject = _device_subject(parts, tmp_path)
    ours = render_sample(subject, RenderSettings(resolution=64, dirs=64, shadow_size=96), framing=framing,
                         yaw_deg=yaw, generator=torch.Generator().manual_seed(1))
    ref_subject = turn_subject(bank.to_subject(data), yaw)
    ref = embree_sample(ref_subject, fit_camera(ref_subject, 64, framing=framing), 256, seed=0)
    mask = ours["mask"][0].numpy()
    assert np.array_equal(mask, ref["mask"])
    inside = mask > 0
    assert np.abs(ours["albedo"].numpy().transpose(1, 2, 0)[inside] - ref["albedo"][inside]).max() < 1e-4
    assert np.array_equal(ours["skin"][0].numpy()[inside] > 0.5, ref["skin"][inside] > 0.5)
    t_ours = ours["transport"].numpy().transpose(1, 2, 0)[inside]
    t_ref = ref["transport"][inside]
    corr = np.corrcoef(t_ours.ravel(), t_ref.ravel())[0, 1]
    assert corr > 0.98, corr
