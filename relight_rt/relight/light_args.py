"""A light argument of the Relighter's verbs resolved to the (9, 3) RGB SH light the stages use (``Relighter.
resolve_light`` is the one place it happens; this module holds how), and a list of them with each one's exposure."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..engine.errors import RelightError
from ..image.io import sibling_mask
from ..light import exposure as _exposure
from ..light import sh
from ..light.spec import LightSpec
from .decomposition import Decomposition

Decompose = Callable[..., Decomposition]  # ``Relighter.decompose``: (photo, mask) -> its Decomposition


def float32_light(light, name: str) -> np.ndarray:
    """A checked (9, 3) light in float32, the dtype it is used in (too large or non-finite there: RelightError)."""
    arr = sh.check_light(light, name).astype(np.float32)
    if not np.isfinite(arr).all():
        raise RelightError(f"{name}: SH light overflows float32 (|value| must be <= {sh.MAX_COEFF:g})")
    return arr


def resolve_light(light, decompose: Decompose, dtype=np.float32) -> np.ndarray:
    """``Relighter.resolve_light`` (which documents what is accepted), with the photo of a person's light estimated
    by ``decompose`` (that Relighter's stage 1, as "light me like that photo": its light taken as white)."""
    try:
        known = np.dtype(dtype) in (np.float32, np.float64)
    except TypeError:  # a name numpy does not know ("nonsense")
        known = False
    if not known:
        raise RelightError(f"dtype: expected float32 or float64, got {dtype!r}")
    if isinstance(light, Decomposition):
        return np.array(light.white_light, dtype=dtype)

    def estimate(photo: Path, mask: str | None) -> np.ndarray:
        dec = decompose(photo, mask if mask is not None else sibling_mask(photo))
        return np.array(dec.white_light, np.float32)

    lit = LightSpec.of(light).resolve(estimate, dtype=np.float64)
    return float32_light(lit, "light") if np.dtype(dtype) == np.float32 else sh.check_light(lit, "light")


def resolve_lights(values, resolve: Callable[[object], np.ndarray]) -> np.ndarray:
    """A (K, 9, 3) array, or a list of anything ``resolve`` (``Relighter.resolve_light``) accepts → (K, 9, 3)
    float32, K >= 1."""
    if isinstance(values, np.ndarray):
        if values.ndim != 3 or values.shape[1:] != (9, 3):
            raise RelightError(f"lights: expected (K, 9, 3) SH lights, got {values.shape} {values.dtype}")
    elif not isinstance(values, (list, tuple)):
        raise RelightError(f"lights: expected a (K, 9, 3) array or a list of lights, got {type(values).__name__}")
    if len(values) == 0:
        raise RelightError("lights: expected at least one light, got none")
    return np.stack([resolve(v) for v in values])


def lights_with_exposures(lights, exposure, resolve: Callable[[object], np.ndarray]) -> tuple[np.ndarray, list]:
    """K lights (as ``resolve_lights`` takes them) → their (K, 9, 3) float32 SH lights and each one's exposure:
    ``exposure`` (as ``Relighter.relight`` takes it), or the one a preset asks for (``exposure.for_light``: night a
    stop darker). A string or path is read once, by the one rule: its exposure and its light."""
    if isinstance(lights, (list, tuple)):
        lights = [LightSpec.of(v) if isinstance(v, (str, os.PathLike)) else v for v in lights]
    resolved = resolve_lights(lights, resolve)
    exposures = [_exposure.for_light(exposure, v) for v in lights] if isinstance(lights, list) else \
        [_exposure.parse_exposure(exposure)] * len(resolved)
    return resolved, exposures
