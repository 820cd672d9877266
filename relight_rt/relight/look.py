"""The look of a relit photo: how its colours and highlights behave, whatever produced the relighting factor.

The highlight shoulder (``knee``, ``shoulder``), the colour of dark pixels a strong gain brightens
(``dark_colour``, ``steady_chroma``), the chroma of near-neutral darks a light brightens (``neutral_darks``,
``keep_neutral``), the colour range a light can give (``tint_range``), and the chroma shaded
skin keeps (``shaded_skin``, ``skin_chroma``; the studio's preview applies the same rule with ``SKIN_CHROMA``).
Plain functions of arrays: no model, no state.
"""

from __future__ import annotations

import threading
from typing import NamedTuple

import cv2
import numpy as np

from ..image.color import REC709, channel_max
from ..light import sh
from ..light.exposure import knee as knee  # the public name here (the one definition sits in light.exposure)
from ..light.exposure import rolled_off
from .decomposition import readonly

_DARK = np.float32(0.25)  # steady_chroma: a pixel below this luminance, brightened by a gain, takes its dark
_AMPLIFIED = np.float32(2.0)  # ... neighbours' colour, fully from a gain of 1 + this,
_CHROMA_RADIUS = 4  # ... those within this many pixels (the constants: the reference photo's jaw, module tests)
_NEUTRAL_L = (30.0, 40.0)  # dark_colour: a pixel of Lab L* below the first is dark, from the second not ...
_NEUTRAL_C = (6.0, 12.0)  # ... and near-black when its Lab chroma C* is below the first, from the second not,
_NEUTRAL_A = (-4.0, -1.0)  # ... with a green-cyan cast: a* below the first, none from the second up,
_NEUTRAL_HUE = (0.4, 0.7)  # ... or a faint one by its direction: -a* / C* above the second, none below the first
_NEUTRAL_STEP = 4  # ... measured on the photo reduced this many times (a cloth's cast is shared by its pixels)
_NEUTRAL_PULL = np.float32(2.0)  # ... and pulled toward grey this many times as readily as a dark pixel's colour
_GREY_L = (35.0, 45.0)  # neutral_darks: a pixel of Lab L* below the first is dark, from the second not ...
_GREY_C = (8.0, 12.0)  # ... and near-neutral when its chroma C* is below the first, from the second not ...
_GREY_NOISE = 4.0  # ... the mean of its pixels' own C* less this (JPEG's chroma noise) counting as well ...
_GREY_VIVID = (0.3, 0.4)  # ... and its pixels' C* / (L* + 16) below the first (none from the second) ...
_GREY_MATERIAL = (14.0, 20.0)  # ... unless its hue nearby reaches this C* (from the first less, none from the second):
_GREY_REACH = 6  # ... within this many pixels of the reduced photo (blue jeans' deep fold beside their lit front)
_GREY_SECTORS = 12  # ... its hue: one of this many sectors of a*, b*, or either beside it
_GREY_HUE_C = 4.0  # ... a pixel below this C* taking its neighbourhood's hue
_GREY_WARM = (10.0, 100.0)  # ... and a warm hue (Lab hue angle, degrees) is left alone: skin, brown hair, wood ...
_GREY_WARM_SOFT = 10.0  # ... fully from this many degrees inside those bounds
_GREY_EDGE = 4  # ... and within this many pixels of the matte's outline, by the pixel's own colour alone (the
# outline's pixels mix the backdrop in: its teal on half A, p104 / p138 / p224, lay within 5 px of the outline)
_GREY_HUE_L = (4.0, 8.0)  # ... there a hue of its own from this L* (none below the first): below 8 lies sRGB's and
# L*'s linear toe, where one 8-bit level moves a* by ~1 and JPEG's chroma by several (half A: p186's black outline)
NEUTRAL_LIFT = (1.1, 1.5)  # ... relit brighter than the photo by less than the first: untouched, from the second: fully
NEUTRAL_CHROMA_EXP = np.float32(2.2 / 3)  # C* ~ (chroma relative to luminance) x Y_linear^(1/3), Y_linear ~ y^2.2
# (both public: the studio's preview grade applies the rule with them, sh.js neutralStep)
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


def to_lab(image: np.ndarray) -> np.ndarray:
    """cv2's RGB -> Lab of (h, w, 3) float32 RGB in [0, 1] (L* 0-100), after the tables ``prepare_lab`` may be
    building (one builder at a time)."""
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


def _falling(v: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """1 at and below ``lo``, 0 at and above ``hi``, linear between (``v``'s shape)."""
    return np.clip((hi - v) / (hi - lo), 0, 1)


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
    lab = to_lab(small)
    chroma = np.hypot(lab[..., 1], lab[..., 2])
    black = _falling(lab[..., 0], *_NEUTRAL_L) * _falling(chroma, *_NEUTRAL_C)
    # a green-cyan cast only: what a brightening light turns teal; a faint one by its direction (a* small because C*
    # is: grey cloth at levels (22, 24, 22), a* -1.3, went past a* -8 under a side lamp's 4-5x)
    hue = -lab[..., 1] / np.maximum(chroma, 1e-3)
    black *= np.maximum(_falling(lab[..., 1], *_NEUTRAL_A), _falling(-hue, -_NEUTRAL_HUE[1], -_NEUTRAL_HUE[0]))
    darkness = np.clip(1 - y / _DARK, 0, 1)
    if not black.any():  # most photos: nothing near-black with a cast
        return y, darkness, colour
    black = cv2.resize(black, (w, h), interpolation=cv2.INTER_LINEAR)
    near = black > 0
    b = black[near][:, None]
    colour[near] += b * (1 - colour[near])  # toward grey: luminance 1 per unit of luminance
    darkness[near] = np.maximum(darkness[near], _NEUTRAL_PULL * b[:, 0])
    return y, darkness, colour


def material_chroma(hue: np.ndarray, chroma: np.ndarray, reach: float) -> np.ndarray:
    """(h, w) the highest Lab C* that a pixel's hue (its sector of ``_GREY_SECTORS`` or either beside it) reaches
    within ``reach`` pixels of it: the colour of the material a dark pixel belongs to (blue jeans' lit front beside
    their shaded fold, which is dark and so low in C* while blue). ``hue``: (h, w) in degrees; ``chroma``: C*."""
    r = max(int(round(reach)), 1)
    sector = np.floor(hue / 360 * _GREY_SECTORS).astype(np.int64) % _GREY_SECTORS
    disk = np.ones((2 * r + 1, 2 * r + 1), np.uint8)  # a square: OpenCV dilates by it in separable passes
    most = np.stack([cv2.dilate(np.where(sector == k, chroma, 0).astype(np.float32), disk)
                     for k in range(_GREY_SECTORS)])
    most = np.maximum(most, np.maximum(np.roll(most, 1, axis=0), np.roll(most, -1, axis=0)))
    return np.take_along_axis(most, sector[None], axis=0)[0]


class NeutralDarks(NamedTuple):
    """``neutral_darks`` of a photo: what ``keep_neutral`` reads under each light, for the k near-neutral dark
    pixels only (read-only arrays, laid out for that per-light step: channel by channel, no per-light conversion)."""

    index: np.ndarray  # (3, k) int64: flat indices of their values in an (h, w, 3) array, row c channel c
    weight: np.ndarray  # (k,) float32 in (0, 1]: how near-neutral and dark the photo is there
    chroma: np.ndarray  # (3, k) float32: their chroma relative to luminance, (P - Y) / Y, row c channel c
    size: np.ndarray  # (k,) float32: its length |(P - Y) / Y| (at least 1e-6)
    luminance: np.ndarray  # (k,) float32: their luminance Y (Rec. 709, linear; at least 1e-6)


def _warmth(hue: np.ndarray) -> np.ndarray:
    """1 where a Lab hue angle (degrees) is warm (``_GREY_WARM``, ``_GREY_WARM_SOFT`` inside its bounds), 0 outside
    them, linear between."""
    return np.minimum(np.clip((hue - _GREY_WARM[0]) / _GREY_WARM_SOFT, 0, 1),
                      np.clip((_GREY_WARM[1] - hue) / _GREY_WARM_SOFT, 0, 1))


def block_gates(image: np.ndarray, origin: tuple[int, int], solid: np.ndarray | None) -> dict[str, np.ndarray]:
    """``neutral_darks``' gates on the photo's reduced blocks (its docstring), for ``image`` (h, w, 3) float32 RGB in
    [0, 1] at ``origin`` (y, x) in the photo, ``solid`` (h, w) bool or None (all): a dict of (sh, sw) float32 arrays
    on the grid of ``_NEUTRAL_STEP``-pixel blocks, each in [0, 1] and 1 where the block passes: "L", "C", "vivid",
    "warm" (1 - its warmth), "material"; and the readings "L*", "C*" and "hue" (degrees, the hue a near-black block
    takes from its neighbours). The weight is their product (``_block_weight``); ``at_pixels`` puts any of them back
    on ``image``'s pixels. benchmarks/teal_sources.py reads them to say which gate let a pixel through."""
    h, w = image.shape[:2]
    # the reduction's grid on the photo's own: a group's person (a window of the photo) reads as they do alone
    oy, ox = origin[0] % _NEUTRAL_STEP, origin[1] % _NEUTRAL_STEP
    grid = cv2.copyMakeBorder(np.clip(image, 0, 1), oy, 0, ox, 0, cv2.BORDER_REPLICATE)
    gh, gw = grid.shape[:2]
    sh, sw = max(gh // _NEUTRAL_STEP, 1), max(gw // _NEUTRAL_STEP, 1)
    # whole blocks only: INTER_AREA to a size that is not a 1 / _NEUTRAL_STEP of the input spreads its blocks over the
    # photo, a window of another size then reads another grid (the rows and columns past the last block take its
    # values, the edge padding below)
    grid = grid[: sh * _NEUTRAL_STEP, : sw * _NEUTRAL_STEP]
    small = cv2.resize(grid, (sw, sh), interpolation=cv2.INTER_AREA)
    # the person's blocks on that grid: what the material and a near-black pixel's hue are read from
    person = np.ones((sh, sw), np.float32) if solid is None else cv2.resize(
        cv2.copyMakeBorder(np.asarray(solid, np.float32), oy, 0, ox, 0, cv2.BORDER_REPLICATE)[
            : sh * _NEUTRAL_STEP, : sw * _NEUTRAL_STEP], (sw, sh), interpolation=cv2.INTER_AREA) >= 0.5
    lab = to_lab(small)
    chroma = np.hypot(lab[..., 1], lab[..., 2])
    # near-neutral by its pixels' own chroma too: fine red and blue stripes average to a grey they are not
    full = to_lab(grid)
    size = small.shape[1::-1]
    own_c = np.hypot(full[..., 1], full[..., 2])
    own = cv2.resize(own_c, size, interpolation=cv2.INTER_AREA)
    # ... and by its chroma for its lightness (C* / (L* + 16) ~ chroma relative to luminance): a dark saturated colour
    # is low in C* only because it is dark (a red stripe in shade: 0.48; dark hair with a blue cast: 0.15-0.27)
    vivid = cv2.resize(own_c / (full[..., 0] + 16), size, interpolation=cv2.INTER_AREA)
    gates = {"L": _falling(lab[..., 0], *_GREY_L), "C": _falling(np.maximum(chroma, own - _GREY_NOISE), *_GREY_C),
             "vivid": _falling(vivid, *_GREY_VIVID), "L*": lab[..., 0], "C*": chroma}
    weight = gates["L"] * gates["C"] * gates["vivid"]
    reach = float(_GREY_REACH)  # in pixels, not a share of the photo: a group's person sees it as they do alone
    # a near-black pixel's own hue is noise: it takes that of the person's near-neutral darks around it (the jeans'
    # deep fold, the jeans' dark blue), weighted by how near-neutral and dark they are: a plain blur of a*b* is the
    # saturated neighbours' hue (a teal backdrop's, the skin's beside black hair), not the material's
    ab = np.ascontiguousarray(lab[..., 1:])
    near = (weight * person).astype(np.float32)
    total = cv2.GaussianBlur(near, (0, 0), reach / 2)
    around = cv2.GaussianBlur(ab * near[..., None], (0, 0), reach / 2) / np.maximum(total, 1e-6)[..., None]
    ab = np.where(((chroma < _GREY_HUE_C) & (total > 1e-3))[..., None], around, ab)
    hue = np.degrees(np.arctan2(ab[..., 1], ab[..., 0])) % 360
    gates["hue"] = hue
    gates["warm"] = 1 - _warmth(hue)
    # the material: the person's own colours nearby only (a backdrop of the hair's cast is not the hair's material)
    gates["material"] = _falling(material_chroma(hue, chroma * person, reach), *_GREY_MATERIAL)
    return gates


def at_pixels(block: np.ndarray, shape: tuple[int, int], origin: tuple[int, int], smooth: bool = False) -> np.ndarray:
    """A (sh, sw) reading of ``block_gates`` on the (h, w) pixels of ``shape`` at ``origin`` (y, x): each block's
    value over its pixels (nearest), or ``smooth``: blurred over a reduced pixel and interpolated, as the weight is
    (a colour the group's soft edge and the person alone see differently moves less). Past the last whole block the
    edge's value."""
    h, w = shape
    oy, ox = origin[0] % _NEUTRAL_STEP, origin[1] % _NEUTRAL_STEP
    gh, gw = h + oy, w + ox
    blocks = (block.shape[1] * _NEUTRAL_STEP, block.shape[0] * _NEUTRAL_STEP)  # (w, h) the whole blocks cover
    if smooth:
        big = cv2.resize(cv2.GaussianBlur(block, (0, 0), 1.0), blocks, interpolation=cv2.INTER_LINEAR)
    else:
        big = np.repeat(np.repeat(block, _NEUTRAL_STEP, 0), _NEUTRAL_STEP, 1)
    big = np.pad(big, ((0, max(gh - blocks[1], 0)), (0, max(gw - blocks[0], 0))), mode="edge")
    return big[oy : oy + h, ox : ox + w]


def _block_weight(image: np.ndarray, origin: tuple[int, int], solid: np.ndarray | None) -> np.ndarray | None:
    """``neutral_darks``' weight read on the photo's reduced blocks (its docstring, ``block_gates``): (h * w,) float32
    per pixel of ``image`` (h, w, 3) in [0, 1], 0 off ``solid``; None where no block is near-neutral and dark."""
    gates = block_gates(image, origin, solid)
    weight = gates["L"] * gates["C"] * gates["vivid"]
    if not weight.any():
        return None
    weight *= gates["warm"] * gates["material"]
    if not weight.any():
        return None
    weight = at_pixels(weight, image.shape[:2], origin, smooth=True).ravel()
    if solid is not None:
        weight = weight * solid.ravel()
    return weight


def _outline_darks(image: np.ndarray, solid: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """(index, weight): the flat indices of ``image``'s (h, w, 3) pixels on the matte's outline (``solid`` (h, w) bool,
    within ``_GREY_EDGE`` px of a pixel that is not solid; not at the photo's border) that are near-neutral and dark by
    their own Lab colour (``_GREY_L``, ``_GREY_C``, ``_GREY_VIVID``, not warm, C* of ``_GREY_HUE_C`` or more at L* of
    ``_GREY_HUE_L[1]`` or more: a hue of their own), and that weight in (0, 1]; None: none.

    A block across the outline reads the person mixed with the backdrop, and the outline's own pixels mix it in too
    (the matte's edge, the lens, JPEG's half-resolution chroma): the block's reading (bright, coloured, a material)
    left dark hair before green leaves or a dark shirt before grey pavement half held or not at all, and the light
    brightened the backdrop's cast with them (teal on half A's worst photos, p104's hair under rim, p224's shirt
    under window-left). A near-neutral dark pixel there keeps its own chroma whatever its block reads."""
    mask = np.asarray(solid, np.uint8)
    disk = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * _GREY_EDGE + 1,) * 2)
    band = np.flatnonzero(mask.ravel() > cv2.erode(mask, disk).ravel())  # the erosion ignores the photo's border
    if band.size == 0:
        return None
    lab = to_lab(np.clip(np.take(image.reshape(-1, 3), band, axis=0), 0, 1)[None])[0]
    chroma = np.hypot(lab[:, 1], lab[:, 2])
    weight = _falling(lab[:, 0], *_GREY_L) * _falling(chroma, *_GREY_C)
    weight *= _falling(chroma / (lab[:, 0] + 16), *_GREY_VIVID)
    weight *= 1 - _warmth(np.degrees(np.arctan2(lab[:, 2], lab[:, 1])) % 360)
    # ... and only where the pixel has a hue of its own (C* from _GREY_HUE_C / 2, fully from _GREY_HUE_C; L* from
    # _GREY_HUE_L[0], fully from _GREY_HUE_L[1]): a near-black pixel's hue is noise, its material the block's (the
    # bundled example's brown trousers, black at their outline, went grey-blue there held by their own noise; p186's
    # black (0, 13, 7) at L* 2.8, C* 4.7, green-grey under RIGHT where the block's reading gives it the beige around)
    weight *= np.clip(2 * chroma / _GREY_HUE_C - 1, 0, 1)
    weight *= np.clip((lab[:, 0] - _GREY_HUE_L[0]) / (_GREY_HUE_L[1] - _GREY_HUE_L[0]), 0, 1)
    keep = weight > 1e-3
    return (band[keep], weight[keep].astype(np.float32)) if keep.any() else None


def neutral_darks(image: np.ndarray, origin: tuple[int, int] = (0, 0), solid: np.ndarray | None = None
                  ) -> NeutralDarks | None:
    """What ``keep_neutral`` needs of a photo (``image``: (h, w, 3) float32 RGB in [0, 1]) whatever the light, on
    its near-neutral dark pixels only (``NeutralDarks``), or None where no pixel is near-neutral and dark.
    ``origin``: (y, x) of ``image``'s top-left pixel in the photo (the reduction's grid is the photo's). ``solid``:
    (h, w) bool, where the photo is the person's own colour (not a soft edge's mix: there the relit colour is
    another's, the estimated foreground); None: all. Computed once per photo (the runtime keeps it per
    Decomposition), so that the per-light step is arithmetic on those pixels alone.

    Near-neutral dark: 1 where the photo's CIE Lab L* and C* (on the photo reduced ``_NEUTRAL_STEP`` times, as
    ``dark_colour``: the cast of a cloth or of hair is shared by its pixels, a pixel's own chroma is JPEG's noise) are
    below ``_GREY_L[0]`` and ``_GREY_C[0]``, 0 from ``_GREY_L[1]`` or ``_GREY_C[1]`` up, linear between; of a hue
    that is not warm (``_GREY_WARM``: shaded dark skin is dark and low in C* too, and a warm dark brightened reads as
    its material, brown hair or skin, where a cool or magenta one reads as a cast: blue-grey, teal, violet); and not
    where the pixel's hue reaches ``_GREY_MATERIAL`` nearby (``material_chroma``: blue jeans' deep folds are dark
    and low in C* while the jeans are blue), read on the person's pixels (``solid``) only. A near-black pixel (C*
    below ``_GREY_HUE_C``) takes the hue of the person's near-neutral darks around it (not a backdrop's or the skin's
    beside it). A pixel whose own colour is warm and past ``_GREY_C`` (skin at the edge of dark hair) is left alone
    whatever its reduced pixel reads. On the matte's outline (within ``_GREY_EDGE`` px of a pixel that is not
    ``solid``) a pixel near-neutral and dark by its own colour counts at least by that (``_outline_darks``): its block
    mixes the backdrop in. The relative chroma is each pixel's own (the hair's strands and the cloth's weave keep their
    colours).
    """
    image = np.asarray(image, np.float32)
    weight = _block_weight(image, origin, solid)
    outline = None if solid is None else _outline_darks(image, solid)
    if outline is not None:
        weight = np.zeros(image.shape[0] * image.shape[1], np.float32) if weight is None else weight
        weight[outline[0]] = np.maximum(weight[outline[0]], outline[1])
    if weight is None:
        return None
    index = np.flatnonzero(weight > 1e-3)
    if index.size == 0:
        return None
    # a pixel that is itself a warm colour (skin at the edge of dark hair, a brown strand) is its material, whatever
    # the reduced pixel it lies in reads as: from _GREY_C[1] of its own C* up, as a warm reduced pixel is
    pixels = np.take(image.reshape(-1, 3), index, axis=0)
    own_lab = to_lab(np.clip(pixels, 0, 1)[None])[0]  # one row: cv2 converts row by row
    grey = _falling(np.hypot(own_lab[:, 1], own_lab[:, 2]), *_GREY_C)  # 1: grey by its own C*, 0: a colour
    coloured = grey < 1  # the hue of those only (most are grey)
    own_warm = _warmth(np.degrees(np.arctan2(own_lab[coloured, 2], own_lab[coloured, 1])) % 360)
    keep = weight[index]
    keep[coloured] *= 1 - own_warm * (1 - grey[coloured])
    index, pixels, keep = index[keep > 1e-3], pixels[keep > 1e-3], keep[keep > 1e-3]
    if index.size == 0:
        return None
    return _packed(index, keep, pixels)


def with_material(neutral: NeutralDarks | None, image: np.ndarray, material: np.ndarray | None,
                  ) -> NeutralDarks | None:
    """``neutral`` (``neutral_darks`` of ``image``, (h, w, 3) float32 RGB in [0, 1]) with the pixels of a near-neutral
    dark ``material`` ((h, w) weights in [0, 1]; None: none) counted whatever their hue, each at the larger of the two
    weights: a black beard (relight_rt.relight.dark_beard) is a near-black material even where its faint cast is warm,
    which ``neutral_darks`` leaves alone as brown hair or skin (p024's beard brightened 2-3x went brown, C* 6 -> 10)."""
    if material is None:
        return neutral
    weight = np.asarray(material, np.float32).ravel()
    index = np.flatnonzero(weight > 1e-3)
    if index.size == 0:
        return neutral
    if neutral is not None:  # the union: neutral_darks' own pixels at the larger weight
        own = neutral.index[0] // 3
        merged = np.zeros(weight.shape, np.float32)
        merged[own] = neutral.weight
        np.maximum(merged, weight, out=merged)
        index = np.union1d(index, own)
        weight = merged
    return _packed(index, weight[index], np.take(np.asarray(image, np.float32).reshape(-1, 3), index, axis=0))


def _packed(index: np.ndarray, weight: np.ndarray, pixels: np.ndarray) -> NeutralDarks:
    """The ``NeutralDarks`` of the photo's flat pixel indices ``index`` (k,), their weights (k,) and colours (k, 3)."""
    relative, size, y = neutral_chroma(pixels.T)  # (3, k)
    return NeutralDarks(*(readonly(np.ascontiguousarray(a)) for a in (
        index * 3 + np.arange(3)[:, None], weight.astype(np.float32), relative, size, y)))


def keep_neutral(colour: np.ndarray, gain: np.ndarray, neutral: NeutralDarks | None) -> np.ndarray:
    """The relit ``colour`` (h, w, 3) with the photo's near-neutral darks no more colourful than the photo shows
    them, as far as the new light's own colour allows (a new array; ``colour`` itself when there is nothing to do).

    A dark near-grey pixel (dark hair, a black sweater) carries a faint cast: the photo's shade light, a
    backdrop's spill, JPEG's chroma. A gain that brightens it keeps its chromaticity, and Lab chroma grows with
    lightness (C* ~ the chroma relative to luminance x Y^(1/3)): under a white side lamp that brightened it 2-4x,
    dark hair came out blue-grey or violet (the first look's p264, p272, p287), though a white light changes
    brightness, not colour. Here Q, the relit colour, is taken without the light's colour t (``gain`` at luminance
    1, per pixel), at its luminance Y'; its chroma relative to Y' keeps the pixel's own direction c (the photo's,
    ``neutral_darks``) and at most s |c|, s = (Y / Y')^NEUTRAL_CHROMA_EXP capped at 1 (the photo's C* at the new
    lightness), nor more than Q had (what the dark rules and the fill left):
    Q -> t Y' (1 + c min(s, |Q / t / Y' - 1| / |c|)), blended by the near-neutral weight and by how much brighter
    Y' is than Y (none below ``NEUTRAL_LIFT[0]`` x, all from ``NEUTRAL_LIFT[1]`` x: the photo's own light still gives
    the photo back). The light's colour stays: campfire tints grey hair orange, a cool window leaves it cool, a
    white lamp as grey as the photo had it, and where ``gain`` has none of a channel (1e-4 or less: a pure cyan
    lamp) the pixel is left as it came. A real colour (C* past ``_GREY_C[1]``: a teal shirt, skin) is left
    alone. ``gain``: (h, w, 3) the factor the colour was relit by; ``neutral``: ``neutral_darks`` of the photo
    (None: nothing to do). Only the k pixels ``neutral`` names are read and written, channel by channel in float32.
    """
    if neutral is None:
        return colour
    q = np.take(colour.reshape(-1), neutral.index)  # (3, k)
    step = neutral_values(q, np.take(gain.reshape(-1), neutral.index), *neutral[1:])
    if step is None:
        return colour
    out = colour.copy()
    out.reshape(-1)[neutral.index] = step
    return out


def neutral_values(q: np.ndarray, g: np.ndarray, n: np.ndarray, c: np.ndarray, size: np.ndarray, y0: np.ndarray
                   ) -> np.ndarray | None:
    """``keep_neutral``'s step on k pixels, channel by channel: the relit colour ``q`` (3, k), the gain ``g`` (3, k)
    it was relit by (only its colour counts: the light's), and the photo's ``NeutralDarks`` fields there (weight
    ``n`` (k,), relative chroma ``c`` (3, k), its length ``size`` (k,), luminance ``y0`` (k,)); a new (3, k) float32
    array (``g`` is used as scratch), or None when the light brightens none of them (a pixel whose gain has a channel
    at or below 1e-4 is left as it came: a pure-coloured light). The studio's background grade
    applies it to its sample (relight_rt.relight.compose ``sampled_grade``; sh.js ``neutralStep`` the same)."""
    # only what the light brightens can change (a white light: Y(Q) is Y'; a coloured one, of luminance 1, about it)
    lit = _luminance(q) > y0
    # ... and only under a gain with some of every channel: where a light gives none of one (a pure cyan lamp), the
    # colour a white light would give is not known there (the tint's fallback of 1 put red into a cyan-lit dark)
    lit &= (g > 1e-4).all(axis=0)
    if not lit.any():
        return None
    g_lum = _luminance(g)
    tint = np.divide(g, g_lum, out=np.ones_like(g), where=(g_lum > 1e-4) & (g > 1e-4))
    white = q / tint  # the relit colour as a white light of the gain's brightness would give it
    y1 = np.maximum(_luminance(white), 1e-6)
    off = np.divide(white, y1, out=white)
    off -= 1
    keep = np.minimum(np.minimum((y0 / y1) ** NEUTRAL_CHROMA_EXP, 1), np.sqrt(np.einsum("ij,ij->j", off, off)) / size)
    blend = np.clip((y1 / y0 - NEUTRAL_LIFT[0]) / (NEUTRAL_LIFT[1] - NEUTRAL_LIFT[0]), 0, 1)
    blend *= n
    blend *= lit
    blend *= y1
    # Q + blend (t Y' (1 + c keep) - Q), with Q = t Y' (1 + off)
    step = np.multiply(c, keep, out=g if g.dtype == np.float32 and g.flags.writeable else None)
    step -= off
    step *= tint
    step *= blend
    step += q
    return step


def neutral_chroma(colour: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``NeutralDarks``' chroma, its length and luminance of (3, k) colours: (P - Y) / Y (Y floored at 1e-3), its
    length (at least 1e-6), Y (at least 1e-6), float32."""
    y = _luminance(colour)
    relative = (colour - y) / np.maximum(y, 1e-3)
    size = np.maximum(np.sqrt(np.einsum("ij,ij->j", relative, relative)), 1e-6)
    return relative.astype(np.float32), size.astype(np.float32), np.maximum(y, 1e-6).astype(np.float32)


def _luminance(rgb: np.ndarray) -> np.ndarray:
    """(k,) Rec. 709 luminance of (3, k) channel rows, elementwise (a BLAS product wakes its threads: ~1 ms)."""
    return REC709[0] * rgb[0] + REC709[1] * rgb[1] + REC709[2] * rgb[2]


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

