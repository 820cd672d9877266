"""export.render.transport: occlusion-aware SH transport, albedo and masks on simple shapes."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("embreex")

from export.render import shapes  # noqa: E402
from export.render.camera import fit_camera  # noqa: E402
from export.render.raycast import Tracer  # noqa: E402
from export.render.scene import Subject  # noqa: E402
from export.render.transport import (  # noqa: E402
    cosine_directions,
    render_gbuffer,
    render_sample,
    sample_texture,
    transport,
)
from relight_rt import RelightError  # noqa: E402
from relight_rt.light.sh import basis, cosine_lobe  # noqa: E402


def test_unoccluded_sphere_matches_cosine_lobe():
    """Unoccluded, T_k(p) = A_l · Y_k(n_p) (DESIGN.md §3): RMS relative error under 2% at 256 directions."""
    subject = Subject([shapes.sphere(radius=0.5)])
    tracer = Tracer(subject)
    g = render_gbuffer(subject, fit_camera(subject, 24), tracer)
    t = transport(tracer, g, 256, rng=np.random.default_rng(0))
    exact = cosine_lobe()[None] * basis(g.normal.astype(np.float64))
    rel = np.linalg.norm(t - exact, axis=1) / np.linalg.norm(exact, axis=1)
    assert np.sqrt(np.mean(rel**2)) < 0.02
    np.testing.assert_allclose(t[:, 0], np.pi * basis(np.zeros(3))[0], rtol=1e-5)  # band 0 sees every ray


def test_sphere_in_bowl_is_darker_where_occluded():
    ball = shapes.sphere(center=(0, 0, 0), radius=0.3, albedo=(1.0, 0.0, 0.0))
    cup = shapes.bowl(center=(0, 0, 0.0), radius=0.6, depth=0.55, albedo=(0.0, 0.0, 1.0))
    alone, inside = Subject([ball]), Subject([ball, cup])
    cam = fit_camera(inside, 32)
    a = render_sample(alone, cam, 64, seed=0)
    b = render_sample(inside, cam, 64, seed=0)
    t0a, t0b = a["transport"][..., 0], b["transport"][..., 0]
    ball_seen = b["albedo"][..., 0] > 0.5  # the ball is red, the cup blue
    top = np.nonzero(ball_seen[:, 16])[0][0]  # the ball's top sees open sky in both scenes
    assert t0b[top, 16] == pytest.approx(t0a[top, 16], rel=1e-5)
    rows = np.arange(32)[:, None]
    low = ball_seen & (rows > 17)  # just above the rim (z < -0.2): the cup hides most of the sky
    assert low.sum() >= 5
    assert (t0b[low] < 0.5 * t0a[low]).all()
    assert (t0b[ball_seen] <= t0a[ball_seen] + 1e-5).all()


def test_textured_plane_gives_texture_and_full_mask():
    rng = np.random.default_rng(3)
    tex = rng.random((16, 16, 3)).astype(np.float32)
    skin = (rng.random((16, 16)) > 0.5).astype(np.float32)
    subject = Subject([shapes.plane(size=1.0, albedo=tex, skin=skin)])
    out = render_sample(subject, fit_camera(subject, 16, margin=0.0), 4, seed=0)
    assert (out["mask"] == 1).all()
    np.testing.assert_allclose(out["albedo"], tex, atol=1e-5)  # pixel centres land on texel centres
    np.testing.assert_allclose(out["skin"], skin, atol=1e-5)
    np.testing.assert_allclose(out["transport"][..., 0], np.pi * basis(np.zeros(3))[0], rtol=1e-5)


def test_same_seed_same_transport():
    subject = Subject([shapes.sphere(radius=0.3), shapes.bowl(radius=0.6)])
    cam = fit_camera(subject, 16)
    a = render_sample(subject, cam, 16, seed=5)
    b = render_sample(subject, cam, 16, seed=5)
    c = render_sample(subject, cam, 16, seed=6)
    np.testing.assert_array_equal(a["transport"], b["transport"])
    assert not np.array_equal(a["transport"], c["transport"])


@pytest.mark.parametrize("n", [1, 7, 16, 30])
def test_cosine_directions_are_in_the_hemisphere(n):
    normals = np.float32([[0, 0, 1], [0, 0, -1], [1, 0, 0], [0.6, 0, 0.8]])
    d = cosine_directions(normals, n, np.random.default_rng(0))
    assert d.shape == (4, n, 3)
    np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 1.0, atol=1e-5)
    assert (np.einsum("pnd,pd->pn", d, normals) >= -1e-6).all()


def test_cosine_directions_mean():
    """E[ω] under pdf cos θ/π is (2/3) n."""
    n = np.float32([[0, 0.6, 0.8]])
    d = cosine_directions(np.repeat(n, 200, 0), 64, np.random.default_rng(1))
    np.testing.assert_allclose(d.reshape(-1, 3).mean(0), 2 / 3 * n[0], atol=5e-3)


def test_sample_texture():
    tex = np.arange(12, dtype=np.float32).reshape(2, 2, 3)
    uv = np.float32([[0.25, 0.75], [0.75, 0.25], [0.5, 0.5]])
    out = sample_texture(tex, uv)
    np.testing.assert_allclose(out[0], tex[0, 0])  # v up: row 0 holds v near 1
    np.testing.assert_allclose(out[1], tex[1, 1])
    np.testing.assert_allclose(out[2], tex.mean((0, 1)))
    np.testing.assert_allclose(sample_texture(0.3, uv), [0.3] * 3)
    with pytest.raises(RelightError, match="texture"):
        sample_texture(np.zeros((2, 2, 2, 2)), uv)


def test_bad_direction_count():
    subject = Subject([shapes.sphere(rows=4)])
    tracer = Tracer(subject)
    g = render_gbuffer(subject, fit_camera(subject, 4), tracer)
    with pytest.raises(RelightError, match="n_dirs"):
        transport(tracer, g, 0, rng=np.random.default_rng(0))


def test_anny_body_has_self_occlusion(tmp_path):
    """On a rendered body, crevices (armpits, between the legs, under the chin) receive much less of the sky
    than open surfaces such as the chest, and the sample reads back with the right channel order."""
    pytest.importorskip("anny")
    from export import dataset
    from export.render.subjects import random_subject

    subject = random_subject(0, clothing=False)
    out = render_sample(subject, fit_camera(subject, 96), 64, seed=0)
    t0 = out["transport"][..., 0][out["mask"] > 0] / (np.pi * basis(np.zeros(3))[0])
    assert t0.max() > 0.9  # open surfaces see nearly the whole hemisphere
    assert (t0 < 0.5).mean() > 0.01  # crevices
    assert (out["skin"][out["mask"] > 0] > 0.5).mean() > 0.3  # a bare body is mostly skin
    dataset.write_sample(tmp_path, "body", **out)
    back = dataset.read_sample(tmp_path, "body")
    np.testing.assert_allclose(back["albedo"], out["albedo"], atol=0.5 / 255 + 1e-6)
    np.testing.assert_array_equal(back["transport"], out["transport"])
