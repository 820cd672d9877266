"""Simple test shapes as subject parts: a sphere, a textured plane and a bowl (all in the DESIGN §3 frame).

They let the renderer be tested and demonstrated without body models.
"""

from __future__ import annotations

import numpy as np

from .scene import Part


def _grid_faces(rows: int, cols: int) -> np.ndarray:
    """Two counter-clockwise triangles per cell of a (rows+1)×(cols+1) vertex grid, row-major."""
    i, j = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    a = (i * (cols + 1) + j).ravel()
    b, c, d = a + 1, a + cols + 1, a + cols + 2
    return np.concatenate([np.stack([a, c, b], 1), np.stack([b, c, d], 1)]).astype(np.int32)


def _part(name, vertices, faces, uv_vertices, albedo, **material) -> Part:
    tri = np.asarray(vertices)[faces]
    area = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    faces = faces[area > 1e-12]  # degenerate triangles at the poles
    uv = np.asarray(uv_vertices, np.float32)[faces]
    return Part(name, np.asarray(vertices, np.float32), faces, uv, np.asarray(albedo, np.float32), **material)


def sphere(
    center=(0.0, 0.0, 0.0), radius: float = 0.5, albedo=(0.6, 0.6, 0.6), *, rows: int = 48, name: str = "sphere",
    **material,
) -> Part:
    """A UV sphere (latitude/longitude grid: u = azimuth, v = height), outward-facing."""
    theta = np.linspace(0.0, np.pi, rows + 1)  # from +z down
    phi = np.linspace(0.0, 2.0 * np.pi, 2 * rows + 1)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    v = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1).reshape(-1, 3)
    uv = np.stack([p / (2 * np.pi), 1.0 - t / np.pi], -1).reshape(-1, 2)
    faces = _grid_faces(rows, 2 * rows)
    return _part(name, v * radius + np.asarray(center), faces, uv, albedo, **material)


def plane(
    size: float = 1.0, albedo=(0.6, 0.6, 0.6), *, x: float = 0.0, cells: int = 4, name: str = "plane", **material
) -> Part:
    """A square in the plane x = ``x`` facing the camera (+x), centred on the x axis.

    The texture covers it exactly: u runs along +y (left → right in the image), v along +z (up).
    """
    s = np.linspace(-0.5, 0.5, cells + 1)
    z, y = np.meshgrid(s[::-1], s, indexing="ij")  # rows from top (+z) down
    v = np.stack([np.full_like(y, x), y * size, z * size], -1).reshape(-1, 3)
    uv = np.stack([y + 0.5, z + 0.5], -1).reshape(-1, 2)
    faces = _grid_faces(cells, cells)
    return _part(name, v, faces, uv, albedo, **material)


def bowl(
    center=(0.0, 0.0, 0.0),
    radius: float = 1.0,
    depth: float = 0.5,
    albedo=(0.5, 0.5, 0.5),
    *,
    rows: int = 24,
    name: str = "bowl",
    **material,
) -> Part:
    """An open spherical cap below ``center`` (a cup opening to +z); ``depth`` 1 is a hemisphere, 0 flat."""
    # polar angle from +z, from the bottom (θ ≈ π) up to the rim at height -radius * (1 - depth)
    rim = np.arccos(-(1.0 - float(np.clip(depth, 0.0, 1.0))))
    theta = np.linspace(np.pi, rim, rows + 1)
    phi = np.linspace(0.0, 2.0 * np.pi, 2 * rows + 1)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    v = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1).reshape(-1, 3)
    uv = np.stack([p / (2 * np.pi), (t - theta[0]) / (theta[-1] - theta[0])], -1).reshape(-1, 2)
    faces = _grid_faces(rows, 2 * rows)
    return _part(name, v * radius + np.asarray(center), faces, uv, albedo, **material)


def random_scene(seed: int) -> list[Part]:
    """A small figure of touching spheres with random colours: a stand-in subject for tests and demos
    that has some self-occlusion (neck, "armpits", between the legs) but needs no body model."""
    rng = np.random.default_rng(seed)

    def color():
        return rng.uniform(0.2, 0.9, 3)

    skin = dict(skin=1.0, subsurface=1.0, specular=0.06, roughness=0.4)
    cloth = dict(skin=0.0, specular=float(rng.uniform(0.01, 0.3)), roughness=float(rng.uniform(0.15, 0.9)))
    tone = rng.uniform(0.35, 0.85) * np.array([1.0, 0.78, 0.62])
    arm = rng.uniform(0.22, 0.3)
    return [
        sphere((0, 0, 1.0), 0.3, color(), name="torso", **cloth),
        sphere((0, 0, 1.45), 0.15, tone, name="head", **skin),
        sphere((0, -arm - 0.05, 0.95), 0.09, tone, name="hand_l", **skin),
        sphere((0, arm + 0.05, 0.95), 0.09, tone, name="hand_r", **skin),
        sphere((0, -0.12, 0.55), 0.13, color(), name="leg_l", **cloth),
        sphere((0, 0.12, 0.55), 0.13, color(), name="leg_r", **cloth),
    ]
