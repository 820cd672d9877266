"""Equirectangular environment maps: their pixel grid, projection onto SH lights, previews and files.

Layout (DESIGN.md §3, "Environment maps"): (H, 2H, 3) linear RGB radiance; pixel (i, j) looks along
θ = π(i+½)/H from +z, φ = 2π(j+½)/W, ω = (sinθ cosφ, −sinθ sinφ, cosθ), seen from inside, not mirrored:
the top row is the sky, the centre column straight ahead of the camera (behind the subject). Projection
weights each pixel by its solid angle sinθ · (π/H) · (2π/W). The SH basis itself is ``relight_rt.light.sh``'s.
"""

from __future__ import annotations

import functools
import logging
from pathlib import Path

import numpy as np

from ..engine.environment import openexr_enabled
from ..engine.errors import RelightError
from ..image.color import srgb_to_linear
from .sh import N_COEFFS, NORM, check_light, check_magnitude, describe_array

__all__ = [
    "directions_envmap",
    "envmap_from_light",
    "load_envmap",
    "project_envmap",
    "solid_angles_envmap",
]

logger = logging.getLogger(__name__)

# Separable form of the basis on the lat-long grid: Y_k(θ, φ) = const_k · Θ_t(θ) · Φ_f(φ).
# Θ_t: 1, sinθ, cosθ, sin²θ, sinθ·cosθ, 3cos²θ − 1.   Φ_f: 1, −sinφ, cosφ, −sinφ·cosφ, cos2φ.
# const_k is sh.NORM[k], the constant of Y_k.
_SEPARABLE = (  # (t, f) for k = 0…8
    (0, 0),
    (1, 1),  # y = sinθ · (−sinφ)
    (2, 0),  # z = cosθ
    (1, 2),  # x = sinθ · cosφ
    (3, 3),  # xy = sin²θ · (−sinφ cosφ)
    (4, 1),  # yz
    (5, 0),  # 3z² − 1
    (4, 2),  # xz
    (3, 4),  # x² − y² = sin²θ · cos2φ
)
_SEP_T = np.array([t for t, _ in _SEPARABLE])
_SEP_F = np.array([f for _, f in _SEPARABLE])
_SEP_C = np.array(NORM)


def _check_height(height) -> int:
    from ..engine.limits import check_pixels

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
    from ..engine.limits import check_array_pixels

    arr = np.asarray(env)
    if arr.ndim != 3 or arr.shape[2] != 3 or arr.shape[0] < 1 or arr.shape[1] != 2 * arr.shape[0]:
        raise RelightError(f"{name}: expected an equirectangular (H, 2H, 3) RGB map, got {describe_array(arr)}")
    check_array_pixels(arr, name)
    if arr.dtype.kind != "f":
        raise RelightError(
            f"{name}: expected float linear RGB, got {arr.dtype} (decode display values with "
            "relight_rt.image.color.srgb_to_linear or read files with load_envmap)"
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

    Raises:
        RelightError: a map that is not (H, 2H, 3), holds NaN/Inf, or whose light passes ``sh.MAX_COEFF``.
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
    # the one rule for a light (sh.MAX_COEFF): a map of 1e38s projected to 6e38, which every command then refused
    check_magnitude(light, "env: the environment map's light")
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


def _reduce_envmap(rgb: np.ndarray, ldr: bool, max_pixels: int) -> np.ndarray:
    """An (H, 2H[, C]) map as decoded (uint8/uint16 sRGB when ``ldr``, else float; channels as stored) shrunk by
    area averaging to the largest (h, 2h) of at most ``max_pixels`` (relight_rt.engine.limits ``shrink``), as float32
    linear values: what it averages is linear light (sRGB codes go through a 16-bit linear table first), and no
    full-size float copy is made."""
    from ..engine.limits import shrink

    if ldr:
        top = np.iinfo(rgb.dtype).max
        table = np.rint(srgb_to_linear(np.arange(top + 1, dtype=np.float32) / top) * 65535).astype(np.uint16)
        rgb = table[rgb]  # linear, uint16: 6 bytes a pixel
    small = shrink(rgb, max_pixels)
    return small.astype(np.float32) / np.float32(65535) if ldr else small.astype(np.float32)


def load_envmap(path, *, max_pixels: int | None = None) -> np.ndarray:
    """Read an equirectangular environment map as linear RGB.

    Radiance `.hdr` (and `.pic`) through OpenCV; `.exr` when the installed OpenCV reads it (set
    OPENCV_IO_ENABLE_OPENEXR=1 before Python starts, with an OpenCV built with OpenEXR); `.png` /
    `.jpg` are sRGB and linearised. Alpha is dropped; grey maps become three equal channels.

    Args:
        path: file path.
        max_pixels: None (full size), or the most pixels of the map returned: a larger one is shrunk (area
            average of linear light) right after decoding, before any full-size float copy (the studio's
            uploads: a 40-MP map cost ~60 bytes a pixel, issue 50 bug 6; degree-2 SH needs few pixels).

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
    from ..engine.limits import check_pixels, header_size

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
        if ext == ".exr" and not openexr_enabled():
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
    if img.ndim == 3 and img.shape[2] not in (1, 3, 4):
        raise RelightError(f"{p}: expected a colour or grey environment map, got {img.shape[2]} channels")
    ldr = ext in (".png", ".jpg", ".jpeg")
    if ldr and img.dtype not in (np.uint8, np.uint16):
        raise RelightError(f"{p}: expected an 8- or 16-bit image, got {img.dtype}")
    h, w = img.shape[:2]
    if w != 2 * h:
        raise RelightError(f"{p}: expected an equirectangular map with width = 2 × height, got {w}×{h} (W×H)")
    reduce = max_pixels is not None and h * w > max_pixels
    if reduce:  # as decoded (BGR(A) or grey), before any full-size copy
        img = _reduce_envmap(img, ldr, int(max_pixels))
    if img.ndim == 2:
        img = img[:, :, None]
    rgb = np.repeat(img, 3, axis=2) if img.shape[2] == 1 else img[:, :, 2::-1]
    out = np.ascontiguousarray(srgb_to_linear(rgb) if ldr and not reduce else rgb, dtype=np.float32)
    if not np.all(np.isfinite(out)):
        raise RelightError(f"{p}: environment map contains NaN or Inf")
    return out
