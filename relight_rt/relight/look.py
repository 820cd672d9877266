"""The look of a relit photo: how its colours and highlights behave, whatever produced the relighting factor.

The highlight shoulder (``knee``, ``shoulder``), the colour of dark pixels a strong gain brightens
(``dark_colour``, ``steady_chroma``), the colour range a light can give (``tint_range``), and the chroma shaded
skin keeps (``shaded_skin``, ``skin_chroma``; the studio's preview applies the same rule with ``SKIN_CHROMA``).
Plain functions of arrays: no model, no state.
"""

from __future__ import annotations

import threading

import cv2
import numpy as np

from ..image.color import REC709, channel_max
from ..light import sh
from ..light.exposure import knee as knee  # the public name here (the one definition sits in light.exposure)
from ..light.exposure import rolled_off

_DARK = np.float32(0.25)  # steady_chroma: a pixel below this luminance, brightened by a gain, takes its dark
_AMPLIFIED = np.float32(2.0)  # ... neighbours' colour, fully from a gain of 1 + this,
_CHROMA_RADIUS = 4  # ... those within this many pixels (the constants: the reference photo's jaw, module tests)
_NEUTRAL_L = (30.0, 40.0)  # dark_colour: a pixel of Lab L* below the first is dark, from the second not ...
_NEUTRAL_C = (6.0, 12.0)  # ... and near-black when its Lab chroma C* is below the first, from the second not,
_NEUTRAL_A = (-4.0, -1.0)  # ... with a green-cyan cast: a* below the first, none from the second up,
_NEUTRAL_HUE = (0.4, 0.7)  # ... or a faint one by its direction: -a* / C* above the second, none below the first
_NEUTRAL_STEP = 4  # ... measured on the photo reduced this many times (a cloth's cast is shared by its pixels)
_NEUTRAL_PULL = np.float32(2.0)  # ... and pulled toward grey this many times as readily as a dark pixel's colour
_TINT_LIT = 0.05  # tint_range: the normals a light gives at least this share of its brightest irradiance
SKIN_CHROMA = 0.5  # shaded_skin: skin a new light darkens by r keeps its chroma x r**this (a grey dimming: x r)
_SKIN_SIGMA = 1.5  # ... the skin's colour taken over this many network pixels


_SPHERE = sh.sphere_directions(1024).astype(np.float32)  # tint_range's normals
_LAB_TABLES: threading.Thread | None = None  # OpenCV's Lab tables, built beside the photo's first stages
_LAB_LOCK = threading.Lock()


def _build_lab_tables() -> None:
    cv2.cvtColor(np.zeros((1, 1, 3), np.float32), cv2.COLOR_RGB2Lab)


def prepare_lab() -> None:
    """Have OpenCV build its Lab tables (``dark_colour`` needs them once per process; the first conversion spends
    ~0.12 s CPU building them, a tenth of a cold 1-MP ``relight``) on a thread of its own, while the photo is read,
    matted and decomposed: not a run on dummy data, the tables every photo's relight uses. Idempotent; ``dark_colour``
    waits for it before its own first conversion."""
    global _LAB_TABLES
    with _LAB_LOCK:
        if _LAB_TABLES is None:
            # not a daemon: the interpreter waits for it at exit (a tenth of a second at most), where a daemon
            # thread stopped inside OpenCV aborts the process ("terminate called without an active exception")
            _LAB_TABLES = threading.Thread(target=_build_lab_tables, name="relight_rt-lab-tables")
            _LAB_TABLES.start()


def _lab(image: np.ndarray) -> np.ndarray:
    """cv2's RGB -> Lab, after the tables ``prepare_lab`` may be building (one builder at a time)."""
    tables = _LAB_TABLES
    if tables is not None:
        tables.join()
    return cv2.cvtColor(image, cv2.COLOR_RGB2Lab)


def tint_range(light: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Per channel, the lowest and highest colour (luminance 1) that ``light`` gives an unoccluded diffuse
    surface, over the normals it lights at least _TINT_LIT of its brightest; None for a light that lights
    nothing. Light reaching a pixel is a positive mix of the light's directions, so its colour stays about within
    this range; a learned transport can leave one channel's shading at 0 where another's is not (the ringing of a
    warm sun and a blue sky: the reference photo's dark scarf went saturated blue under golden-hour)."""
    e = sh.irradiance(light, _SPHERE)
    y = e @ REC709
    top = float(y.max())
    if top <= 1e-6:
        return None
    keep = y >= _TINT_LIT * top
    t = e[keep] / y[keep, None]
    return t.min(0).astype(np.float32), t.max(0).astype(np.float32)


def shaded_skin(factor: np.ndarray, ratio: np.ndarray, chroma: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """The relighting factor (h, w, 3) with skin that the new light darkens keeping more of its colour.

    Scaling a pixel by r at one chromaticity scales its chroma with it (Lab C* ~ L*^0.85 for skin colours): a
    face's shaded side turns grey-brown. Real skin does not: over the skin of ten real photos' faces (DPR's
    portrait, Grace Hopper, the astronaut, the reference photo, ...), from the darkest fifth of the face's
    lightness to the middle one, C* ~ L*^0.33 at the median (-0.1 to 0.8; docs/RESULTS.md): light scattered
    inside skin and between its folds comes out redder where the direct light is weak (DPR, which keeps a* and
    b*, looks alive there for that reason). So where the skin ``weight`` is positive and the luminance ratio
    ``ratio`` is below 1, the white-light relit colour r P = r Y + r (P - Y) becomes r Y + r**SKIN_CHROMA (P - Y)
    (Y the photo's luminance: the luminance stays, the chroma falls more slowly; 0.5 gives C* ~ L*^0.3), folded
    into ``factor`` as a per-channel gain (from the skin's local ``chroma`` (P - Y) / P, between 1/4 and 4) and
    blended by the weight (both from ``skin_chroma``). Where the light brightens the skin, and off the skin,
    ``factor`` is unchanged; r = 1 (the photo's own light) gives 1.
    """
    boost = np.clip(ratio, 1e-4, 1.0)[..., None] ** (SKIN_CHROMA - 1.0) - 1.0  # 0 where the light brightens
    gain = np.clip(1.0 + boost * chroma, 0.25, 4.0)  # (r Y + r**g (P - Y)) / (r P)
    return (factor * (1 + weight[..., None] * (gain - 1))).astype(np.float32)


def skin_chroma(photo: np.ndarray, skin: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``shaded_skin``'s inputs that do not depend on the light: (P - Y) / P per channel of the skin's local
    colour (h, w, 3, in [-1, 1]) and the skin weight (h, w, in [0, 1]). The colour is the skin's, not its texture
    (a normalised blur over the skin), so the gain stays smooth and a pixel with one channel near 0 (lips, a red
    scarf the skin map touches) cannot swing it. The studio's preview takes the same two (relight_rt.apps.studio)."""
    weight = np.clip(skin, 0, 1).astype(np.float32)
    colour = cv2.GaussianBlur(np.asarray(photo, np.float32) * weight[..., None], (0, 0), _SKIN_SIGMA)
    colour /= np.maximum(cv2.GaussianBlur(weight, (0, 0), _SKIN_SIGMA), 1e-6)[..., None]
    y = (colour @ REC709)[..., None]
    chroma = np.clip((colour - y) / np.maximum(colour, 1e-3), -1.0, 1.0).astype(np.float32)
    # stage 1's skin map is blurry and gives clothes up to ~0.5 (a coat, a striped top): the rule is for skin, so
    # the weight also asks for a skin colour (YCrCb: Cr 135-180, Cb 85-135, soft over 8 levels; Chai & Ngan 1999)
    ycc = cv2.cvtColor(np.clip(colour, 0, 1).astype(np.float32), cv2.COLOR_RGB2YCrCb) * 255
    cr, cb = ycc[..., 1], ycc[..., 2]
    ramp = lambda v, lo, hi: np.clip(np.minimum(v - lo, hi - v) / 8 + 0.5, 0, 1)  # noqa: E731
    return chroma, (weight * ramp(cr, 135, 180) * ramp(cb, 85, 135)).astype(np.float32)


def shoulder(colour: np.ndarray, knee: np.ndarray) -> np.ndarray:
    """Bring colours made brighter than 1 back into [0, 1] as film does, in place: a smooth shoulder.

    The brightest channel m of a pixel is rolled off above a knee q, m -> q + (1 - q)(1 - exp(-(m - q)/(1 - q)))
    (slope 1 at q, approaching 1; relight_rt.light.exposure ``rolled_off``, the one curve: "auto" meters what it
    takes, ``shoulder_gain``), and the three channels are scaled together, so a brightly lit side keeps
    its hue and its gradation (a per-channel clip turns skin yellow; a plain rescale of the peak to 1 flattens
    it). The knee (``knee``) is the photo's own peak, at least 0.8: a pixel no brighter than it was in the
    photo is untouched, so the photo's own light gives the photo back.
    """
    peak = channel_max(colour)
    over = peak > knee
    if over.any():
        m = peak[over]
        colour[over] *= (rolled_off(m, knee[over]) / m)[:, None]
    return colour


def dark_colour(image: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What ``steady_chroma`` needs of a photo whatever the light: its luminance (h, w), how far a gain may pull its
    colour (h, w: its darkness 1 - Y / _DARK clipped to [0, 1], or ``_NEUTRAL_PULL`` x its near-blackness where
    larger: a near-black pixel is pulled fully from a gain of 2, not 3), and the colour
    it is pulled toward per unit of luminance (h, w, 3): its dark pixels' (Y < _DARK) within ``_CHROMA_RADIUS``,
    moved toward grey by its near-blackness.

    Near-black: 1 where the photo's CIE Lab L*, chroma C* and a* (on the photo reduced ``_NEUTRAL_STEP`` times: a
    cloth's cast is shared by its pixels) are below ``_NEUTRAL_L[0]``, ``_NEUTRAL_C[0]`` and ``_NEUTRAL_A[0]``, 0
    from ``_NEUTRAL_L[1]``, ``_NEUTRAL_C[1]`` or ``_NEUTRAL_A[1]`` up, linear between; a cast too faint for the a*
    gate counts by its direction, -a* / C* from ``_NEUTRAL_HUE[0]`` (none) to ``_NEUTRAL_HUE[1]`` (all): grey cloth
    at levels (22, 24, 22), a* -1.3 and C* 1.6, went past a* -8 under a side lamp that brightened it 4-5x (grey
    near-black pixels turned teal over 52 real photos, worst 0.61 % -> 0.33 %). Only a green-cyan cast
    (what a light turns teal): without that gate the deep shade of blue jeans ((6, 9, 14), a* 0) and shaded dark
    skin (warm, C* 8-12 at L* < 30) went grey on the bundled example under studio (up to 33 levels). Dark pixels
    whose neighbours agree on a green-cyan cast keep it under the neighbours' rule, and a light that brightens them
    2-4x shows it, a warm light as green (the factor carries the light's colour only: cyan less blue); pulled toward
    grey, they take the light's colour instead. Where the cast is the photo's grade (a teal-graded photo: 21 % of
    its grey near-black pixels past a* -8 under rim without this rule, 0.3 % with it) or a green backdrop's spill
    in dark hair (3.7 % -> 0.4 % under window-left), that is right; where it is the cloth's own colour, the folds
    of a dark teal shirt ((0.04, 0.10, 0.12), C* ~6 at L* ~8, green where lit), it is not: the pulled folds turn
    brown-olive beside the green ones under campfire (docs/RESULTS.md, "Real photos, broad sets").
    """
    y = cv2.transform(image, REC709.reshape(1, 3))  # (h, w): one output channel
    dark = (y < _DARK).astype(np.float32)
    size = (2 * _CHROMA_RADIUS + 1,) * 2
    colour = cv2.boxFilter(image * dark[..., None], -1, size)
    colour /= np.maximum(cv2.boxFilter(y * dark, -1, size), 1e-4)[..., None]
    h, w = y.shape
    small = cv2.resize(np.clip(image, 0, 1), (max(w // _NEUTRAL_STEP, 1), max(h // _NEUTRAL_STEP, 1)),
                       interpolation=cv2.INTER_AREA)
    lab = _lab(small)
    ramp = lambda v, lo, hi: np.clip((hi - v) / (hi - lo), 0, 1)  # noqa: E731 - 1 below lo, 0 above hi
    chroma = np.hypot(lab[..., 1], lab[..., 2])
    black = ramp(lab[..., 0], *_NEUTRAL_L) * ramp(chroma, *_NEUTRAL_C)
    # a green-cyan cast only: what a brightening light turns teal; a faint one by its direction (a* small because C*
    # is: grey cloth at levels (22, 24, 22), a* -1.3, went past a* -8 under a side lamp's 4-5x)
    hue = -lab[..., 1] / np.maximum(chroma, 1e-3)
    black *= np.maximum(ramp(lab[..., 1], *_NEUTRAL_A), ramp(-hue, -_NEUTRAL_HUE[1], -_NEUTRAL_HUE[0]))
    darkness = np.clip(1 - y / _DARK, 0, 1)
    if not black.any():  # most photos: nothing near-black with a cast
        return y, darkness, colour
    black = cv2.resize(black, (w, h), interpolation=cv2.INTER_LINEAR)
    near = black > 0
    b = black[near][:, None]
    colour[near] += b * (1 - colour[near])  # toward grey: luminance 1 per unit of luminance
    darkness[near] = np.maximum(darkness[near], _NEUTRAL_PULL * b[:, 0])
    return y, darkness, colour


def steady_chroma(image: np.ndarray, gain: np.ndarray, dark: tuple | None = None) -> np.ndarray:
    """``image`` x ``gain`` (both (h, w, 3)), where a strong gain brightens a dark pixel whose colour is not its
    neighbours', that colour pulled toward theirs first.

    A dark pixel's colour is easily its compression's error: JPEG keeps colour at half resolution, so along a lit
    jaw the dark hair beside it carries the skin's chroma or an overshoot of it ((0.13, 0.04, 0.00), (0.04, 0.00,
    0.00) on the reference photo); relit by a side lamp that brightens it 4-5x, that became a red and blue fringe.
    The colour the dark pixels around it (luminance below ``_DARK``, within ``_CHROMA_RADIUS``) have on average,
    at the pixel's own luminance, is what it is pulled toward, by w = (1 - Y / _DARK) x min((g - 1) /
    _AMPLIFIED, 1) (Y the pixel's luminance, g the gain's): a dark cloth whose pixels agree keeps its colour (the
    held-out renders' RMSE is unchanged or lower), a pixel not brightened or bright enough for its colour to be
    signal is untouched, and the gain's own colour (the new light's) stays. A near-black pixel is pulled the same
    way toward grey at its luminance (``dark_colour``: a faint cast no one sees, amplified, became teal). ``dark``:
    ``dark_colour(image)``, computed here when not given (it does not depend on the light: the runtime keeps it per
    photo).
    """
    g = cv2.transform(gain, REC709.reshape(1, 3))
    y, darkness, colour = dark_colour(image) if dark is None else dark
    w = np.minimum(darkness * np.clip((g - 1) / _AMPLIFIED, 0, 1), 1)  # darkness: up to _NEUTRAL_PULL
    if not w.any():
        return image * gain
    return (image * (1 - w)[..., None] + colour * (w * y)[..., None]) * gain

