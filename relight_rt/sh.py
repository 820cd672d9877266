"""Spherical harmonics lighting: the one source of truth for every light in relight_rt.

Conventions (DESIGN.md §3, pinned by tests/test_sh.py against pyshtools golden values):

* Frame: subject/camera frame, +x from the subject toward the camera, +y toward the image's right,
  +z up. Right-handed.
* Basis: real, orthonormal (∫ Y_k² dω = 1), no Condon–Shortley phase, degree 2, nine coefficients
  in the order k = 0…8 ↔ (l, m) = (0,0), (1,−1), (1,0), (1,1), (2,−2), (2,−1), (2,0), (2,1), (2,2),
  i.e. 1, y, z, x, xy, yz, 3z²−1, xz, x²−y² times the constants below.
* Light: float array (9, 3); column c holds the SH coefficients of the radiance arriving from
  direction ω in colour channel c (R, G, B): L_c(ω) ≈ Σ_k light[k, c] · Y_k(ω).
* Transport (H, W, 9) and shading S = max(0, T · light), see `shading`.
* Environment maps: equirectangular (H, 2H, 3) linear RGB; pixel (i, j) looks along
  θ = π(i+½)/H from +z, φ = 2π(j+½)/W, ω = (sinθ cosφ, −sinθ sinφ, cosθ).
* Rotation: `rotate(light, R)` is active, new(ω) = old(Rᵀω); `rotate_z(light, a)` turns the
  environment by a about +z, carrying +x toward +y.
"""

from __future__ import annotations

import functools
import json
import logging
import math
import os
from pathlib import Path

import numpy as np

from ._errors import RelightError
from .color import srgb_to_linear

__all__ = [
    "basis",
    "check_light",
    "cosine_lobe",
    "directions_envmap",
    "envmap_from_light",
    "irradiance",
    "load_envmap",
    "load_light",
    "project_envmap",
    "render_sphere",
    "rotate",
    "rotate_z",
    "rotation_matrix",
    "save_light",
    "shading",
    "solid_angles_envmap",
]

logger = logging.getLogger(__name__)

N_COEFFS = 9
#: Degree l of each coefficient k.
BAND = (0, 1, 1, 1, 2, 2, 2, 2, 2)

# Normalisation constants of the real orthonormal basis, written exactly.
_C0 = 1 / (2 * math.sqrt(math.pi))  # 0.282095
_C1 = math.sqrt(3 / (4 * math.pi))  # 0.488603
_C2 = math.sqrt(15 / math.pi) / 2  # 1.092548 (xy, yz, xz)
_C20 = math.sqrt(5 / math.pi) / 4  # 0.315392 (3z² − 1)
_C22 = math.sqrt(15 / math.pi) / 4  # 0.546274 (x² − y²)

# Band 1 holds (y, z, x): coefficient k = 1, 2, 3 is axis _BAND1_AXES[k - 1].
_BAND1_AXES = (1, 2, 0)


def _band2_forms() -> np.ndarray:
    """(5, 3, 3) symmetric traceless Q_m with Y_{4+m}(ω) = ωᵀ Q_m ω on the unit sphere."""
    q = np.zeros((5, 3, 3))
    q[0, 0, 1] = q[0, 1, 0] = _C2 / 2  # xy
    q[1, 1, 2] = q[1, 2, 1] = _C2 / 2  # yz
    q[2] = np.diag([-_C20, -_C20, 2 * _C20])  # 3z² − 1 = 2z² − x² − y² on the sphere
    q[3, 0, 2] = q[3, 2, 0] = _C2 / 2  # xz
    q[4] = np.diag([_C22, -_C22, 0.0])  # x² − y²
    q.setflags(write=False)
    return q


_Q2 = _band2_forms()
_Q2_NORM2 = np.einsum("mij,mij->m", _Q2, _Q2)


# --------------------------------------------------------------------------------------------- basis


def basis(dirs) -> np.ndarray:
    """Evaluate the nine SH basis functions (DESIGN.md §3 order) at unit directions.

    Args:
        dirs: (..., 3) unit vectors (x, y, z) in the subject frame. They are not normalised here:
            the functions are the polynomials of §3, which equal the SH only on the unit sphere.

    Returns:
        (..., 9) array; float32 for float32 input, float64 otherwise.
    """
    d = np.asarray(dirs)
    if d.dtype.kind not in "fiu" or d.ndim < 1 or d.shape[-1] != 3:
        raise RelightError(f"dirs: expected (..., 3) unit vectors, got {d.shape} {d.dtype}")
    if d.dtype not in (np.float32, np.float64):
        d = d.astype(np.float64)
    t = d.dtype.type
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    out = np.empty(d.shape[:-1] + (N_COEFFS,), dtype=d.dtype)
    out[..., 0] = t(_C0)
    out[..., 1] = t(_C1) * y
    out[..., 2] = t(_C1) * z
    out[..., 3] = t(_C1) * x
    out[..., 4] = t(_C2) * x * y
    out[..., 5] = t(_C2) * y * z
    out[..., 6] = t(_C20) * (t(3) * z * z - t(1))
    out[..., 7] = t(_C2) * x * z
    out[..., 8] = t(_C22) * (x * x - y * y)
    return out


def cosine_lobe() -> np.ndarray:
    """Zonal coefficients A_l of the clamped cosine max(0, n·ω), repeated per coefficient.

    Returns:
        (9,) float64: π, 2π/3 (×3), π/4 (×5). Unoccluded transport is T_k(n) = A_l · Y_k(n) and the
        irradiance of a light at normal n is Σ_k A_l · Y_k(n) · light[k].
    """
    a = (math.pi, 2 * math.pi / 3, math.pi / 4)
    return np.array([a[band] for band in BAND], dtype=np.float64)


# --------------------------------------------------------------------------------------------- lights


def _describe(arr: np.ndarray) -> str:
    return f"{arr.shape} {arr.dtype}"


def _check_lights(light, name: str) -> np.ndarray:
    """Validate a light or a stack of lights (..., 9, 3); return a float64 copy."""
    try:
        arr = np.array(light, dtype=np.float64, copy=True)
    except (TypeError, ValueError) as exc:
        raise RelightError(f"{name}: expected an SH light of shape (9, 3), got an unreadable value ({exc})") from None
    src = np.asarray(light)
    if src.dtype.kind not in "fiu":
        raise RelightError(f"{name}: expected a numeric SH light of shape (9, 3), got {_describe(src)}")
    if arr.ndim < 2 or arr.shape[-2:] != (N_COEFFS, 3):
        raise RelightError(f"{name}: expected an SH light of shape (9, 3) (or (N, 9, 3)), got {_describe(src)}")
    if not np.all(np.isfinite(arr)):
        raise RelightError(f"{name}: SH light contains NaN or Inf")
    _check_magnitude(arr, name)
    return arr


MAX_COEFF = 1e30
"""Largest |coefficient| of a light that is accepted. Lights are used in float32 (whose largest value is
3.4e38); shading sums 9 products of a coefficient with the transport, so beyond this a plausible
transport overflows to Inf and the result turns to NaN. Presets have coefficients of about 1."""


_MAX_COEFF_F32 = float(np.float32(MAX_COEFF))  # MAX_COEFF as float32 holds it: a checked light's float32 copy passes


def _check_magnitude(arr: np.ndarray, name: str) -> None:
    peak = float(np.max(np.abs(arr))) if arr.size else 0.0
    if peak > _MAX_COEFF_F32:
        raise RelightError(
            f"{name}: SH light coefficient {peak:.3g} is too large (|value| must be <= {MAX_COEFF:g}; "
            "float32 shading would overflow)"
        )


def check_light(light, name: str = "light") -> np.ndarray:
    """Validate one SH light.

    Args:
        light: array-like (9, 3): coefficient k (§3 order) × colour (R, G, B).
        name: how the input is named in the error message.

    Returns:
        A float64 (9, 3) copy.

    Raises:
        RelightError: wrong shape, non-numeric, NaN or Inf.
    """
    arr = _check_lights(light, name)
    if arr.shape != (N_COEFFS, 3):
        raise RelightError(f"{name}: expected an SH light of shape (9, 3), got {_describe(np.asarray(light))}")
    return arr


def shading(transport, light) -> np.ndarray:
    """Diffuse shading S_c = max(0, Σ_k T_k · light[k, c]), the runtime's hot path.

    Args:
        transport: (..., 9) light transport (e.g. (H, W, 9)); float32 is used as is, other dtypes
            are converted. Not modified.
        light: (9, 3) SH light, RGB columns.

    Returns:
        (..., 3) float32 RGB shading, ≥ 0 (not clipped above).
    """
    t = np.asarray(transport)
    if t.ndim < 1 or t.shape[-1] != N_COEFFS or t.dtype.kind not in "fiu":
        raise RelightError(f"transport: expected (..., 9) SH transport, got {_describe(t)}")
    lit = check_light(light).astype(np.float32)
    flat = t.reshape(-1, N_COEFFS)
    if flat.dtype != np.float32:
        flat = flat.astype(np.float32)
    out = flat @ lit
    np.maximum(out, 0, out=out)
    return out.reshape(t.shape[:-1] + (3,))


def dominant_direction(coeffs) -> tuple[np.ndarray | None, float]:
    """Where a one-channel light (9,) mostly comes from, by its degree-1 band, and how directional it is.

    Returns:
        (unit direction (3,) in the subject frame or None for a light without a direction,
        |band 1| / (√3 · band 0): 1 for light from a single direction, 0 for a uniform one).
    """
    c = np.asarray(coeffs, np.float64).reshape(-1)
    if c.shape != (N_COEFFS,):
        raise RelightError(f"light: expected 9 SH coefficients of one channel, got {c.shape}")
    v = np.array([c[3], c[1], c[2]])  # (x, y, z): Y_3 ∝ x, Y_1 ∝ y, Y_2 ∝ z
    n = float(np.linalg.norm(v))
    if n <= 1e-9 or c[0] <= 1e-9:
        return None, 0.0
    return v / n, min(1.0, n / (math.sqrt(3) * float(c[0])))


def irradiance(light, normals) -> np.ndarray:
    """Irradiance of an unoccluded diffuse surface, E_c(n) = Σ_k A_l · Y_k(n) · light[k, c].

    This is the exact irradiance of the degree-2 light (no clamping: it can dip below 0 for lights
    with strong ringing). For any non-negative environment the degree-2 irradiance differs from the
    true one by at most 3/32 of the light's total power ∫L dω (max |max(0,t) − K₂(t)| = 3/32 at t = 0).

    Args:
        light: (9, 3) SH light, RGB.
        normals: (..., 3) unit normals in the subject frame.

    Returns:
        (..., 3) RGB irradiance; float32 for float32 normals, float64 otherwise.
    """
    lit = check_light(light)
    y = basis(normals)
    weighted = (cosine_lobe()[:, None] * lit).astype(y.dtype)
    return y @ weighted


def render_sphere(light, size: int = 256, return_mask: bool = False):
    """Preview a light on an unoccluded white diffuse sphere seen from the camera.

    Orthographic view along −x (the camera looks at the subject from +x): image column → +y,
    image row → −z. Each pixel shows max(0, irradiance) at the sphere's normal there (the shading S
    of an albedo-1 surface); the background is 0.

    Args:
        light: (9, 3) SH light, RGB.
        size: image side in pixels (≥ 1).
        return_mask: also return the (size, size) bool mask of the sphere.

    Returns:
        (size, size, 3) float32 RGB shading, or (image, mask) when return_mask is True.
    """
    from ._limits import check_pixels

    if isinstance(size, bool) or not isinstance(size, (int, np.integer)) or size < 1:
        raise RelightError(f"size: expected a positive integer, got {size!r}")
    check_pixels(int(size), int(size), "sphere")
    lit = check_light(light)
    c = (np.arange(size, dtype=np.float32) + np.float32(0.5)) * np.float32(2 / size) - np.float32(1)
    y = np.broadcast_to(c[None, :], (size, size))
    z = np.broadcast_to(-c[:, None], (size, size))
    r2 = y * y + z * z
    mask = r2 <= 1
    x = np.sqrt(np.maximum(np.float32(0), np.float32(1) - r2))
    normals = np.stack([x, y, z], axis=-1)
    image = irradiance(lit, normals)
    np.maximum(image, 0, out=image)
    image[~mask] = 0
    image = image.astype(np.float32, copy=False)
    return (image, mask) if return_mask else image


# --------------------------------------------------------------------------------------------- rotation


def _check_rotation(rot, name: str = "R") -> np.ndarray:
    arr = np.asarray(rot)
    if arr.dtype.kind not in "fiu" or arr.ndim < 2 or arr.shape[-2:] != (3, 3):
        raise RelightError(f"{name}: expected a (3, 3) rotation matrix, got {_describe(arr)}")
    r = arr.astype(np.float64)
    if not np.all(np.isfinite(r)):
        raise RelightError(f"{name}: rotation matrix contains NaN or Inf")
    err = np.abs(r @ np.swapaxes(r, -1, -2) - np.eye(3)).max()
    if err > 1e-5:
        raise RelightError(f"{name}: not a rotation matrix: not orthonormal (max |R·Rᵀ − I| = {err:.3g})")
    det = np.linalg.det(r)
    if np.any(det < 0):
        raise RelightError(f"{name}: not a rotation matrix: det = {det.min():.3g} (a reflection); expected +1")
    return r


def _sh_rotation(r: np.ndarray) -> np.ndarray:
    """(..., 9, 9) matrices M with rotate(light, R) = M @ light, exact (closed form per band).

    Band 1 is the vector (y, z, x): M₁[a, b] = R[p(a), p(b)]. Band 2 functions are quadratic forms
    ωᵀQ_mω with symmetric traceless Q_m, orthogonal under the Frobenius product; the rotated function
    ω ↦ Y_m(Rᵀω) has the form R Q_m Rᵀ, whose coordinates on the Q_n are ⟨R Q_m Rᵀ, Q_n⟩ / ⟨Q_n, Q_n⟩.
    """
    m = np.zeros(r.shape[:-2] + (N_COEFFS, N_COEFFS))
    m[..., 0, 0] = 1.0
    p = list(_BAND1_AXES)
    m[..., 1:4, 1:4] = r[..., p, :][..., :, p]
    rq = np.einsum("...ij,mjk,...lk->...mil", r, _Q2, r)
    d = np.einsum("...mil,nil->...mn", rq, _Q2) / _Q2_NORM2  # Y_m(Rᵀω) = Σ_n d[m, n] Y_n(ω)
    m[..., 4:, 4:] = np.swapaxes(d, -1, -2)
    return m


def rotate(light, R) -> np.ndarray:
    """Rotate an SH light actively by a rotation matrix: new(ω) = old(Rᵀω). Exact for degree 2.

    A light arriving from direction d arrives from R·d afterwards.

    Args:
        light: (9, 3) or (N, 9, 3) SH lights (RGB).
        R: (3, 3) or (N, 3, 3) proper rotation matrix (orthonormal, det +1) in the subject frame;
            leading dimensions broadcast with the light's.

    Returns:
        (..., 9, 3) float64 rotated light(s); the input is not modified.

    Raises:
        RelightError: a bad light, or R not a rotation (not orthonormal, or a reflection).
    """
    lit = _check_lights(light, "light")
    r = _check_rotation(R)
    return _sh_rotation(r) @ lit


def rotate_z(light, angle) -> np.ndarray:
    """Turn the environment by `angle` radians about +z, carrying +x toward +y (= rotate(light, Rz)).

    Args:
        light: (9, 3) or (N, 9, 3) SH lights (RGB).
        angle: radians, scalar or array broadcasting with the light's leading dimensions (a (N,)
            array with a (9, 3) light gives N rotated copies).

    Returns:
        (..., 9, 3) float64 rotated light(s).
    """
    lit = _check_lights(light, "light")
    a = np.asarray(angle, dtype=np.float64)
    if not np.all(np.isfinite(a)):
        raise RelightError(f"angle: expected finite radians, got {angle!r}")
    a = a[..., None]  # broadcast over the colour column
    c1, s1, c2, s2 = np.cos(a), np.sin(a), np.cos(2 * a), np.sin(2 * a)
    try:
        lead = np.broadcast_shapes(lit.shape[:-2], a.shape[:-1])
    except ValueError:
        raise RelightError(f"angle: shape {a.shape[:-1]} does not broadcast with lights {lit.shape}") from None
    out = np.empty(lead + (N_COEFFS, 3))
    k = [lit[..., i, :] for i in range(N_COEFFS)]
    out[..., 0, :] = k[0]
    out[..., 2, :] = k[2]
    out[..., 6, :] = k[6]
    # (cos, sin) pairs of each band: x ↔ y (l=1), xz ↔ yz (l=2, |m|=1), x²−y² ↔ xy (l=2, |m|=2).
    out[..., 3, :] = c1 * k[3] - s1 * k[1]
    out[..., 1, :] = s1 * k[3] + c1 * k[1]
    out[..., 7, :] = c1 * k[7] - s1 * k[5]
    out[..., 5, :] = s1 * k[7] + c1 * k[5]
    out[..., 8, :] = c2 * k[8] - s2 * k[4]
    out[..., 4, :] = s2 * k[8] + c2 * k[4]
    return out


def rotation_matrix(yaw=0.0, pitch=0.0, roll=0.0, degrees: bool = False) -> np.ndarray:
    """Rotation matrix R = Rz(yaw) · Ry(pitch) · Rx(roll) in the subject frame (+x camera, +y right, +z up).

    Applied to a direction: first roll about +x (carries +y toward +z), then pitch about +y (carries
    +z toward +x, so a light in front of the subject moves down), then yaw about +z (carries +x
    toward +y, so a light in front of the subject moves to the image's right). All right-handed.
    Pass the result to `rotate`.

    Args:
        yaw, pitch, roll: angles (radians, or degrees when degrees=True); scalars or broadcasting
            arrays.
        degrees: interpret the angles as degrees.

    Returns:
        (..., 3, 3) float64 rotation matrix ((3, 3) for scalar angles).
    """
    angles = [np.asarray(v, dtype=np.float64) for v in (yaw, pitch, roll)]
    if not all(np.all(np.isfinite(v)) for v in angles):
        raise RelightError(f"rotation_matrix: expected finite angles, got yaw={yaw!r} pitch={pitch!r} roll={roll!r}")
    if degrees:
        angles = [np.deg2rad(v) for v in angles]
    yaw_, pitch_, roll_ = np.broadcast_arrays(*angles)
    one, zero = np.ones_like(yaw_), np.zeros_like(yaw_)

    def mat(rows):
        return np.stack([np.stack(row, axis=-1) for row in rows], axis=-2)

    cz, sz = np.cos(yaw_), np.sin(yaw_)
    cy, sy = np.cos(pitch_), np.sin(pitch_)
    cx, sx = np.cos(roll_), np.sin(roll_)
    rz = mat([[cz, -sz, zero], [sz, cz, zero], [zero, zero, one]])
    ry = mat([[cy, zero, sy], [zero, one, zero], [-sy, zero, cy]])
    rx = mat([[one, zero, zero], [zero, cx, -sx], [zero, sx, cx]])
    return rz @ ry @ rx


# --------------------------------------------------------------------------------------------- env maps

# Separable form of the basis on the lat-long grid: Y_k(θ, φ) = const_k · Θ_t(θ) · Φ_f(φ).
# Θ_t: 1, sinθ, cosθ, sin²θ, sinθ·cosθ, 3cos²θ − 1.   Φ_f: 1, −sinφ, cosφ, −sinφ·cosφ, cos2φ.
_SEPARABLE = (  # (t, f, const) for k = 0…8
    (0, 0, _C0),
    (1, 1, _C1),  # y = sinθ · (−sinφ)
    (2, 0, _C1),  # z = cosθ
    (1, 2, _C1),  # x = sinθ · cosφ
    (3, 3, _C2),  # xy = sin²θ · (−sinφ cosφ)
    (4, 1, _C2),  # yz
    (5, 0, _C20),  # 3z² − 1
    (4, 2, _C2),  # xz
    (3, 4, _C22),  # x² − y² = sin²θ · cos2φ
)
_SEP_T = np.array([t for t, _, _ in _SEPARABLE])
_SEP_F = np.array([f for _, f, _ in _SEPARABLE])
_SEP_C = np.array([c for _, _, c in _SEPARABLE])


def _check_height(height) -> int:
    from ._limits import check_pixels

    if isinstance(height, bool) or not isinstance(height, (int, np.integer)) or height < 1:
        raise RelightError(f"height: expected a positive integer, got {height!r}")
    check_pixels(2 * int(height), int(height), "environment map")  # (H, 2H): held to the pixel limit
    return int(height)


@functools.lru_cache(maxsize=8)
def _grid_factors(height: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-row (6, H) Θ_t(θ_i), per-row (H,) solid angle sinθ·dθ·dφ, per-column (5, W) Φ_f(φ_j)."""
    width = 2 * height
    theta = np.pi * (np.arange(height) + 0.5) / height
    phi = 2 * np.pi * (np.arange(width) + 0.5) / width
    st, ct = np.sin(theta), np.cos(theta)
    rows = np.stack([np.ones_like(st), st, ct, st * st, st * ct, 3 * ct * ct - 1])
    weight = st * (np.pi / height) * (2 * np.pi / width)
    sp, cp = np.sin(phi), np.cos(phi)
    cols = np.stack([np.ones_like(sp), -sp, cp, -sp * cp, np.cos(2 * phi)])
    for a in (rows, weight, cols):
        a.setflags(write=False)
    return rows, weight, cols


def directions_envmap(height: int) -> np.ndarray:
    """Unit direction of every pixel centre of an (H, 2H) equirectangular map (DESIGN.md §3).

    Returns:
        (H, 2H, 3) float64, ω = (sinθ cosφ, −sinθ sinφ, cosθ) with θ = π(i+½)/H, φ = 2π(j+½)/(2H).
    """
    h = _check_height(height)
    theta = np.pi * (np.arange(h) + 0.5) / h
    phi = 2 * np.pi * (np.arange(2 * h) + 0.5) / (2 * h)
    st, ct = np.sin(theta)[:, None], np.cos(theta)[:, None]
    x = st * np.cos(phi)[None, :]
    y = -st * np.sin(phi)[None, :]
    z = np.broadcast_to(ct, x.shape)
    return np.stack([x, y, z], axis=-1)


def solid_angles_envmap(height: int) -> np.ndarray:
    """Solid angle of every pixel of an (H, 2H) equirectangular map: sinθ · (π/H) · (2π/W).

    Returns:
        (H, 2H) float64; sums to ≈ 4π.
    """
    h = _check_height(height)
    _, weight, _ = _grid_factors(h)
    return np.repeat(weight[:, None], 2 * h, axis=1)


def _check_envmap(env, name: str = "env") -> np.ndarray:
    from ._limits import check_array_pixels

    arr = np.asarray(env)
    if arr.ndim != 3 or arr.shape[2] != 3 or arr.shape[0] < 1 or arr.shape[1] != 2 * arr.shape[0]:
        raise RelightError(f"{name}: expected an equirectangular (H, 2H, 3) RGB map, got {_describe(arr)}")
    check_array_pixels(arr, name)
    if arr.dtype.kind != "f":
        raise RelightError(
            f"{name}: expected float linear RGB, got {arr.dtype} (decode display values with "
            "relight_rt.color.srgb_to_linear or read files with load_envmap)"
        )
    if arr.dtype not in (np.float32, np.float64):
        arr = arr.astype(np.float32)
    return arr


def project_envmap(env) -> np.ndarray:
    """Project an equirectangular environment map onto the nine SH functions (solid-angle weighted).

    light[k, c] = Σ_ij env[i, j, c] · Y_k(ω_ij) · sinθ_i · (π/H) · (2π/W). The sum is separable
    (Y_k = const · Θ(θ) · Φ(φ)), so it is one (6, H) × (H, 2H·3) product followed by small sums.

    Args:
        env: (H, 2H, 3) float linear RGB radiance, layout of DESIGN.md §3 (top row = sky, centre
            column = straight ahead of the camera, behind the subject).

    Returns:
        (9, 3) float64 RGB light.
    """
    arr = _check_envmap(env)
    h, w = arr.shape[:2]
    rows, weight, cols = _grid_factors(h)
    theta_w = (rows * weight).astype(arr.dtype)
    per_col = (theta_w @ np.ascontiguousarray(arr).reshape(h, w * 3)).reshape(6, w, 3).astype(np.float64)
    sums = np.einsum("tjc,fj->tfc", per_col, cols)  # (6, 5, 3)
    light = _SEP_C[:, None] * sums[_SEP_T, _SEP_F]
    if not np.all(np.isfinite(light)):
        raise RelightError("env: environment map contains NaN or Inf")
    return light


def envmap_from_light(light, height: int) -> np.ndarray:
    """Evaluate an SH light on the equirectangular grid (a preview of what the light looks like).

    Args:
        light: (9, 3) SH light, RGB.
        height: map height H (width 2H).

    Returns:
        (H, 2H, 3) float32 linear RGB radiance Σ_k light[k] · Y_k(ω_ij) (may be negative where the
        degree-2 approximation rings).
    """
    lit = check_light(light)
    h = _check_height(height)
    rows, _, cols = _grid_factors(h)
    per_col = np.zeros((6, 2 * h, 3))
    for k in range(N_COEFFS):
        per_col[_SEP_T[k]] += _SEP_C[k] * cols[_SEP_F[k]][:, None] * lit[k][None, :]
    env = np.ascontiguousarray(rows.T, dtype=np.float32) @ per_col.reshape(6, 2 * h * 3).astype(np.float32)
    return env.reshape(h, 2 * h, 3)


_ENV_EXTS = (".hdr", ".pic", ".exr", ".png", ".jpg", ".jpeg")


def load_envmap(path) -> np.ndarray:
    """Read an equirectangular environment map as linear RGB.

    Radiance `.hdr` (and `.pic`) through OpenCV; `.exr` when the installed OpenCV reads it (set
    OPENCV_IO_ENABLE_OPENEXR=1 before Python starts, with an OpenCV built with OpenEXR); `.png` /
    `.jpg` are sRGB and linearised. Alpha is dropped; grey maps become three equal channels.

    Args:
        path: file path.

    Returns:
        (H, 2H, 3) float32 linear RGB.

    Raises:
        RelightError: missing or unreadable file, unsupported extension, EXR support missing, a width
            that is not twice the height (never silently resized), NaN/Inf values.
    """
    import cv2

    p = Path(path)
    ext = p.suffix.lower()
    if ext not in _ENV_EXTS:
        raise RelightError(f"{p}: unsupported environment map type {ext!r}; expected one of {', '.join(_ENV_EXTS)}")
    if not p.is_file():
        raise RelightError(f"{p}: environment map {'is not a regular file' if p.exists() else 'not found'}")
    from ._limits import check_pixels, header_size

    try:
        size = header_size(p, f"environment map {p}")
        if size is not None:
            check_pixels(size[0], size[1], f"environment map {p}")
        data = np.fromfile(p, dtype=np.uint8)
        img = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data.size else None
    except (OSError, cv2.error) as exc:
        logger.debug("decoding %s failed: %s", p, exc)
        img = None
    if img is None:
        if ext == ".exr" and os.environ.get("OPENCV_IO_ENABLE_OPENEXR", "").lower() not in ("1", "true", "on"):
            raise RelightError(
                f"{p}: OpenCV's .exr reader is disabled; set the environment variable OPENCV_IO_ENABLE_OPENEXR=1 "
                "before starting Python (needs an OpenCV built with OpenEXR), or convert the map to .hdr"
            )
        if ext == ".exr":
            raise RelightError(
                f"{p}: cannot decode .exr (corrupt file, or this OpenCV was built without OpenEXR; "
                "OPENCV_IO_ENABLE_OPENEXR is set); convert the map to .hdr"
            )
        raise RelightError(f"{p}: cannot decode environment map (corrupt or not a {ext} image)")
    check_pixels(img.shape[1], img.shape[0], f"environment map {p}")
    if img.ndim == 2:
        img = np.repeat(img[:, :, None], 3, axis=2)
    if img.shape[2] == 4:
        img = img[:, :, :3]
    elif img.shape[2] != 3:
        raise RelightError(f"{p}: expected a colour or grey environment map, got {img.shape[2]} channels")
    rgb = img[:, :, ::-1]
    if ext in (".png", ".jpg", ".jpeg"):
        if rgb.dtype not in (np.uint8, np.uint16):
            raise RelightError(f"{p}: expected an 8- or 16-bit image, got {rgb.dtype}")
        out = srgb_to_linear(rgb)
    else:
        out = rgb.astype(np.float32)
    out = np.ascontiguousarray(out, dtype=np.float32)
    h, w = out.shape[:2]
    if w != 2 * h:
        raise RelightError(f"{p}: expected an equirectangular map with width = 2 × height, got {w}×{h} (W×H)")
    if not np.all(np.isfinite(out)):
        raise RelightError(f"{p}: environment map contains NaN or Inf")
    return out


# --------------------------------------------------------------------------------------------- files

_LAYOUTS = (None, "27-kc", "3x9")
_JSON_MAX_BYTES = 1 << 20


def _shape_light(arr: np.ndarray, layout, p: Path) -> np.ndarray:
    if layout not in _LAYOUTS:
        raise RelightError(f"layout: expected None, '27-kc' or '3x9', got {layout!r}")
    if layout is None:
        if arr.shape in ((27,), (3, 9)):
            raise RelightError(
                f"{p}: light has shape {arr.shape}; say how to read it: layout='27-kc' (index 3k + c) "
                "for (27,), layout='3x9' (row c, column k) for (3, 9)"
            )
        if arr.shape != (N_COEFFS, 3):
            raise RelightError(f"{p}: expected an SH light of shape (9, 3), got {arr.shape}")
        return arr
    want = (27,) if layout == "27-kc" else (3, 9)
    if arr.shape != want:
        raise RelightError(f"{p}: layout={layout!r} expects shape {want}, got {arr.shape}")
    return arr.reshape(N_COEFFS, 3) if layout == "27-kc" else arr.T


def load_light(path, bgr: bool = False, layout: str | None = None) -> np.ndarray:
    """Read an SH light file as RGB.

    Formats: `.npy` holding (9, 3) (coefficient × colour), read with allow_pickle=False; `.json`
    {"sh": [[r, g, b] × 9], "order": "rgb"} ("order": "bgr" is honoured too).

    Args:
        path: file path.
        bgr: the file's columns are B, G, R (the reference implementation's light files, e.g.
            ../shared/reference/lights); they are swapped to RGB. An explicit choice, never guessed.
        layout: how to read a flat or transposed array: '27-kc' for (27,) with index 3k + c,
            '3x9' for (3, 9) with row c and column k. None accepts only (9, 3).

    Returns:
        (9, 3) float64 RGB light.

    Raises:
        RelightError: naming the file and the problem (missing, unreadable, wrong shape, NaN/Inf,
            conflicting colour order).
    """
    p = Path(path)
    ext = p.suffix.lower()
    if ext not in (".npy", ".json"):
        raise RelightError(f"{p}: unsupported light file type {ext!r}; expected .npy or .json")
    if not p.is_file():
        raise RelightError(f"{p}: light file {'is not a regular file' if p.exists() else 'not found'}")
    swap = bool(bgr)
    try:
        if ext == ".npy":
            from ._limits import load_npy

            raw = load_npy(p, "light", max_bytes=1 << 20)
        else:
            if p.stat().st_size > _JSON_MAX_BYTES:
                size = p.stat().st_size
                raise RelightError(f"{p}: {size:,} bytes is too large for a light file (a light is 27 numbers)")
            doc = json.loads(p.read_text(encoding="utf-8"))
            if not isinstance(doc, dict) or "sh" not in doc:
                raise RelightError(f'{p}: expected a JSON object {{"sh": [[r, g, b] x 9], "order": "rgb"}}')
            order = str(doc.get("order", "bgr" if bgr else "rgb")).lower()
            if order not in ("rgb", "bgr"):
                raise RelightError(f"{p}: \"order\" must be 'rgb' or 'bgr', got {doc.get('order')!r}")
            if bgr and order == "rgb":
                raise RelightError(f'{p}: bgr=True but the file says "order": "rgb"')
            swap = order == "bgr"
            raw = np.array(doc["sh"], dtype=np.float64)
    except RelightError:
        raise
    except RecursionError:
        raise RelightError(f"{p}: cannot read light file (JSON nested too deeply)") from None
    except (OSError, EOFError, ValueError, TypeError, UnicodeDecodeError) as exc:
        raise RelightError(f"{p}: cannot read light file ({exc})") from None
    if raw.dtype.kind not in "fiu":
        raise RelightError(f"{p}: expected a numeric SH light, got dtype {raw.dtype}")
    arr = _shape_light(np.asarray(raw, dtype=np.float64), layout, p)
    if not np.all(np.isfinite(arr)):
        raise RelightError(f"{p}: light contains NaN or Inf")
    _check_magnitude(arr, str(p))
    if swap:
        arr = arr[:, ::-1]
    return np.array(arr, dtype=np.float64, copy=True)


def save_light(path, light, bgr: bool = False) -> None:
    """Write an SH light atomically (temporary file in the same folder, then os.replace).

    Args:
        path: `.npy` ((9, 3) float64) or `.json` ({"sh": [[r, g, b] × 9], "order": "rgb"}).
        light: (9, 3) RGB light.
        bgr: write the columns as B, G, R (the reference's order; .json then says "order": "bgr").
    """
    p = Path(path)
    lit = check_light(light)
    ext = p.suffix.lower()
    if ext not in (".npy", ".json"):
        raise RelightError(f"{p}: unsupported light file type {ext!r}; expected .npy or .json")
    if not p.parent.is_dir():
        raise RelightError(f"{p}: folder {p.parent} does not exist")
    data = lit[:, ::-1].copy() if bgr else lit
    from ._io import atomic_path

    with atomic_path(p) as tmp, open(tmp, "wb") as f:
        if ext == ".npy":
            np.save(f, data, allow_pickle=False)
        else:
            doc = {"sh": data.tolist(), "order": "bgr" if bgr else "rgb"}
            f.write(json.dumps(doc, indent=1).encode("utf-8"))
