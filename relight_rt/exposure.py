"""Exposure: how bright a relit person comes out (DESIGN.md §3, "Exposure").

Shading is positively homogeneous in the light: max(0, T·(s L)) = s · max(0, T·L) for s > 0. So the
overall brightness of a relit person is one scalar on the light, and an automatic exposure is exact:

* ``"auto"`` (the default everywhere a light is applied): the new light is scaled by one scalar so
  that the relit person's mean luminance equals a target. In ``relight`` / ``relight_many`` /
  ``iter_relight`` the target is the input person's own mean luminance (what a camera's automatic
  exposure does): the light's direction and colour change the picture, not its overall brightness.
  In ``composite`` the target is the brightness the background's own light gives the person
  (relight_rt.scene).
* a number ``EV``: the automatic scale times 2**EV (+1 is twice as bright, −1 half).
* ``"physical"``: the light's absolute intensity is kept (no scaling).

Mean luminance: Rec. 709 weights (0.2126 R + 0.7152 G + 0.0722 B) on the values of the pipeline, which
treats them as linear, averaged inside the (soft) mask and weighted by it, on the network-resolution
diffuse image albedo ⊙ max(0, T·L) before clipping. Stage 2 and the clip to [0, 1] come after the
scale, so the final picture's luminance follows the target closely but not exactly (saturated pixels
cannot get brighter).
"""

from __future__ import annotations

import math

import numpy as np

from . import sh
from ._errors import RelightError

__all__ = ["REC709", "exposure_scale", "mean_luminance", "parse_exposure"]

REC709 = np.array([0.2126, 0.7152, 0.0722], np.float32)
MAX_EV = 20.0  # |EV| beyond this is a mistake, not a photograph
_TINY = 1e-8


def parse_exposure(value) -> str | float:
    """The one exposure parameter → ``"auto"``, ``"physical"`` or a float EV offset from auto.

    Accepts ``"auto"``, ``"physical"``, a number, or a string holding a number (the CLI's
    ``--exposure``: ``auto``, ``physical``, ``+1``, ``-0.5``).

    Raises:
        RelightError: anything else, or an EV that is not finite or beyond ±20.
    """
    if isinstance(value, str):
        text = value.strip().lower()
        if text in ("auto", "physical"):
            return text
        try:
            ev = float(text)
        except ValueError:
            raise RelightError(f"exposure: expected 'auto', 'physical' or an EV number (+1), got {value!r}") from None
    elif isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool):
        try:
            ev = float(value)
        except OverflowError:  # an integer of 400 digits (a JSON request can hold one)
            raise RelightError(f"exposure: expected an EV offset within ±{MAX_EV:g}, got an integer too large "
                               "for a float") from None
    else:
        raise RelightError(f"exposure: expected 'auto', 'physical' or an EV number, got {type(value).__name__}")
    if not math.isfinite(ev) or abs(ev) > MAX_EV:
        raise RelightError(f"exposure: expected an EV offset within ±{MAX_EV:g}, got {value!r}")
    return ev


def mean_luminance(albedo, transport, mask, light) -> float:
    """Mask-weighted mean Rec. 709 luminance of the diffuse image albedo ⊙ max(0, T·light), unclipped.

    Args:
        albedo: (R, R, 3) float albedo (network frame, masked).
        transport: (R, R, 9) float transport.
        mask: (R, R) float mask in [0, 1] (soft masks weight their pixels).
        light: (9, 3) RGB SH light.

    Returns:
        The mean luminance (0 for an empty mask).
    """
    a = np.asarray(albedo, np.float32)
    t = np.asarray(transport, np.float32)
    m = np.asarray(mask, np.float32)
    if a.ndim != 3 or a.shape[2] != 3 or t.shape != a.shape[:2] + (9,) or m.shape != a.shape[:2]:
        raise RelightError(
            f"exposure: expected albedo (R, R, 3), transport (R, R, 9) and mask (R, R) of one size, got "
            f"{a.shape}, {t.shape}, {m.shape}"
        )
    lit = np.asarray(light, np.float32)
    if lit.shape != (9, 3) or not np.isfinite(lit).all():
        raise RelightError(f"light: expected a finite (9, 3) SH light, got {lit.shape}")
    weight = float(m.sum())
    if weight <= 0:
        return 0.0
    inside = m > 0  # only the person's pixels (often a third of the square)
    lum = (sh.shading(t[inside], lit) * a[inside]) @ REC709
    return float(lum @ m[inside]) / weight


def exposure_scale(albedo, transport, mask, light, target_luminance: float, exposure="auto") -> float:
    """The scalar s to multiply ``light`` by, for ``exposure`` (see the module docstring).

    Args:
        albedo, transport, mask: the person in the network frame (see ``mean_luminance``).
        light: (9, 3) the new light.
        target_luminance: the mean luminance the person should have ("auto" and EV); ignored for
            "physical".
        exposure: "auto", "physical" or an EV offset (anything ``parse_exposure`` accepts).

    Returns:
        s > 0 (1.0 for "physical"). When the light leaves the person black (nothing to scale) the
        result is 2**EV.

    Raises:
        RelightError: a bad exposure value or a negative / non-finite target.
    """
    mode = parse_exposure(exposure)
    if mode == "physical":
        return 1.0
    target = float(target_luminance)
    if not math.isfinite(target) or target < 0:
        raise RelightError(f"exposure: the target luminance must be finite and >= 0, got {target_luminance!r}")
    gain = 1.0 if mode == "auto" else 2.0**mode
    current = mean_luminance(albedo, transport, mask, light)
    if current <= _TINY or target <= _TINY:
        return gain
    return gain * target / current


def expose(dec, lights: np.ndarray, exposure="auto", target_luminance: float | None = None) -> np.ndarray:
    """Scale each of the (K, 9, 3) or (9, 3) ``lights`` for a Decomposition ``dec``.

    ``target_luminance`` None: the photo's own mean luminance (its diffuse reconstruction under its
    estimated light taken as white, ``Decomposition.white_light``). Returns float32 lights of the same
    shape; the input is not modified.
    """
    mode = parse_exposure(exposure)
    lits = np.asarray(lights, np.float32)
    if mode == "physical":
        return lits.copy()
    albedo, transport, mask = dec.albedo, dec.transport, dec.network_mask
    if target_luminance is None:  # the photo under its own light, taken as white (as the Relighter divides by it)
        target_luminance = mean_luminance(albedo, transport, mask, dec.white_light)
    flat = lits.reshape(-1, 9, 3)
    scales = [exposure_scale(albedo, transport, mask, lit, target_luminance, mode) for lit in flat]
    out = flat * np.asarray(scales, np.float32)[:, None, None]
    return out.reshape(lits.shape)
