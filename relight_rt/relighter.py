"""The Relighter: decompose a photo of a person, relight it, and put it back at full resolution.

Pipeline (DESIGN.md §1, §4, §5)::

    photo + mask ─► crop/pad/resize (CropGeometry) ─► stage 1 ─► albedo, skin, transport, light
    new light L' ─► diffuse D = clip(albedo ⊙ max(0, T·L'), 0, 1) ─► stage 2 ─► relit (network frame)
    relit ─► back to the input's size and position ─► composited over the background

Full-resolution detail (the default): the network's relit image is not simply upsampled, because on real
photos its colours are stage 1's guess (an albedo that may be green for fair skin, a light estimate whose colour
cast is wrong) and its resolution is the network's. Instead the photo itself is relit by a factor:

    colour = F ⊙ up(c' · max(Y(A ⊙ S' + r'), ε) / max(Y(A ⊙ Ŝ + r̂), ε))

The luminance Y of the pipeline's image under the new light (albedo A times the shading S' = max(0, T·L'),
plus stage 2's residual r'), over its luminance under the photo's own light (Ŝ = max(0, T·l̂), l̂ the
luminance of stage 1's estimate taken as white: cameras white-balance their photos), both unclipped, ε = 0.01;
T is stage 1's transport with its degree-1 and degree-2 bands scaled back up by the shrinkage measured against
true transports (relight_rt._strength: a regressed transport makes every light look softer than it is), then
moved along the photo's own light half-way toward the shading the photo shows (``explain_photo``: what the
regression blurred away of the photo's own shading stays as far as a new light resembles the photo's);
and c' = S' / Y(S'), the colour of the new light arriving at that pixel (luminance 1). So the brightness change
is the whole pipeline's (stage 2's shadows and highlights included), its colour is the new light's alone, and
neither the albedo's colour nor an error in the estimated light's colour can tint the skin: under a white
light the photo keeps its colours. Skin that the new light darkens keeps more of its chroma than a grey dimming
would leave it, as real shaded skin does (``_shaded_skin``). F is the person's own colour (``_foreground``: at a
soft matte's edge, the photo without what lies behind). The factor is upsampled edge-aware with a fast guided
filter (He & Sun 2015: the local linear model g ≈ a·I + b is fitted at network resolution on the gray input, and
a, b are upsampled and applied with the full-resolution gray input I), so the input's own high-frequency detail
survives. Colours
made brighter than the photo's own peak are rolled off by a smooth shoulder on the brightest channel, all
three channels scaled together (a bright lit side keeps its hue and its gradation; a per-channel clip would
turn it yellow, a hard clip flat). Relighting with the photo's own light gives the input back. A face that
stage 1 saw small gets a second pass (relight_rt._face). (``cv2.ximgproc.guidedFilter`` at full resolution
gives the same kind of result but costs ~0.6 s per 2-megapixel crop with a colour guide; this costs ~30 ms.)
With ``detail=False`` the network's relit image is upsampled as it is.

Without ``stage2.onnx`` the output is the diffuse image only: ``Relighter.diffuse_only`` is True, a
warning is logged at load, and ``RelightResult.diffuse_only`` says so.
"""

from __future__ import annotations

import importlib.util
import logging
import os
import threading
import warnings
import weakref
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, fields, replace
from pathlib import Path

import cv2
import numpy as np

from . import exposure as _exposure
from . import sh
from ._chain import DeviceChain
from ._detail import extend_outward, guided_upsample, unpremultiply, window
from ._errors import RelightError
from ._face import feather, head_box
from ._face_geometry import MIN_FACE_NET, FaceMesh, face_transport
from ._geometry import CropGeometry
from ._io import read_image, sibling_mask
from ._strength import explain_photo, face_refit, refit_light, restore_bands
from .compositing import Background, clean_edge_colour, over_box, parse_background
from .config import RuntimeConfig
from .contract import kind_spec
from .foreground import estimate_foreground, nearest_colours
from .lightspec import LightSpec
from .masks import Matter, resolve_mask
from .session import Model, check_finite, find_models, load_model

log = logging.getLogger(__name__)

ImageLike = str | os.PathLike | np.ndarray
_RATIO_EPS = np.float32(0.01)  # the ratio's denominator is floored here (dark pixels: noise, not light)
_OWN_FLOOR = np.float32(0.5)  # light the model misses, up to this share of the photo, stays under a new light (_own)
_ALPHA_MIN = np.float32(1e-3)
_DARK = np.float32(0.25)  # _steady_chroma: a pixel below this luminance, brightened by a gain, takes its dark
_AMPLIFIED = np.float32(2.0)  # ... neighbours' colour, fully from a gain of 1 + this,
_CHROMA_RADIUS = 4  # ... those within this many pixels (the constants: the reference photo's jaw, module tests)
_NEUTRAL_L = (30.0, 40.0)  # _dark_colour: a pixel of Lab L* below the first is dark, from the second not ...
_NEUTRAL_C = (6.0, 12.0)  # ... and near-black when its Lab chroma C* is below the first, from the second not,
_NEUTRAL_A = (-4.0, -1.0)  # ... with a green-cyan cast: a* below the first, none from the second up
_NEUTRAL_STEP = 4  # ... measured on the photo reduced this many times (a cloth's cast is shared by its pixels)
_NEUTRAL_PULL = np.float32(2.0)  # ... and pulled toward grey this many times as readily as a dark pixel's colour
_SOFT = 1.0 / 255  # a matte value further than this from 0 and 1 is a soft edge (mixes person and background)
_THIN_EDGE = 4.0  # px: a soft edge no wider than this on average is feathering or anti-aliasing (F/B from beside it)
_SHADING_MIN = np.float32(1e-3)  # full-resolution albedo: photo / shading, shading floored here
_SHADING_TRUST = np.float32(0.1)  # ... and trusted fully from this shading up (blended into the network's below)
_TINT_LIT = 0.05  # _tint_range: the normals a light gives at least this share of its brightest irradiance
_SKIN_CHROMA = 0.5  # _shaded_skin: skin a new light darkens by r keeps its chroma x r**this (a grey dimming: x r)
_SKIN_SIGMA = 1.5  # ... the skin's colour taken over this many network pixels
_MAX_PEOPLE = 16  # matting="all": a photo of more people than this is relit as one group (memory: a mask each)


_SPHERE = sh.sphere_directions(1024).astype(np.float32)  # _tint_range's normals


def _tint_range(light: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Per channel, the lowest and highest colour (luminance 1) that ``light`` gives an unoccluded diffuse
    surface, over the normals it lights at least _TINT_LIT of its brightest; None for a light that lights
    nothing. Light reaching a pixel is a positive mix of the light's directions, so its colour stays about within
    this range; a learned transport can leave one channel's shading at 0 where another's is not (the ringing of a
    warm sun and a blue sky: the reference photo's dark scarf went saturated blue under golden-hour)."""
    e = sh.irradiance(light, _SPHERE)
    y = e @ _exposure.REC709
    top = float(y.max())
    if top <= 1e-6:
        return None
    keep = y >= _TINT_LIT * top
    t = e[keep] / y[keep, None]
    return t.min(0).astype(np.float32), t.max(0).astype(np.float32)


def _shaded_skin(factor: np.ndarray, ratio: np.ndarray, chroma: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """The relighting factor (h, w, 3) with skin that the new light darkens keeping more of its colour.

    Scaling a pixel by r at one chromaticity scales its chroma with it (Lab C* ~ L*^0.85 for skin colours): a
    face's shaded side turns grey-brown. Real skin does not: over the skin of ten real photos' faces (DPR's
    portrait, Grace Hopper, the astronaut, the reference photo, ...), from the darkest fifth of the face's
    lightness to the middle one, C* ~ L*^0.33 at the median (-0.1 to 0.8; docs/RESULTS.md): light scattered
    inside skin and between its folds comes out redder where the direct light is weak (DPR, which keeps a* and
    b*, looks alive there for that reason). So where the skin ``weight`` is positive and the luminance ratio
    ``ratio`` is below 1, the white-light relit colour r P = r Y + r (P - Y) becomes r Y + r**_SKIN_CHROMA (P - Y)
    (Y the photo's luminance: the luminance stays, the chroma falls more slowly; 0.5 gives C* ~ L*^0.3), folded
    into ``factor`` as a per-channel gain (from the skin's local ``chroma`` (P - Y) / P, between 1/4 and 4) and
    blended by the weight (both from ``_skin_chroma``). Where the light brightens the skin, and off the skin,
    ``factor`` is unchanged; r = 1 (the photo's own light) gives 1.
    """
    boost = np.clip(ratio, 1e-4, 1.0)[..., None] ** (_SKIN_CHROMA - 1.0) - 1.0  # 0 where the light brightens
    gain = np.clip(1.0 + boost * chroma, 0.25, 4.0)  # (r Y + r**g (P - Y)) / (r P)
    return (factor * (1 + weight[..., None] * (gain - 1))).astype(np.float32)


def _skin_chroma(photo: np.ndarray, skin: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``_shaded_skin``'s inputs that do not depend on the light: (P - Y) / P per channel of the skin's local
    colour (h, w, 3, in [-1, 1]) and the skin weight (h, w, in [0, 1]). The colour is the skin's, not its texture
    (a normalised blur over the skin), so the gain stays smooth and a pixel with one channel near 0 (lips, a red
    scarf the skin map touches) cannot swing it. The studio's preview takes the same two (relight_rt.studio)."""
    weight = np.clip(skin, 0, 1).astype(np.float32)
    colour = cv2.GaussianBlur(np.asarray(photo, np.float32) * weight[..., None], (0, 0), _SKIN_SIGMA)
    colour /= np.maximum(cv2.GaussianBlur(weight, (0, 0), _SKIN_SIGMA), 1e-6)[..., None]
    y = (colour @ _exposure.REC709)[..., None]
    chroma = np.clip((colour - y) / np.maximum(colour, 1e-3), -1.0, 1.0).astype(np.float32)
    # stage 1's skin map is blurry and gives clothes up to ~0.5 (a coat, a striped top): the rule is for skin, so
    # the weight also asks for a skin colour (YCrCb: Cr 135-180, Cb 85-135, soft over 8 levels; Chai & Ngan 1999)
    ycc = cv2.cvtColor(np.clip(colour, 0, 1).astype(np.float32), cv2.COLOR_RGB2YCrCb) * 255
    cr, cb = ycc[..., 1], ycc[..., 2]
    ramp = lambda v, lo, hi: np.clip(np.minimum(v - lo, hi - v) / 8 + 0.5, 0, 1)  # noqa: E731
    return chroma, (weight * ramp(cr, 135, 180) * ramp(cb, 85, 135)).astype(np.float32)


def _float32_light(light, name: str) -> np.ndarray:
    """A checked (9, 3) light in float32, the dtype it is used in (too large or non-finite there: RelightError)."""
    arr = sh.check_light(light, name).astype(np.float32)
    if not np.isfinite(arr).all():
        raise RelightError(f"{name}: SH light overflows float32 (|value| must be <= {sh.MAX_COEFF:g})")
    return arr


def _luminance_window(chw: np.ndarray, alpha: np.ndarray, box: tuple[int, int, int, int]) -> np.ndarray:
    """(r, r') Rec. 709 luminance of a masked (3, R, R) network output inside ``box``, unpremultiplied."""
    y0, y1, x0, x1 = box
    lum = np.tensordot(_exposure.REC709, chw[:, y0:y1, x0:x1], axes=1)
    return np.divide(lum, alpha, out=np.zeros_like(lum), where=alpha > 0.5)


def _channel_max(rgb: np.ndarray) -> np.ndarray:
    """(H, W) the brightest of the three channels (two elementwise maxima: ~10x faster than max(axis=2))."""
    return np.maximum(np.maximum(rgb[..., 0], rgb[..., 1]), rgb[..., 2])


def _knee(photo: np.ndarray) -> np.ndarray:
    """(H, W) where the highlight shoulder starts for each pixel: the photo's own peak, within [0.8, 0.999]."""
    return np.clip(_channel_max(photo), 0.8, 0.999)


def _shoulder(colour: np.ndarray, knee: np.ndarray) -> np.ndarray:
    """Bring colours made brighter than 1 back into [0, 1] as film does, in place: a smooth shoulder.

    The brightest channel m of a pixel is rolled off above a knee q, m -> q + (1 - q)(1 - exp(-(m - q)/(1 - q)))
    (slope 1 at q, approaching 1), and the three channels are scaled together, so a brightly lit side keeps
    its hue and its gradation (a per-channel clip turns skin yellow; a plain rescale of the peak to 1 flattens
    it). The knee (``_knee``) is the photo's own peak, at least 0.8: a pixel no brighter than it was in the
    photo is untouched, so the photo's own light gives the photo back.
    """
    peak = _channel_max(colour)
    over = peak > knee
    if over.any():
        m, q = peak[over], knee[over]
        rolled = q + (1 - q) * -np.expm1(-(m - q) / (1 - q))
        colour[over] *= (rolled / m)[:, None]
    return colour


def _dark_colour(image: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What ``_steady_chroma`` needs of a photo whatever the light: its luminance (h, w), how far a gain may pull its
    colour (h, w: its darkness 1 - Y / _DARK clipped to [0, 1], or ``_NEUTRAL_PULL`` x its near-blackness where
    larger: a near-black pixel is pulled fully from a gain of 2, not 3), and the colour
    it is pulled toward per unit of luminance (h, w, 3): its dark pixels' (Y < _DARK) within ``_CHROMA_RADIUS``,
    moved toward grey by its near-blackness.

    Near-black: 1 where the photo's CIE Lab L*, chroma C* and a* (on the photo reduced ``_NEUTRAL_STEP`` times: a
    cloth's cast is shared by its pixels) are below ``_NEUTRAL_L[0]``, ``_NEUTRAL_C[0]`` and ``_NEUTRAL_A[0]``, 0
    from ``_NEUTRAL_L[1]``, ``_NEUTRAL_C[1]`` or ``_NEUTRAL_A[1]`` up, linear between. Only a green-cyan cast
    (what a light turns teal): without that gate the deep shade of blue jeans ((6, 9, 14), a* 0) and shaded dark
    skin (warm, C* 8-12 at L* < 30) went grey on the bundled example under studio (up to 33 levels). A black
    jacket whose pixels agree on a faint cyan cast (0.04, 0.10, 0.12: C* ~6 at L* ~8) kept it under the neighbours'
    rule, and a light that brightened it 2-4x made it a visible teal (issue 48: on people photos up to 20 % of such
    pixels at a* < -8 under campfire, 48 % under front on a teal-graded photo); pulled toward grey, it takes the
    light's colour instead.
    """
    y = cv2.transform(image, _exposure.REC709.reshape(1, 3))  # (h, w): one output channel
    dark = (y < _DARK).astype(np.float32)
    size = (2 * _CHROMA_RADIUS + 1,) * 2
    colour = cv2.boxFilter(image * dark[..., None], -1, size)
    colour /= np.maximum(cv2.boxFilter(y * dark, -1, size), 1e-4)[..., None]
    h, w = y.shape
    small = cv2.resize(np.clip(image, 0, 1), (max(w // _NEUTRAL_STEP, 1), max(h // _NEUTRAL_STEP, 1)),
                       interpolation=cv2.INTER_AREA)
    lab = cv2.cvtColor(small, cv2.COLOR_RGB2Lab)
    ramp = lambda v, lo, hi: np.clip((hi - v) / (hi - lo), 0, 1)  # noqa: E731 - 1 below lo, 0 above hi
    black = ramp(lab[..., 0], *_NEUTRAL_L) * ramp(np.hypot(lab[..., 1], lab[..., 2]), *_NEUTRAL_C)
    black *= ramp(lab[..., 1], *_NEUTRAL_A)  # a green-cyan cast only: what a brightening light turns teal
    darkness = np.clip(1 - y / _DARK, 0, 1)
    if not black.any():  # most photos: nothing near-black with a cast
        return y, darkness, colour
    black = cv2.resize(black, (w, h), interpolation=cv2.INTER_LINEAR)
    near = black > 0
    b = black[near][:, None]
    colour[near] += b * (1 - colour[near])  # toward grey: luminance 1 per unit of luminance
    darkness[near] = np.maximum(darkness[near], _NEUTRAL_PULL * b[:, 0])
    return y, darkness, colour


def _steady_chroma(image: np.ndarray, gain: np.ndarray, dark: tuple | None = None) -> np.ndarray:
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
    way toward grey at its luminance (``_dark_colour``: a faint cast no one sees, amplified, became teal). ``dark``:
    ``_dark_colour(image)``, computed here when not given (it does not depend on the light: the runtime keeps it per
    photo).
    """
    g = cv2.transform(gain, _exposure.REC709.reshape(1, 3))
    y, darkness, colour = _dark_colour(image) if dark is None else dark
    w = np.minimum(darkness * np.clip((g - 1) / _AMPLIFIED, 0, 1), 1)  # darkness: up to _NEUTRAL_PULL
    if not w.any():
        return image * gain
    return (image * (1 - w)[..., None] + colour * (w * y)[..., None]) * gain


def _consistent(image: np.ndarray, alpha: np.ndarray, fg: np.ndarray, bg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Foreground and background colours adjusted so that alpha F + (1 - alpha) B is the photo again, in place.

    The estimate minimises that equation's error among smoothness terms, so it does not hold exactly; here, on
    the soft pixels, B is solved from it (kept in [0, 1]) and then F from B, so that composing them over each
    other gives the photo back (to rounding) wherever that is possible in [0, 1].
    """
    soft = (alpha > _SOFT) & (alpha < 1 - _SOFT)
    a = alpha[soft][:, None]
    i, f = image[soft], fg[soft]
    b = np.clip((i - a * f) / (1 - a), 0, 1)
    bg[soft] = b
    fg[soft] = np.clip((i - (1 - a) * b) / a, 0, 1)
    background, person = alpha <= _SOFT, alpha >= 1 - _SOFT  # exactly the photo where it is not mixed
    bg[background] = image[background]
    fg[person] = image[person]
    return fg, bg


def _soft_edge_width(alpha: np.ndarray) -> float:
    """Mean width in pixels of a matte's soft edge: its soft pixels over the length of its outline."""
    soft = int(np.count_nonzero((alpha > _SOFT) & (alpha < 1 - _SOFT)))
    if soft == 0:
        return 0.0
    inside = (alpha > 0.5).astype(np.uint8)
    outline = int(np.count_nonzero(inside - cv2.erode(inside, np.ones((3, 3), np.uint8))))
    return soft / max(outline, 1)


def _readonly(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


class _Parts:
    """A Matter that keeps each person's share of the matte it returns (``PersonMatter.parts``): a group photo,
    relit person by person (``Relighter._by_person``)."""

    def __init__(self, matter):
        self.matter, self.found = matter, None

    def __call__(self, rgb: np.ndarray, name: str = "image") -> np.ndarray:
        alpha, self.found = self.matter.parts(rgb, name)
        return alpha


@dataclass(frozen=True, eq=False)
class Decomposition:
    """Stage 1's answer for one photo, with what is needed to put results back into the photo: plain data.

    Only arrays and the crop geometry: a Decomposition pickles (to another process, a Ray worker) and
    holds no session or device memory; a Relighter keeps whatever it prepares for one (device copies, the
    reconstruction) on its own side, keyed to it. Network-frame arrays are R x R views of the
    crop/pad/resize square (see ``geometry``); input-frame arrays have the photo's (H, W). All arrays are
    float32 and read-only; colours are RGB.

    Attributes:
        albedo_chw: (3, R, R) albedo in [0, 1], masked (``albedo`` is the (R, R, 3) view).
        skin: (R, R) skin probability in [0, 1], masked.
        transport_chw: (9, R, R) SH light transport (DESIGN.md §3 order), masked (``transport``: (R, R, 9)).
        light: (9, 3) the photo's estimated SH light, RGB columns: stage 1's estimate, for a photo refit so
            that albedo x shading explains it (relight_rt._strength ``refit_light``; a video frame keeps
            stage 1's). Relighting with it gives the photo back.
        network_mask: (R, R) the mask in the network frame, in [0, 1].
        network_image: (R, R, 3) the input photo in the network frame (what stage 1 saw, before masking).
        mask: (H, W) the person mask in the input frame, in [0, 1].
        image: (H, W, 3) the input photo, RGB in [0, 1].
        geometry: the CropGeometry mapping network pixels to input pixels.
    """

    albedo_chw: np.ndarray
    skin: np.ndarray
    transport_chw: np.ndarray
    light: np.ndarray
    network_mask: np.ndarray
    network_image: np.ndarray
    mask: np.ndarray
    image: np.ndarray
    geometry: CropGeometry

    def __post_init__(self) -> None:
        put = lambda name, value: object.__setattr__(self, name, _readonly(value))  # noqa: E731
        for name in ("albedo_chw", "transport_chw", "skin", "network_mask", "network_image"):
            put(name, np.ascontiguousarray(getattr(self, name), dtype=np.float32))
        put("light", np.array(self.light, dtype=np.float32))
        put("mask", np.asarray(self.mask, dtype=np.float32))
        put("image", np.asarray(self.image, dtype=np.float32))

    def __reduce__(self):  # unpickled through the constructor, so the arrays come back read-only
        return (type(self), tuple(getattr(self, f.name) for f in fields(self)))

    @property
    def albedo(self) -> np.ndarray:
        """(R, R, 3) albedo, RGB in [0, 1] (a view)."""
        return self.albedo_chw.transpose(1, 2, 0)

    @property
    def transport(self) -> np.ndarray:
        """(R, R, 9) light transport (a view)."""
        return self.transport_chw.transpose(1, 2, 0)

    @property
    def resolution(self) -> int:
        """R, the network's square size."""
        return self.geometry.resolution

    @property
    def white_light(self) -> np.ndarray:
        """(9, 3) the photo's own light taken as white: each colour column is the Rec. 709 luminance of ``light``.

        The runtime divides by the shading under this light (a white-balanced photo's colours are its
        albedo's), so an error in the estimate's colour cannot tint the result.
        """
        lum = self.light.astype(np.float64) @ _exposure.REC709.astype(np.float64)
        return np.repeat(lum[:, None], 3, axis=1).astype(np.float32)

    def shading(self, light: np.ndarray | None = None) -> np.ndarray:
        """(R, R, 3) float32 shading max(0, T·L) under ``light`` (default: the photo's own light, white)."""
        return sh.shading(self.transport, self.white_light if light is None else light)

    def to_input(self, layer: np.ndarray) -> np.ndarray:
        """Map a network-frame layer (R, R[, C]) to the input frame (H, W[, C]), zero outside the crop."""
        return self.geometry.to_input(layer)

    def __repr__(self) -> str:
        h, w = self.geometry.frame
        return f"Decomposition(input {h}x{w}, box {self.geometry.box}, resolution {self.resolution})"


@dataclass(frozen=True)
class RelightResult:
    """What ``relight_layers`` returns: the relit photo and the layers that made it.

    Attributes:
        image: (H, W, 3) RGB or (H, W, 4) RGBA float32 in [0, 1], the relit photo.
        layers: input-frame float32 layers: "albedo" (H, W, 3), "shading" (H, W, 3, not clipped),
            "diffuse" (H, W, 3), "residual" (H, W, 3, zero when diffuse-only), "relit" (H, W, 3 network
            output, upsampled without detail transfer), "mask" (H, W).
        light: (9, 3) the light used, RGB.
        diffuse_only: True when no stage-2 model was available: no residual (specular etc.) was added.
    """

    image: np.ndarray
    layers: dict
    light: np.ndarray
    diffuse_only: bool


def diffuse_batch(albedo_chw: np.ndarray, transport_chw: np.ndarray, lights: np.ndarray) -> np.ndarray:
    """Diffuse images clip(albedo ⊙ max(0, T·L_k), 0, 1) for K lights at once, channel-first.

    ``sh.shading_chw`` with the albedo (the one shading formula, in blocks of pixels).

    Args:
        albedo_chw: (3, R, R) float32.
        transport_chw: (9, R, R) float32.
        lights: (K, 9, 3) float RGB lights.

    Returns:
        (K, 3, R, R) float32 in [0, 1], ready for stage 2.
    """
    return sh.shading_chw(transport_chw, lights, albedo_chw)


_LEGACY = object()  # a keyword of the old constructor that was not given


class Relighter:
    """Relight photos of people with the relight_rt ONNX models.

    ``Relighter(config)``: decompose a photo once (``decompose``), relight it under as many lights as wanted
    (``relight``, with its layers by ``layers=True``; ``relight_many`` / ``iter_relight`` for K lights in
    stage-2 batches), put it into a scene (``composite``).

    Args:
        config: a :class:`relight_rt.config.RuntimeConfig`: which models (folder with ``stage1.onnx`` and
            optionally ``stage2.onnx``, without which results are diffuse-only, and ``dvp.onnx``), the device,
            precision ("fp32"; "fp16" graphs ``stage1_fp16.onnx``, ... for CUDA; "int8" for CPU; a graph
            missing in that precision is taken in fp32, logged), preprocessing ("quality" or "reference", the
            reference's resize bit for bit), detail transfer, warm-up and automatic matting. None: the
            defaults (the bundled models, or $RELIGHT_RT_MODELS). Kept once, as ``self.config``.
        providers: explicit onnxruntime providers (win over the config's device).
        models, device, device_id, preprocess, detail, warmup, precision, matting: the old keyword constructor,
            ``Relighter(models, device=...)`` (``config`` then a models folder or None): deprecated, it warns
            and builds the same RuntimeConfig; removed in the next release.

    Raises:
        RelightError: no models found, a model file unreadable or breaking the contract, a bad setting.
    """

    def __init__(
        self, config: RuntimeConfig | str | os.PathLike | None = None, *, providers: list | None = None,
        models=_LEGACY, device=_LEGACY, device_id=_LEGACY, preprocess=_LEGACY, detail=_LEGACY, warmup=_LEGACY,
        precision=_LEGACY, matting=_LEGACY,
    ) -> None:  # fmt: skip
        legacy = {name: value for name, value in (
            ("device", device), ("device_id", device_id), ("preprocess", preprocess), ("detail", detail),
            ("warmup", warmup), ("precision", precision), ("matting", matting)) if value is not _LEGACY}
        if models is not _LEGACY:  # Relighter(models="folder", ...): the old keyword of the models folder
            if config is not None:
                raise RelightError("Relighter: give the models folder once (models= or the first argument)")
            config, legacy["models"] = models, models
        if isinstance(config, RuntimeConfig):
            if legacy:
                raise RelightError(f"Relighter: give {', '.join(legacy)} in the RuntimeConfig, not beside it")
        elif config is None and not legacy:
            config = RuntimeConfig()
        elif config is None or isinstance(config, (str, os.PathLike)):
            warnings.warn(
                "Relighter(models, device=..., ...) is deprecated and goes in the next release: use "
                "Relighter(RuntimeConfig(models=..., device=..., ...))", DeprecationWarning, stacklevel=2)
            if "detail" in legacy:
                legacy["detail"] = bool(legacy["detail"])
            legacy.pop("models", None)
            config = RuntimeConfig(models=config, **legacy)
        else:
            raise RelightError(f"Relighter: expected a RuntimeConfig (or None), got {type(config).__name__}")
        self.config = config
        self.models_dir = find_models(config.models)
        # a second stage-1 pass on a face seen small (relight_rt._face); photos only, with detail on
        self.face_pass = True
        self._session_args = {"device": config.device, "device_id": config.device_id, "providers": providers}
        self.stage1: Model = load_model(self._graph("stage1"), "stage1", warmup=False, **self._session_args)
        warmup = config.warmup
        if warmup is None:
            warmup = self.stage1.on_cuda
        if warmup:
            self.stage1.warm_up()
        self.stage2: Model | None = None
        stage2_path = self._graph("stage2")
        if stage2_path.is_file():
            self.stage2 = load_model(stage2_path, "stage2", warmup=warmup, **self._session_args)
            res2 = self.stage2.config.resolution
            if res2 not in (0, self.resolution):
                raise RelightError(
                    f"{stage2_path}: resolution {res2} does not match stage 1's {self.resolution} (or 0 for any size)"
                )
        else:
            log.warning("%s has no stage2.onnx: results are diffuse-only (no residual/specular)", self.models_dir)
        self._dvp: Model | None = None
        self._matter: Matter | None = None
        self._matter_loaded = False
        self._faces: FaceMesh | None = None  # face normals (relight_rt._face_geometry), loaded on first use
        self._chain = None  # CUDA: stage 1 → shading → stage 2 without host round trips
        if self.stage1.on_cuda and (self.stage2 is None or self.stage2.on_cuda):
            self._chain = DeviceChain(self.stage1, self.stage2, "cuda", config.device_id)
        # What this Relighter prepares for a Decomposition (device copies, reconstruction, window), kept
        # here rather than on the (plain-data) Decomposition, and dropped with it.
        self._state: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
        self._state_lock = threading.Lock()
        CropGeometry.from_mask(np.ones((1, 1), np.float32), self.resolution, config.preprocess)  # checks the mode

    @classmethod
    def from_config(cls, config: RuntimeConfig, providers: list | None = None) -> Relighter:
        """``Relighter(config, providers=providers)``."""
        if not isinstance(config, RuntimeConfig):
            raise RelightError(f"config: expected a RuntimeConfig, got {type(config).__name__}")
        return cls(config, providers=providers)

    # the settings, read from self.config (kept there once)
    @property
    def precision(self) -> str:
        """``self.config.precision``."""
        return self.config.precision

    @property
    def preprocess(self) -> str:
        """``self.config.preprocess``."""
        return self.config.preprocess

    @property
    def detail(self) -> bool:
        """``self.config.detail``."""
        return self.config.detail

    def _graph(self, kind: str) -> Path:
        """The file of ``kind`` in this Relighter's precision, falling back to fp32 (logged) when absent."""
        fp32 = self.models_dir / kind_spec(kind).filename
        if self.precision == "fp32":
            return fp32
        path = fp32.with_name(f"{fp32.stem}_{self.precision}{fp32.suffix}")
        if path.is_file() or not fp32.is_file():
            return path
        log.warning("%s: no %s, running %s in fp32", self.models_dir, path.name, kind)
        return fp32

    @property
    def resolution(self) -> int:
        """R, stage 1's square input size."""
        return self.stage1.config.resolution

    @property
    def diffuse_only(self) -> bool:
        """True when there is no stage-2 model: results lack the residual (specular, etc.)."""
        return self.stage2 is None

    @property
    def dvp(self) -> Model | None:
        """The deep-video-prior graph (``dvp.onnx`` in the models folder), loaded on first use; None if absent."""
        path = self.models_dir / kind_spec("dvp").filename
        if self._dvp is None and path.is_file():
            self._dvp = load_model(path, "dvp", warmup=False, **self._session_args)
        return self._dvp

    @property
    def matter(self) -> Matter | None:
        """The automatic person matte (relight_rt.matting), loaded on first use; None when off or not installed."""
        if not self._matter_loaded:
            self._matter_loaded = True
            if self.config.matting != "off" and importlib.util.find_spec(f"{__package__}.matting") is not None:
                from .matting import find_matting_models, shared_matter

                try:
                    find_matting_models()
                except RelightError as exc:  # the graphs are not installed: photos then need a mask or alpha
                    log.debug("no automatic matting: %s", exc)
                else:
                    person = "all" if self.config.matting == "all" else "largest"
                    self._matter = shared_matter(device=self.config.device, person=person)
        return self._matter

    def _prepared(self, dec: Decomposition) -> dict:
        """This Relighter's per-decomposition state (created on first use; freed with the Decomposition)."""
        with self._state_lock:
            state = self._state.get(dec)
            if state is None:
                state = self._state[dec] = {}
            return state

    # ------------------------------------------------------------------------------------ stage 1

    def decompose(self, image: ImageLike, mask: ImageLike | None = None) -> Decomposition:
        """Run stage 1 on a photo.

        Args:
            image: a path or an array (H, W, 3) RGB / (H, W, 4) RGBA, uint8 or float in [0, 1].
            mask: a path or an array (H, W), (H, W, 1) or (H, W, 3), binary or soft, same H x W as the
                image; ``"auto"``: the automatic matte; None: the image's alpha channel, else the automatic
                matte (relight_rt.masks.resolve_mask).

        Raises:
            RelightError: bad image or mask (see relight_rt._io.read_image / read_mask), no mask to be had.
        """
        return self.decompose_batch([image], [mask])[0]

    def decompose_batch(
        self, images: Sequence[ImageLike], masks: Sequence[ImageLike | None] | None = None, *,
        allow_full: bool = False,
    ) -> list[Decomposition]:
        """Run stage 1 on several photos in one batch (video frames, folders).

        Args:
            images: photos as for ``decompose`` (any sizes).
            masks: one per image (None entries: alpha, else the automatic matte); None: all None.
            allow_full: accept a mask that covers the whole image (a video frame filled by the person).

        Returns:
            One Decomposition per image, in order.
        """
        if masks is None:
            masks = [None] * len(images)
        if len(masks) != len(images):
            raise RelightError(f"masks: expected one per image ({len(images)}), got {len(masks)}")
        if not images:
            return []
        decs = self._stage1(images, masks, allow_full)
        people = [self._prepared(dec).pop("people", None) for dec in decs]
        if not allow_full:  # photos; video frames skip the work done once per photo (a second pass, the matte's
            for i, dec in enumerate(decs):  # foreground colours, the light's refit): per frame it would cost more
                self._prepared(dec)["photo"] = True  # than it shows
                self._prepared(dec)["faces"] = self.detail
                if self.detail:  # the photo's light, refit to the transport the relit photo is divided by
                    decs[i] = self._refit(dec)
            if self.detail and self.face_pass:
                self._look_at_faces(decs)
            for dec, masks_i in zip(decs, people, strict=True):
                if masks_i is not None:  # a group photo (matting="all"): each person decomposed on their own too
                    self._prepared(dec)["parts"] = tuple(self.decompose_batch([dec.image] * len(masks_i), masks_i))
        return decs

    def _look_at_faces(self, decs: list[Decomposition]) -> None:
        """Run stage 1 again on the head of each person whose face it saw small (relight_rt._face)."""
        todo = []
        for i, dec in enumerate(decs):
            box = head_box(dec.skin, dec.network_mask, dec.geometry)
            if box is not None:
                y0, y1, x0, x1 = box
                todo.append((i, dec, box, np.ascontiguousarray(dec.image[y0:y1, x0:x1]),
                             np.ascontiguousarray(dec.mask[y0:y1, x0:x1])))
        if not todo:
            return
        heads = self._stage1([t[3] for t in todo], [t[4] for t in todo], True)
        for (i, dec, box, _, _), head in zip(todo, heads, strict=True):
            # the head pass gives the face's transport; the photo's light is the body's estimate (one light for
            # one photo: the change of shading is measured from it in both passes, so the photo's own light
            # gives the photo back everywhere), turned by the face the head pass sees large (``_face_light``)
            self._prepared(head)["faces"] = True
            decs[i] = dec = self._face_light(dec, head)
            head = self._with_light(head, dec.light)
            self._prepared(dec)["head"] = (head, box)
            log.debug("second stage-1 pass on the head at %s", box)

    def _stage1(self, images: Sequence[ImageLike], masks: Sequence, allow_full: bool) -> list[Decomposition]:
        """Stage 1 on a batch: read, resolve masks, crop, run; one Decomposition per image."""
        rgbs, ms, geoms, people = [], [], [], []
        for i, (image, mask) in enumerate(zip(images, masks, strict=True)):
            name = str(image) if isinstance(image, (str, os.PathLike)) else f"image {i}" if len(images) > 1 else "image"
            # an array no one can write to (a Decomposition's photo: a group's people) is not copied
            img = read_image(image, "image", copy=not (isinstance(image, np.ndarray) and not image.flags.writeable))
            matter = self.matter if mask is None or isinstance(mask, str) else None
            if matter is not None and self.config.matting == "all" and not allow_full and hasattr(matter, "parts"):
                matter = _Parts(matter)  # a group photo: everyone's share of the matte kept (``_by_person``)
            m = resolve_mask(img, mask, matter=matter, allow_empty=allow_full, name=name)
            rgbs.append(np.ascontiguousarray(img[..., :3]) if img.shape[2] == 4 else img)
            ms.append(m)
            found = matter.found if isinstance(matter, _Parts) else None
            if found is not None and len(found) > _MAX_PEOPLE:
                log.info("%s: %d people found, relit as one group (person by person up to %d: each holds a mask "
                         "the size of the photo)", name, len(found), _MAX_PEOPLE)
                found = None
            people.append(found if found is not None and len(found) > 1 else None)
            geoms.append(CropGeometry.from_mask(m, self.resolution, self.preprocess))
        net_imgs = [g.to_network(rgb) for g, rgb in zip(geoms, rgbs, strict=True)]
        net_masks = [g.to_network(m) for g, m in zip(geoms, ms, strict=True)]
        on_device: list = [None] * len(images)
        if self._chain is not None:
            outs = []
            for i, (ni, nm) in enumerate(zip(net_imgs, net_masks, strict=True)):
                out, on_device[i] = self._chain.run_stage1(ni.transpose(2, 0, 1)[None], nm[None, None])
                check_finite(out, self.stage1.name)
                outs.append(out)
            out = {k: np.concatenate([o[k] for o in outs]) for k in outs[0]}
        else:
            out = self.stage1.run({"image": np.stack(net_imgs).transpose(0, 3, 1, 2),
                                   "mask": np.stack(net_masks)[:, None]})
        decs = []
        for i, geom in enumerate(geoms):
            light = out["light"][i]
            if not np.isfinite(light).all():
                raise RelightError(f"{self.stage1.name}: stage 1 estimated a non-finite light for this image")
            dec = Decomposition(out["albedo"][i], out["skin"][i, 0], out["transport"][i], light, net_masks[i],
                                net_imgs[i], ms[i], rgbs[i], geom)
            if on_device[i] is not None:
                self._prepared(dec)["device"] = on_device[i]
            if people[i] is not None:
                self._prepared(dec)["people"] = people[i]
            decs.append(dec)
        return decs

    # ------------------------------------------------------------------------------------ lights

    def _estimate_light(self, photo: Path, mask: str | None) -> np.ndarray:
        dec = self.decompose(photo, mask if mask is not None else sibling_mask(photo))
        return np.array(dec.white_light, np.float32)

    def resolve_light(self, light, dtype=np.float32) -> np.ndarray:
        """Any accepted light argument → (9, 3) RGB SH light: the one place where a light is resolved.

        Accepted: an array (9, 3); a ``Decomposition`` (its estimated light, taken as white as the photo's own
        light is: "light me like that photo");
        a :class:`relight_rt.lightspec.LightSpec`; a string or path, read by the one rule of
        relight_rt.lightspec (light file, environment map, photo of a person, or preset name). A photo's light
        is estimated by this Relighter's stage 1; every other source needs no model (``LightSpec.resolve``).

        Args:
            light: as above.
            dtype: float32 (default: the dtype the pipeline uses; a light too large for it is refused) or float64
                (a light schedule's keys, turned and interpolated before use).
        """
        if isinstance(light, Decomposition):
            return np.array(light.white_light, dtype=dtype)
        if np.dtype(dtype) not in (np.float32, np.float64):
            raise RelightError(f"dtype: expected float32 or float64, got {dtype!r}")
        lit = LightSpec.of(light).resolve(self._estimate_light, dtype=np.float64)
        return _float32_light(lit, "light") if np.dtype(dtype) == np.float32 else sh.check_light(lit, "light")

    def _resolve_lights(self, values) -> np.ndarray:
        """A (K, 9, 3) array, or a list of anything ``resolve_light`` accepts → (K, 9, 3) float32, K >= 1."""
        if isinstance(values, np.ndarray):
            if values.ndim != 3 or values.shape[1:] != (9, 3):
                raise RelightError(f"lights: expected (K, 9, 3) SH lights, got {values.shape} {values.dtype}")
        elif not isinstance(values, (list, tuple)):
            raise RelightError(f"lights: expected a (K, 9, 3) array or a list of lights, got {type(values).__name__}")
        if len(values) == 0:
            raise RelightError("lights: expected at least one light, got none")
        return np.stack([self.resolve_light(v) for v in values])

    # ------------------------------------------------------------------------------------ relight

    def _network_relit(
        self, dec: Decomposition, lights: np.ndarray, batch_size: int, want_layers: bool = True
    ) -> Iterator[tuple]:
        """Yield (diffuse, residual, relit), each (3, R, R) float32, per light, in batches.

        residual is None when diffuse-only; on CUDA diffuse and residual are None unless ``want_layers``.
        """
        net_mask = dec.network_mask[None, None]
        if self._chain is not None:
            yield from self._device_relit(dec, lights, batch_size, want_layers)
            return
        for start in range(0, lights.shape[0], batch_size):
            diffuse = diffuse_batch(dec.albedo_chw, dec.transport_chw, lights[start : start + batch_size])
            if not np.isfinite(diffuse).all():  # a NaN here is the light's or stage 1's, not stage 2's
                raise RelightError(f"light: shading under this light is not finite (stage 1: {self.stage1.name})")
            if self.stage2 is None:
                for d in diffuse:
                    yield d, None, d
                continue
            n = diffuse.shape[0]
            out = self.stage2.run({"diffuse": diffuse, "mask": np.broadcast_to(net_mask, (n,) + net_mask.shape[1:])})
            for i in range(n):
                yield diffuse[i], out["residual"][i], out["relit"][i]

    def _device_relit(self, dec: Decomposition, lights: np.ndarray, batch_size: int, want_layers: bool) -> Iterator:
        """``_network_relit`` on CUDA through the DeviceChain (stage-1 outputs stay on the device)."""
        chain = self._chain
        state = self._prepared(dec)
        if "device" not in state:  # a decomposition made elsewhere: upload its stage-1 outputs once
            state["device"] = {"albedo": chain.upload(dec.albedo_chw[None]),
                               "transport": chain.upload(dec.transport_chw[None])}
        for start in range(0, lights.shape[0], batch_size):
            batch = lights[start : start + batch_size]
            mask_key = ("device-mask", batch.shape[0])
            if mask_key not in state:
                shape = (batch.shape[0], 1) + dec.network_mask.shape
                state[mask_key] = chain.upload(np.broadcast_to(dec.network_mask, shape))
            for diffuse, residual, relit in chain.relit(state["device"], state[mask_key], batch, want_layers):
                check_finite({"relit": relit}, self.stage2.name if self.stage2 is not None else "shading")
                yield diffuse, residual, relit

    def _own_residual(self, dec: Decomposition) -> np.ndarray | None:
        """(3, R, R) stage 2's residual under the photo's own (white) light, cached; None when diffuse-only."""
        if self.stage2 is None:
            return None
        state = self._prepared(dec)
        if "own_residual" not in state:
            _, residual, _ = next(self._network_relit(dec, dec.white_light[None], 1, want_layers=True))
            state["own_residual"] = _readonly(np.array(residual, np.float32))
        return state["own_residual"]

    def _restored(self, dec: Decomposition) -> dict:
        """What the relighting factor needs that does not depend on any light, in the person's window (cached).

        "window" (y0, y1, x0, x1): the network pixels near the person (the whole square when the network's
        square is not smaller than the photo's: to_crop takes a window only when enlarging); "alpha", "inner"
        (alpha > 0.5); "transport" (r, r', 9) unpremultiplied, its directional bands restored
        (relight_rt._strength) and the face mesh's transport blended in, "albedo" luminance (r, r')
        unpremultiplied, "photo" (r, r') the luminance of the photo stage 1 saw, and "face_skin" (r, r') bool, the
        person's pixels well inside a face mesh (``_add_faces``; none without one).
        """
        state = self._prepared(dec)
        if "restored" not in state:
            geom = dec.geometry
            r = geom.resolution
            y0, y1, x0, x1 = window(dec.network_mask) if geom.side > r else (0, r, 0, r)
            alpha = dec.network_mask[y0:y1, x0:x1]
            # the directional bands restored to their true strength (relight_rt._strength), for both sides of the ratio
            transport = restore_bands(unpremultiply(np.ascontiguousarray(dec.transport[y0:y1, x0:x1]), alpha))
            skin = np.zeros(alpha.shape, bool)
            if state.get("faces"):  # a face's shape from its mesh where stage 1's transport is a blur
                skin = self._add_faces(dec, transport, (y0, y1, x0, x1))
            albedo = unpremultiply(np.ascontiguousarray(dec.albedo[y0:y1, x0:x1]), alpha) @ _exposure.REC709
            photo = dec.network_image[y0:y1, x0:x1] @ _exposure.REC709
            state["restored"] = {"window": (y0, y1, x0, x1), "alpha": alpha, "inner": alpha > 0.5,
                                 "transport": _readonly(transport), "albedo": _readonly(albedo.astype(np.float32)),
                                 "photo": _readonly(photo.astype(np.float32)),
                                 "face_skin": _readonly(skin & (alpha > 0.5))}
        return state["restored"]

    def _own(self, dec: Decomposition, with_residual: bool = True) -> dict:
        """What every relight of ``dec`` divides by, in the person's window of the network frame (cached).

        ``_restored``'s entries, "transport" moved along the photo's own light toward the shading the photo shows
        (relight_rt._strength ``explain_photo``), and "own" (r, r') the luminance of the pipeline's image under the
        photo's own light taken as white (diffuse plus stage 2's residual) plus "missing" (r, r'), what that falls
        short of ``_OWN_FLOOR`` x the photo's luminance (light the model misses; ``_gain`` adds it to every new light
        too), floored at the ratio's floor.
        """
        state = self._prepared(dec)
        key = "own" if with_residual else "own_diffuse"
        if key not in state:
            base = self._restored(dec)
            # the shading the photo shows and stage 1 misses, kept along the photo's own light (relight_rt._strength)
            white = dec.white_light[:, 0]
            moved = explain_photo(base["transport"], base["albedo"], base["photo"], white, base["inner"])
            base = {**base, "transport": _readonly(moved)}
            own = base["albedo"] * sh.shading(base["transport"], dec.white_light)[..., 0]  # white: columns equal
            residual = self._own_residual(dec) if with_residual else None
            if residual is not None:
                own += _luminance_window(residual, base["alpha"], base["window"])
            # where the photo is far brighter than its own reconstruction, the model misses light that is there
            # (stage 1's light from above and behind put a profile face in deep shade, then a front light made
            # it 3-5x brighter, blown out): that missing light, up to a share of the photo, is taken to stay under
            # every new light (added to both sides of the ratio, so the photo's own light still gives the photo)
            missing = np.maximum(_OWN_FLOOR * base["photo"] - own, 0).astype(np.float32)
            state[key] = {**base, "missing": _readonly(missing),
                          "own": _readonly(np.maximum(own + missing, _RATIO_EPS).astype(np.float32))}
        return state[key]

    def _refit(self, dec: Decomposition) -> Decomposition:
        """``dec`` with its light refit to the transport the relighting factor divides with (relight_rt._strength
        ``refit_light``), then turned toward what a face mesh's skin shows (``face_refit``); what was prepared for
        ``dec`` that does not depend on its light goes along."""
        base = self._restored(dec)
        y0, y1, x0, x1 = base["window"]
        inner = base["inner"]
        albedo, transport = base["albedo"][inner], base["transport"][inner]
        # what stage 1's own reconstruction (its transport, its light) leaves unexplained of the photo ...
        plain = unpremultiply(np.ascontiguousarray(dec.transport[y0:y1, x0:x1]), base["alpha"])[inner]
        white = dec.white_light[:, 0]
        unexplained = base["photo"][inner] - albedo * (plain @ white)
        # ... is what the light's correction explains, through the transport the relit photo is divided by
        light = refit_light(dec.light, albedo, transport, albedo * (transport @ white) + unexplained)
        skin = base["face_skin"]  # where a face mesh's shape says what light the skin shows (relight_rt._strength)
        if skin.any():
            light = face_refit(light, base["transport"][skin], base["photo"][skin], albedo, transport)
        return self._with_light(dec, light)

    def _face_light(self, dec: Decomposition, head: Decomposition) -> Decomposition:
        """``dec`` with its light turned by the face its head pass ``head`` sees (relight_rt._strength
        ``face_refit``), where the body pass saw the face too small for a mesh; ``dec`` itself otherwise."""
        base = self._restored(dec)
        if base["face_skin"].any():  # the body pass's own face turned it already (_refit)
            return dec
        face = self._restored(head)
        skin = face["face_skin"]
        if not skin.any():
            return dec
        inner = base["inner"]
        light = face_refit(dec.light, face["transport"][skin], face["photo"][skin], base["albedo"][inner],
                           base["transport"][inner])
        return self._with_light(dec, light)

    def _with_light(self, dec: Decomposition, light: np.ndarray) -> Decomposition:
        """``dec`` with another light; what was prepared for it that does not depend on its light goes along."""
        new = replace(dec, light=np.asarray(light, np.float32))
        old, state = self._prepared(dec), self._prepared(new)
        for key in ("photo", "faces", "face_meshes", "restored", "device", "gray"):
            if key in old:
                state[key] = old[key]
        return new

    def _face_mesh(self):
        """The face detector and landmarker of the models folder (relight_rt._face_geometry), loaded once."""
        if self._faces is None:
            with self._state_lock:
                if self._faces is None:
                    self._faces = FaceMesh(self.models_dir, device="cpu")
        return self._faces

    def _add_faces(self, dec: Decomposition, transport: np.ndarray, window: tuple[int, int, int, int]) -> np.ndarray:
        """Blend the transport of each face's mesh into ``transport`` (the window's, unpremultiplied), in place;
        returns where the faces' skin lies well inside their meshes (``face_transport``; none without a mesh)."""
        mesh = self._face_mesh()
        if not mesh.available:
            return np.zeros(transport.shape[:2], bool)
        geom = dec.geometry
        k = geom.scale
        (by0, _, bx0, _), (oy, ox) = geom.box, geom.offset
        y0, _, x0, _ = window
        state = self._prepared(dec)
        if "face_meshes" not in state:  # once per decomposition (both "own" entries use them)
            state["face_meshes"] = mesh.faces(dec.image, geom.box)
        skin = np.zeros(transport.shape[:2], bool)
        for pts in state["face_meshes"]:
            net = np.empty_like(pts)  # input pixels -> the window's pixel indices (centres at integers)
            net[:, 0] = (pts[:, 0] - bx0 + ox) / k - 0.5 - x0
            net[:, 1] = (pts[:, 1] - by0 + oy) / k - 0.5 - y0
            net[:, 2] = pts[:, 2] / k
            if np.ptp(net[:, :2], axis=0).max() < MIN_FACE_NET:
                continue
            t_face, weight, face_skin = face_transport(net, mesh.triangles, transport[..., 0])
            transport += weight[..., None] * (t_face - transport)
            skin |= face_skin
        return skin

    def _person_colour(
        self, dec: Decomposition, light: np.ndarray, residual: np.ndarray | None, relit: np.ndarray
    ) -> np.ndarray:
        """(h, w, 3) straight (not premultiplied) colour of the relit person inside the crop box.

        ``light`` is the (exposed) new light, ``residual`` and ``relit`` stage 2's outputs under it (3, R, R).
        """
        geom = dec.geometry
        if not self.detail:
            premult = geom.to_crop(relit.transpose(1, 2, 0))
            alpha = geom.to_crop(dec.network_mask)[..., None]
            colour = np.divide(premult, alpha, out=np.zeros_like(premult), where=alpha > _ALPHA_MIN)
            np.clip(colour, 0, 1, out=colour)
            return colour
        image, _ = self._foreground(dec)
        gain = self._gain(dec, light, image, residual)
        state = self._prepared(dec)
        head = state.get("head")
        if head is not None:
            self._blend_head(dec, gain, light, *head)
        if "dark" not in state:  # once per photo: what steadying dark pixels' colour needs whatever the light
            state["dark"] = tuple(_readonly(a) for a in _dark_colour(image))
        colour = _steady_chroma(image, gain, state["dark"])
        np.maximum(colour, 0, out=colour)
        if "knee" not in state:
            state["knee"] = _readonly(_knee(image))
        return _shoulder(colour, state["knee"])

    def _foreground(self, dec: Decomposition, always: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """(h, w, 3) twice, in the crop box: the person's own colour F and the colour behind it B (cached).

        At a soft matte's edge a pixel mixes both (I = a F + (1 - a) B); relighting or moving I would carry the
        old background along (a halo in a new scene, the new light's colour spilt onto the street). For a photo
        F and B come from relight_rt.foreground (multilevel foreground estimation, once per photo); for a hard
        edge a pixel or two wide (anti-aliasing, feathering), and for video frames (unless ``always``: the
        multilevel estimate costs about as much as the frame's relighting), the solid colours beside each soft
        pixel (relight_rt.foreground.nearest_colours); for a hard mask both are the photo.
        """
        state = self._prepared(dec)
        if "foreground" not in state:
            image = np.ascontiguousarray(dec.geometry.crop(dec.image))
            alpha = np.ascontiguousarray(dec.geometry.crop(dec.mask))
            width = _soft_edge_width(alpha)
            if (state.get("photo") or always) and width > _THIN_EDGE:
                fg, bg = estimate_foreground(image, alpha, return_background=True)
                fg, bg = _consistent(image, alpha, fg, bg)
            elif width > 0:
                fg, bg = nearest_colours(image, alpha)
            else:  # a hard mask: nothing of the background to take out
                fg = bg = image
            state["foreground"] = (_readonly(fg), _readonly(bg))
        return state["foreground"]

    def _backdrop(self, dec: Decomposition, bg: Background) -> np.ndarray | None:
        """The full-frame backdrop the relit person goes over (the photo itself for the original background:
        ``_compose`` puts the colours behind the person's soft edge into it)."""
        return dec.image if bg.kind == "original" else bg.backdrop(dec.image)

    def _gain(
        self, dec: Decomposition, light: np.ndarray, image: np.ndarray, residual: np.ndarray | None = None
    ) -> np.ndarray:
        """(h, w, 3) the factor on the photo in the crop box (module docstring), upsampled edge-aware.

        ``residual``: stage 2's residual under ``light`` (3, R, R), None for the diffuse image alone.
        """
        own = self._own(dec, with_residual=residual is not None)
        y0, y1, x0, x1 = own["window"]
        transport, alpha = own["transport"], own["alpha"]
        light = np.asarray(light, np.float32)
        shading = sh.shading(transport, light)
        lum = shading @ _exposure.REC709
        new = own["albedo"] * lum
        if residual is not None:
            new += _luminance_window(residual, alpha, own["window"])
        new += own["missing"]  # the light the photo shows and the model misses stays (``_own``)
        ratio = np.maximum(new, _RATIO_EPS) / own["own"]  # both floored: the photo's own light gives 1
        # the colour of the new light at each pixel, luminance 1 (where it leaves the pixel dark: its overall colour,
        # or white when that is not a colour: a light whose mean is not positive)
        dc_lum = float(light[0] @ _exposure.REC709)
        dc = light[0] / dc_lum if dc_lum > 1e-6 and (light[0] > 0).all() else np.ones(3, np.float32)
        tint = np.divide(shading, lum[..., None], out=np.broadcast_to(dc.astype(np.float32), shading.shape).copy(),
                         where=lum[..., None] > 1e-4)
        span = _tint_range(light)
        if span is not None:  # no colour the light cannot give (_tint_range), at the same luminance
            np.clip(tint, *span, out=tint)
            tint /= np.maximum(tint @ _exposure.REC709, 1e-6)[..., None]
            np.clip(tint, *span, out=tint)  # the rescale can lift one channel past its bound again
        state = self._prepared(dec)
        if "skin_chroma" not in state:  # the shaded-skin rule's light-independent inputs, kept for every light
            state["skin_chroma"] = tuple(map(_readonly, _skin_chroma(dec.network_image[y0:y1, x0:x1],
                                                                     dec.skin[y0:y1, x0:x1])))
        factor = _shaded_skin(tint * ratio[..., None], ratio, *state["skin_chroma"])  # shaded skin keeps its colour
        gain = extend_outward(factor, own["inner"])
        if "gray" not in state:  # the full-resolution guide, kept for every light
            state["gray"] = _readonly(cv2.cvtColor(image, cv2.COLOR_RGB2GRAY))
        return guided_upsample(dec.geometry, gain, dec.network_image[y0:y1, x0:x1], state["gray"], (y0, x0))

    def _blend_head(self, dec: Decomposition, gain: np.ndarray, light: np.ndarray, head: Decomposition,
                    box: tuple[int, int, int, int]) -> None:
        """Blend the head pass's change of shading into ``gain`` (the body's, crop frame), in place.

        The head pass sees the face larger, so it gives the shape of the change; its overall level is the
        body pass's (the two estimate the photo's light separately), matched on the head's skin.
        """
        by0, by1, bx0, bx1 = dec.geometry.box
        hy0, hy1, hx0, hx1 = head.geometry.box  # in the head square's frame
        y0, y1, x0, x1 = box[0] + hy0, box[0] + hy1, box[2] + hx0, box[2] + hx1  # input frame
        cy0, cy1, cx0, cx1 = max(y0, by0), min(y1, by1), max(x0, bx0), min(x1, bx1)
        if cy1 <= cy0 or cx1 <= cx0:
            return
        head_image = np.ascontiguousarray(head.geometry.crop(head.image))
        g_head = self._gain(head, light, head_image)[cy0 - y0 : cy1 - y0, cx0 - x0 : cx1 - x0]
        h_img, w_img = dec.geometry.frame
        weight = feather(box[1] - box[0], box[3] - box[2],
                         (box[0] == 0, box[1] == h_img, box[2] == 0, box[3] == w_img))
        weight = weight[cy0 - box[0] : cy1 - box[0], cx0 - box[2] : cx1 - box[2]]
        weight = weight * dec.mask[cy0:cy1, cx0:cx1]
        region = gain[cy0 - by0 : cy1 - by0, cx0 - bx0 : cx1 - bx0]
        skin = head.to_input(head.skin)[cy0 - box[0] : cy1 - box[0], cx0 - box[2] : cx1 - box[2]] * weight
        if skin.sum() < 1:
            return
        level = float((region @ _exposure.REC709 * skin).sum()) / max(float((g_head @ _exposure.REC709 * skin).sum()),
                                                                      1e-6)
        region += weight[..., None] * (level * g_head - region)

    def layers(self, dec: Decomposition, shading: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """The photo's intrinsic layers at its own resolution, with its own detail (input frame).

        The network's shading under the photo's own light is smooth (it comes from the transport), so it
        is upsampled plainly; the photo's high frequencies (clothing pattern, hair, skin texture) then go
        into the albedo: albedo = photo / shading, where the shading is large enough for the ratio to be
        stable, blending into the network's upsampled albedo where it is dark (below 0.1). The skin map is
        upsampled edge-aware, guided by the photo. Outside the person every layer is 0; each is multiplied
        by the (soft) mask, as the network's outputs are.

        Returns:
            {"albedo": (H, W, 3), "shading": (H, W, 3) not clipped, "skin": (H, W), "mask": (H, W)},
            float32, albedo and skin in [0, 1].

        ``shading``: the (R, R, 3) network-frame shading the albedo is taken over, masked as
        ``Decomposition.shading`` is (default: that, the photo's own light through stage 1's transport). The
        studio's preview gives the shading the relighting factor divides by (bands restored), so that its albedo
        under the photo's own light is the photo again.
        """
        geom = dec.geometry
        alpha = dec.network_mask
        inner = alpha > 0.5
        shading_net = extend_outward(unpremultiply(dec.shading() if shading is None else shading, alpha), inner)
        albedo_net = extend_outward(unpremultiply(np.ascontiguousarray(dec.albedo), alpha), inner)
        skin_net = extend_outward(unpremultiply(np.repeat(dec.skin[..., None], 3, axis=2), alpha), inner)
        photo = np.ascontiguousarray(geom.crop(dec.image))
        shading = np.maximum(geom.to_crop(shading_net), 0)
        albedo_up = np.clip(geom.to_crop(albedo_net), 0, 1)
        if geom.side > geom.resolution:
            y0, y1, x0, x1 = window(alpha)
            skin = guided_upsample(geom, skin_net[y0:y1, x0:x1], dec.network_image[y0:y1, x0:x1], photo, (y0, x0))
        else:
            skin = geom.to_crop(skin_net)
        ratio = np.clip(photo / np.maximum(shading, _SHADING_MIN), 0, 1)
        trust = np.clip(shading / _SHADING_TRUST, 0, 1)  # dark pixels: the ratio amplifies noise; trust the network
        albedo = albedo_up + (ratio - albedo_up) * trust
        m = geom.crop(dec.mask)[..., None]
        h, w = geom.frame
        y0, y1, x0, x1 = geom.box
        out = {"albedo": np.zeros((h, w, 3), np.float32), "shading": np.zeros((h, w, 3), np.float32),
               "skin": np.zeros((h, w), np.float32), "mask": np.array(dec.mask)}
        out["albedo"][y0:y1, x0:x1] = albedo * m
        out["shading"][y0:y1, x0:x1] = shading * m
        out["skin"][y0:y1, x0:x1] = np.clip(skin[..., 0], 0, 1) * m[..., 0]
        return out

    def to_photo(self, dec: Decomposition, light, background="original", exposure="auto") -> np.ndarray:
        """Deprecated (goes in the next release): ``relight(dec, light, background=..., exposure=...)``."""
        warnings.warn("Relighter.to_photo is deprecated: use Relighter.relight(dec, light, ...)", DeprecationWarning,
                      stacklevel=2)
        return self.relight(dec, light, background=background, exposure=exposure)

    def _compose(
        self, dec: Decomposition, light: np.ndarray, outputs: tuple, backdrop: np.ndarray | None, clean: bool = False
    ) -> np.ndarray:
        """The photo relit under the (exposed) ``light``, given stage 2's ``outputs`` (diffuse, residual, relit).

        ``clean``: a new backdrop. With detail on the person's colour is already its foreground colour relit
        (``_person_colour``); the network image (``detail=False``) gets its soft edge cleaned of the old
        background here (relight_rt.compositing.clean_edge_colour). Over the photo's own background (not
        ``clean``) the soft edge's share of background is the colour behind it (``_foreground``), so that the
        photo's own light gives the photo back.
        """
        geom = dec.geometry
        _, residual, relit = outputs
        colour = self._person_colour(dec, light, residual, relit)
        alpha = geom.crop(dec.mask)
        behind = None
        if clean and not self.detail:
            photo = np.ascontiguousarray(geom.crop(dec.image))
            fg, _ = self._foreground(dec, always=True)
            colour = clean_edge_colour(colour, photo, fg, alpha)
        elif not clean and backdrop is not None:
            fg, bg = self._foreground(dec)
            behind = None if bg is fg else bg
        return over_box(colour, alpha[..., None], geom.box, backdrop, dec.mask, behind)

    def _by_person(
        self, dec: Decomposition, parts: tuple[Decomposition, ...], light: np.ndarray, exposure, bg: Background
    ) -> np.ndarray:
        """A group photo relit person by person: each of ``parts`` (the people of ``dec``, each decomposed on their
        own with their share of its matte: their own shape, their face seen at their size, their own exposure)
        gives the person's relit colour; the colours, weighted by the shares (which sum to the matte, so where
        people overlap their changes blend), go over the backdrop with the group's matte. The person's own colour
        and the colour behind the soft edge are the group's (``_foreground`` once, on the whole matte: where two
        people meet neither is background)."""
        backdrop = self._backdrop(dec, bg)
        clean = bg.kind != "original"
        fg, behind = self._foreground(dec, always=clean and not self.detail)
        y0, y1, x0, x1 = dec.geometry.box
        alpha = dec.geometry.crop(dec.mask)[..., None]
        weighted = np.zeros(fg.shape, np.float32)  # the people's colours times their shares of the matte, summed
        for part in parts:
            py0, py1, px0, px1 = part.geometry.box
            cy0, cy1, cx0, cx1 = max(py0, y0), min(py1, y1), max(px0, x0), min(px1, x1)
            if cy1 <= cy0 or cx1 <= cx0:
                continue
            state = self._prepared(part)
            if "foreground" not in state and (cy0, cy1, cx0, cx1) == (py0, py1, px0, px1):
                # the person's box lies in the group's (their share lies in its matte): what the group has of the
                # photo whatever the light is theirs, as views (a group photo of many megapixels holds it once)
                group = (slice(py0 - y0, py1 - y0), slice(px0 - x0, px1 - x0))
                whole = self._prepared(dec)
                if "dark" not in whole:
                    whole["dark"] = tuple(_readonly(a) for a in _dark_colour(fg))
                    whole["knee"] = _readonly(_knee(fg))
                state["foreground"] = (fg[group], behind[group])
                state["dark"] = tuple(a[group] for a in whole["dark"])
                state["knee"] = whole["knee"][group]
            lit = self._expose(part, light[None], exposure)[0]
            _, residual, relit = next(self._network_relit(part, lit[None], 1, want_layers=self.detail))
            colour = self._person_colour(part, lit, residual, relit)
            share = part.geometry.crop(part.mask)[..., None]
            if clean and not self.detail:
                colour = clean_edge_colour(colour, np.ascontiguousarray(part.geometry.crop(part.image)),
                                           self._foreground(part, always=True)[0], share[..., 0])
            sl = (slice(cy0 - py0, cy1 - py0), slice(cx0 - px0, cx1 - px0))
            weighted[cy0 - y0 : cy1 - y0, cx0 - x0 : cx1 - x0] += (colour * share)[sl]
        if backdrop is None:  # RGBA, straight colour
            out = np.zeros(dec.geometry.frame + (4,), np.float32)
            np.divide(weighted, alpha, out=out[y0:y1, x0:x1, :3], where=alpha > 0)
            out[..., 3] = dec.mask
        else:
            out = np.array(backdrop, np.float32)
            under = behind if not clean and behind is not fg else out[y0:y1, x0:x1]
            out[y0:y1, x0:x1] = under * (1 - alpha) + weighted
        return np.clip(out, 0, 1, out=out)

    def _expose(self, dec: Decomposition, lights: np.ndarray, exposure) -> np.ndarray:
        """relight_rt.exposure.expose with the photo's own mean luminance measured once per Decomposition, then
        the highlight guard (relight_rt.exposure ``highlight_factor``) on each light before any EV offset."""
        mode = _exposure.parse_exposure(exposure)
        if mode == "physical":
            return np.array(lights, np.float32)
        state = self._prepared(dec)
        if "target" not in state:
            state["target"] = _exposure.mean_luminance(dec.albedo, dec.transport, dec.network_mask, dec.white_light)
        lits = _exposure.expose(dec, lights, "auto", target_luminance=state["target"])
        return _exposure.guarded(lits, mode, self._highlight_inputs(dec))

    def _highlight_inputs(self, dec: Decomposition) -> tuple:
        """What ``highlight_factor`` reads of ``dec`` whatever the light (cached): the person's pixels (alpha > 0.5,
        network frame) as the relit picture is made of them, and the share past white allowed.

        With detail the picture is the photo times the relighting factor (module docstring; diffuse part): per
        pixel the photo's colour times albedo / own scales with the light and the photo's colour times missing /
        own stays; without it, the network's albedo times the shading. The share allowed is the photo's own
        share at white there, at least ``HIGHLIGHT_SHARE``.
        """
        state = self._prepared(dec)
        if "highlight" not in state:
            if self.detail:
                own = self._own(dec, with_residual=False)
                y0, y1, x0, x1 = own["window"]
                inner = own["inner"]
                photo = dec.network_image[y0:y1, x0:x1][inner]
                base = own["own"][inner]
                lit = photo * (own["albedo"][inner] / base)[:, None]
                steady = photo * (own["missing"][inner] / base)[:, None]
                transport = own["transport"][inner]
            else:
                alpha = dec.network_mask
                inner = alpha > 0.5
                photo = dec.network_image[inner]
                lit = unpremultiply(np.ascontiguousarray(dec.albedo), alpha)[inner]
                steady = np.zeros_like(lit)
                transport = unpremultiply(np.ascontiguousarray(dec.transport), alpha)[inner]
            at_white = float(np.mean(_channel_max(photo) >= 0.99 * _exposure.HIGHLIGHT_LIMIT)) if photo.size else 0.0
            state["highlight"] = (_readonly(lit.astype(np.float32)), _readonly(steady.astype(np.float32)),
                                  _readonly(np.ascontiguousarray(transport, np.float32)),
                                  max(at_white, _exposure.HIGHLIGHT_SHARE))
        return state["highlight"]

    def _prepare(self, image, mask) -> Decomposition:
        if isinstance(image, Decomposition):
            if mask is not None:
                raise RelightError("mask: a Decomposition already has its mask; pass mask only with an image")
            return image
        return self.decompose(image, mask)

    def relight(
        self,
        image: ImageLike | Decomposition,
        light,
        *,
        mask: ImageLike | None = None,
        background: Background | str | os.PathLike | np.ndarray = "original",
        exposure="auto",
        layers: bool = False,
    ) -> np.ndarray | RelightResult:
        """Relight a photo (or a Decomposition: decompose once, relight many) under a new light.

        Args:
            image: a photo (see ``decompose``) or a ``Decomposition`` (no stage-1 pass).
            light: see ``resolve_light``: (9, 3) array, LightSpec, light file, HDR map, photo, Decomposition or
                preset.
            mask: the photo's mask (see ``decompose``); not with a Decomposition.
            background: a :class:`relight_rt.compositing.Background`, or its shorthand: "original" (the
                photo), "transparent" (RGBA output, alpha = mask), a colour ("black", "#RRGGBB") or an image
                (path or array; fitted to the photo by "cover").
            exposure: "auto" (default: the light is scaled so the person keeps its mean luminance, lowered by up
                to a stop where that would put more than 8 % of the person past white), an EV offset from
                auto (+1 twice as bright), or "physical" (the light as given); relight_rt.exposure.
            layers: also return the input-frame layers that made the picture.

        Returns:
            (H, W, 3) float32 RGB in [0, 1] at the input's size ((H, W, 4) RGBA for "transparent"); pixels
            where the mask is 0 are the background's, untouched. With ``layers=True`` a :class:`RelightResult`
            (that picture as ``.image``, its ``.layers`` and ``.light``).
        """
        dec = self._prepare(image, mask)
        if isinstance(light, (str, os.PathLike)):
            light = LightSpec.of(light)  # read once by the one rule: its exposure and its light
        exposure = _exposure.for_light(exposure, light)  # a preset may ask for its own exposure (night: darker)
        parts = self._prepared(dec).get("parts")
        if parts:
            bg = parse_background(background)
            light = self.resolve_light(light)
            out = self._by_person(dec, parts, light, exposure, bg)
            if layers:  # the layers are the group's, decomposed as one
                return replace(self._relight_with_layers(dec, self._expose(dec, light, exposure), bg), image=out)
            return out
        lit = self._expose(dec, self.resolve_light(light), exposure)
        bg = parse_background(background)
        if layers:
            return self._relight_with_layers(dec, lit, bg)
        outputs = next(self._network_relit(dec, lit[None], 1, want_layers=self.detail))
        return self._compose(dec, lit, outputs, self._backdrop(dec, bg), clean=bg.kind != "original")

    def relight_layers(
        self,
        image: ImageLike | Decomposition,
        light,
        *,
        mask: ImageLike | None = None,
        background: Background | str | os.PathLike | np.ndarray = "original",
        exposure="auto",
    ) -> RelightResult:
        """Deprecated (goes in the next release): ``relight(..., layers=True)``."""
        warnings.warn("Relighter.relight_layers is deprecated: use Relighter.relight(..., layers=True)",
                      DeprecationWarning, stacklevel=2)
        return self.relight(image, light, mask=mask, background=background, exposure=exposure, layers=True)

    def _relight_with_layers(self, dec: Decomposition, lit: np.ndarray, bg: Background) -> RelightResult:
        """The picture under the exposed light ``lit`` and the input-frame layers that made it."""
        diffuse, residual, relit = next(self._network_relit(dec, lit[None], 1, want_layers=True))
        out = self._compose(dec, lit, (diffuse, residual, relit), self._backdrop(dec, bg), clean=bg.kind != "original")
        chw = lambda a: dec.to_input(np.ascontiguousarray(a.transpose(1, 2, 0)))  # noqa: E731
        layers = {
            "albedo": self.layers(dec)["albedo"],
            "shading": dec.to_input(dec.shading(lit)),
            "diffuse": chw(diffuse),
            "residual": chw(residual) if residual is not None else np.zeros(dec.image.shape, np.float32),
            "relit": chw(relit),
            "mask": np.array(dec.mask),
        }
        return RelightResult(out, layers, lit, self.diffuse_only)

    def iter_relight(
        self,
        image: ImageLike | Decomposition,
        lights,
        *,
        mask: ImageLike | None = None,
        background: Background | str | os.PathLike | np.ndarray = "original",
        batch_size: int = 4,
        exposure="auto",
    ) -> Iterator[np.ndarray]:
        """Like ``relight_many`` but yields one (H, W, 3|4) result at a time (for long sweeps and video)."""
        if not isinstance(batch_size, int) or batch_size < 1:
            raise RelightError(f"batch_size: expected a whole number >= 1, got {batch_size!r}")
        dec = self._prepare(image, mask)
        if isinstance(lights, (list, tuple)):  # strings read once by the one rule: their exposure and their light
            lights = [LightSpec.of(v) if isinstance(v, (str, os.PathLike)) else v for v in lights]
        resolved = self._resolve_lights(lights)
        # each light's exposure: a preset may ask for its own (``exposure.for_light``: night a stop darker)
        exposures = [_exposure.for_light(exposure, v) for v in lights] if isinstance(lights, list) else \
            [_exposure.parse_exposure(exposure)] * len(resolved)
        parts = self._prepared(dec).get("parts")
        if parts:
            bg = parse_background(background)
            for light, exp in zip(resolved, exposures, strict=True):
                yield self._by_person(dec, parts, light, exp, bg)
            return
        if all(e == exposures[0] for e in exposures):
            lits = self._expose(dec, resolved, exposures[0])
        else:
            lits = np.stack([self._expose(dec, one[None], e)[0] for one, e in zip(resolved, exposures, strict=True)])
        bg = parse_background(background)
        backdrop = self._backdrop(dec, bg)
        for lit, outputs in zip(lits, self._network_relit(dec, lits, batch_size, want_layers=self.detail), strict=True):
            yield self._compose(dec, lit, outputs, backdrop, clean=bg.kind != "original")

    def relight_many(
        self,
        image: ImageLike | Decomposition,
        lights,
        *,
        mask: ImageLike | None = None,
        background: Background | str | os.PathLike | np.ndarray = "original",
        batch_size: int = 4,
        exposure="auto",
    ) -> np.ndarray:
        """One stage-1 pass, then K relights through stage 2 in batches of ``batch_size``.

        Args:
            image: a photo or a Decomposition (as for ``relight``).
            lights: (K, 9, 3) array or a list of anything ``resolve_light`` accepts.
            mask, background: as for ``relight``.
            batch_size: lights per stage-2 run.
            exposure: as for ``relight``, for each light on its own.

        Returns:
            (K, H, W, 3) float32 RGB ((K, H, W, 4) for "transparent"); K full-size images are held in memory,
            use ``iter_relight`` for long sweeps.
        """
        dec = self._prepare(image, mask)
        # a list is resolved light by light in iter_relight (a photo's light once); an array is checked here
        count = len(lights) if isinstance(lights, (list, tuple)) else len(self._resolve_lights(lights))
        bg = parse_background(background)
        out = np.empty((count,) + dec.geometry.frame + (bg.channels,), np.float32)
        results = self.iter_relight(dec, lights, background=bg, batch_size=batch_size, exposure=exposure)
        for i, img in enumerate(results):
            out[i] = img
        return out

    def composite(
        self,
        image: ImageLike,
        background,
        *,
        mask: ImageLike | None = None,
        light=None,
        position=None,
        height: float | None = None,
        shadow: bool = True,
        exposure="auto",
        fov: float = 60.0,
        white_balance: bool = True,
        key_light=None,
        horizon: float = 0.5,
        meter: str = "frame",
        match_camera: bool = True,
        light_wrap: bool = True,
        rim: bool = False,
    ) -> np.ndarray:
        """Relight the person of ``image`` for the scene of ``background`` and put it there.

        See ``relight_rt.scene.composite`` for the arguments. Returns (H_bg, W_bg, 3) float32 sRGB.
        """
        from .scene import composite

        return composite(self, image, background, mask=mask, light=light, position=position, height=height,
                         shadow=shadow, exposure=exposure, fov=fov, white_balance=white_balance, key_light=key_light,
                         horizon=horizon, meter=meter, match_camera=match_camera,
                         light_wrap=light_wrap, rim=rim)


def compose_step(relighter: Relighter, dec: Decomposition, light: np.ndarray):
    """A call that runs only the full-resolution half of a relight (the photo times the relighting factor, over
    the photo's own backdrop) for one light, with stage 2's outputs computed once beforehand: what
    ``relight-rt bench --sections compose`` times (relight_rt.timing)."""
    outputs = next(relighter._network_relit(dec, light[None], 1, want_layers=True))
    return lambda: relighter._compose(dec, light, outputs, dec.image)
