"""Per-pixel buffers of a subject seen by a camera: mask, albedo, skin, and occlusion-aware transport.

Transport (DESIGN.md §3): T_k(p) = ∫ V(p,ω) · max(0, n_p·ω) · Y_k(ω) dω, estimated by Monte Carlo
with cosine-weighted directions on a jittered (stratified) grid: with pdf cos θ / π the estimate is
T_k ≈ (π / n) Σ_i V(p, ω_i) · Y_k(ω_i). Shadow rays start a small distance off the surface (along
the face normal) so that a surface does not shadow itself.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from relight_rt.engine.errors import RelightError
from relight_rt.light.sh import basis

from .camera import Camera
from .raycast import Tracer
from .scene import Subject

RAYS_PER_BATCH = 1 << 20


@dataclass
class GBuffer:
    """What the camera sees, one row per covered pixel (``index`` into the flattened R×R image).

    Attributes:
        resolution: R.
        index: (M,) int64 flat pixel indices (row-major) of the covered pixels.
        position, normal, geo_normal, view: (M, 3) float32; ``view`` is the unit vector toward the eye.
        part: (M,) int64 part index.
        albedo: (M, 3) float32 RGB in [0, 1]; skin, roughness, specular, subsurface: (M,) float32.
    """

    resolution: int
    index: np.ndarray
    position: np.ndarray
    normal: np.ndarray
    geo_normal: np.ndarray
    view: np.ndarray
    part: np.ndarray
    albedo: np.ndarray
    skin: np.ndarray
    roughness: np.ndarray
    specular: np.ndarray
    subsurface: np.ndarray

    def image(self, values: np.ndarray, fill: float = 0.0) -> np.ndarray:
        """Scatter per-pixel values (M, ...) into an (R, R, ...) float32 image, ``fill`` elsewhere."""
        r = self.resolution
        out = np.full((r * r, *values.shape[1:]), fill, np.float32)
        out[self.index] = values
        return out.reshape(r, r, *values.shape[1:])

    @property
    def mask(self) -> np.ndarray:
        """(R, R) float32, 1 where the subject covers the pixel centre."""
        return self.image(np.ones(len(self.index), np.float32))


def sample_texture(texture, uv: np.ndarray, name: str = "texture") -> np.ndarray:
    """Bilinear lookup of a texture at UV coordinates (v up: row 0 is v = 1), clamped at the border.

    Args:
        texture: (Ht, Wt, C) or (Ht, Wt) array, or a constant (scalar or (C,)).
        uv: (N, 2) coordinates in [0, 1].

    Returns:
        (N, C) or (N,) float32.
    """
    t = np.asarray(texture, dtype=np.float32)
    n = len(uv)
    if t.ndim <= 1:
        return np.broadcast_to(t, (n, *t.shape)).astype(np.float32)
    if t.ndim not in (2, 3):
        raise RelightError(f"{name}: expected (H, W[, C]) texture or a constant, got {t.shape}")
    h, w = t.shape[:2]
    x = np.clip(uv[:, 0] * w - 0.5, 0.0, w - 1.0)
    y = np.clip((1.0 - uv[:, 1]) * h - 0.5, 0.0, h - 1.0)
    x0 = np.minimum(np.floor(x).astype(np.int64), w - 2 if w > 1 else 0)
    y0 = np.minimum(np.floor(y).astype(np.int64), h - 2 if h > 1 else 0)
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    fx, fy = (x - x0).astype(np.float32), (y - y0).astype(np.float32)
    if t.ndim == 3:
        fx, fy = fx[:, None], fy[:, None]
    top = t[y0, x0] * (1 - fx) + t[y0, x1] * fx
    bottom = t[y1, x0] * (1 - fx) + t[y1, x1] * fx
    return (top * (1 - fy) + bottom * fy).astype(np.float32)


def render_gbuffer(subject: Subject, camera: Camera, tracer: Tracer | None = None) -> GBuffer:
    """Cast one ray per pixel centre and look up every material property at the hits."""
    tracer = tracer or Tracer(subject)
    origins, dirs = camera.rays()
    hits = tracer.intersect(origins, dirs)
    index = np.flatnonzero(hits.hit)
    face, bary, part = hits.face[index], hits.bary[index], hits.part[index]
    m = len(index)
    albedo = np.zeros((m, 3), np.float32)
    skin, rough, spec, sss = (np.zeros(m, np.float32) for _ in range(4))
    for i, p in enumerate(subject.parts):
        sel = np.flatnonzero(part == i)
        if len(sel) == 0:
            continue
        uv_corners = np.asarray(p.uv, dtype=np.float32)[face[sel] - tracer.face_start[i]]  # (n, 3, 2)
        uv = np.einsum("nc,ncd->nd", bary[sel], uv_corners)
        albedo[sel] = np.clip(sample_texture(p.albedo, uv, f"{p.name}.albedo")[:, :3], 0.0, 1.0)
        skin[sel] = np.clip(sample_texture(p.skin, uv, f"{p.name}.skin"), 0.0, 1.0)
        rough[sel] = np.clip(sample_texture(p.roughness, uv, f"{p.name}.roughness"), 0.02, 1.0)
        spec[sel] = np.maximum(sample_texture(p.specular, uv, f"{p.name}.specular"), 0.0)
        sss[sel] = float(np.clip(p.subsurface, 0.0, 1.0))
    return GBuffer(
        resolution=camera.resolution,
        index=index,
        position=hits.position[index],
        normal=hits.normal[index],
        geo_normal=hits.geo_normal[index],
        view=-dirs[index],
        part=part,
        albedo=albedo,
        skin=skin,
        roughness=rough,
        specular=spec,
        subsurface=sss,
    )


def tangent_frame(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit tangents (t, b) with (t, b, n) right-handed orthonormal, for unit normals n (N, 3)
    (Duff et al. 2017, "Building an orthonormal basis, revisited")."""
    x, y, z = n[:, 0], n[:, 1], n[:, 2]
    s = np.where(z >= 0, 1.0, -1.0)
    a = -1.0 / (s + z)
    b = x * y * a
    t = np.stack([1.0 + s * x * x * a, s * b, -s * x], axis=1)
    bt = np.stack([b, s + y * y * a, -y], axis=1)
    return t.astype(np.float32), bt.astype(np.float32)


def _grid(n: int) -> tuple[int, int]:
    """Strata (a, b) with a * b = n and a ≤ b as close to square as possible."""
    a = int(math.isqrt(n))
    while n % a:
        a -= 1
    return a, n // a


def cosine_directions(normals: np.ndarray, n_dirs: int, rng: np.random.Generator) -> np.ndarray:
    """Cosine-weighted directions about each normal on a jittered a×b grid (a·b = n_dirs).

    Args:
        normals: (P, 3) unit normals.
        n_dirs: directions per normal.
        rng: source of the jitter (a fresh jitter per normal).

    Returns:
        (P, n_dirs, 3) float32 unit directions in the hemisphere of each normal, pdf cos θ / π.
    """
    a, b = _grid(n_dirs)
    p = len(normals)
    jitter = rng.random((p, n_dirs, 2), dtype=np.float32)
    u1 = (np.repeat(np.arange(a, dtype=np.float32), b) + jitter[..., 0]) / a  # stratified in sin² θ
    phi = (np.tile(np.arange(b, dtype=np.float32), a) + jitter[..., 1]) * np.float32(2.0 * np.pi / b)  # and azimuth
    r = np.sqrt(u1)
    local = np.empty((p, n_dirs, 3), np.float32)
    local[..., 0] = r * np.cos(phi)
    local[..., 1] = r * np.sin(phi)
    local[..., 2] = np.sqrt(np.maximum(0.0, 1.0 - u1))
    t, bt = tangent_frame(normals)
    frame = np.stack([t, bt, np.asarray(normals, np.float32)], axis=1)  # rows: t, b, n
    return np.matmul(local, frame)


@functools.lru_cache(maxsize=1)
def _sh_from_moments() -> np.ndarray:
    """(10, 9) matrix M with basis(ω) = m(ω) @ M for unit ω, m = (1, x, y, z, x², y², z², xy, yz, xz).

    Derived from ``basis`` itself (least squares on a spread of unit directions; exact because every
    degree-2 SH is a quadratic polynomial), so the SH definition stays in one place.
    """
    k = np.arange(200) + 0.5
    z = 1.0 - 2.0 * k / 200
    phi = np.pi * (1.0 + 5.0**0.5) * k
    d = np.stack([np.sqrt(1 - z * z) * np.cos(phi), np.sqrt(1 - z * z) * np.sin(phi), z], axis=1)
    m = _monomials(d)
    y = np.asarray(basis(d), dtype=np.float64)
    mat, *_ = np.linalg.lstsq(m, y, rcond=None)
    if not np.allclose(m @ mat, y, atol=1e-9):
        raise RuntimeError("the SH basis is not a quadratic polynomial of the direction")
    return mat


def _monomials(d: np.ndarray) -> np.ndarray:
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    return np.stack([np.ones_like(x), x, y, z, x * x, y * y, z * z, x * y, y * z, x * z], axis=-1)


def transport(
    tracer: Tracer,
    gbuffer: GBuffer,
    n_dirs: int = 256,
    *,
    rng: np.random.Generator,
    offset: float | None = None,
) -> np.ndarray:
    """Occlusion-aware transport of every covered pixel.

    Args:
        tracer: the subject's tracer (shadow rays).
        gbuffer: covered pixels (positions, normals).
        n_dirs: Monte Carlo directions per pixel (≥ 1).
        rng: random generator (the only source of randomness: same state → same result).
        offset: shadow-ray start offset along the face normal, metres; default 1e-4 of the
            subject's bounding-box diagonal.

    Returns:
        (M, 9) float32 transport per covered pixel (DESIGN.md §3 SH order).
    """
    if int(n_dirs) < 1:
        raise RelightError(f"n_dirs: expected at least 1 direction, got {n_dirs}")
    n_dirs = int(n_dirs)
    eps = 1e-4 * tracer.scale if offset is None else float(offset)
    to_sh = (_sh_from_moments() * (np.pi / n_dirs)).astype(np.float32)
    m = len(gbuffer.index)
    out = np.zeros((m, 9), np.float32)
    chunk = max(1, RAYS_PER_BATCH // n_dirs)
    for s in range(0, m, chunk):
        e = min(m, s + chunk)
        dirs = cosine_directions(gbuffer.normal[s:e], n_dirs, rng)
        origins = gbuffer.position[s:e] + eps * gbuffer.geo_normal[s:e]
        origins = np.broadcast_to(origins[:, None], dirs.shape).reshape(-1, 3)
        visible = (~tracer.occluded(origins, dirs.reshape(-1, 3))).reshape(e - s, n_dirs).astype(np.float32)
        # moments of the visible directions: Σ V, Σ V ω, Σ V ω ωᵀ; the SH sums follow linearly
        vd = dirs * visible[..., None]
        second = np.matmul(vd.transpose(0, 2, 1), dirs)  # (P, 3, 3)
        moments = np.concatenate(
            [
                visible.sum(axis=1, keepdims=True),
                vd.sum(axis=1),
                second[:, [0, 1, 2, 0, 1, 0], [0, 1, 2, 1, 2, 2]],
            ],
            axis=1,
        )
        out[s:e] = moments @ to_sh
    return out


def render_sample(
    subject: Subject,
    camera: Camera,
    n_dirs: int = 256,
    *,
    seed: int | np.random.Generator = 0,
    tracer: Tracer | None = None,
) -> dict[str, np.ndarray]:
    """Render a stage-1 training sample.

    Returns:
        dict with ``albedo`` (R, R, 3) float32 RGB in [0, 1], ``mask`` and ``skin`` (R, R) float32 in
        [0, 1], ``transport`` (R, R, 9) float32 (zero off the mask).
    """
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    tracer = tracer or Tracer(subject)
    g = render_gbuffer(subject, camera, tracer)
    t = transport(tracer, g, n_dirs, rng=rng)
    return {"albedo": g.image(g.albedo), "mask": g.mask, "skin": g.image(g.skin), "transport": g.image(t)}
