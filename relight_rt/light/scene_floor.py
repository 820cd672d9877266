"""The photo's own scene light under a new light, where the person stays in the photo (the background kept).

A lamp that misses one side of a person leaves that side near black: the presets are studio lights (ambient 0.03-0.1
of the peak), and under them the far side's shading falls to a tenth of the photo's own. Over a background the photo
keeps, that side sits beside a scene whose own light (sky, bounce from the ground and the walls) reached it in the
photo and would still reach it with a lamp added: the person reads as pasted in (docs/RESULTS.md, the first look).

The rule (``with_scene_floor``): the light that reached the person from every side in the photo stays. Its share is
the photo's own light's floor (``floor``): the least irradiance its degree-2 SH gives any direction of the sphere over
its mean over the sphere, from its luminance (the light taken as white, as the relighting factor divides by it:
``Decomposition.white_light``). A new light whose own floor is lower is blended, at the same mean irradiance over the
sphere, with uniform white light (the photo's white-balanced colour) until its floor is the photo's:
L' = (1 - t) L + t m U, U the uniform light of irradiance 1, m L's mean irradiance, t the least blend that lifts the
floor. The photo's own light has its own floor, so it is left as it is and gives the photo back; a light with more
light from every side than the photo had is left as it is too. "auto" then meters the blend as it meters any light,
so the exposure's statements hold as they were.

It applies only where the person stays in the photo's scene: the background kept (``Background`` "original") and the
exposure not "physical" (a light given at its absolute intensity is the user's own composition of the scene); a new
backdrop, the RGBA output and ``composite`` (relight_rt.apps.scene: the new scene's own light) do not take it.
"""

from __future__ import annotations

import math

import numpy as np

from ..engine.errors import RelightError
from ..image.color import REC709
from . import sh

__all__ = ["floor", "with_scene_floor"]

FLOAT_TOL = 1e-5  # a floor short of the photo's by less than this is the photo's (its light rounded to float32)
SPHERE = 2048  # directions the floor is read over (sh.sphere_directions: an even lattice over the whole sphere)
_Y00 = 1 / (2 * math.sqrt(math.pi))
_DIRS = sh.sphere_directions(SPHERE)
# irradiance of one channel's 9 coefficients at the lattice's directions: E(n) = sum_k A_l Y_k(n) c_k
_IRRADIANCE = (sh.basis(_DIRS) * sh.cosine_lobe()[None, :]).astype(np.float64)  # (SPHERE, 9)


def _floor_and_mean(coeffs: np.ndarray) -> tuple[float, float]:
    """(least irradiance over the sphere, mean irradiance over it) of a one-channel light (9,)."""
    e = _IRRADIANCE @ np.asarray(coeffs, np.float64)
    return float(e.min()), math.pi * _Y00 * float(coeffs[0])


def floor(light) -> float:
    """The share of a light that reaches every side: its luminance's least degree-2 irradiance over the sphere over its
    mean over the sphere, in [0, 1] (0 for a light without a positive mean: nothing to keep).

    Args:
        light: (9, 3) RGB SH light, or (9,) one channel.
    """
    c = _luminance(light)
    low, mean = _floor_and_mean(c)
    if mean <= 1e-9:
        return 0.0
    return float(min(max(low / mean, 0.0), 1.0))


def _luminance(light) -> np.ndarray:
    arr = np.asarray(light, np.float64)
    if arr.shape == (sh.N_COEFFS, 3):
        return arr @ REC709
    if arr.shape == (sh.N_COEFFS,):
        return arr
    raise RelightError(f"light: expected a (9, 3) SH light or (9,) one channel, got {arr.shape}")


def with_scene_floor(lights, own_floor: float) -> np.ndarray:
    """``lights`` (K, 9, 3) or (9, 3), each blended with uniform white light at its own mean irradiance over the sphere
    just enough that its ``floor`` is at least ``own_floor`` (module docstring); a light already there, or without a
    positive mean, unchanged. Returns a new float32 array of the same shape.

    Args:
        lights: RGB SH lights.
        own_floor: the photo's own light's ``floor``, in [0, 1].
    """
    target = float(own_floor)
    if not math.isfinite(target) or not 0 <= target <= 1:
        raise RelightError(f"own_floor: expected a share in [0, 1], got {own_floor!r}")
    lits = np.asarray(lights, np.float32)
    flat = lits.reshape(-1, sh.N_COEFFS, 3).copy()
    for i, one in enumerate(flat):
        low, mean = _floor_and_mean(one.astype(np.float64) @ REC709)
        if mean <= 1e-9:
            continue
        have = max(low / mean, 0.0)  # as ``floor`` reads it (degree-2 ringing below 0 is none)
        if have >= target - FLOAT_TOL:  # (the photo's own light in float32: its floor)
            continue
        t = (target - have) / (1 - have)  # (1 - t) have + t = target; have < target <= 1
        uniform = np.zeros((sh.N_COEFFS, 3), np.float64)
        uniform[0] = mean / (math.pi * _Y00)  # irradiance ``mean`` in every direction, white (luminance ``mean``)
        flat[i] = ((1 - t) * one.astype(np.float64) + t * uniform).astype(np.float32)
    return flat.reshape(lits.shape)
