"""Toy training data without a renderer: spheres, random lights and "photos" (tests, quickstart fallback).

A sample is a sphere seen by the camera (DESIGN.md §3 frame: +x toward the camera, +y to the
image's right, +z up): a disc mask, a smooth random albedo, skin on the upper part, and the
unoccluded transport T_k = A_l · Y_k(n) of the sphere's normals (no ray casting, no anny, no
embree). Photos add a view-dependent-looking highlight (a non-diffuse part that stage 2 can learn)
to the diffuse image. Files are written with :mod:`export.dataset`, in the real data's layout.
"""

from __future__ import annotations

import os

import numpy as np

from relight_rt.light.sh import basis as sh_basis
from relight_rt.light.sh import cosine_lobe
from relight_rt.light.sh import shading as sh_shading

from .dataset import photo_name, write_light, write_photo, write_sample

COSINE_LOBE = cosine_lobe()


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


def highlight(normals: np.ndarray, mask: np.ndarray, light: np.ndarray, strength: float = 0.35,
              exponent: float = 24.0) -> np.ndarray:
    """A Blinn-Phong highlight (H,W,3) toward the light's dominant direction (its band-1 vector), camera at +x."""
    d = np.array([light[3].mean(), light[1].mean(), light[2].mean()])  # Y1 ∝ y, Y2 ∝ z, Y3 ∝ x
    d = d / max(np.linalg.norm(d), 1e-8)
    half = d + np.array([1.0, 0.0, 0.0])
    half /= max(np.linalg.norm(half), 1e-8)
    lobe = np.clip(normals @ half, 0.0, 1.0) ** exponent
    colour = np.clip(light[0] / max(light[0].max(), 1e-8), 0.0, 1.0)
    return (strength * lobe[..., None] * colour * mask[..., None]).astype(np.float32)


def make_samples(root: str | os.PathLike, n: int, size: int, seed: int = 0) -> list[str]:
    """Write n sphere samples (with jittered position and radius) to root; returns their names."""
    rng = np.random.default_rng(seed)
    names = []
    for k in range(n):
        mask, normals = sphere(size, rng.uniform(0.3, 0.45), tuple(rng.uniform(-0.08, 0.08, 2) * size))
        skin = mask * (normals[..., 2] > 0.3)
        name = f"s{k:03d}"
        write_sample(root, name, smooth_albedo(size, rng), mask, skin, sphere_transport(normals, mask))
        names.append(name)
    return names


def make_lights(root: str | os.PathLike, n: int, seed: int = 1) -> np.ndarray:
    """Write n random training lights (BGR files) to root; returns them (n,9,3) RGB."""
    rng = np.random.default_rng(seed)
    lights = np.stack([random_light(rng) for _ in range(n)])
    for k, light in enumerate(lights):
        write_light(root, f"light{k:03d}", light)
    return lights


def make_photos(root: str | os.PathLike, n_subjects: int, n_lights: int, size: int, seed: int = 2) -> list[str]:
    """Photos SUBJECT__L{j}: a diffuse sphere plus a highlight that moves with the light (non-diffuse part)."""
    rng = np.random.default_rng(seed)
    names = []
    for s in range(n_subjects):
        mask, normals = sphere(size, rng.uniform(0.3, 0.45))
        albedo = smooth_albedo(size, rng)
        transport = sphere_transport(normals, mask)
        for j in range(n_lights):
            light = random_light(rng)
            shading = sh_shading(transport, light)
            diffuse = np.clip(albedo * shading, 0, 1) * mask[..., None]
            photo = np.clip(diffuse + highlight(normals, mask, light), 0, 1)
            name = photo_name(f"subj{s}", j)
            write_photo(root, name, photo, diffuse, mask, light)
            names.append(name)
    return names
