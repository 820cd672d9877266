"""The kept background's light on the person's edge: a rim the new light does not take away.

With the photo's own background kept (``relight-rt relight``'s default), the scene behind the person is still
there, and some of the light that reaches the camera from the person's outline is that scene's: fine fibres at
the edge (hair, fuzz, a thin fabric's edge) scatter forward the light of the background just behind them, and a
smooth opaque edge shows at most a thin grazing line of it. That part of the photo's edge pixel is not lit by the
photo's lamp, so a new lamp should not take it away: without it the side a new lamp misses goes near black with a
hard edge against a bright background, and the person looks pasted (``benchmarks/dark_edge.py``, issue 48).

The rule (``kept_rim`` once per photo, ``with_kept_rim`` per light): each outline pixel's rim is the background
beside it (the photo's mean over the solid background within the rim's reach, linear light: its local colour and
level, not a clipped sun) times ``KEPT_SCATTER``, times the outline's band (``relight_rt.apps.scene_rim.key_rim``'s:
where the matte says fibres, ``fibre_share``, the full reach, ``REACH`` of the person's height, falling inward;
a smooth edge only within ``GRAZE_WIDTH`` of it), and never more than the photo's own pixel holds (its luminance
at most the person's own colour's there: the rim is a share of the photo, not a light added to it). It is part of
the photo, so it is kept as it was while the rest of the pixel follows the new light: a relit pixel whose
luminance the light moved by g (relit over own, linear) is the rim plus g times the rest, so ``rim · (1 − g)``
is added where g < 1. Under the photo's own light (g = 1) the photo comes back; where the new light brightens the
edge the rim is left to scale with it (as before this rule); a dark background (Yale's backdrop, a night street)
gives no rim. The composite applies it over the photo's own background with the automatic matte only (a group's
too, its background what no one covers): a mask or alpha given is the user's word, kept as it is (as the shown edge,
``compose.shown_edge``), a new backdrop has its own rim rules (``relight_rt.apps.scene``), the RGBA output none.

The matte's softness is a weak word on fibres (``image.fibres.fibre_share``; the scene app says as much): along a
smooth cheek whose automatic matte is soft it laid a band of the background's colour 10-15 px wide (p071 under a
side lamp, issue 48's first look). So the photo's own edge has the last word (``_photo_edge``): where it is a
sharp step across the matte's outline, the outline is smooth whatever the matte says, and takes at most the grazing
line on the outline's own pixels; and the rim goes no deeper inside than the photo's own transition from background
to person (a couple of its widths): between an edge half sure it is smooth and a soft matte, a bright sky's rim went
the matte's whole reach into dark hair whose own edge is crisp, a smooth grey veil 15-20 px wide (p071, p138 under
RIGHT, issue 48's look43). And skin is never fibres (``SkinMap``): a rim of the background's colour over a
cheek, a jaw or an arm reads as a fringe, whatever the matte and the photo's edge say (p071's jaw under LEFT kept a
3-5 px olive edge where its photo's edge is soft); skin takes none (its grazing line on the outline's own pixels
read as a pale stroke drawn round the jaw).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import cv2
import numpy as np

from ..image.blur import wide_blur
from ..image.color import REC709, linear_to_srgb, srgb_to_linear
from ..image.fibres import FIBRE_RATIO, GRAZE_WIDTH, HARD_PX, WIDTH_REACH, fibre_share, outline
from .detail import extend_outward, unpremultiply

__all__ = ["KEPT_SCATTER", "LEAST", "REACH", "KeptRim", "SkinMap", "kept_rim", "with_kept_rim"]

KEPT_SCATTER = 0.7  #: the share of the background's light beside the outline that its fibres send on to the camera
REACH = 0.01  #: the rim's reach inside the outline (Gaussian sigma), share of the person's height (the scene app's
# ``RIM_RADIUS``). Both chosen on half A of the first look's photos (``benchmarks/dark_edge.py``, LEFT / RIGHT /
# campfire / rim; dark edge 0.139 without the rule), on the rule's first form (the matte's holes filled, ``body``):
# the scene app's ``SCATTER`` 0.1 gave 0.123 (-12 %); 0.3 / 0.4 / 0.6: 0.101 / 0.094 / 0.086. A reach of 0.02 with
# 0.3 did as well (0.090) but laid a band twice as wide, read at 100 % as a veil of the background's colour over dark
# hair (p286 under RIGHT, campfire). With the matte's softness alone: A 0.074 (-46 %), half B 0.174 -> 0.085 (-51 %);
# as shipped, the photo's sharp edges smooth (``_photo_edge``) and the wide reads at half size: A 0.092 (-34 %),
# B 0.111 (-36 %). The photo's own pixel bounds the rim whatever the share (``kept_rim``): 0.6 is where the photo
# allows most of it. With skin taking no rim (``SkinMap``) 0.6 gave A 0.0958 (-30.9 % of main's 0.1385 today), B
# 0.1169 (-32.9 % of 0.1742); 0.7: A 0.0923 (-33.4 %), B 0.1130 (-35.1 %); 0.75: A 0.0908 (a denser veil over
# p286's dark hair). 0.7 kept.
_SMALL_FROM = 4.0  # from this reach (px) on the rim's wide reads are on a half-size copy (``blur.wide_blur``'s
# rule): on the reference photo (reach 10 px) the rim's sum 8 % lower, its pixels the same to 3 %
SKIN_FROM, SKIN_SURE = 0.55, 0.75  # stage 1's skin probability (straight, not times the matte) where a pixel starts
# to be skin and where it surely is (linear between): chosen on half A of the first look's photos, where the rim's
# pixels over hair and cloth read 0.1-0.5 and over faces and arms 0.6-0.9 (p071's cheek and jaw 0.7-0.9, its hair
# 0.3-0.45)
_ACROSS = 4  # the photo's edge is read across the matte's 0.5 line this many pixels either side
DEEP = (1.0, 2.0)  # the rim whole up to this many of the photo's own edge widths inside the outline, none from the
# second (plus a pixel; ``_photo_edge``). Chosen on half A's dark edge (``benchmarks/dark_edge.py``): (1, 2) A 0.0960,
# (0.5, 1.5) A 0.0988, with no difference seen at 300 % on p071's hair (half B) between them; without the bound
# (edge43) A 0.0923, but a 15-20 px smoky veil over dark hair against a bright sky (p071, p138; veil43)
_SURE = 0.02  # |F - B|^2 (sRGB) at which the photo's word on its edge counts half (``compose._SHOWN_TAU``)
LEAST = 0.5 / 255 / 12.92  # a pixel whose rim luminance (linear) is below this is left out: half an 8-bit level
# on black, where sRGB is steepest
_LEVELS = 4096  # sRGB is decoded through a table of this many levels (12 bits: 20 ms -> 3 ms on a 2.5-MP crop box)
_DECODE = srgb_to_linear(np.linspace(0, 1, _LEVELS, dtype=np.float32))
_DECODE.flags.writeable = False
_ENCODE = linear_to_srgb(np.linspace(0, 1, _LEVELS, dtype=np.float32) ** 2)  # indexed by sqrt(linear): steps of
_ENCODE.flags.writeable = False  # at most 2e-4 in sRGB (sRGB is smooth in the root of light)
_PIXEL = np.dtype((np.void, 12))  # an RGB float32 pixel as one item (``with_kept_rim``'s gather and put)


def _decoded(values: np.ndarray) -> np.ndarray:
    """sRGB ``values`` (any shape, float, finite and within +-5e5: the index's int32 cast) decoded to linear light
    through ``_DECODE`` (as clipped to [0, 1] first)."""
    at = np.multiply(values, np.float32(_LEVELS - 1), dtype=np.float32)
    at += np.float32(0.5)  # the table's index clipped to its ends (``take``'s clip): as clipping the values first
    return np.take(_DECODE, at.astype(np.int32), mode="clip")


def _encoded(light: np.ndarray) -> np.ndarray:
    """Linear ``light`` (any shape, float, finite and below 2e5: the index's int32 cast) encoded to sRGB through
    ``_ENCODE`` (as clipped to [0, 1] first)."""
    at = np.sqrt(np.maximum(light, 0, dtype=np.float32))
    at *= np.float32(_LEVELS - 1)
    at += np.float32(0.5)
    return np.take(_ENCODE, at.astype(np.int32), mode="clip")


class SkinMap(NamedTuple):
    """Where the person is skin, as stage 1 sees it, for the crop box's pixels: read on the rim's pixels only.

    Attributes:
        share: (r, r) float32 in [0, 1], how surely each network pixel is skin (``skin_share``), straight (not
            times the matte), extended past the outline.
        to_net: (2, 3) float64, the affine map from a crop-box pixel (x, y) to ``share``'s (x, y).
    """

    share: np.ndarray
    to_net: np.ndarray

    def at(self, ys: np.ndarray, xs: np.ndarray) -> np.ndarray:
        """(n,) float32 in [0, 1]: ``share`` at the crop box's pixels (ys, xs), bilinear."""
        m = self.to_net
        x = (m[0, 0] * xs + m[0, 1] * ys + m[0, 2]).astype(np.float32)
        y = (m[1, 0] * xs + m[1, 1] * ys + m[1, 2]).astype(np.float32)
        return _remap_points(self.share, x, y)[:, 0]

    def on_grid(self, k: int, shape: tuple[int, int]) -> np.ndarray:
        """``shape`` (h', w') float32 in [0, 1]: ``share`` on the crop box's grid k times smaller (its pixel (x, y)
        centred on the crop box's k x + (k - 1) / 2), bilinear."""
        m = np.array(self.to_net, np.float64)
        at = np.hstack([m[:, :2] * k, (m[:, :2] @ [(k - 1) / 2, (k - 1) / 2] + m[:, 2])[:, None]])
        return cv2.warpAffine(np.ascontiguousarray(self.share, np.float32), at, (shape[1], shape[0]),
                              flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_REPLICATE)


def skin_share(skin: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """(r, r) float32 in [0, 1]: how surely each pixel is skin, from stage 1's skin map ``skin`` (r, r, times the
    matte) and its matte ``alpha`` (r, r) in the network frame: the straight probability where alpha > 0.5, spread
    past the outline from the pixels inside it (``detail.extend_outward``, as ``intrinsic_layers`` upsamples it), then
    0 below ``SKIN_FROM`` and 1 from ``SKIN_SURE``. Times the matte the map falls to ~0.5 on the outline whatever
    the person is there, so that a cheek's edge read as not skin (edge42's try)."""
    inner = alpha > 0.5
    straight = extend_outward(unpremultiply(np.asarray(skin, np.float32)[..., None], alpha), inner)[..., 0]
    return np.clip((straight - SKIN_FROM) / (SKIN_SURE - SKIN_FROM), 0, 1).astype(np.float32)


class KeptRim(NamedTuple):
    """What ``with_kept_rim`` adds to a relit person whatever the light, on the n pixels of a crop box it reaches.

    Attributes:
        index: (n,) int64, the pixels' flat indices in the crop box (row-major), increasing.
        rim: (n, 3) float32, the rim's linear RGB radiance there (the photo's units: sRGB decoded).
        own: (n,) float32, the person's own colour's luminance there (linear, Rec. 709), > 0.
    """

    index: np.ndarray
    rim: np.ndarray
    own: np.ndarray


def kept_rim(behind: np.ndarray, alpha: np.ndarray, fg: np.ndarray, cover: np.ndarray | None = None,
             image: np.ndarray | None = None, skin: SkinMap | None = None) -> KeptRim | None:
    """The rim the photo's own background puts on the person's outline (module docstring).

    Args:
        behind: (h, w, 3) float32 sRGB in [0, 1], the photo's background in the person's crop box: the photo where
            the matte is 0, the colour behind a soft edge on its soft pixels (``compose.own_colours``' B), so that
            the person's own colour at a soft edge is not taken for background.
        alpha: (h, w) float32 in [0, 1], the person's matte there (its softness says where the outline is fibres).
        fg: (h, w, 3) float32 sRGB in [0, 1], the person's own colour there (the composite's foreground).
        cover: (h, w) float32 in [0, 1], the matte of everyone in the photo there (a group's person: the group's
            matte, so that a neighbour is not taken for background and their meeting is no outline); None: ``alpha``.
        image: (h, w, 3) float32 sRGB in [0, 1], the photo there: its own edge's sharpness across the outline says
            fibres or smooth (``_photo_edge``); None: the matte's softness alone.
        skin: where the person is skin (``SkinMap``): no rim there; None: no skin map (the photo's edge and the
            matte decide).

    Returns:
        A ``KeptRim``, or None where there is none (no outline, no background beside it, a black background).
    """
    a0 = np.ascontiguousarray(alpha, np.float32)
    # unlike the scene app's key rim (``scene_rim.body``) the matte's holes and crumbs are kept: a hole shows the
    # background, whose light reaches the hole's edge too, and a crumb's rim is bounded by the photo's own pixel
    c = a0 if cover is None else np.ascontiguousarray(cover, np.float32)
    inside = (c >= 0.5).view(np.uint8)
    rows = np.flatnonzero(inside.any(axis=1))
    if rows.size == 0:
        return None
    height = float(rows[-1] + 1 - rows[0])  # the person's, in rows
    radius = max(0.5, REACH * height)
    # the wide reads on a copy k times smaller (area shrinking; k = 2 once the reach is ``_SMALL_FROM`` px), read
    # back on the band's pixels (bilinear): the rim's reach and the matte's width vary over several pixels; the
    # photo's edge and the matte's own value are read at full size
    h, w = c.shape
    k = 2 if radius >= _SMALL_FROM else 1
    grid = ((w + k - 1) // k, (h + k - 1) // k)
    shrink = (lambda x: x) if k == 1 else (lambda x: cv2.resize(x, grid, interpolation=cv2.INTER_AREA))  # noqa: E731
    scaled = lambda s: math.sqrt(max((s / k) ** 2 - (k * k - 1) / 12, 0.0625))  # a Gaussian's sigma there  # noqa: E731
    c2 = shrink(c)
    o2 = 1 - c2
    # the background's light: its colour's mean over each small pixel's background share, decoded there (a quarter
    # of the table's reads at k = 2; the mean's error at a 2 x 2 block's colour steps is the reach's to blur)
    weighted = cv2.multiply(np.asarray(behind, np.float32), cv2.merge([1 - c] * 3))
    o23 = np.repeat(o2[..., None], 3, axis=2)  # numpy's broadcasting over three channels is slow
    light2 = _decoded(shrink(weighted) / np.maximum(o23, np.float32(1e-6)))
    light2 *= o23
    reach2 = wide_blur(o2, scaled(radius))  # the share of the background within the rim's reach
    if not (reach2 > 1e-3).any():
        return None
    f2 = fibre_share(c2, float(k))
    smooth2 = np.zeros(o2.shape, np.float32)
    light_blur = wide_blur(light2, scaled(radius))
    if image is not None:  # the photo's own edge: how sure it is smooth, and how deep inside it goes
        smooth2, deep2 = _photo_edge(image, c, inside, c2, k, height)
        light_blur *= deep2[..., None]  # the rim's light (and with it its band's pixels) no deeper than that
    thin2 = wide_blur(o2, scaled(max(0.5, GRAZE_WIDTH * radius)))
    # the band's pixels: where a bound of the rim (its fields' largest over each small pixel's 3 x 3, the skin's and
    # the photo's word their least, the matte 1) adds half a level on black, the matte above 0 (a bound: the pixels
    # it leaves out take none below; on the reference photo ~40 % of those within the reach)
    most = lambda x: cv2.dilate(x, np.ones((3, 3), np.uint8))  # noqa: E731
    least = lambda x: cv2.erode(x, np.ones((3, 3), np.uint8))  # noqa: E731
    skin2 = 0 if skin is None else least(skin.on_grid(k, o2.shape))
    bound = (most(f2) * (1 - least(smooth2)) * np.minimum(2 * most(reach2), 1) + np.minimum(2 * most(thin2), 1))
    bound *= np.float32(KEPT_SCATTER) * (1 - skin2) * most((light_blur @ REC709) / np.maximum(reach2, 1e-3))
    near2 = (bound >= LEAST).view(np.uint8)
    edge = (a0 > 0) & ((near2 if k == 1 else cv2.resize(near2, (w, h), interpolation=cv2.INTER_NEAREST)) > 0)
    index = np.flatnonzero(edge)
    if index.size == 0:
        return None
    ys, xs = np.divmod(index, w)
    fields, light_at = _at_small([cv2.merge([reach2, f2, smooth2, thin2]), light_blur], ys, xs, k)
    reach, f, smooth, thin = np.clip(fields, 0, 1).T
    beside = light_at / np.maximum(reach, 1e-3)[:, None]
    ae = np.minimum(a0.reshape(-1).take(index), 1)
    graze = np.minimum(2 * ae * thin, 1)
    if image is not None:  # where the photo's own edge is sharp: no fibres, and the grazing line on its pixel only
        ring = np.ones((3, 3), np.uint8)
        graze *= 1 - smooth * (1 - (cv2.dilate(inside, ring) - cv2.erode(inside, ring)).reshape(-1).take(index))
        f *= 1 - smooth
    band = f * np.minimum(2 * ae * reach, 1) + (1 - f) * graze
    if skin is not None:  # skin is smooth and opaque: no rim of the background's colour on it, not even the grazing
        # line (on the outline's own pixels it read at 400 % as a pale, stair-stepped stroke along p071's jaw)
        band *= 1 - skin.at(ys, xs)
    rim = (np.float32(KEPT_SCATTER) * band)[:, None] * beside
    y = rim @ REC709
    seen = np.flatnonzero(y >= LEAST)  # the rest adds less than half a level whatever the photo's pixel
    index, rim, y = index.take(seen), _rows(rim, seen), y.take(seen)
    own = _decoded(_rows(np.asarray(fg, np.float32).reshape(-1, 3), index)) @ REC709
    rim *= np.minimum(1, own / np.maximum(y, 1e-12))[:, None]  # no more than the photo's own pixel holds
    keep = np.flatnonzero(own >= LEAST)
    if keep.size == 0:
        return None
    return KeptRim(index.take(keep), _rows(rim, keep), own.take(keep).astype(np.float32))


def _photo_edge(image: np.ndarray, c: np.ndarray, inside: np.ndarray, c2: np.ndarray, k: int, height: float
                ) -> tuple[np.ndarray, np.ndarray]:
    """What the photo's own edge says of the rim, on ``c2``'s grid (k times smaller than ``c``'s): how sure it is
    that the outline near each pixel is smooth, and how much of the rim it lets as deep inside as each pixel is.

    The photo is read across the matte's 0.5 line (its pixels beside one below 0.5), ``_ACROSS`` px either side
    along the matte's normal (bilinear): its edge's width is the step from one end to the other over the steepest
    one-pixel step between (a sharp edge ~1-2 px; strands over a background a gradual, ragged change).

    - Smooth: widths up to ``fibres.HARD_PX`` are smooth (a cheek, an arm or cloth against the background), from
      ``FIBRE_RATIO`` times it fibres, linear between (``fibre_share``'s scale for the matte); the word counts as far
      as the two ends' colours tell the sides apart (|step|^2 over |step|^2 + ``_SURE``: alike colours, a rim of
      them is not seen either). Why: an automatic matte is soft along some smooth edges (p071's cheek and jaw),
      where ``fibre_share`` alone laid a 10-15 px band of the background's colour under a side lamp.
    - Deep: the rim is whole up to ``DEEP[0]`` of the photo's edge widths inside the outline (the distance from
      the matte's 0.5 line), none from ``DEEP[1]`` of them plus a pixel, linear between; as far as the word counts
      (a step the photo does not show bounds nothing: the reach alone). Why: the scene's light that fibres send on is
      in the photo's own transition from background to person and no deeper; between an edge half sure it is smooth
      and a soft matte the rim went the matte's whole reach, a smooth veil of the sky's light 15-20 px into dark hair
      whose own edge is 2-4 px (p071, p138 under RIGHT / LEFT / campfire, issue 48's look43). The width read is at
      most the read's span, 2 ``_ACROSS``.

    Both averaged along the outline over ``fibres.WIDTH_REACH`` of the person's height, as ``fibre_share``
    averages the matte's width (the width weighted by the word).

    Args:
        image: (h, w, 3) float32 sRGB in [0, 1], the photo in the crop box.
        c: (h, w) float32 in [0, 1], the matte whose outline is read.
        inside: (h, w) uint8, ``c`` >= 0.5.
        c2: (h', w') float32 in [0, 1], ``c`` on a grid ``k`` times smaller (area shrinking).
        k: the grid's pixel in ``c``'s (1 or 2): (h', w') = ((h + k - 1) // k, (w + k - 1) // k).
        height: the person's height in ``c``'s rows (``inside``'s first to last row).

    Returns:
        (smooth, deep): (h', w') float32 in [0, 1] each; smooth 0 and deep 1 far from the outline.
    """
    line = outline(inside)
    h, w = c.shape
    half = c2.shape
    out = np.zeros(half, np.float32)
    points = cv2.findNonZero(line)  # (x, y) in row-major order (a third of ``np.flatnonzero``'s time); None: none
    if points is None:
        return out, np.ones(half, np.float32)
    xs, ys = points.reshape(-1, 2).T.astype(np.int64)
    at = lambda y, x: c[np.clip(y, 0, h - 1), np.clip(x, 0, w - 1)]  # noqa: E731
    gy, gx = at(ys + 2, xs) - at(ys - 2, xs), at(ys, xs + 2) - at(ys, xs - 2)  # the matte's normal, inward
    norm = np.hypot(gx, gy) + np.float32(1e-6)
    span = np.arange(-_ACROSS, _ACROSS + 1, dtype=np.float32)
    my = (ys[:, None] + (gy / norm)[:, None] * span).astype(np.float32)
    mx = (xs[:, None] + (gx / norm)[:, None] * span).astype(np.float32)
    across = cv2.remap(np.asarray(image, np.float32), mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    apart = np.sqrt(((across[:, -1] - across[:, 0]) ** 2).sum(axis=1))
    step = np.diff(across, axis=1)
    step *= step  # the channels summed one by one: numpy's reduction over an axis of three is slow, the same sum
    steepest = np.sqrt((step[..., 0] + step[..., 1] + step[..., 2]).max(axis=1))
    width = apart / np.maximum(steepest, 1e-6)
    fibres = np.clip((width / HARD_PX - 1) / (FIBRE_RATIO - 1), 0, 1)
    sure = apart * apart / (apart * apart + np.float32(_SURE))
    cell = (ys // k) * half[1] + xs // k  # the line's pixels and their word, summed on the small grid
    size = half[0] * half[1]
    wide = np.minimum(width, 2 * _ACROSS)  # the read's span bounds what it can tell
    sums = np.empty(half + (4,), np.float32)  # the line's pixels, their word, the word, the word times the width
    for j, weights in enumerate((None, sure * (1 - fibres), sure, sure * wide)):
        sums[..., j] = np.bincount(cell, weights, minlength=size).reshape(half)
    sums = wide_blur(sums, max(1.0, WIDTH_REACH * height / k))
    count, smooth, said, widths = (sums[..., j] for j in range(4))
    floor = np.float32(1e-3 * float(count.max()))
    near = count > floor
    out[near] = np.clip(smooth[near] / count[near], 0, 1)
    # how deep the rim may go: within the photo's own edge's width where it shows a step (sure), the reach where not
    # (whole-grid arithmetic, no masks)
    told = np.minimum(said / np.maximum(count, floor), 1)
    edge = widths / np.maximum(said, np.float32(1e-6))  # ~0 where nothing is told (told ~0 there)
    depth = cv2.distanceTransform((c2 >= 0.5).view(np.uint8), cv2.DIST_L2, 3)  # from the outline, in c2's pixels
    depth = np.maximum(k * (depth - 0.5), 0)  # in the photo's, from the 0.5 line (about half a pixel outside)
    deep = (DEEP[1] * edge + 1) - depth  # whole up to DEEP[0] widths, none from DEEP[1] widths plus a pixel
    deep /= (DEEP[1] - DEEP[0]) * edge + 1
    np.clip(deep, 0, 1, out=deep)
    deep -= 1
    deep *= told
    deep += 1  # 1 - told (1 - deep): as far as the photo's word counts
    return out, deep


def _at_small(fields: list[np.ndarray], ys: np.ndarray, xs: np.ndarray, k: int) -> list[np.ndarray]:
    """(n, c) float32 for each of ``fields`` (h', w'[, c], c <= 4) on a grid ``k`` times smaller (area shrinking)
    read at the full-size pixels (ys, xs), bilinear (a small pixel's centre is at k y + (k - 1) / 2; the points' maps
    made once for all); k = 1: the pixels themselves."""
    if k == 1:
        return [field[ys, xs].reshape(ys.size, -1) for field in fields]
    return _remap_points(fields, (xs.astype(np.float32) + 0.5) / k - 0.5, (ys.astype(np.float32) + 0.5) / k - 0.5)


def _remap_points(fields: np.ndarray | list[np.ndarray], x: np.ndarray, y: np.ndarray) -> np.ndarray | list:
    """(n, c) float32: ``fields`` (h, w[, c], c <= 4: more channels take OpenCV's other path, whose weights differ
    in their last bits) read bilinear at the n points (x, y) (float32, its pixels; the border repeated); a list of
    fields: a list of their reads, the maps made once."""
    n = x.size
    cols = 1024  # remap's maps are at most 32767 long a side: the points laid out in rows of this many
    pad = -n % cols
    mx, my = np.pad(x, (0, pad)).reshape(-1, cols), np.pad(y, (0, pad)).reshape(-1, cols)
    read = lambda f: cv2.remap(f, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE  # noqa: E731
                               ).reshape(n + pad, -1)[:n]
    return [read(f) for f in fields] if isinstance(fields, list) else read(fields)


def _rows(a: np.ndarray, index: np.ndarray) -> np.ndarray:
    """(n, 3) float32: the rows ``index`` (n,) of ``a`` (m, 3) float32, a pixel's three channels taken as one item
    (numpy's row gather goes a channel at a time: a third of the time on the rim's ~10^5 pixels)."""
    return np.ascontiguousarray(a, np.float32).view(_PIXEL)[:, 0].take(index).view(np.float32).reshape(-1, 3)


def with_kept_rim(colour: np.ndarray, kept: KeptRim | None, copy: bool = True) -> np.ndarray:
    """``colour`` with the kept rim: on ``kept``'s pixels, where the new light leaves the pixel's luminance g (its
    linear luminance over the own colour's) below 1, the rim's part of the photo that the light took with it added
    back: rim · (1 − g) per channel. The background's grade (``Background.grade``) is not followed: it moves the
    backdrop only, the person's pixels are the same with and without it.

    Args:
        colour: (h, w, 3) float32 sRGB, the relit person's straight colour in the crop box (not modified).
        kept: ``kept_rim`` of the same crop box, or None (``colour`` returned as it is).
        copy: False: written into ``colour`` where it is a writeable row-major float32 array (a caller's own: the
            composite's relit person; a copy of a 2.5-MP photo's crop box is ~0.8 ms of the light's ~4 ms).

    Returns:
        (h, w, 3) float32, a new array (``colour`` itself when ``kept`` is None, or written into with ``copy`` False).
    """
    if kept is None:
        return colour
    own = not copy and colour.dtype == np.float32 and colour.flags.c_contiguous and colour.flags.writeable
    out = colour if own else np.array(colour, dtype=np.float32)
    pixels = out.reshape(-1, 3).view(_PIXEL)[:, 0]  # a pixel's three channels as one item: one gather, one put
    relit = _decoded(_rows(out.reshape(-1, 3), kept.index))
    lost = 1 - (relit @ REC709) / kept.own
    # written only where it adds at least ``LEAST`` (half an 8-bit level on black): a light that leaves the edge as
    # it was (the photo's own, to rounding) leaves its pixels as they were, not re-encoded through the table
    at = np.flatnonzero(lost * (kept.rim @ REC709) >= LEAST)
    if at.size == kept.index.size:  # all of them (a light that darkens the whole edge): no gathers
        index, rim = kept.index, kept.rim
    elif at.size:
        index, rim, relit, lost = kept.index.take(at), _rows(kept.rim, at), _rows(relit, at), lost.take(at)
    else:
        return out
    np.put(pixels, index, np.ascontiguousarray(_encoded(relit + rim * lost[:, None]), np.float32).view(_PIXEL)[:, 0])
    return out
