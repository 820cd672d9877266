"""Tiny synthetic stage-1 samples, lights and photos for the training/evaluation tests.

A sample is a sphere seen by the camera (DESIGN.md §3 frame: +x toward the camera, +y to the
image's right, +z up): a disc mask, a smooth random albedo, skin on the upper half, and the
unoccluded transport T_k = A_l · Y_k(n) of the sphere's normals (no ray casting, no anny).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

# DESIGN.md §3 table, constants written exactly
_C0 = 1 / (2 * math.sqrt(math.pi))
_C1 = math.sqrt(3 / (4 * math.pi))
_C2 = math.sqrt(15 / math.pi) / 2
_C3 = math.sqrt(5 / math.pi) / 4
_C4 = math.sqrt(15 / math.pi) / 4
COSINE_LOBE = np.array([math.pi] + [2 * math.pi / 3] * 3 + [math.pi / 4] * 5)


def sh_basis(n: np.ndarray) -> np.ndarray:
    """Real orthonormal SH (DESIGN.md §3 order) of unit vectors (..., 3) -> (..., 9)."""
    x, y, z = n[..., 0], n[..., 1], n[..., 2]
    return np.stack(
        [np.full_like(x, _C0), _C1 * y, _C1 * z, _C1 * x, _C2 * x * y, _C2 * y * z, _C3 * (3 * z * z - 1),
         _C2 * x * z, _C4 * (x * x - y * y)],
        axis=-1,
    )


def sphere(size: int, radius_frac: float = 0.42, shift: tuple[float, float] = (0.0, 0.0)):
    """(mask (H,W), normals (H,W,3)) of a sphere centred in a size² image (shift in pixels: row, col)."""
    c = (size - 1) / 2
    r = radius_frac * size
    i, j = np.mgrid[0:size, 0:size].astype(np.float64)
    u = (j - c - shift[1]) / r
    v = -(i - c - shift[0]) / r
    rho2 = u * u + v * v
    mask = (rho2 < 1.0).astype(np.float32)
    nx = np.sqrt(np.clip(1.0 - rho2, 0.0, 1.0))
    normals = np.stack([nx, u, v], axis=-1) * mask[..., None]
    return mask, normals


def sphere_transport(normals: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Unoccluded transport A_l · Y_k(n) (H,W,9) float32, zero off the mask."""
    return (COSINE_LOBE * sh_basis(normals) * mask[..., None]).astype(np.float32)


def smooth_albedo(size: int, rng: np.random.Generator) -> np.ndarray:
    """A smooth random RGB albedo in [0.2, 0.9] (sum of a few random low-frequency sinusoids)."""
    i, j = np.mgrid[0:size, 0:size] / size
    out = np.empty((size, size, 3), np.float32)
    for c in range(3):
        f = rng.uniform(0.5, 3.0, size=(3, 2))
        ph = rng.uniform(0, 2 * np.pi, size=3)
        wave = sum(np.sin(2 * np.pi * (f[k, 0] * i + f[k, 1] * j) + ph[k]) for k in range(3)) / 3
        out[..., c] = 0.55 + 0.3 * wave * rng.uniform(0.3, 1.0) + rng.uniform(-0.1, 0.1)
    return np.clip(out, 0.2, 0.9)


def random_light(rng: np.random.Generator) -> np.ndarray:
    """A plausible random (9,3) RGB light: ambient plus a soft directional part (brightest irradiance ≈ 1)."""
    d = rng.normal(size=3)
    d[0] = abs(d[0]) + 0.5  # mostly from the camera side
    d /= np.linalg.norm(d)
    colour = rng.uniform(0.7, 1.0, size=3)
    light = np.outer(sh_basis(d), colour) * rng.uniform(1.0, 2.0)
    light[0] += rng.uniform(0.6, 1.0) * colour
    return (light * 0.45).astype(np.float32)


def make_samples(root: Path, n: int, size: int, seed: int = 0) -> list[str]:
    """Write n sphere samples (with jittered position and radius) to root; returns their names."""
    from export.dataset import write_sample

    rng = np.random.default_rng(seed)
    names = []
    for k in range(n):
        mask, normals = sphere(size, rng.uniform(0.3, 0.45), tuple(rng.uniform(-0.08, 0.08, 2) * size))
        skin = mask * (normals[..., 2] > 0.3)
        name = f"s{k:03d}"
        write_sample(root, name, smooth_albedo(size, rng), mask, skin, sphere_transport(normals, mask))
        names.append(name)
    return names


def make_lights(root: Path, n: int, seed: int = 1) -> np.ndarray:
    """Write n random training lights (BGR files) to root; returns them (n,9,3) RGB."""
    from export.dataset import write_light

    rng = np.random.default_rng(seed)
    lights = np.stack([random_light(rng) for _ in range(n)])
    for k, light in enumerate(lights):
        write_light(root, f"light{k:03d}", light)
    return lights


def make_photos(root: Path, n_subjects: int, n_lights: int, size: int, seed: int = 2) -> list[str]:
    """Photos SUBJECT__L{j}: diffuse sphere plus a view-independent 'sheen' (a non-diffuse part)."""
    from export.dataset import photo_name, write_photo

    rng = np.random.default_rng(seed)
    names = []
    for s in range(n_subjects):
        mask, normals = sphere(size, rng.uniform(0.3, 0.45))
        albedo = smooth_albedo(size, rng)
        transport = sphere_transport(normals, mask)
        for j in range(n_lights):
            light = random_light(rng)
            shading = np.maximum(0.0, np.einsum("hwk,kc->hwc", transport, light))
            diffuse = np.clip(albedo * shading, 0, 1) * mask[..., None]
            sheen = 0.25 * normals[..., :1] ** 8 * mask[..., None]  # bright centre: a non-diffuse highlight
            photo = np.clip(diffuse + sheen, 0, 1)
            name = photo_name(f"subj{s}", j)
            write_photo(root, name, photo, diffuse, mask, light)
            names.append(name)
    return names
