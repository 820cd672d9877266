"""Spherical harmonics lighting: the one source of truth for every light in relight_rt.

Conventions (DESIGN.md §3, pinned by tests/runtime/light/test_sh.py against pyshtools golden values):

* Frame: subject/camera frame, +x from the subject toward the camera, +y toward the image's right,
  +z up. Right-handed.
* Basis: real, orthonormal (∫ Y_k² dω = 1), no Condon–Shortley phase, degree 2, nine coefficients
  in the order k = 0…8 ↔ (l, m) = (0,0), (1,−1), (1,0), (1,1), (2,−2), (2,−1), (2,0), (2,1), (2,2),
  i.e. 1, y, z, x, xy, yz, 3z²−1, xz, x²−y² times the constants below.
* Light: float array (9, 3); column c holds the SH coefficients of the radiance arriving from
  direction ω in colour channel c (R, G, B): L_c(ω) ≈ Σ_k light[k, c] · Y_k(ω).
* Transport (H, W, 9) and shading S = max(0, T · light), see `shading`.
* Environment maps live in ``relight_rt.light.envmap``, light files in ``relight_rt.light.files``.
* Rotation: `rotate(light, R)` is active, new(ω) = old(Rᵀω); `rotate_z(light, a)` turns the
  environment by a about +z, carrying +x toward +y.
"""

from __future__ import annotations

import logging
import math
import numbers

import numpy as np

from ..engine.errors import RelightError

__all__ = [
    "basis",
    "check_light",
    "check_lights",
    "cosine_lobe",
    "dominant_direction",
    "irradiance",
    "render_sphere",
    "rotate",
    "rotate_z",
    "rotation_coefficients",
    "rotation_matrix",
    "shading",
    "shading_chw",
    "sphere_directions",
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

#: The constant of each basis function: Y_k = NORM[k] · (1, y, z, x, xy, yz, 3z² − 1, xz, x² − y²)[k].
NORM = (_C0, _C1, _C1, _C1, _C2, _C2, _C20, _C2, _C22)

# Band 1 holds (y, z, x): coefficient k = 1, 2, 3 is axis _BAND1_AXES[k - 1].
_BAND1_AXES = (1, 2, 0)


# a picture mirrored left-right is the scene mirrored y -> -y (the picture's right is +y, DESIGN.md §3): the
# coefficients odd in y (k = 1: y, 4: xy, 5: yz) change sign, the others keep it; a light L seen in the mirror is
# MIRROR_SIGNS * L and a transport T(p) is MIRROR_SIGNS * T(mirrored p), so their shading is the original's mirrored
# (relight_rt.relight.upright ``mirror_averaged``: the mirror-symmetric chain)
MIRROR_SIGNS = np.array([1.0, -1.0, 1.0, 1.0, -1.0, -1.0, 1.0, 1.0, 1.0])


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


def cap_zonal(cos_a: float) -> np.ndarray:
    """Per-band zonal factors g_l (l = 0, 1, 2) of a uniform cap of half-angle a, normalised by its solid angle.

    The cap of unit radiance around d has SH coefficients Ω · g_l · Y_k(d) with Ω = 2π(1 − cos a):
    ∫_cap Y_l0 = 2π ∫_{cos a}^1 sqrt((2l+1)/4π) P_l(t) dt gives g_0 = 1, g_1 = (1 + cos a)/2,
    g_2 = cos a (1 + cos a)/2 (all → 1 as a → 0: the delta limit). Per coefficient: ``cap_zonal(c)[list(BAND)]``.
    """
    c = cos_a
    return np.array([1.0, (1 + c) / 2, c * (1 + c) / 2])


def cosine_lobe() -> np.ndarray:
    """Zonal coefficients A_l of the clamped cosine max(0, n·ω), repeated per coefficient.

    Returns:
        (9,) float64: π, 2π/3 (×3), π/4 (×5). Unoccluded transport is T_k(n) = A_l · Y_k(n) and the
        irradiance of a light at normal n is Σ_k A_l · Y_k(n) · light[k].
    """
    a = (math.pi, 2 * math.pi / 3, math.pi / 4)
    return np.array([a[band] for band in BAND], dtype=np.float64)


# --------------------------------------------------------------------------------------------- lights


def describe_array(arr: np.ndarray) -> str:
    """``(shape) dtype`` of an array, for error messages that say what arrived."""
    return f"{arr.shape} {arr.dtype}"


def numbers_only(values) -> bool:
    """Whether ``values`` (nested lists / tuples, arrays, scalars, parsed JSON) holds real numbers only: no bools,
    strings or None, which numpy would read as numbers or refuse later (``[True, 0.5]`` reads as 1.0). An array, or
    anything numpy turns into one, counts by its dtype."""
    if isinstance(values, (list, tuple)):
        return all(numbers_only(v) for v in values)
    if isinstance(values, (bool, np.bool_)):
        return False
    if isinstance(values, numbers.Real):
        return True
    if isinstance(values, np.ndarray) or hasattr(values, "__array__"):
        return np.asarray(values).dtype.kind in "iuf"
    return False


def check_lights(light, name: str = "light") -> np.ndarray:
    """Validate a light or a stack of lights (..., 9, 3) (shape, numbers, NaN/Inf, ``MAX_COEFF``).

    Returns:
        A float64 copy of the same shape.

    Raises:
        RelightError: naming ``name`` and what arrived.
    """
    try:
        arr = np.array(light, dtype=np.float64, copy=True)
    except (TypeError, ValueError) as exc:
        raise RelightError(f"{name}: expected an SH light of shape (9, 3), got an unreadable value ({exc})") from None
    except OverflowError:  # a Python integer of 400 digits in a list
        raise RelightError(f"{name}: expected an SH light of shape (9, 3), got an integer too large for a float") \
            from None
    src = np.asarray(light)
    if src.dtype.kind not in "fiu":
        raise RelightError(f"{name}: expected a numeric SH light of shape (9, 3), got {describe_array(src)}")
    if isinstance(light, (list, tuple)) and not numbers_only(light):  # numpy reads [True, 0.5, 0] as numbers
        raise RelightError(f"{name}: expected numbers in the SH light, got true/false")
    if arr.ndim < 2 or arr.shape[-2:] != (N_COEFFS, 3):
        raise RelightError(f"{name}: expected an SH light of shape (9, 3) (or (N, 9, 3)), got {describe_array(src)}")
    if not np.all(np.isfinite(arr)):
        raise RelightError(f"{name}: SH light contains NaN or Inf")
    check_magnitude(arr, name)
    return arr


MAX_COEFF = 1e30
"""Largest |coefficient| of a light that is accepted. Lights are used in float32 (whose largest value is
3.4e38); shading sums 9 products of a coefficient with the transport, so beyond this a plausible
transport overflows to Inf and the result turns to NaN. Presets have coefficients of about 1."""


_MAX_COEFF_F32 = float(np.float32(MAX_COEFF))  # MAX_COEFF as float32 holds it: a checked light's float32 copy passes


def check_magnitude(arr: np.ndarray, name: str) -> None:
    """Refuse a light whose largest |coefficient| exceeds ``MAX_COEFF`` (float32 shading would overflow)."""
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
    arr = check_lights(light, name)
    if arr.shape != (N_COEFFS, 3):
        raise RelightError(f"{name}: expected an SH light of shape (9, 3), got {describe_array(np.asarray(light))}")
    return arr


def _relu_product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """max(0, a @ b) in float32: the one shading formula (S = max(0, T·L)) behind both layouts below."""
    out = a @ b
    np.maximum(out, 0, out=out)
    return out


def shading(transport, light) -> np.ndarray:
    """Diffuse shading S_c = max(0, Σ_k T_k · light[k, c]) (DESIGN.md §3).

    Args:
        transport: (..., 9) light transport (e.g. (H, W, 9)); float32 is used as is, other dtypes
            are converted. Not modified.
        light: (9, 3) SH light, RGB columns.

    Returns:
        (..., 3) float32 RGB shading, ≥ 0 (not clipped above).

    See ``shading_chw`` for channel-first transport and many lights at once (the relight hot path).
    """
    t = np.asarray(transport)
    if t.ndim < 1 or t.shape[-1] != N_COEFFS or t.dtype.kind not in "fiu":
        raise RelightError(f"transport: expected (..., 9) SH transport, got {describe_array(t)}")
    lit = check_light(light).astype(np.float32)
    flat = t.reshape(-1, N_COEFFS)
    if flat.dtype != np.float32:
        flat = flat.astype(np.float32)
    out = np.empty((flat.shape[0], 3), np.float32)
    for s in range(0, flat.shape[0], SHADE_ROWS):  # in blocks: OpenBLAS keeps each small product on one thread
        np.matmul(flat[s : s + SHADE_ROWS], lit, out=out[s : s + SHADE_ROWS])
    np.maximum(out, 0, out=out)
    return out.reshape(t.shape[:-1] + (3,))


SHADE_ROWS = 8192
"""Pixels per product of ``shading`` (8192 x 9 x 3 multiply-adds, under OpenBLAS's threading threshold of 4 x 65536):
one (n, 9) x (9, 3) product over a whole window was split across BLAS threads, which then busy-waited for the next
call; on two cores shared with onnxruntime and OpenCV, or with other jobs, one 512 x 400 window took 5-12 ms instead
of under 1 (the values are the same bit for bit: each row's 9-term sum does not depend on the block)."""


SHADE_BLOCK = 1 << 19
"""Multiply-adds per pixel block of ``shading_chw`` (about 2 MB of float32 temporaries)."""


def shading_chw(transport_chw, lights, albedo_chw=None) -> np.ndarray:
    """``shading`` on channel-first arrays for K lights at once; with ``albedo_chw``, the diffuse images.

    The same formula, max(0, T·L_k), as a (3, 9) × (9, n) product per light and block of pixels: each block's
    product, ReLU (and albedo product and clip) run while it is in cache (one pass over memory instead of
    four), and BLAS stays on one thread for such small products (its threads only add start-up and
    contention for a 9-deep inner dimension).

    Args:
        transport_chw: (9, H, W) float32 transport.
        lights: (K, 9, 3) float RGB lights (or one (9, 3) light: K = 1).
        albedo_chw: None, or (3, H, W) float32 albedo: return clip(albedo ⊙ S_k, 0, 1) instead of S_k.

    Returns:
        (K, 3, H, W) float32: the shading (≥ 0, not clipped above), or the diffuse images in [0, 1].

    Raises:
        RelightError: transport not (9, H, W), an albedo of another size, bad lights.
    """
    t = np.asarray(transport_chw)
    if t.ndim != 3 or t.shape[0] != N_COEFFS or t.dtype.kind not in "fiu":
        raise RelightError(f"transport: expected (9, H, W) channel-first SH transport, got {describe_array(t)}")
    lits = check_lights(lights, "lights")
    if lits.ndim == 2:
        lits = lits[None]
    if lits.ndim != 3:
        raise RelightError(f"lights: expected (K, 9, 3) SH lights, got {describe_array(np.asarray(lights))}")
    k = lits.shape[0]
    _, h, w = t.shape
    n = h * w
    transport = t.reshape(N_COEFFS, n)
    if transport.dtype != np.float32:
        transport = transport.astype(np.float32)
    albedo = None
    if albedo_chw is not None:
        a = np.asarray(albedo_chw)
        if a.shape != (3, h, w):
            raise RelightError(f"albedo: expected (3, {h}, {w}) to match the transport, got {describe_array(a)}")
        albedo = a.reshape(1, 3, n).astype(np.float32, copy=False)
    coeffs = np.ascontiguousarray(lits.transpose(0, 2, 1).reshape(3 * k, N_COEFFS), dtype=np.float32)
    out = np.empty((k, 3, n), np.float32)
    step = max(256, SHADE_BLOCK // (27 * k))
    for s in range(0, n, step):
        e = min(s + step, n)
        # light by light: BLAS sums a (3K, 9) product's rows in an order that depends on K (OpenBLAS 0.3.31: up to
        # 2e-6 apart), and a light must shade alike alone and among others (relight_many = relight, bit for bit)
        block = np.empty((k, 3, e - s), np.float32)
        for j in range(k):
            block[j] = _relu_product(coeffs[3 * j : 3 * j + 3], transport[:, s:e])
        if albedo is None:
            out[:, :, s:e] = block
        else:
            block *= albedo[:, :, s:e]
            np.clip(block, 0, 1, out=out[:, :, s:e])
    return out.reshape(k, 3, h, w)


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


def sphere_directions(n: int) -> np.ndarray:
    """(n, 3) float64 unit vectors spread evenly over the whole sphere (a Fibonacci lattice: equal-area bands in
    z, successive points a golden angle apart): for sums over every direction, such as a light's range of colour
    or a body side's mean irradiance."""
    k = np.arange(n) + 0.5
    z = 1 - 2 * k / n
    phi = math.pi * (1 + math.sqrt(5)) * k
    r = np.sqrt(1 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], 1)


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
    from ..engine.limits import check_pixels

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
        raise RelightError(f"{name}: expected a (3, 3) rotation matrix, got {describe_array(arr)}")
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
    lit = check_lights(light, "light")
    r = _check_rotation(R)
    return _sh_rotation(r) @ lit


def rotation_coefficients(R) -> np.ndarray:
    """The (9, 9) matrix M of an active rotation R on SH coefficients: ``rotate(light, R) == M @ light``.

    M is orthogonal (the basis is orthonormal), so M.T undoes it. A transport row vector T (shading T . L) seen in
    the rotated frame is ``T @ M`` in the frame before: (T @ M) . L = T . (M @ L).

    Args:
        R: (3, 3) or (N, 3, 3) proper rotation matrix in the subject frame.

    Returns:
        (..., 9, 9) float64.
    """
    return _sh_rotation(_check_rotation(R))


def rotate_z(light, angle) -> np.ndarray:
    """Turn the environment by `angle` radians about +z, carrying +x toward +y (= rotate(light, Rz)).

    Args:
        light: (9, 3) or (N, 9, 3) SH lights (RGB).
        angle: radians, scalar or array broadcasting with the light's leading dimensions (a (N,)
            array with a (9, 3) light gives N rotated copies).

    Returns:
        (..., 9, 3) float64 rotated light(s).
    """
    lit = check_lights(light, "light")
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

