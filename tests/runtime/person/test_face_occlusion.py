"""relight_rt.person.face_mesh: the light a face mesh's own relief hides (an eye's socket under the brow)."""

from __future__ import annotations

import numpy as np
import pytest

from relight_rt.light import sh
from relight_rt.person import face_mesh
from relight_rt.person.face_mesh import face_transport, lobe_transport, occlusion_loss, rasterise_depth


def _grid(size: float, depth, n: int = 41, origin: float = 5.0):
    """An n x n grid of vertices over a square of ``size`` pixels from ``origin``, z = depth(x, y), triangulated."""
    u = np.linspace(origin, origin + size, n)
    xx, yy = np.meshgrid(u, u)
    pts = np.column_stack([xx.ravel(), yy.ravel(), depth(xx, yy).ravel()])
    i = np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None, :]
    tris = np.concatenate([np.stack([i, i + 1, i + n + 1], -1).reshape(-1, 3),
                           np.stack([i, i + n + 1, i + n], -1).reshape(-1, 3)])
    return pts, tris


def _pit(size: float):
    """A round pit in the middle of a flat square (z away from the camera): a socket, a third of it as deep."""
    c, s = 5 + size / 2, size / 8

    def depth(x, y):
        return size / 3 * np.exp(-((x - c) ** 2 + (y - c) ** 2) / (2 * s * s))

    return _grid(size, depth), int(round(c))


def test_the_depth_is_the_nearest_triangles_plane_and_inf_off_the_mesh():
    (pts, tris), c = _pit(40)
    depth, seen = rasterise_depth(pts, tris, (60, 60))
    assert seen[c, c] and not seen[50:, :].any() and np.isinf(depth[~seen]).all()
    assert depth[c, c] == pytest.approx(40 / 3, rel=0.02)  # the pit's bottom (a vertex there)
    assert abs(depth[8, 8]) < 1e-3  # the flat border around it
    plane = np.array([[5, 5, 0.0], [45, 5, 20.0], [45, 45, 20.0], [5, 45, 0.0]])
    depth, _ = rasterise_depth(plane, np.array([[0, 1, 2], [0, 2, 3]]), (60, 60))
    np.testing.assert_allclose(depth[10:40, 10:40], np.arange(10, 40) * 0.5 - 2.5 + np.zeros((30, 1)), atol=1e-4)


@pytest.mark.parametrize("slope", [(0.0, 0.0), (0.5, 0.0), (0.0, -0.8), (0.6, 0.6)])
def test_a_plane_hides_nothing_of_its_own_light(slope):
    """A tilted plane is its own horizon: the directions below it are behind its normal anyway, so it loses
    nothing but the quadrature's error (each direction takes the nearest of OCCLUSION_AZIMUTHS horizons: at most
    0.22 % of band 0 on the steepest plane here)."""
    sx, sy = slope
    pts, tris = _grid(40, lambda x, y: sx * x + sy * y, n=3)
    depth, seen = rasterise_depth(pts, tris, (60, 60))
    n = np.array([1.0, sx, -sy]) / np.linalg.norm([1.0, sx, -sy])  # the plane's normal, subject frame
    normals = np.broadcast_to(n.astype(np.float32), (60, 60, 3))
    loss = occlusion_loss(depth, seen, normals, 40.0)
    assert np.abs(loss[seen][:, 0]).max() < 3e-3 * lobe_transport(n)[0]
    assert not loss[~seen].any()


@pytest.mark.parametrize("size", [40, 200])  # 200: found on the coarser grid (OCCLUSION_GRID) and resized back
def test_the_bottom_of_a_pit_gets_less_light_than_its_normal_says(size):
    """The rule: without the occlusion term the pit's bottom, facing the camera, takes the light of a flat face
    (band 0 is the same for every normal); with it, the pit's walls hide part of the sky."""
    (pts, tris), c = _pit(size)
    shape = (size + 20, size + 20)
    t0 = np.full(shape, 0.7, np.float32)
    free, weight, _, _ = face_transport(pts, tris, t0, occlusion=False)
    seen, *_ = face_transport(pts, tris, t0, occlusion=True)
    assert weight[c, c] > 0.99
    assert free[c, c, 0] == pytest.approx(0.7, rel=1e-5)
    assert seen[c, c, 0] < 0.9 * 0.7  # the walls hide more than a tenth of the light
    assert seen[c, c, 0] > 0.3 * 0.7  # ... not all of it: the pit is open toward the camera
    assert (seen[..., 0] <= free[..., 0] + 1e-3 * 0.7).all()  # relief only ever hides light
    frontal = sh.basis(np.array([1.0, 0, 0]))
    assert seen[c, c] @ frontal < 0.97 * (free[c, c] @ frontal)  # a frontal lamp, band-limited, reaches it less


def test_a_ledge_above_hides_the_light_from_above_not_from_below():
    """An eye under the brow: a ledge nearer the camera above the point hides a lamp from above, not one from
    below."""
    pts, tris = _grid(40, lambda x, y: np.where(y < 24, 0.0, 8.0), n=81)  # the step at y = 24 (the brow's edge)
    depth, seen = rasterise_depth(pts, tris, (60, 60))
    normals = np.zeros((60, 60, 3), np.float32)
    normals[..., 0] = 1  # the floor below the ledge faces the camera
    loss = occlusion_loss(depth, seen, normals, 40.0)
    from_above = sh.basis(np.array([np.cos(0.6), 0, np.sin(0.6)]))
    from_below = sh.basis(np.array([np.cos(0.6), 0, -np.sin(0.6)]))
    unoccluded = lobe_transport(np.array([1.0, 0, 0])) @ from_above
    below_ledge = loss[27, 25]
    assert below_ledge @ from_above > 0.1 * unoccluded
    assert below_ledge @ from_above > 3 * (below_ledge @ from_below)
    assert np.abs(loss[12, 25]).max() < 1e-2 * unoccluded  # on the ledge itself nothing rises above the point


def test_the_switch_decides_when_not_told(monkeypatch):
    (pts, tris), c = _pit(40)
    t0 = np.full((60, 60), 0.7, np.float32)
    for on in (False, True):
        monkeypatch.setattr(face_mesh, "MESH_OCCLUSION", on)
        told = face_transport(pts, tris, t0, occlusion=on)[0]
        np.testing.assert_array_equal(face_transport(pts, tris, t0)[0], told)


def test_the_loss_on_the_seen_box_is_the_loss_on_the_whole_window():
    """``occlusion_loss`` works on the seen box and what its horizons and blur read: the same as on the whole window,
    also where the depth goes on (finite) beyond the seen part, with a tall ledge near the horizons' reach (past the
    blur's, 0.22 of the size against 0.25)."""
    (pts, tris), _ = _pit(200)
    depth, seen = rasterise_depth(pts, tris, (220, 220))
    big_depth = np.zeros((600, 600), np.float32)
    big_depth[150:370, 150:370] = np.where(seen, depth, 0.0)
    big_seen = np.zeros((600, 600), bool)
    big_seen[150:370, 150:370] = seen
    right = int(np.nonzero(big_seen.any(axis=0))[0][-1])
    big_depth[:, right + 47 : right + 50] = -500.0  # nearer the camera: hides what the seen edge sees of the sky
    normals = np.zeros((600, 600, 3), np.float32)
    normals[..., 0] = 1.0
    cropped = occlusion_loss(big_depth, big_seen, normals, 200.0)
    whole = face_mesh._window_loss(big_depth, big_seen, normals, 200.0, face_mesh.OCCLUSION_REACH * 200.0)
    assert np.abs(whole).max() > 1e-3  # the pit hides something
    np.testing.assert_allclose(cropped, whole, atol=1e-7)
