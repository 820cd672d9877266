"""Procedural HDR environment maps (sun and sky, overcast, studio soft boxes, windows, coloured lamps,
night, an on-camera flash, a hard lamp at face height), their rotation about the vertical axis, scale
normalisation and .hdr files.

Maps are equirectangular (H, 2H, 3) float32 linear RGB radiance in the layout of DESIGN.md §3
(top row = sky; pixel directions from ``relight_rt.envmap.directions_envmap``). Their SH projection is
``relight_rt.envmap.project_envmap``. Scale convention: a map is scaled so that the brightest
irradiance an unoccluded surface receives from it, in its brightest colour channel, is ``target``
(by default drawn log-uniformly in [0.9, 2.6], the range of the reference's ten test lights:
0.91–2.65; their median 1.5).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

from relight_rt.engine.errors import RelightError
from relight_rt.image.color import REC709
from relight_rt.light.envmap import directions_envmap, project_envmap, solid_angles_envmap
from relight_rt.light.sh import irradiance

log = logging.getLogger(__name__)

TARGET_RANGE = (0.9, 2.6)


# ------------------------------------------------------------------------------------ building blocks


def _unit(az: float, el: float) -> np.ndarray:
    """Direction of azimuth ``az`` (DESIGN §3: φ, measured from +x toward −y) and elevation ``el``, radians."""
    return np.array([math.cos(el) * math.cos(az), -math.cos(el) * math.sin(az), math.sin(el)])


def _angle_to(dirs: np.ndarray, d: np.ndarray) -> np.ndarray:
    return np.arccos(np.clip(dirs @ d, -1.0, 1.0))


def _disc(dirs: np.ndarray, d: np.ndarray, radius: float, soft: float) -> np.ndarray:
    """1 inside an angular disc of ``radius`` around d, fading to 0 over ``soft`` radians."""
    return np.clip((radius + soft - _angle_to(dirs, d)) / max(soft, 1e-6), 0.0, 1.0)


def _box(dirs: np.ndarray, az: float, el: float, half_w: float, half_h: float, soft: float) -> np.ndarray:
    """A soft rectangle in (azimuth, elevation) around (az, el): a window or a soft box, radians."""
    phi = np.arctan2(-dirs[..., 1], dirs[..., 0])
    elev = np.arcsin(np.clip(dirs[..., 2], -1.0, 1.0))
    dphi = np.abs((phi - az + np.pi) % (2 * np.pi) - np.pi) * np.cos(elev)
    de = np.abs(elev - el)
    wx = np.clip((half_w + soft - dphi) / soft, 0.0, 1.0)
    wy = np.clip((half_h + soft - de) / soft, 0.0, 1.0)
    return wx * wy


def _hue(rng: np.random.Generator, saturation: tuple[float, float]) -> np.ndarray:
    hsv = np.uint8([[[rng.integers(0, 180), int(255 * rng.uniform(*saturation)), 255]]])
    return cv2.cvtColor(hsv, cv2.COLOR_HSV2RGB)[0, 0].astype(np.float64) / 255.0


def _temperature(rng: np.random.Generator, lo: float = -1.0, hi: float = 1.0) -> np.ndarray:
    """A white between warm (−1, incandescent) and cool (+1, blue sky), unit luminance."""
    t = rng.uniform(lo, hi)
    rgb = np.array([1.0 - 0.25 * t, 1.0 - 0.05 * abs(t), 1.0 + 0.35 * t]) if t > 0 else np.array(
        [1.0, 1.0 + 0.25 * t, 1.0 + 0.6 * t]
    )
    return rgb / (rgb @ REC709)


def _add_source(env: np.ndarray, weight: np.ndarray, color: np.ndarray, power: float, omega: np.ndarray) -> None:
    """Add an emitter of shape ``weight`` whose irradiance at normal incidence is about ``power``."""
    area = float((weight * omega).sum())
    if area > 0:
        env += (power / area) * weight[..., None] * color


# ------------------------------------------------------------------------------------ the map kinds


def _sun_sky(dirs, omega, rng, ground_albedo=None):
    z = dirs[..., 2]
    sun_el = math.radians(rng.uniform(5, 75))
    sun = _unit(rng.uniform(0, 2 * math.pi), sun_el)
    up = np.clip(z, 0.0, 1.0)
    zenith = np.array([0.25, 0.45, 1.0]) * rng.uniform(0.6, 1.0)
    horizon = np.array([0.8, 0.85, 0.95])
    sky = horizon + (zenith - horizon) * np.sqrt(up)[..., None]
    sky *= (1.0 + 2.0 * np.exp(-_angle_to(dirs, sun) / 0.35))[..., None]  # circumsolar glow
    ground = np.array([0.35, 0.3, 0.25]) * rng.uniform(0.4, 1.0) * rng.uniform(0.2, 0.5)
    env = np.where((z >= 0)[..., None], sky, ground * (0.6 + 0.4 * (1 + z))[..., None])
    sky_e = float((env.mean(axis=-1) * omega * np.clip(z, 0, 1)).sum())
    warm = np.array([1.0, 0.75, 0.5]) if sun_el < math.radians(20) else np.array([1.0, 0.95, 0.88])
    _add_source(env, _disc(dirs, sun, math.radians(2.5), math.radians(2.0)), warm, sky_e * rng.uniform(1.5, 6), omega)
    if ground_albedo is not None:
        env = _lit_ground(env, dirs, omega, rng, ground_albedo)
    return env


def _lit_ground(env, dirs, omega, rng, albedo_range):
    """The lower half of ``env`` replaced by a flat diffuse ground lit by the upper half: radiance
    ρ_c · E_c / π, with E_c the irradiance the sky and sun give a horizontal surface and ρ = an albedo drawn in
    ``albedo_range`` (grass and asphalt ~0.1, dry soil and concrete 0.2-0.35, sand ~0.4) times a pale tint of
    unit luminance. The bounce from below that a plain dark ground leaves out."""
    z = dirs[..., 2]
    up = (omega * np.clip(z, 0.0, 1.0))[..., None]
    irr = (env * up).sum(axis=(0, 1))  # (3,) irradiance on a horizontal surface from above
    tint = _hue(rng, (0.0, 0.35))
    rho = rng.uniform(*albedo_range) * tint / (tint @ REC709)
    return np.where((z >= 0)[..., None], env, rho * irr / math.pi)


def _overcast(dirs, omega, rng):
    z = dirs[..., 2]
    lum = (1.0 + 2.0 * np.clip(z, 0, 1)) / 3.0  # CIE standard overcast sky
    sky = lum[..., None] * _temperature(rng, 0.0, 0.6)
    ground = rng.uniform(0.1, 0.35) * np.array([0.9, 0.85, 0.8])
    env = np.where((z >= 0)[..., None], sky, ground)
    if rng.random() < 0.5:  # a brighter patch where the sun is behind thin cloud
        d = _unit(rng.uniform(0, 2 * math.pi), math.radians(rng.uniform(20, 70)))
        env = env * (1.0 + rng.uniform(0.5, 2.0) * np.exp(-_angle_to(dirs, d) / 0.5))[..., None]
    return env


def _room(dirs, rng, level: float):
    """Dim walls (a warm-ish tone), a darker floor and a slightly brighter ceiling."""
    z = dirs[..., 2]
    wall = _hue(rng, (0.0, 0.3)) * level
    shade = np.where(z < -0.2, 0.5, np.where(z > 0.6, 1.2, 1.0))
    return shade[..., None] * wall


def _softbox(dirs, omega, rng):
    env = _room(dirs, rng, rng.uniform(0.02, 0.1))
    key_az = rng.uniform(0, 2 * math.pi)
    for i in range(rng.integers(1, 4)):
        az = key_az + (0 if i == 0 else rng.uniform(1.0, 5.3))
        w = _box(dirs, az, math.radians(rng.uniform(0, 60)), math.radians(rng.uniform(8, 25)),
                 math.radians(rng.uniform(8, 25)), math.radians(3))
        _add_source(env, w, _temperature(rng, -0.3, 0.3), (1.0 if i == 0 else rng.uniform(0.2, 0.7)) * 3.0, omega)
    return env


def _window(dirs, omega, rng):
    env = _room(dirs, rng, rng.uniform(0.05, 0.2))
    az = rng.uniform(0, 2 * math.pi)
    for i in range(rng.integers(1, 3)):
        a = az + i * rng.uniform(0.4, 1.0)
        el = math.radians(rng.uniform(5, 30))
        hw, hh = math.radians(rng.uniform(10, 25)), math.radians(rng.uniform(10, 22))
        w = _box(dirs, a, el, hw, hh, math.radians(1.5))
        mullion = 1.0 - 0.9 * np.maximum(_box(dirs, a, el, math.radians(1), hh, 0.01),
                                         _box(dirs, a, el, hw, math.radians(1), 0.01))
        _add_source(env, w * mullion, _temperature(rng, 0.0, 1.0), 3.0 * rng.uniform(0.5, 1.0), omega)
    return env


def _lamps(dirs, omega, rng):
    env = _room(dirs, rng, rng.uniform(0.01, 0.05))
    for _ in range(rng.integers(2, 5)):
        d = _unit(rng.uniform(0, 2 * math.pi), math.radians(rng.uniform(-10, 60)))
        radius = math.radians(rng.uniform(4, 15))
        _add_source(env, np.exp(-((_angle_to(dirs, d) / radius) ** 2)), _hue(rng, (0.5, 1.0)),
                    rng.uniform(0.5, 2.0), omega)
    return env


def _night(dirs, omega, rng):
    z = dirs[..., 2]
    sky = np.array([0.01, 0.015, 0.04]) * (0.3 + 0.7 * np.clip(z, 0, 1))[..., None]
    env = np.where((z >= 0)[..., None], sky, np.array([0.01, 0.008, 0.006]))
    for _ in range(rng.integers(1, 4)):
        d = _unit(rng.uniform(0, 2 * math.pi), math.radians(rng.uniform(10, 55)))
        color = np.array([1.0, 0.55, 0.2]) if rng.random() < 0.6 else _temperature(rng, -0.2, 0.4)
        _add_source(env, _disc(dirs, d, math.radians(rng.uniform(2, 5)), math.radians(2)), color,
                    rng.uniform(0.3, 1.0), omega)
    if rng.random() < 0.3:
        d = _unit(rng.uniform(0, 2 * math.pi), math.radians(rng.uniform(20, 70)))
        _add_source(env, _disc(dirs, d, math.radians(2), math.radians(1.5)), np.array([0.8, 0.9, 1.0]), 0.2, omega)
    return env


def _face_height_light(dirs, omega, rng, spread: float, warmth: tuple[float, float]):
    """One small hard source (a Gaussian lobe of 2-5°) at about the face's height (elevation −15..+20°) within
    ``spread`` degrees of +x (toward the camera), of a white in ``warmth`` (:func:`_temperature`), over a dim room's
    walls and, half the time, a ceiling lamp with a tenth to a third of its power."""
    env = _room(dirs, rng, rng.uniform(0.02, 0.12))
    d = _unit(math.radians(rng.uniform(-spread, spread)), math.radians(rng.uniform(-15, 20)))
    radius = math.radians(rng.uniform(2, 5))
    _add_source(env, np.exp(-((_angle_to(dirs, d) / radius) ** 2)), _temperature(rng, *warmth), 3.0, omega)
    if rng.random() < 0.5:
        lamp = _unit(rng.uniform(0, 2 * math.pi), math.radians(rng.uniform(40, 85)))
        _add_source(env, np.exp(-((_angle_to(dirs, lamp) / math.radians(10)) ** 2)), _temperature(rng, -1.0, 0.0),
                    3.0 * rng.uniform(0.1, 0.35), omega)
    return env


def _flash(dirs, omega, rng):
    """An on-camera flash (a phone's LED, a hot-shoe flash, a ring light): :func:`_face_height_light` within 10°
    of the camera, daylight white. :data:`CAMERA_BOUND`: the ``lights`` command turns it only a little about the
    vertical, as a flash stays on the camera wherever the photographer stands."""
    return _face_height_light(dirs, omega, rng, 10.0, (-0.1, 0.3))


def _low_lamp(dirs, omega, rng):
    """A hard light at face height from anywhere around (a bare bulb or a lamp on a table, an off-camera flash on a
    stand, the sun through a low window): :func:`_face_height_light` at any azimuth, warm to neutral."""
    return _face_height_light(dirs, omega, rng, 180.0, (-0.8, 0.2))


_KINDS: dict[str, Callable] = {
    "sun_sky": _sun_sky,
    "overcast": _overcast,
    "softbox": _softbox,
    "window": _window,
    "lamps": _lamps,
    "night": _night,
    "flash": _flash,
    "low_lamp": _low_lamp,
}
KINDS = tuple(_KINDS)
# what ``python -m export lights`` draws when no --kinds are named: the kinds every shipped model's lights were drawn
# from, in the order that makes the same maps for the same seed as before flash and low_lamp were added
DEFAULT_KINDS = ("sun_sky", "overcast", "softbox", "window", "lamps", "night")
# kinds whose key light is fixed to the camera: a turn about the vertical that puts it behind the subject would
# no longer be that light (the ``lights`` command turns these by --camera-turn at most)
CAMERA_BOUND = frozenset({"flash"})
GROUND_ALBEDO = (0.1, 0.4)  # the range real ground has (grass, asphalt 0.1; soil, concrete 0.2-0.35; sand 0.4)


# ------------------------------------------------------------------------------------ public API


def max_irradiance(light: np.ndarray) -> float:
    """Brightest irradiance Σ_k A_l Y_k(n) light[k, c] over normals n (a 2,000-point spiral) and channels c."""
    k = np.arange(2000) + 0.5
    z = 1.0 - 2.0 * k / 2000
    phi = math.pi * (1.0 + math.sqrt(5.0)) * k
    r = np.sqrt(1.0 - z * z)
    normals = np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)
    return float(irradiance(light, normals).max())


def normalize_envmap(env: np.ndarray, target: float = 1.0) -> np.ndarray:
    """Scale a map so that the brightest irradiance (any channel) of its SH projection is ``target``."""
    e = max_irradiance(project_envmap(env))
    if not e > 0:
        raise RelightError("env: the environment map has no positive irradiance anywhere")
    return (np.asarray(env, np.float64) * (target / e)).astype(np.float32)


def white_balance(env: np.ndarray, strength: float) -> np.ndarray:
    """Remove ``strength`` of a map's colour cast, as a camera's automatic white balance does.

    The cast is the colour of the map's average radiance (its SH coefficient 0); each channel is scaled by
    (grey / cast)^strength, and the luminance of that average is kept (Rec. 709). 0 leaves the map as it
    is, 1 makes its average neutral; cameras keep part of a warm or cool cast, so photos lie in between.
    """
    if not 0.0 <= strength <= 1.0:
        raise RelightError(f"white balance strength: expected a value in [0, 1], got {strength}")
    env = np.asarray(env, np.float64)
    dc = project_envmap(env)[0]
    if not (dc > 0).all():
        return env.astype(np.float32)
    gain = (dc.mean() / dc) ** strength
    gain *= (dc @ REC709) / ((dc * gain) @ REC709)
    return (env * gain).astype(np.float32)


def procedural_envmap(kind: str, rng: np.random.Generator, height: int = 64, target: float | None = None, *,
                      ground_albedo: tuple[float, float] | None = None) -> np.ndarray:
    """Make one procedural environment map.

    Args:
        kind: one of :data:`KINDS`.
        rng: random generator (the only source of randomness).
        height: map height H (width 2H).
        target: brightest irradiance after normalisation; default log-uniform in :data:`TARGET_RANGE`.
        ground_albedo: "sun_sky" only: (lo, hi) in [0, 1]: the ground is a diffuse surface of an albedo drawn in
            that range, lit by the sky and sun (e.g. :data:`GROUND_ALBEDO`); None (the default): the dim ground
            the shipped stage 1 was trained with, and the same map for the same generator as before the option.

    Returns:
        (H, 2H, 3) float32 linear RGB radiance, ≥ 0.
    """
    if kind not in _KINDS:
        raise RelightError(f"environment map kind {kind!r}: expected one of {KINDS}")
    if ground_albedo is not None:
        lo, hi = ground_albedo
        if not 0.0 <= lo <= hi <= 1.0:
            raise RelightError(f"ground albedo: expected 0 <= lo <= hi <= 1, got {ground_albedo}")
    dirs = directions_envmap(height).astype(np.float64)
    omega = solid_angles_envmap(height).astype(np.float64)
    if kind == "sun_sky":
        env = _sun_sky(dirs, omega, rng, ground_albedo)
    else:
        env = _KINDS[kind](dirs, omega, rng)
    env = env * np.exp(rng.normal(0.0, 0.08, 3))  # a slight overall tint (white balance)
    if target is None:
        target = math.exp(rng.uniform(math.log(TARGET_RANGE[0]), math.log(TARGET_RANGE[1])))
    return normalize_envmap(np.maximum(env, 0.0), target)


def rotate_envmap(env: np.ndarray, steps: int, n_steps: int = 10) -> np.ndarray:
    """Turn a map about +z by ``steps`` × 360°/``n_steps``, carrying +x toward +y (like ``relight_rt.sh.rotate_z``).

    The width must be divisible by ``n_steps`` (the turn is a whole number of columns, exact).
    """
    env = np.asarray(env)
    w = env.shape[1]
    if w % n_steps:
        raise RelightError(f"env: width {w} is not divisible by {n_steps} rotation steps")
    # new(φ) = old(φ + a): azimuth φ grows from +x toward −y, so carrying +x toward +y subtracts a
    return np.roll(env, -(steps * w // n_steps), axis=1)


def resize_envmap(env: np.ndarray, height: int) -> np.ndarray:
    """Area-average a map down (or bilinear up) to height H, width 2H."""
    env = np.asarray(env, np.float32)
    if env.shape[0] == height:
        return env.copy()
    interp = cv2.INTER_AREA if env.shape[0] > height else cv2.INTER_LINEAR
    return cv2.resize(env, (2 * height, height), interpolation=interp)


def write_hdr(path: str | Path, env: np.ndarray) -> None:
    """Write a linear RGB map as Radiance .hdr (BGR inside, as OpenCV writes it), atomically."""
    from export.dataset import atomic_write

    rgb = np.asarray(env, np.float32)

    def write(tmp: str) -> None:
        if not cv2.imwrite(tmp, np.ascontiguousarray(rgb[:, :, ::-1])):
            raise RelightError(f"could not write environment map {path}")

    atomic_write(Path(path), write)
