"""The plain-PyTorch z-buffer (export.gpu.raster): coverage by pixel centres, nearest wins, chunking."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from export.gpu.raster import depth_map, rasterize  # noqa: E402


def _inside(tri: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Brute-force point-in-triangle (edges included) for pixel centres (x, y)."""
    (x0, y0), (x1, y1), (x2, y2) = tri

    def edge(ax, ay, bx, by):
        return (bx - ax) * (y - ay) - (by - ay) * (x - ax)

    e = np.stack([edge(x0, y0, x1, y1), edge(x1, y1, x2, y2), edge(x2, y2, x0, y0)])
    return (e >= 0).all(0) | (e <= 0).all(0)


@pytest.mark.parametrize("size", [(16, 16), (24, 40)])
def test_one_triangle_covers_the_centres_inside_it(size):
    h, w = size
    rng = np.random.default_rng(1)
    for _ in range(5):
        corners = rng.uniform(-3, [w + 3, h + 3], (3, 2))
        xy = torch.tensor(corners, dtype=torch.float32)[None]
        face, bary = rasterize(xy, torch.zeros(1, 3), torch.tensor([[0, 1, 2]]), h, w)
        jj, ii = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
        want = _inside(corners, jj, ii)
        got = face[0].numpy() == 0
        assert (got != want).sum() <= 2  # centres exactly on an edge may go either way in float32
        b = bary[0].numpy()[got]
        assert np.allclose(b.sum(-1), 1.0, atol=1e-5)
        centres = b @ corners
        assert np.allclose(centres, np.stack([jj[got], ii[got]], -1), atol=1e-3)


def test_the_nearest_triangle_wins_whatever_the_order():
    xy = torch.tensor([[0, 0], [20, 0], [0, 20], [0, 0], [20, 0], [0, 20]], dtype=torch.float32)[None]
    faces = torch.tensor([[0, 1, 2], [3, 4, 5]])
    for near in (0, 1):
        depth = torch.tensor([[2.0] * 3 + [1.0] * 3]) if near else torch.tensor([[1.0] * 3 + [2.0] * 3])
        face, _ = rasterize(xy, depth, faces, 16, 16)
        covered = face[0] >= 0
        assert covered.sum() > 50
        assert (face[0][covered] == near).all()


def test_chunking_and_large_triangles_do_not_change_the_result():
    rng = np.random.default_rng(3)
    xy = torch.tensor(rng.uniform(-10, 74, (2, 60, 2)), dtype=torch.float32)  # large, overlapping triangles
    depth = torch.tensor(rng.uniform(0, 1, (2, 60)), dtype=torch.float32)
    faces = torch.tensor(rng.integers(0, 60, (40, 3)))
    a, _ = rasterize(xy, depth, faces, 64, 64)
    b, _ = rasterize(xy, depth, faces, 64, 64, max_candidates=97)
    assert torch.equal(a, b)
    assert (a >= 0).float().mean() > 0.5


def test_depth_map_holds_the_nearest_depth_and_inf_where_empty():
    xy = torch.tensor([[[2, 2], [30, 2], [2, 30], [2, 2], [30, 2], [2, 30]]], dtype=torch.float32)
    depth = torch.tensor([[3.0, 3.0, 3.0, -1.0, -1.0, 5.0]])
    zbuf = depth_map(xy, depth, torch.tensor([[0, 1, 2], [3, 4, 5]]), 32)
    assert torch.isinf(zbuf[0, 31, 31])
    # near (2, 2) the second triangle is at about -1, nearer than 3
    assert zbuf[0, 2, 2] < 0.0
    assert torch.isfinite(zbuf[0, 10, 10]) and zbuf[0, 10, 10] <= 3.0
