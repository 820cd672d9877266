"""Parametric SH lights, named presets and light sequences for video.

For people who think in lamps rather than coefficients. Every function returns a new float64
(9, 3) RGB light (or an (N, 9, 3) stack) in the conventions of `relight_rt.light.sh` (DESIGN.md §3:
+x toward the camera, +y toward the image's right, +z up). Lights add as arrays:
``directional((1, -1, 1)) + ambient((0.1, 0.1, 0.1))``.

Scale: the irradiance of an unoccluded white diffuse surface, as `relight_rt.light.sh.irradiance` and
`relight_rt.light.sh.render_sphere` show it, which is also the shading S = T·L of the pipeline. A preset's
brightest irradiance on the sphere seen from the camera is about 1.
"""

from __future__ import annotations

import math

import numpy as np

from ..engine.errors import RelightError
from .sh import BAND, N_COEFFS, basis, cap_zonal, check_lights, cosine_lobe, irradiance, rotate, rotate_z

__all__ = [
    "ambient",
    "directional",
    "interpolate",
    "list_presets",
    "preset",
    "rotation_sequence",
    "sky",
]

_Y00 = 1 / (2 * math.sqrt(math.pi))


def _vec3(value, name: str, nonneg: bool = False) -> np.ndarray:
    try:
        arr = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise RelightError(f"{name}: expected 3 numbers, got {value!r}") from None
    if arr.ndim == 0:
        arr = np.full(3, float(arr))
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise RelightError(f"{name}: expected 3 finite numbers, got {value!r}")
    if nonneg and np.any(arr < 0):
        raise RelightError(f"{name}: expected non-negative values, got {value!r}")
    return arr


def _scalar(value, name: str, low: float = -math.inf, high: float = math.inf) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise RelightError(f"{name}: expected a number, got {value!r}") from None
    if not math.isfinite(v) or v < low or v > high:
        raise RelightError(f"{name}: expected a finite number in [{low}, {high}], got {value!r}")
    return v


def directional(direction, color=(1.0, 1.0, 1.0), intensity: float = 1.0, angular_radius: float = 0.0) -> np.ndarray:
    """A lamp: the exact degree-2 SH of a uniform spherical cap of light arriving from `direction`.

    The cap's zonal coefficients are integrated in closed form and rotated to the direction; radius 0
    is the delta limit, a point source: light[k] ∝ Y_k(direction).

    Scale: `intensity` is the irradiance (per colour channel, times `color`) that a diffuse surface
    facing the lamp receives under the degree-2 light, i.e. irradiance(light, direction) ==
    intensity · color for every radius. For radius 0 this makes light = (16/17) · intensity · color ·
    Y_k(direction): the degree-2 irradiance of a point source of power P at its own normal is
    (17/16) · P.

    Args:
        direction: 3 numbers, the direction the light comes from (toward the lamp) in the subject
            frame (+x toward the camera, +y image right, +z up); normalised here.
        color: RGB, 3 non-negative numbers (or one for grey).
        intensity: non-negative scale.
        angular_radius: half-angle of the lamp's disc in radians, in [0, π] (π: the whole sphere).

    Returns:
        (9, 3) float64 RGB light.
    """
    d = _vec3(direction, "direction")
    norm = float(np.linalg.norm(d))
    if norm < 1e-12:
        raise RelightError(f"direction: expected a non-zero vector, got {direction!r}")
    d = d / norm
    rgb = _vec3(color, "color", nonneg=True)
    power = _scalar(intensity, "intensity", low=0.0)
    radius = _scalar(angular_radius, "angular_radius", low=0.0, high=math.pi)
    g = cap_zonal(math.cos(radius))[list(BAND)]
    # Degree-2 irradiance at the facing normal per unit Ω·ρ: Σ_k A_l g_l Y_k(d)² = Σ_l A_l g_l (2l+1)/4π.
    facing = float(np.sum(cosine_lobe() * g * basis(d) ** 2))
    return (power / facing) * (g * basis(d))[:, None] * rgb[None, :]


def ambient(color) -> np.ndarray:
    """Uniform light from every direction, scaled so that every normal receives irradiance `color`.

    Args:
        color: RGB, 3 non-negative numbers (or one for grey).

    Returns:
        (9, 3) float64 RGB light (only coefficient 0 non-zero: color / (π · Y_0)).
    """
    rgb = _vec3(color, "color", nonneg=True)
    light = np.zeros((N_COEFFS, 3))
    light[0] = rgb / (math.pi * _Y00)
    return light


def sky(zenith_color, ground_color) -> np.ndarray:
    """A smooth vertical gradient: radiance linear in z from `ground_color` (nadir) to `zenith_color`.

    Radiance(ω) = (ground + (zenith − ground) · (1 + z) / 2) / π, so equal colours give
    `ambient(color)`. A surface facing up receives (5 · zenith + ground) / 6, one facing down
    (zenith + 5 · ground) / 6, a vertical one the mean.

    Args:
        zenith_color, ground_color: RGB, 3 non-negative numbers each (or one for grey).

    Returns:
        (9, 3) float64 RGB light (coefficients 0 and 2, i.e. (0,0) and (1,0), non-zero).
    """
    top = _vec3(zenith_color, "zenith_color", nonneg=True)
    bottom = _vec3(ground_color, "ground_color", nonneg=True)
    light = ambient((top + bottom) / 2)
    # Radiance slope (top − bottom) / (2π) along z; z = Y_2 / sqrt(3 / 4π).
    light[2] = (top - bottom) / (2 * math.pi) / math.sqrt(3 / (4 * math.pi))
    return light


# --------------------------------------------------------------------------------------------- presets

_WARM = (1.0, 0.95, 0.88)
_COOL = (0.9, 0.95, 1.0)


def _studio() -> np.ndarray:
    key = directional((1.0, -0.8, 0.7), _WARM, 1.0, angular_radius=0.35)
    fill = directional((1.0, 0.9, 0.0), _COOL, 0.25, angular_radius=0.6)
    rim = directional((-1.0, 0.6, 0.6), (1.0, 1.0, 1.0), 0.4, angular_radius=0.2)
    return key + fill + rim + ambient(0.03)


def _window_left() -> np.ndarray:
    return directional((0.35, -1.0, 0.25), _COOL, 1.0, angular_radius=0.6) + ambient((0.06, 0.06, 0.07))


def _overhead_noon() -> np.ndarray:
    sun = directional((0.15, 0.05, 1.0), (1.0, 0.97, 0.92), 1.0, angular_radius=0.05)
    return sun + sky((0.25, 0.33, 0.45), (0.12, 0.10, 0.08))


def _golden_hour() -> np.ndarray:
    sun = directional((0.7, 0.7, 0.2), (1.0, 0.74, 0.48), 1.0, angular_radius=0.08)
    return sun + sky((0.18, 0.22, 0.35), (0.12, 0.08, 0.05))


def _overcast() -> np.ndarray:
    return sky((0.95, 0.97, 1.0), (0.3, 0.3, 0.3)) + directional((0.3, 0.0, 1.0), _COOL, 0.3, angular_radius=1.0)


def _neon() -> np.ndarray:
    magenta = directional((0.3, -1.0, 0.15), (1.0, 0.15, 0.8), 1.0, angular_radius=0.4)
    cyan = directional((0.3, 1.0, 0.15), (0.1, 0.85, 1.0), 1.0, angular_radius=0.4)
    return magenta + cyan + ambient((0.03, 0.02, 0.05))


def _rim() -> np.ndarray:
    # two backlights alone leave a face that looks at the camera black (degree-2 SH: the front of a diffuse head
    # gets only the ambient, the lobes' ringing even less); a rim light in practice comes with a weak key or
    # fill, so a soft frontal fill keeps the face readable (issue 32). The rims stand 60 degrees behind the sides,
    # not 45 behind: from (-1, +-0.9) the fill evened the face out and rim changed a real face least of all lights
    # (median |dL*| on 8 faces 0.42x a white side lamp's, no edge to see); from (-0.5, +-1) with a fill of 0.15
    # the cheeks and jaw line light up beside a darker centre (0.69x; fill 0.1: 0.83x, the centre of a face that
    # looks at the camera at a tenth of the peak; issue 48, benchmarks/photo_faults.py)
    left = directional((-0.5, -1.0, 0.35), _COOL, 1.0, angular_radius=0.2)
    right = directional((-0.5, 1.0, 0.35), _COOL, 1.0, angular_radius=0.2)
    fill = directional((1.0, 0.0, 0.15), (1.0, 1.0, 1.0), 0.15, angular_radius=0.8)
    return left + right + fill + ambient(0.03)


def _night() -> np.ndarray:
    # moonlight as film shows it: cool and pale, not violet; with (0.55, 0.65, 1.0) the skin of real photos went
    # lilac (its red times a saturated blue: skin hue moved 93 degrees on average, docs/RESULTS.md) (issue 32)
    moon = directional((0.4, -0.6, 0.9), (0.68, 0.78, 1.0), 1.0, angular_radius=0.03)
    return moon + sky((0.05, 0.07, 0.15), (0.02, 0.02, 0.03))


def _front() -> np.ndarray:
    return directional((1.0, 0.0, 0.2), (1.0, 1.0, 1.0), 1.0, angular_radius=0.8) + ambient(0.1)


def _campfire() -> np.ndarray:
    # a fire low in front, not straight below: from 45 degrees down a small lamp's degree-2 SH leaves every
    # surface that faces up (forehead, top of the head) at 4 % of the peak, a dark band at the hairline on real
    # photos; from about 30 degrees down, a little wider and over a little more night sky it is 15 % (issue 32)
    fire = directional((0.9, 0.25, -0.5), (1.0, 0.66, 0.36), 1.0, angular_radius=0.5)
    return fire + ambient((0.05, 0.05, 0.08))


# Warm lights are as a camera white-balanced for daylight records them after its automatic white balance has
# taken out part of the cast (golden hour ~3500 K, a fire ~2500 K seen through it): a fully saturated orange,
# with the person's mean luminance kept, leaves nothing of the face but one flat orange (and the automatic
# exposure lowers a light that would put much of the person past white: relight_rt.light.exposure).
# name → (builder, peak irradiance on the visible half of the sphere, what it looks like)
_PRESETS = {
    "studio": (_studio, 1.0, "three-point: warm key upper camera-left, cool fill camera-right, rim from behind"),
    "window-left": (_window_left, 1.0, "large soft daylight window on the image's left"),
    "overhead-noon": (_overhead_noon, 1.0, "small sun almost straight above, blue sky, dark ground"),
    "golden-hour": (_golden_hour, 1.0, "low warm sun front-right, dusky sky"),
    "overcast": (_overcast, 1.0, "bright soft sky, no hard direction"),
    "neon": (_neon, 1.0, "magenta from the left, cyan from the right"),
    "rim": (_rim, 1.0, "two cool lights behind the sides and a weak frontal fill: cheeks and jaw bright, "
             "the face's centre dim but readable (degree-2 SH makes a rim a wide glow, no thin line)"),
    "night": (_night, 0.5, "cool, pale moonlight from upper left over a dark sky; a stop darker than the photo "
               "under the \"auto\" exposure (a night scene is darker than the day it was shot in)"),
    "front": (_front, 1.0, "flat frontal light from the camera"),
    "campfire": (_campfire, 1.0, "warm light from below in front, dark surroundings"),
}


# the EV a preset adds to the "auto" exposure (which keeps the person's brightness): a night scene is darker
_PRESET_EV = {"night": -1.0}


def preset_exposure(name: str) -> float:
    """The EV offset preset ``name`` asks of the "auto" exposure: night -1 (auto keeps the person's mean
    brightness, and moonlight at the photo's brightness reads as a cool grade, not as night); 0 for the others.
    The runtime adds it wherever a preset is given by name (relight_rt.light.exposure ``for_light``).

    Raises:
        RelightError: unknown name.
    """
    if name not in _PRESETS:
        raise RelightError(f"unknown light preset {name!r}; known presets: {', '.join(_PRESETS)}")
    return _PRESET_EV.get(name, 0.0)


def _visible_normals(size: int = 48) -> np.ndarray:
    c = (np.arange(size) + 0.5) * (2 / size) - 1
    y, z = np.meshgrid(c, -c)
    inside = y * y + z * z <= 1
    x = np.sqrt(np.maximum(0.0, 1 - y * y - z * z))
    return np.stack([x, y, z], axis=-1)[inside]


def _peak(light: np.ndarray) -> float:
    """Brightest irradiance (over channels) on the half of the sphere the camera sees."""
    return float(irradiance(light, _visible_normals()).max())


def list_presets() -> list[str]:
    """Names of the named lights, for `preset(name)`."""
    return list(_PRESETS)


def describe_preset(name: str) -> str:
    """What preset ``name`` looks like, in a few words (``relight-rt lights list``); "" for an unknown name."""
    return _PRESETS[name][2] if name in _PRESETS else ""


def preset(name: str) -> np.ndarray:
    """A named light, scaled so that its brightest irradiance on the camera-facing sphere is ~1.

    Presets (subject frame, "left"/"right" as seen in the image): studio, window-left,
    overhead-noon, golden-hour, overcast, neon, rim, night (peak 0.5), front, campfire.

    Args:
        name: one of `list_presets()`.

    Returns:
        (9, 3) float64 RGB light (a new array).

    Raises:
        RelightError: unknown name (the message lists the known ones).
    """
    if name not in _PRESETS:
        raise RelightError(f"unknown light preset {name!r}; known presets: {', '.join(_PRESETS)}")
    build, peak, _ = _PRESETS[name]
    light = build()
    return light * (peak / _peak(light))


# --------------------------------------------------------------------------------------------- sequences

_AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}


def _positive_int(value, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise RelightError(f"{name}: expected a positive integer, got {value!r}")
    return int(value)


def rotation_sequence(light, n_frames: int, axis="z", turns: float = 1.0) -> np.ndarray:
    """A light turning about an axis over a clip: frame i is rotated by 2π · turns · i / n_frames.

    The last frame stops one step short of the full turn, so the clip loops seamlessly. Positive
    turns rotate right-handedly about the axis (about 'z': +x toward +y, i.e. a light in front of the
    subject moves toward the image's right).

    Args:
        light: (9, 3) SH light, RGB.
        n_frames: number of frames N ≥ 1.
        axis: 'x', 'y', 'z' or a 3-vector in the subject frame.
        turns: number of full turns (negative: the other way).

    Returns:
        (N, 9, 3) float64; frame 0 is the light itself.
    """
    lit = check_lights(light, "light")
    if lit.shape != (N_COEFFS, 3):
        raise RelightError(f"light: expected an SH light of shape (9, 3), got {lit.shape}")
    n = _positive_int(n_frames, "n_frames")
    t = _scalar(turns, "turns")
    angles = 2 * math.pi * t * np.arange(n) / n
    if isinstance(axis, str):
        if axis not in _AXES:
            raise RelightError(f"axis: expected 'x', 'y', 'z' or a 3-vector, got {axis!r}")
        if axis == "z":
            return rotate_z(lit, angles)
        u = np.array(_AXES[axis])
    else:
        u = _vec3(axis, "axis")
        norm = float(np.linalg.norm(u))
        if norm < 1e-12:
            raise RelightError(f"axis: expected a non-zero vector, got {axis!r}")
        u = u / norm
    # Rodrigues: R = I + sin a · K + (1 − cos a) · K², K the cross-product matrix of u.
    k = np.array([[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]])
    s, c = np.sin(angles)[:, None, None], np.cos(angles)[:, None, None]
    rots = np.eye(3) + s * k + (1 - c) * (k @ k)
    return rotate(lit, rots)


def interpolate(lights, n_frames: int) -> np.ndarray:
    """Piecewise-linear interpolation of SH coefficients through key lights, sampled at N frames.

    Frames are spread evenly from the first key (frame 0) to the last (frame N − 1); with K keys,
    key j sits at position j · (N − 1) / (K − 1). Linear in the coefficients, so a blend of two
    lights is the light of the blended environments.

    Args:
        lights: K ≥ 1 key lights: a (K, 9, 3) array or a list of (9, 3) arrays, RGB.
        n_frames: number of frames N ≥ 1.

    Returns:
        (N, 9, 3) float64.
    """
    if isinstance(lights, (list, tuple)) and len(lights) == 0:
        raise RelightError("lights: expected at least one key light, got an empty list")
    keys = check_lights(lights, "lights")
    if keys.ndim != 3 or keys.shape[0] < 1:
        raise RelightError(f"lights: expected (K, 9, 3) key lights with K ≥ 1, got {keys.shape}")
    n = _positive_int(n_frames, "n_frames")
    count = keys.shape[0]
    if count == 1:
        return np.repeat(keys, n, axis=0)
    pos = np.linspace(0.0, count - 1, n)
    lo = np.minimum(np.floor(pos).astype(int), count - 2)
    frac = (pos - lo)[:, None, None]
    return (1 - frac) * keys[lo] + frac * keys[lo + 1]
