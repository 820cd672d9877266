"""Exposure: how bright a relit person comes out (DESIGN.md §3, "Exposure").

Shading is positively homogeneous in the light: max(0, T·(s L)) = s · max(0, T·L) for s > 0. So the
overall brightness of a relit person is one scalar on the light, and an automatic exposure is exact:

* ``"auto"`` (the default everywhere a light is applied): the new light is scaled by one scalar so
  that the relit person's mean luminance equals a target. In ``relight`` / ``relight_many`` /
  ``iter_relight`` the target is the input person's own mean luminance (what a camera's automatic
  exposure does): the light's direction and colour change the picture, not its overall brightness.
  In ``composite`` the target is the brightness the background's own light gives the person
  (relight_rt.apps.scene).
  Where keeping the mean would push more of the person past white than the photo itself has there (at least
  ``HIGHLIGHT_SHARE``; a face lit from one side by a lamp as strong as the whole photo's light), the scale is
  lowered just enough (``highlight_factor``), by at most ``HIGHLIGHT_MAX_DOWN`` (one stop): a camera's
  highlight-weighted metering. Without it the lit side of a fair face went flat at the limit (a fifth of the
  person under campfire on DPR's portrait), its shading gone, and the shade beside it read as a blotch. The
  photo's own light is never lowered (its share past white is the photo's), so it still gives the photo back.
  This guard applies where the target is the photo's own brightness; a composite's person takes the scene's
  exposure as it is (the backdrop's highlights are the backdrop's). Before the guard, what the highlight shoulder
  (relight_rt.relight.look ``shoulder``) takes of a picture the light spreads past white is given back
  (``shoulder_gain``): the mean is kept as the picture is shown, not before its highlights are rolled off (white
  side lamps came out 0.19 EV dark as seen, median of 59 real photos); the guard's one-stop bound still counts from
  the mean-keeping light.
* a number ``EV``: the automatic scale (guard included) times ``ev_gain(EV)``, 2**(EV / ``DISPLAY_GAMMA``): +1 is
  twice the light on the photo as it is seen, −1 half. The pipeline multiplies the photo's encoded (sRGB) values
  by the relighting factor, and light seen on a display goes as those values to the power 2.2, so a factor of
  2**EV moved the picture's light by 2.2 EV: ``night`` (asked a stop darker) came out 1.77 stops darker than the
  person over 59 real photos (median; benchmarks/photo_faults.py, issue 48). ``composite`` (relight_rt.apps.scene)
  works in linear light, where ``exposure_scale``'s 2**EV is already a stop per EV.
* ``"physical"``: the light's absolute intensity is kept (no scaling).

Mean luminance: Rec. 709 weights (``relight_rt.image.color.REC709``) on the values of the pipeline, which
treats them as linear, averaged inside the (soft) mask and weighted by it, on the network-resolution
diffuse image albedo ⊙ max(0, T·L) before clipping. The Relighter's "auto" (``expose``) meters the power mean
(mean of Y ** ``METER_POWER``) ** (1 / ``METER_POWER``): its values are encoded, the light seen goes as their 2.2nd
power, and the plain mean let a light that spreads the picture (a hard small moon: night) keep the encoded mean
while the light seen rose (night came out +0.26 EV above its stop; benchmarks/photo_faults.py, issue 48). The
power mean is still homogeneous of degree 1 in the light, so the scale stays exact. ``relight_rt.apps.scene`` works
in linear light and keeps the plain mean (power 1). Stage 2 and the clip to [0, 1] come after the
scale, so the final picture's luminance follows the target closely but not exactly (saturated pixels
cannot get brighter).
"""

from __future__ import annotations

import math
import os
from typing import NamedTuple

import numpy as np

from ..engine.errors import RelightError
from ..image.color import REC709, channel_max
from . import sh

__all__ = ["DISPLAY_GAMMA", "HIGHLIGHT_LIMIT", "HIGHLIGHT_MAX_DOWN", "HIGHLIGHT_SHARE", "KNEE_RANGE", "METER_POWER",
           "SHOULDER_MAX_UP", "Highlight", "ev_gain", "exposure_scale", "guarded", "highlight_factor", "mean_luminance",
           "knee", "own_light_knee", "parse_exposure", "rolled_off", "shoulder_gain"]

MAX_EV = 20.0  # |EV| beyond this is a mistake, not a photograph
HIGHLIGHT_LIMIT = 1.0  # white: the brightest channel of a relit pixel past this is held by the highlight shoulder
HIGHLIGHT_SHARE = 0.08  # the share of the person "auto" lets past white (or the photo's own share, when larger)
HIGHLIGHT_MAX_DOWN = 0.5  # ... and the most it lowers the light for that: one stop
DISPLAY_GAMMA = 2.2  # light seen ~ (the pipeline's encoded values) ** 2.2: an EV offset acts on what is seen
METER_POWER = DISPLAY_GAMMA  # "auto" on encoded values keeps the mean of luminance ** this: the light as seen
KNEE_RANGE = (0.8, 0.999)  # the highlight shoulder starts at a pixel's own peak in the photo, within this range
SHOULDER_MAX_UP = 2.0  # shoulder_gain gives back the shoulder's loss by at most this factor on the light
SHOULDER_SAMPLES = 1 << 13  # shoulder_gain reads every step-th pixel, at most this many (a scalar of a mean: the
# studio's preview runs it every frame, 5 ms in JavaScript for 11k pixels)
SHOULDER_TOL = 1e-4  # ... and stops within this of the light seen (log ratio)
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


def for_light(exposure, light) -> str | float:
    """The exposure a relight under ``light`` runs at: ``exposure`` (parsed, ``parse_exposure``) plus the EV a
    preset asks of "auto" (``relight_rt.light.presets.preset_exposure``: night a stop darker); an EV offset counts from
    that preset's "auto"; "physical" and every other light (arrays, files, maps) unchanged.

    ``light``: a ``LightSpec``, a string or path (read by the one rule, ``LightSpec.of``: a preset's name or a
    file), or anything else ``Relighter.resolve_light`` takes (no preset).
    """
    from .spec import LightSpec  # lightspec reads lights and files; this module is below it

    mode = parse_exposure(exposure)
    if isinstance(light, (str, os.PathLike)):
        light = LightSpec.of(light)
    if mode == "physical" or not isinstance(light, LightSpec) or light.source != "preset":
        return mode
    from .presets import preset_exposure

    name = light.value
    ev = preset_exposure(name) + (0.0 if mode == "auto" else mode)
    return "auto" if ev == 0 else ev


def ev_gain(ev: float) -> float:
    """The factor on the pipeline's (encoded) values that moves the light seen in the picture by ``ev`` stops:
    2**(ev / DISPLAY_GAMMA) (module docstring)."""
    return 2.0 ** (float(ev) / DISPLAY_GAMMA)


def mean_luminance(albedo, transport, mask, light, power: float = 1.0) -> float:
    """Mask-weighted mean Rec. 709 luminance of the diffuse image albedo ⊙ max(0, T·light), unclipped.

    Args:
        albedo: (R, R, 3) float albedo (network frame, masked).
        transport: (R, R, 9) float transport.
        mask: (R, R) float mask in [0, 1] (soft masks weight their pixels).
        light: (9, 3) RGB SH light.
        power: the power mean's exponent p, (mean of Y ** p) ** (1 / p): 1 the plain mean (linear values),
            ``METER_POWER`` the light seen of encoded values (module docstring).

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
    if power == 1.0:
        return float(lum @ m[inside]) / weight
    mean = float(np.maximum(lum, 0).astype(np.float64) ** power @ m[inside]) / weight
    return mean ** (1.0 / power)


def exposure_scale(albedo, transport, mask, light, target_luminance: float, exposure="auto",
                   power: float = 1.0) -> float:
    """The scalar s to multiply ``light`` by, for ``exposure`` (see the module docstring).

    Args:
        albedo, transport, mask: the person in the network frame (see ``mean_luminance``).
        light: (9, 3) the new light.
        target_luminance: the mean luminance the person should have ("auto" and EV); ignored for
            "physical".
        exposure: "auto", "physical" or an EV offset (anything ``parse_exposure`` accepts).
        power: the mean that is kept (``mean_luminance``'s; the target must be of the same power).

    Returns:
        s > 0 (1.0 for "physical"). When the light leaves the person black (nothing to scale) the
        result is 2**EV. An EV here is one of linear light: ``relight_rt.apps.scene`` composites in linear light, where
        twice the light is twice the values (the Relighter's encoded values take ``guarded``'s ``ev_gain``).

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
    current = mean_luminance(albedo, transport, mask, light, power)
    if current <= _TINY or target <= _TINY:
        return gain
    return gain * target / current


class Highlight(NamedTuple):
    """What the highlight guard (``highlight_factor``) and the shoulder's loss (``shoulder_gain``) read of a relit
    person, whatever the light: its pixels as the relit picture is made of them, under ``s`` times a light with RGB
    shading S = max(0, T·light) and luminance Y(S), ``s * lit * S + steady * S / Y(S)``.

    Attributes:
        lit: (N, 3) float32 per pixel, the colour per unit of shading that scales with the light.
        steady: (N, 3) float32 per pixel, the colour per unit of the light's luminance that stays (zeros for none).
        transport: (N, 9) float32, the transport the relighting uses.
        allowed: the share of the N pixels that may go past white (in [0, 1]).
        knee: (N,) float32, where the highlight shoulder starts for each pixel (relight_rt.relight.look ``knee``:
            its own peak in the photo, within ``KNEE_RANGE``); None: the shoulder's loss is not given back.
    """

    lit: np.ndarray
    steady: np.ndarray
    transport: np.ndarray
    allowed: float
    knee: np.ndarray | None = None


def _pixels(lit, steady, transport) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``Highlight``'s per-pixel arrays as float32 (N, 3), (N, 3), (N, 9), checked to hold one count of pixels."""
    lit = np.asarray(lit, np.float32).reshape(-1, 3)
    steady = np.asarray(steady, np.float32).reshape(-1, 3)
    t = np.asarray(transport, np.float32).reshape(-1, 9)
    if not (lit.shape[0] == steady.shape[0] == t.shape[0]):
        raise RelightError(f"exposure: {lit.shape[0]} lit, {steady.shape[0]} steady and {t.shape[0]} transport pixels")
    return lit, steady, t


def _relit(lit: np.ndarray, steady: np.ndarray, t: np.ndarray, light) -> tuple[np.ndarray, np.ndarray]:
    """Each pixel relit under ``light`` (``Highlight``'s picture at s = 1), in its two parts: (scaled, fixed), (N, 3)
    each, the colour that scales with the light (lit * S) and the one that stays (steady * S / Y(S))."""
    shading = sh.shading(t, np.asarray(light, np.float32))
    lum = shading @ REC709
    return lit * shading, steady * shading / np.maximum(lum, 1e-4)[:, None]


def highlight_factor(lit, steady, transport, light, allowed: float, max_down: float = HIGHLIGHT_MAX_DOWN,
                     top: float = 1.0) -> float:
    """How much "auto" lowers an exposed light so that at most ``allowed`` of the person goes past white.

    The relit colour of each of the person's pixels (network resolution, before stage 2 and the highlight
    shoulder) under ``s`` times ``light`` is taken as ``s * lit * S + steady * S / Y(S)`` (``Highlight``): the part
    that scales with the light and the part that stays whatever its strength (relight_rt.relight.relighter: the
    light the model misses), both carried in the new light's colour. A pixel goes past white (``HIGHLIGHT_LIMIT`` on
    its brightest channel) from some scale s_i on; the factor is the largest s <= ``top`` at which no more than
    ``allowed`` of the pixels are past it, and at least ``max_down``.

    Args:
        lit, steady, transport: (N, 3), (N, 3), (N, 9), ``Highlight``'s per-pixel picture.
        light: (9, 3) the exposed light.
        allowed: the share of the N pixels that may go past white (in [0, 1]).
        max_down: the least factor.
        top: the largest factor (``guarded``: the shoulder's lift, which the guard takes back where it lets more
            past white than ``allowed``).

    Returns:
        The factor in [``max_down``, ``top``]; ``top`` for no pixels.
    """
    lit, steady, t = _pixels(lit, steady, transport)
    n = t.shape[0]
    if n == 0:
        return float(top)
    scaled, fixed = _relit(lit, steady, t, light)
    # the scale at which each channel reaches white (0 when it is there already, inf when it never does)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        reach = np.where(scaled > 0, (HIGHLIGHT_LIMIT - fixed) / scaled, np.inf)
    reach = np.where(fixed >= HIGHLIGHT_LIMIT, 0.0, reach).min(axis=1)
    k = min(int(math.floor(float(np.clip(allowed, 0, 1)) * n)), n - 1)
    s = float(np.partition(reach, k)[k])  # k pixels at most reach white below this scale
    return float(min(max(s, max_down), top))


def rolled_off(peak: np.ndarray, knee: np.ndarray) -> np.ndarray:
    """The highlight shoulder's curve (relight_rt.relight.look ``shoulder``): a pixel's brightest channel ``peak``
    past its ``knee`` q goes to q + (1 - q)(1 - exp(-(peak - q) / (1 - q))) (slope 1 at q, approaching 1); at or
    below q it stays. ``knee`` of ``peak``'s shape or a scalar; returns a new float32 array."""
    m = np.asarray(peak, np.float32)
    q = np.broadcast_to(np.asarray(knee, np.float32), m.shape)
    over = m > q
    out = m.copy()
    if over.any():
        mq, qq = m[over], q[over]
        out[over] = qq + (1 - qq) * -np.expm1(-(mq - qq) / (1 - qq))
    return out


def knee(photo: np.ndarray) -> np.ndarray:
    """(...) where the highlight shoulder starts for each pixel of ``photo`` (..., 3): its own peak (brightest
    channel), within ``KNEE_RANGE`` ([0.8, 0.999])."""
    return np.clip(channel_max(photo), *KNEE_RANGE)


def own_light_knee(lit, steady, transport, white) -> np.ndarray:
    """(N,) float32 each pixel's knee where only ``Highlight``'s picture is at hand: its peak under the photo's own
    light, white (``white`` (9,): ``Decomposition.white_light[:, 0]``), lit * Y(W) + steady with W = max(0, T·white),
    within ``KNEE_RANGE``. Where the picture is the photo times the relighting factor (relight_rt.relight.factor) this
    is the photo's own peak (:func:`knee` of the photo), which ``ExposureMeter.highlight_inputs`` reads directly; the
    network's image (``detail=False``) and the studio page's copy of ``shoulder_gain`` rebuild it this way."""
    lit, steady, t = _pixels(lit, steady, transport)
    own = np.maximum(t @ np.asarray(white, np.float32).reshape(9), 0)
    return knee(lit * own[:, None] + steady).astype(np.float32)


def shoulder_gain(lit, steady, transport, light, knee, power: float = METER_POWER) -> float:
    """How much "auto" raises an exposed light so that the picture keeps, after the highlight shoulder, the light as
    seen that the mean-keeping scale gave it before (the power mean of luminance ** ``power``).

    The mean-keeping scale meters the relit person before the shoulder (relight_rt.relight.look ``shoulder``) rolls its
    highlights off toward white: a light that spreads the picture (a white side lamp: one cheek twice as bright) keeps
    its mean only with values past white that the shoulder then takes back. On 59 real photos that loss was 0.17 of the
    white side lamps' median -0.19 EV as seen (-0.01 without the shoulder and the guard; benchmarks/photo_faults.py,
    issue 48), none of it where the photo's own light keeps every pixel under its own peak (that light gives the photo
    back). Each of the person's pixels is taken as ``highlight_factor`` takes it (``Highlight``), rolled off past its
    ``knee``; the gain k >= 1 has the shouldered picture's power mean at k equal the unshouldered one's at 1 (within
    ``SHOULDER_TOL``), found by the secant on log seen against log k from k = 1 and the first step (target / seen(1))
    ** (1 / power), at most ``SHOULDER_MAX_UP``. Every step-th pixel, at most ``SHOULDER_SAMPLES`` (the studio's
    preview takes every step-th of its own sample the same way).

    Args:
        lit, steady, transport: (N, 3), (N, 3), (N, 9), ``Highlight``'s per-pixel picture.
        light: (9, 3) the exposed light.
        knee: (N,) where the shoulder starts for each pixel (``Highlight.knee``).
        power: the power mean kept (``METER_POWER``).

    Returns:
        The gain in [1, ``SHOULDER_MAX_UP``]; 1 for no pixels.
    """
    lit, steady, t = _pixels(lit, steady, transport)
    knee = np.asarray(knee, np.float32).reshape(-1)
    if knee.shape[0] != t.shape[0]:
        raise RelightError(f"exposure: {knee.shape[0]} knees for {t.shape[0]} pixels")
    step = max(1, math.ceil(t.shape[0] / SHOULDER_SAMPLES))
    lit, steady, t, knee = lit[::step], steady[::step], t[::step], knee[::step]
    if t.shape[0] == 0:
        return 1.0
    scaled, fixed = _relit(lit, steady, t, light)
    y_scaled, y_fixed = scaled @ REC709, fixed @ REC709

    def seen(k: float, shouldered: bool = True) -> float:
        y = np.maximum(k * y_scaled + y_fixed, 0)
        if shouldered:
            peak = channel_max(k * scaled + fixed)
            over = peak > knee
            if over.any():
                y[over] *= rolled_off(peak[over], knee[over]) / peak[over]
        return float(np.mean(y.astype(np.float64) ** power))

    # the secant on log seen against log k, from k = 1 (seen rises with k, slower than k ** power): 3-5 steps
    target = seen(1.0, shouldered=False)
    top = math.log(SHOULDER_MAX_UP)
    x0, f0 = 0.0, _log_ratio(seen(1.0), target)
    if f0 >= -SHOULDER_TOL:  # a loss under 1e-4 of the light seen is none: a photo's own pixels at white (its knee
        return 1.0  # 0.999) under its own light lose 4e-4 each, and that light gives the photo back
    x1 = min(-f0 / power, top)
    f1 = _log_ratio(seen(math.exp(x1)), target)
    for _ in range(8):
        if abs(f1) < SHOULDER_TOL or (x1 >= top and f1 < 0):
            break
        x2 = x1 - f1 * (x1 - x0) / (f1 - f0) if f1 != f0 else x1 - f1 / power
        x0, f0 = x1, f1
        x1 = min(max(x2, 0.0), top)
        f1 = _log_ratio(seen(math.exp(x1)), target)
    return float(math.exp(x1))


def _log_ratio(now: float, target: float) -> float:
    """log(now / target), -inf for nothing seen."""
    return math.log(now / target) if now > 0 and target > 0 else -math.inf if target > 0 else 0.0


def guarded(lights, exposure, highlight: Highlight) -> np.ndarray:
    """Lights at the mean-keeping scale (``expose(..., "auto")``) → the exposure's lights: each times its
    ``shoulder_gain`` k (where ``highlight`` has knees) and its ``highlight_factor``, the two as one clip of the
    guard's scale to [``HIGHLIGHT_MAX_DOWN``, k] (the guard takes back what the lift lets past white beyond the share
    allowed, and its one-stop bound counts from the light as it came), then ``ev_gain(EV)`` for an EV offset. The one
    order of the rule (the shoulder's loss given back, the guard, then the EV), for the runtime and the studio's
    preview alike.

    Args:
        lights: (K, 9, 3) or (9, 3) float32 lights, each already scaled to keep the mean luminance.
        exposure: "auto" or an EV offset (not "physical": those lights are not scaled at all).
        highlight: a ``Highlight`` (or the tuple of its fields, ``knee`` optional: without it the shoulder's loss is
            not given back).

    Returns:
        float32 lights of the same shape.
    """
    mode = parse_exposure(exposure)
    if mode == "physical":
        raise RelightError('exposure: "physical" lights are not scaled, so not guarded')
    gain = 1.0 if mode == "auto" else ev_gain(mode)
    lit, steady, transport, allowed, knee = Highlight(*highlight)
    lits = np.asarray(lights, np.float32)
    flat = lits.reshape(-1, 9, 3)
    factors = []
    for one in flat:
        up = 1.0 if knee is None else shoulder_gain(lit, steady, transport, one, knee)
        factors.append(gain * highlight_factor(lit, steady, transport, one, allowed, HIGHLIGHT_MAX_DOWN, up))
    return (flat * np.asarray(factors, np.float32)[:, None, None]).reshape(lits.shape)


def expose(dec, lights: np.ndarray, exposure="auto", target_luminance: float | None = None) -> np.ndarray:
    """Scale each of the (K, 9, 3) or (9, 3) ``lights`` for a Decomposition ``dec``.

    ``target_luminance`` None: the photo's own mean luminance (its diffuse reconstruction under its
    estimated light taken as white, ``Decomposition.white_light``); both means are power means of ``METER_POWER``
    (a given target must be one too: the light as seen is kept). Returns float32 lights of the same
    shape; the input is not modified. This is the mean-keeping rule alone: ``Relighter.relight`` then applies
    the highlight guard (``highlight_factor``, which reads the runtime's relighting factor) before any EV.
    """
    mode = parse_exposure(exposure)
    lits = np.asarray(lights, np.float32)
    if mode == "physical":
        return lits.copy()
    albedo, transport, mask = dec.albedo, dec.transport, dec.network_mask
    if target_luminance is None:  # the photo under its own light, taken as white (as the Relighter divides by it)
        target_luminance = mean_luminance(albedo, transport, mask, dec.white_light, METER_POWER)
    flat = lits.reshape(-1, 9, 3)
    scales = [exposure_scale(albedo, transport, mask, lit, target_luminance, mode, METER_POWER) for lit in flat]
    out = flat * np.asarray(scales, np.float32)[:, None, None]
    return out.reshape(lits.shape)
