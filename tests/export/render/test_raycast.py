"""export.render.raycast and camera: hits, normals, occlusion and framing on simple shapes."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("embreex")

from export.render import shapes  # noqa: E402
from export.render.camera import Camera, fit_camera  # noqa: E402
from export.render.raycast import Tracer, vertex_normals  # noqa: E402
from export.render.scene import Subject  # noqa: E402
from relight_rt import RelightError  # noqa: E402


@pytest.fixture(scope="module")
def ball() -> Subject:
    return Subject([shapes.sphere(radius=0.5)], name="ball")


def test_sphere_hits_and_normals(ball):
    tracer = Tracer(ball)
    rng = np.random.default_rng(0)
    yz = rng.uniform(-0.3, 0.3, (50, 2))
    origins = np.column_stack([np.full(50, 2.0), yz]).astype(np.float32)
    dirs = np.tile(np.float32([-1, 0, 0]), (50, 1))
    hits = tracer.intersect(origins, dirs)
    assert hits.hit.all()
    expected_x = np.sqrt(0.25 - (yz**2).sum(1))
    np.testing.assert_allclose(hits.position[:, 0], expected_x, atol=5e-3)  # tessellated sphere
    np.testing.assert_allclose(hits.normal, hits.position / 0.5, atol=2e-2)
    assert (np.einsum("nd,nd->n", hits.geo_normal, hits.normal) > 0.9).all()


def test_misses_and_occlusion(ball):
    tracer = Tracer(ball)
    o = np.float32([[2, 0, 0], [2, 0.9, 0], [0, 0, 0.6], [0, 0, -0.6]])
    d = np.float32([[-1, 0, 0], [-1, 0, 0], [0, 0, 1], [0, 0, 1]])
    hits = tracer.intersect(o, d)
    np.testing.assert_array_equal(hits.hit, [True, False, False, True])
    np.testing.assert_array_equal(hits.part, [0, -1, -1, 0])
    np.testing.assert_array_equal(tracer.occluded(o, d), [True, False, False, True])


def test_normals_face_the_viewer_inside_an_open_shell():
    tracer = Tracer(Subject([shapes.bowl(radius=1.0, depth=1.0)]))
    hits = tracer.intersect(np.float32([[0.03, 0.02, 0.5]]), np.float32([[0, 0, -1]]))
    assert hits.hit[0]
    assert hits.normal[0, 2] > 0.98  # seen from inside the cup, the normal points up, toward the ray's origin


def test_vertex_normals_weld_seams():
    part = shapes.sphere(rows=12)
    n = vertex_normals(part.vertices, part.faces)
    radial = part.vertices / np.linalg.norm(part.vertices, axis=1, keepdims=True)
    assert (np.einsum("nd,nd->n", n, radial) > 0.99).all()
    cols = 2 * 12 + 1  # the grid repeats the φ = 0 column at φ = 2π: both copies share one normal
    np.testing.assert_array_equal(n.reshape(13, cols, 3)[:, 0], n.reshape(13, cols, 3)[:, -1])


@pytest.mark.parametrize("kind", ["orthographic", "perspective"])
@pytest.mark.parametrize("res", [8, 33])
def test_camera_frames_subject(ball, kind, res):
    cam = fit_camera(ball, res, margin=0.1, kind=kind)
    origins, dirs = cam.rays()
    assert origins.shape == dirs.shape == (res * res, 3)
    np.testing.assert_allclose(np.linalg.norm(dirs, axis=1), 1.0, atol=1e-6)
    assert (dirs[:, 0] < 0).all()  # looks along −x
    hit = Tracer(ball).intersect(origins, dirs).hit.reshape(res, res)
    assert hit.any() and not hit[0].any() and not hit[-1].any() and not hit[:, 0].any() and not hit[:, -1].any()
    assert Camera.from_dict(cam.to_dict()) == cam


def test_camera_orientation():
    """Image right is +y, image top is +z (DESIGN.md §3)."""
    subject = Subject([shapes.sphere(center=(0, 0.3, 0), radius=0.1), shapes.sphere(center=(0, -0.3, 0.3), radius=0.1)])
    cam = fit_camera(subject, 32)
    hits = Tracer(subject).intersect(*cam.rays())
    part = hits.part.reshape(32, 32)
    rows0, cols0 = np.nonzero(part == 0)
    rows1, cols1 = np.nonzero(part == 1)
    assert cols0.mean() > cols1.mean()  # +y is to the right
    assert rows1.mean() < rows0.mean()  # +z is up


def test_bad_input(ball):
    with pytest.raises(RelightError, match="camera kind"):
        fit_camera(ball, 16, kind="fisheye")
    with pytest.raises(RelightError, match="resolution"):
        fit_camera(ball, 0)
    with pytest.raises(RelightError, match="at least one part"):
        Tracer(Subject([]))
    bad = shapes.sphere(rows=4)
    bad.faces = bad.faces + 1000
    with pytest.raises(RelightError, match="face indices"):
        Tracer(Subject([bad]))


@pytest.mark.parametrize("framing", ["knees-up", "waist-up", "head-shoulders", "face"])
@pytest.mark.parametrize("kind", ["orthographic", "perspective"])
def test_framings_cut_the_subject_at_the_bottom(framing, kind):
    """issue 22: a standing figure (a stack of balls, 1.8 m) framed from the top: the top keeps its margin, the
    figure runs off the bottom border, and tighter framings show less of it."""
    from export.render.camera import FRAMINGS

    figure = Subject([shapes.sphere(center=(0, 0, z), radius=0.2, name=f"b{i}")
                      for i, z in enumerate(np.linspace(0.2, 1.6, 8))], name="figure")
    res = 48
    cam = fit_camera(figure, res, margin=0.1, kind=kind, framing=framing)
    hit = Tracer(figure).intersect(*cam.rays()).hit.reshape(res, res)
    rows = np.flatnonzero(hit.any(axis=1))
    assert hit[-1].any()  # cut by the bottom border
    assert not hit[0].any() and rows[0] >= 2  # the top keeps its margin
    full = fit_camera(figure, res, margin=0.1, kind=kind)
    assert cam.half_extent < full.half_extent  # closer than the full-body framing
    visible_fraction = (2 * cam.half_extent * (1 - 0.1)) / 1.8
    assert visible_fraction == pytest.approx(FRAMINGS[framing], rel=0.02 if kind == "orthographic" else 0.3)


def test_framing_options():
    import argparse

    from export.render.cli import parse_framings, pick_framing

    mix = parse_framings("full=0.4,knees-up=0.15,waist-up=0.15,head-shoulders=0.15,face=0.15")
    assert sum(mix.values()) == pytest.approx(1.0) and mix["full"] == pytest.approx(0.4)
    picks = [pick_framing(mix, seed) for seed in range(400)]
    assert picks == [pick_framing(mix, seed) for seed in range(400)]  # deterministic per subject
    assert 0.3 < picks.count("full") / 400 < 0.5 and set(picks) == set(mix)
    assert parse_framings("face") == {"face": 1.0}
    for bad in ("portrait", "full=-1", "full=x", "full=0"):
        with pytest.raises(argparse.ArgumentTypeError):
            parse_framings(bad)
    with pytest.raises(RelightError, match="framing"):
        fit_camera(Subject([shapes.sphere()]), 8, framing="portrait")
