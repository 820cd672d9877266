"""The relit person put back into the photo: their own colour at a soft edge (``Composer.foreground``), relit by
the factor (relight_rt.relight.factor) with the look's tone and colour rules (relight_rt.relight.look), over a
backdrop (``backdrop``)."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from typing import NamedTuple

import cv2
import numpy as np

from ..image.color import REC709, colour_gradient, srgb_to_linear
from ..image.compositing import Background, clean_edge_colour, over_box
from ..image.foreground import estimate_foreground, nearest_colours
from ..light.exposure import DISPLAY_GAMMA, knee
from . import head_blend
from .decomposition import Decomposition, Memo, RelightResult, intrinsic_layers, readonly
from .factor import Factor
from .kept_rim import KeptRim, SkinMap, kept_rim, skin_share, with_kept_rim
from .look import (
    NeutralDarks,
    dark_colour,
    keep_neutral,
    neutral_chroma,
    neutral_darks,
    neutral_values,
    shoulder,
    steady_chroma,
    with_material,
)

_ALPHA_MIN = np.float32(1e-3)
_SOFT = 1.0 / 255  # a matte value further than this from 0 and 1 is a soft edge (mixes person and background)
_THIN_EDGE = 4.0  # px: a soft edge no wider than this on average is feathering or anti-aliasing (F/B from beside it)
GRADE_SAMPLES = 1 << 16  # light_sums: the matte's pixels the background's grade is measured on (at most)
_SHOWN_REACH = 1.5  # shown_edge: the solid person and background are looked for this x the soft edge's width away ...
_SHOWN_REACH_MIN = 3  # ... and at least this many pixels
_SHOWN_TAU = 0.02  # ... |F - B|^2 at which colour's word on a soft pixel counts half (person and background alike)
_SHOWN_SPREAD = 4.0  # ... and it counts half where |F - B|^2 is this x the two sides' variance (texture, noise)
_SHOWN_STEADY = 1  # ... the shifts averaged over the soft pixels within this many pixels
_SHOWN_OFF_LINE = 0.1  # ... and it falls as exp(-d^2 / (this x |F - B|^2)), d the colour's distance from the line B..F
_SHARP_MARGIN = 2.0  # shown_edge: the rim's outer half steepens where the photo's edge is this x steeper than it ...
_SHARP_MAX = 8.0  # ... by at most this factor
_SHARP_NEAR = 2 / 3  # ... fully within this x the reach of the matte's 0.5 line, fading out to the reach (1 x)
_CHAMFER_AXIS = 0.955  # cv2.distanceTransform's DIST_L2 3 x 3 step along an axis (its distances run short)
_EDGE_BAND_PIXELS = 1 << 20  # shown_edge_bands: a large crop box's rule done about this many pixels at a time
# video frames with the automatic matte (``Decomposition.automatic``), as photos (RESULTS, video: figures, costs):
FRAME_RIM = True  # ... keep the background's rim (``Composer.shown_rim``; videorim44)
FRAME_EDGE = True  # ... go over their own background with the edge the frame shows (``shown_edge_near``; videoedge44)


def consistent(image: np.ndarray, alpha: np.ndarray, fg: np.ndarray, bg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Foreground and background colours adjusted so that alpha F + (1 - alpha) B is the photo again, in place.

    The estimate minimises that equation's error among smoothness terms, so it does not hold exactly; here, on
    the soft pixels, B is solved from it (kept in [0, 1]) and then F from B, so that composing them over each
    other gives the photo back (to rounding) wherever that is possible in [0, 1].
    """
    ys, xs = np.nonzero((alpha > _SOFT) & (alpha < 1 - _SOFT))  # the soft pixels (a band along the outline)
    a = alpha[ys, xs][:, None]
    i, f = image[ys, xs], fg[ys, xs]
    b = np.clip((i - a * f) / (1 - a), 0, 1)
    bg[ys, xs] = b
    fg[ys, xs] = np.clip((i - (1 - a) * b) / a, 0, 1)
    # exactly the photo where it is not mixed (copyto: the same values as a masked assignment, several times faster)
    np.copyto(bg, image, where=(alpha <= _SOFT)[..., None])
    np.copyto(fg, image, where=(alpha >= 1 - _SOFT)[..., None])
    return fg, bg


def crop_origin(dec: Decomposition) -> tuple[int, int]:
    """(y, x) of ``dec``'s crop box's top-left pixel in the photo it was cut from (a group's person: the group's)."""
    return dec.origin[0] + dec.geometry.box[0], dec.origin[1] + dec.geometry.box[2]


def photo_crop(dec: Decomposition) -> np.ndarray:
    """(h, w, 3) the photo itself in ``dec``'s crop box (not the person's colour estimated at a soft edge: what a
    colour rule reads there is then the same for a group's person and for the person relit alone)."""
    return np.ascontiguousarray(dec.geometry.crop(dec.image))


def solid_crop(dec: Decomposition) -> np.ndarray:
    """(h, w) bool: where ``dec``'s matte in its crop box is solid (the photo is the person's own colour there)."""
    return dec.geometry.crop(dec.mask) >= 1 - _SOFT


def person_neutral(dec: Decomposition, beard: np.ndarray | None) -> NeutralDarks | None:
    """``look.neutral_darks`` of the photo in ``dec``'s crop box on its solid matte, a black beard's pixels counted
    whatever their cast (``look.with_material``; ``beard``: ``Factor.beard``'s (h, w) weight, or None)."""
    photo, solid = photo_crop(dec), solid_crop(dec)
    return with_material(neutral_darks(photo, crop_origin(dec), solid), photo, None if beard is None else beard * solid)


def soft_edge_width(alpha: np.ndarray) -> float:
    """Mean width in pixels of a matte's soft edge: its soft pixels over the length of its outline."""
    soft = int(np.count_nonzero((alpha > _SOFT) & (alpha < 1 - _SOFT)))
    if soft == 0:
        return 0.0
    inside = (alpha > 0.5).astype(np.uint8)
    outline = int(np.count_nonzero(inside - cv2.erode(inside, np.ones((3, 3), np.uint8))))
    return soft / max(outline, 1)


def background_grade(colour: np.ndarray, own: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """(3,) float32: the person's change under the new light, one gain per channel on the photo's values, that
    grades the original background (``Background.grade``, relight_rt.image.compositing).

    The change is measured in light: the relit colour and the person's own colour decoded from sRGB, each summed
    over the matte per channel (a ratio of means, so the bright pixels that carry the exposure weigh as they
    show), G = new / old. The backdrop's values are multiplied by G ** (1 / DISPLAY_GAMMA), the exposure's rule for
    light seen on a display (relight_rt.light.exposure: values ~ light ** (1 / 2.2)), so its light moves by G, as the
    person's did. 1 where the person is black.

    Args:
        colour, own: (h, w, 3) the relit person and the person's own colour (their foreground), straight, sRGB.
        alpha: (h, w) or (h, w, 1) the matte there.
    """
    return grade_of_sums(*light_sums(colour, own, alpha))


def light_sums(colour: np.ndarray, own: np.ndarray, alpha: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """``background_grade``'s sums over a matte: the relit and the own colour in light, each (3,) float64, and the
    matte's sum. Sums of several people (a group, relit person by person) add up to the group's grade.

    A mean needs no more than ``GRADE_SAMPLES`` pixels: the sums are taken on an even sample of the matte's pixels
    and scaled to all of them (decoding sRGB costs ~100 ms a megapixel; the grade moves by < 0.1 % of itself)."""
    sample = _sample(alpha)
    return _summed(colour, sample), _summed(own, sample), _weight(alpha)


def _sample(alpha: np.ndarray) -> tuple[np.ndarray, np.ndarray, float] | None:
    """An even sample of the matte's pixels (at most ``GRADE_SAMPLES``, not the same columns on every row): their
    flat indices, their alpha (n, 1) and the scale from the sample's alpha sum to the whole matte's; None: empty."""
    a = alpha.reshape(-1).astype(np.float32, copy=False)
    inside = np.flatnonzero(a > 0)
    if inside.size == 0:
        return None
    step = -(-inside.size // GRADE_SAMPLES)
    while step > 1 and math.gcd(step, alpha.shape[1]) != 1:
        step += 1
    pick = inside[::step]
    w = a[pick, None]
    return pick, w, float(a.sum(dtype=np.float64)) / max(float(w.sum(dtype=np.float64)), 1e-12)


def _summed(colour: np.ndarray, sample: tuple[np.ndarray, np.ndarray, float] | None) -> np.ndarray:
    """(3,) float64: ``colour`` (h, w, 3, sRGB) decoded to light on ``_sample``'s pixels, scaled to the matte."""
    if sample is None:
        return np.zeros(3)
    pick, w, scale = sample
    values = np.clip(colour.reshape(-1, colour.shape[-1])[pick, :3], 0, 1)
    return (srgb_to_linear(values) * w).sum(axis=0, dtype=np.float64) * scale


def _weight(alpha: np.ndarray) -> float:
    return float(alpha.astype(np.float32, copy=False).sum(dtype=np.float64))


def light_sum(colour: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """(3,) float64: ``colour`` (h, w, 3, sRGB) decoded to light and summed over the matte ``alpha`` per channel
    (on ``_sample``'s pixels, scaled to the whole matte)."""
    return _summed(colour, _sample(alpha))


def own_light_sum(own: np.ndarray, alpha: np.ndarray) -> tuple[np.ndarray, float]:
    """``light_sums``' part that does not depend on the light: the own colour's sum and the matte's (kept per
    Decomposition by ``Composer``, which grades every light of one photo against them)."""
    return light_sum(own, alpha), _weight(alpha)


def grade_of_sums(new: np.ndarray, old: np.ndarray, weight: float) -> np.ndarray:
    """``background_grade`` from ``light_sums`` (summed over people where there are several)."""
    ok = old > 1e-6 * max(weight, 1.0)
    light = np.where(ok, new / np.where(ok, old, 1.0), 1.0)
    return (light ** (1.0 / DISPLAY_GAMMA)).astype(np.float32)


class HeadBlend(NamedTuple):
    """What the head pass's blend (relight_rt.relight.factor ``Factor.blend_head``) does to a ``GradeSample``'s
    pixels whatever the light: on the pixels under it, the factor is the body's blended toward the head pass's, that
    one scaled to the body's level on the head pass's skin (a light-dependent scalar, ``level``). K pixels of the
    sample; none (K = 0) without a head pass or without its skin on the sample (no level to match). ``sampled_grade``
    and the studio's sh.js ``backgroundGrade`` apply it.

    Attributes:
        index: (K,) int32, the pixels of the ``GradeSample`` under the blend, increasing.
        weight: (K,) float32 in [0, 1], the blend's weight (its feather times the matte, the matte's mean over the
            pixel).
        skin: (K,) float32, the weight the levels are matched with (the head pass's skin x the feather x the matte).
        body_scale, body_stays: (K,) float32, the body's factor per unit of shading (``Factor.factor_inputs``): its
            luminance under a light of luminance Y is body_scale x Y + body_stays.
        scale, stays: (K,) float32, the head pass's the same.
        transport: (K, 9) float32, the head pass's.
    """

    index: np.ndarray
    weight: np.ndarray
    skin: np.ndarray
    body_scale: np.ndarray
    body_stays: np.ndarray
    scale: np.ndarray
    stays: np.ndarray
    transport: np.ndarray

    @classmethod
    def empty(cls) -> HeadBlend:
        """No pixel under a head pass's blend."""
        return cls(np.zeros(0, np.int32), *(np.zeros(s, np.float32) for s in ((0,),) * 6 + ((0, 9),)))

    def every(self, step: int) -> HeadBlend:
        """The blend on every ``step``-th pixel of its ``GradeSample`` (``GradeSample.every``): those of its pixels,
        their indices in the thinned sample."""
        keep = self.index % step == 0
        if not (self.skin[keep] > 0).any():  # none of its skin kept: no level to match (``head_level``), no blend
            return HeadBlend.empty()
        return HeadBlend((self.index[keep] // step).astype(np.int32),
                         *(np.ascontiguousarray(a[keep], np.float32) for a in self[1:]))


class GradeSample(NamedTuple):
    """What ``background_grade`` reads of a relit person whatever the light, on the network frame's pixels under the
    matte (``Composer.grade_inputs``; the studio's preview grades with it, ``sampled_grade``). Under a light with RGB
    shading S = max(0, T·light) and luminance Y(S) a pixel's relit colour is ``lit * S + steady * S / Y(S)``, blended
    toward the head pass's where it has one (``head``), rolled off past its ``knee`` (relight_rt.relight.look
    ``shoulder``), as ``Composer.person_colour`` makes it, and where the photo is a near-neutral dark (``neutral``)
    its chroma kept as ``look.keep_neutral`` keeps it before that.

    Attributes:
        lit: (N, 3) float32, the colour per unit of shading that scales with the light.
        steady: (N, 3) float32, the colour per unit of the light's luminance that stays.
        transport: (N, 9) float32.
        weight: (N,) float32, the matte over the pixel (its area mean).
        knee: (N,) float32, where the shoulder starts (inf: nowhere).
        own: (N, 3) float32, the person's own colour (``Composer.foreground``'s, the matte's mean over the pixel).
        neutral: (N,) float32, the near-neutral darks' weight (``look.neutral_darks``, the matte's mean over the
            pixel; 0: none).
        head: ``HeadBlend``, the head pass's blend on K of the N pixels.
    """

    lit: np.ndarray
    steady: np.ndarray
    transport: np.ndarray
    weight: np.ndarray
    knee: np.ndarray
    own: np.ndarray
    neutral: np.ndarray
    head: HeadBlend

    @classmethod
    def empty(cls) -> GradeSample:
        """No pixel (a grade of 1)."""
        return cls(*(np.zeros(s, np.float32) for s in ((0, 3), (0, 3), (0, 9), (0,), (0,), (0, 3), (0,))),
                   HeadBlend.empty())

    def every(self, step: int) -> GradeSample:
        """Every ``step``-th pixel (the studio sends the page at most so many), float32, contiguous."""
        return GradeSample(*(np.ascontiguousarray(a[::step], np.float32) for a in self[:-1]), self.head.every(step))


def head_level(sample: GradeSample, light: np.ndarray) -> tuple[float, np.ndarray]:
    """``HeadBlend``'s light-dependent part under ``light`` (9, 3): the level the head pass's factor is scaled to
    (``Factor.blend_head``: the body's factor's luminance over the head pass's, each summed with the skin's weight)
    and the head pass's relit colour on its K pixels (K, 3) float32, before that scale."""
    head = sample.head
    light = np.asarray(light, np.float32).reshape(9, 3)
    shading = np.maximum(head.transport @ light, 0)
    y = np.maximum(shading @ REC709, 1e-4)
    colour = sample.own[head.index] * (head.scale[:, None] * shading + head.stays[:, None] * shading / y[:, None])
    on = np.flatnonzero(head.skin > 0)
    body_y = np.maximum(np.maximum(sample.transport[head.index[on]] @ light, 0) @ REC709, 1e-4)
    body = float((head.skin[on] * (head.body_scale[on] * body_y + head.body_stays[on])).sum(dtype=np.float64))
    seen = float((head.skin[on] * (head.scale[on] * y[on] + head.stays[on])).sum(dtype=np.float64))
    return body / max(seen, 1e-6), colour


def sampled_grade(sample: GradeSample, light: np.ndarray) -> np.ndarray:
    """(3,) float32 ``background_grade`` on a ``GradeSample`` under the (exposed) ``light`` (9, 3): the relit colour
    (the head pass's blended in, ``head_level``) and the own colour decoded from sRGB, summed with the matte's
    weight, G ** (1 / DISPLAY_GAMMA)."""
    shading = np.maximum(sample.transport @ np.asarray(light, np.float32).reshape(9, 3), 0)
    y = np.maximum(shading @ REC709.astype(np.float32), 1e-4)[:, None]
    colour = np.maximum(sample.lit * shading + sample.steady * shading / y, 0)
    if sample.head.index.size:  # the head pass's factor, at the body's level, blended in (``Factor.blend_head``)
        level, on_head = head_level(sample, light)
        at = sample.head.index
        colour[at] += sample.head.weight[:, None] * (np.float32(level) * on_head - colour[at])
    near = np.flatnonzero(sample.neutral > 0)
    if near.size:  # the near-neutral darks' chroma, on the own colour's (the photo's where the matte is solid)
        step = neutral_values(np.ascontiguousarray(colour[near].T), np.ascontiguousarray(shading[near].T),
                              sample.neutral[near], *neutral_chroma(np.ascontiguousarray(sample.own[near].T)))
        if step is not None:
            colour[near] = step.T
    colour = shoulder(colour, sample.knee)
    w = sample.weight[:, None]
    new = (srgb_to_linear(np.clip(colour, 0, 1)) * w).sum(axis=0, dtype=np.float64)
    old = (srgb_to_linear(np.clip(sample.own, 0, 1)) * w).sum(axis=0, dtype=np.float64)
    return grade_of_sums(new, old, float(sample.weight.sum(dtype=np.float64)))


def _side_sums(image: np.ndarray, where: np.ndarray, r: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sums over ``where`` in the (2r + 1)^2 box around each pixel: the count (h, w), ``image``'s (h, w, 3) and its
    square's (h, w, 3) (``_side_at`` reads a mean and a variance from them on the pixels it needs)."""
    w = where.astype(np.float32)
    size = (2 * r + 1, 2 * r + 1)
    box = lambda x: cv2.boxFilter(x, -1, size, normalize=False, borderType=cv2.BORDER_CONSTANT)  # noqa: E731
    return box(w), box(image * w[..., None]), box(image * image * w[..., None])


def _side_at(sums: tuple[np.ndarray, np.ndarray, np.ndarray], ys: np.ndarray, xs: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
    """``_side_sums``' mean (n, 3) and variance (n,), summed over the channels, at the pixels (ys, xs) (only
    there: on the whole crop box that arithmetic was most of ``shown_edge``'s time)."""
    count, total, squares = sums
    n = np.maximum(count[ys, xs], 1e-6)[:, None]
    mean = total[ys, xs] / n
    return mean, np.maximum(squares[ys, xs] / n - mean * mean, 0).sum(axis=1)


def _steepened(image: np.ndarray, alpha: np.ndarray, outer: np.ndarray, r: int, b_sums: tuple,
               halves: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """(n,) float32: ``alpha`` on the n pixels of ``outer`` (its soft rim's outer half, alpha < 0.5; row-major order)
    steepened about 0.5 where the photo's own edge is sharper than that half: by k = the photo's steepest colour
    step on the matte's outline within ``r`` px (per pixel, over |F - B|, the mean colours of the solid background
    within ``r``, its ``_side_sums`` ``b_sums``, and of the solid person within about 2 ``r``) over the rim's mean
    slope (0.5 over the half's width: its pixels per outline pixel within ``r``), divided by ``_SHARP_MARGIN`` (a
    Gaussian feather's mean slope is about half its steepest), within [1, ``_SHARP_MAX``]; the step is taken as far
    as colour tells the sides apart (the weight of ``shown_edge``'s colour move: alike colours, texture and noise say
    nothing of the photo's edge). The step is read on the pixels either side of the matte's 0.5 contour only: a
    sharp line elsewhere within reach (a door frame behind a blurred limb, a seam on the person) is not the
    person's edge, and a matte whose contour lies inside the photo's edge finds no step there and keeps the
    person's own pixels. The lowering is whole within ``_SHARP_NEAR`` ``r`` of the matte's 0.5 line and fades out
    linearly to none at ``r`` (``cv2.distanceTransform``): a rim ramps down from that line, and alpha that stays
    below 0.5 further out is a plateau of a matte already poor there, which a step read within the window's square
    reach would cut to 0 up to straight, box-shaped borders (shown unrelit). Never above ``alpha``: a matte that
    lies past the photo's edge is not made more opaque there. ``halves``: ``_halves`` of the crop box these rows
    are cut from, its rows from the first of these (an even row) on (``shown_edge_bands``); None: of these."""
    size = (2 * r + 1,) * 2
    ys, xs = np.nonzero(outer)
    # the tail of a wide rim lies far from the solid person: its side within 2 r, summed at half resolution
    f_sums = _side_sums(*(_halves(image, alpha) if halves is None else halves), r)
    (b, b_var), (f, f_var) = _side_at(b_sums, ys, xs), _side_at(f_sums, ys // 2, xs // 2)
    apart = ((f - b) ** 2).sum(axis=1)
    seen = (b_sums[0][ys, xs] > 0.5) & (f_sums[0][ys // 2, xs // 2] > 0.5)  # both sides within reach
    odds = apart / (_SHOWN_TAU + _SHOWN_SPREAD * (b_var + f_var))  # ``shown_edge``'s colour weight, as odds
    w = seen * odds * odds / (1 + odds * odds)
    inside = (alpha >= 0.5).astype(np.uint8)
    ring = np.ones((3, 3), np.uint8)
    outline = (cv2.dilate(inside, ring) - inside).astype(np.float32)
    # the photo's step where the matte puts the edge (either side of its 0.5 contour), not anywhere within reach
    contour = cv2.dilate(inside, ring) - cv2.erode(inside, ring)
    steepest = cv2.dilate(colour_gradient(image) * contour, np.ones(size, np.uint8))[ys, xs]
    box = lambda x: cv2.boxFilter(x, -1, size, normalize=False, borderType=cv2.BORDER_CONSTANT)  # noqa: E731
    half_width = (box(outer.astype(np.float32)) / np.maximum(box(outline), 1))[ys, xs]
    # the photo's slope over the rim's: (steepest / |F - B|) / (0.5 / half width)
    k = np.clip(steepest / np.sqrt(apart + 1e-6) * 2 * np.maximum(half_width, 1) / _SHARP_MARGIN, 1, _SHARP_MAX)
    # a rim ramps down from its 0.5 line; alpha that stays below 0.5 far from it is a plateau (a matte already poor
    # there), which the window's square reach would cut with box-shaped borders: the rule fades with the distance
    # every solid pixel that can be within r of a rim pixel is in the crop, so that the distance does not depend on
    # it (nor on a band of rows, ``shown_edge_bands``): the 3 x 3 chamfer's step along an axis is 0.955 px
    pad = math.ceil(r / _CHAMFER_AXIS) + 1
    y0, x0 = max(ys.min() - pad, 0), max(xs.min() - pad, 0)
    far = cv2.distanceTransform(1 - inside[y0 : ys.max() + pad + 1, x0 : xs.max() + pad + 1], cv2.DIST_L2, 3)
    near = np.clip((1 - far[ys - y0, xs - x0] / r) / (1 - _SHARP_NEAR), 0, 1)
    k = 1 + w * (k - 1)
    a = alpha[ys, xs]
    return (a - near * (a - np.clip(0.5 + k * (a - 0.5), 0, a))).astype(np.float32)


def shown_edge(image: np.ndarray, alpha: np.ndarray, fg: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """The soft edge as the photo's colours show it, for the relit person over their own photo: (alpha', behind).

    An automatic matte's soft edge can be wider than the edge the photo shows (a smear of a few pixels past a sharp
    arm, a feathered outline against a white sky). Over the photo's own background a relit person's change then
    spreads onto plain background (a dark or bright halo), and where the matte is under the person's true cover
    the colour behind it takes the person's unrelit colour (a pale line along a shaded outline). On each soft pixel
    alpha moves toward where its colour lies on the line from the solid background's colour B to the solid person's
    F beside it (the means of the photo over alpha 0 and alpha 1 within ``_SHOWN_REACH`` x the edge's width), as far
    as colour can tell: by |F - B|^2 / (|F - B|^2 + ``_SHOWN_TAU`` + ``_SHOWN_SPREAD`` x the two sides' variance,
    texture and noise), less where the colour lies off that line (a third colour says nothing); the moves are
    averaged over 3 x 3 soft pixels. Where colour cannot tell (a pale shoe over its own reflection on a white
    floor: the reflection's colours lie on that line) the photo's sharpness still can: the rim's outer half
    (alpha < 0.5) is lowered by as much as the photo's edge beside it is steeper than the rim (``_steepened``;
    the reference clip's band beside the person, worst p99 over 12 lights 0.6-9.5 -> 0.0-0.24 levels, issue 48). A
    raise goes only as far as ``behind`` can still be solved in [0, 1] so that alpha' F + (1 - alpha') behind is
    the photo again (``fg``: the person's own colour, ``own_colours``): the photo's own light still gives the
    photo back. The matte itself (``Decomposition.mask``, the RGBA output's
    alpha, a new backdrop's composite) is not changed.

    Args:
        image: (h, w, 3) float32 RGB in [0, 1], the photo in the crop box.
        alpha: (h, w) float32 in [0, 1], the matte there.
        fg: (h, w, 3) float32, the person's own colour there.

    Returns:
        (h, w) alpha' and (h, w, 3) behind, new float32 arrays; (alpha, None) for a matte without a soft edge.
    """
    soft = (alpha > _SOFT) & (alpha < 1 - _SOFT)
    if not soft.any():
        return alpha, None
    return _shown(image, alpha, fg, soft, edge_reach(alpha), None)


def shown_edge_near(image: np.ndarray, alpha: np.ndarray, fg: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """``shown_edge``'s values (arguments and returns the same), the rule worked on the box round the soft pixels
    only, with the rows and columns it reads round them (``2 r + 4``, from even ones: the far side's half-resolution
    pixels line up, as in ``shown_edge_bands``); outside that box alpha' is alpha and behind solved from it where
    alpha is partial (a matte's faint tail, under ``_SOFT``). A video frame's person leaves most of the frame plain
    (the reference clip: the box about 40 % of a 720x940 frame)."""
    soft = (alpha > _SOFT) & (alpha < 1 - _SOFT)
    if not soft.any():
        return alpha, None
    r = edge_reach(alpha)
    rows, cols = np.flatnonzero(soft.any(axis=1)), np.flatnonzero(soft.any(axis=0))
    margin = 2 * r + 4
    y0, x0 = max(rows[0] - margin, 0) // 2 * 2, max(cols[0] - margin, 0) // 2 * 2
    y1, x1 = min(rows[-1] + 1 + margin, alpha.shape[0]), min(cols[-1] + 1 + margin, alpha.shape[1])
    half = tuple(np.ascontiguousarray(x[y0 // 2 : (y1 + 1) // 2, x0 // 2 : (x1 + 1) // 2])
                 for x in _halves(image, alpha))
    near, behind_near = _shown(np.ascontiguousarray(image[y0:y1, x0:x1]), np.ascontiguousarray(alpha[y0:y1, x0:x1]),
                               fg[y0:y1, x0:x1], soft[y0:y1, x0:x1], r, half)
    shown = np.array(alpha, dtype=np.float32)
    # outside the box ``_shown``'s colour behind with alpha' = alpha, the same float32 arithmetic on whole arrays
    with np.errstate(divide="ignore", invalid="ignore"):
        solved = np.clip((image - shown[..., None] * fg) / (1 - shown[..., None]), 0, 1)
    behind = np.where(((alpha > 0) & (alpha < 1))[..., None], solved, image).astype(np.float32, copy=False)
    shown[y0:y1, x0:x1], behind[y0:y1, x0:x1] = near, behind_near
    return shown, behind


def edge_reach(alpha: np.ndarray) -> int:
    """``shown_edge``'s reach in pixels for the matte ``alpha`` (h, w): ``_SHOWN_REACH`` x its soft edge's width."""
    return max(_SHOWN_REACH_MIN, math.ceil(_SHOWN_REACH * soft_edge_width(alpha)))


def _halves(image: np.ndarray, alpha: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``image`` (h, w, 3) and where ``alpha`` (h, w) is solid, at half resolution (``_steepened``'s far side)."""
    half = ((image.shape[1] + 1) // 2, (image.shape[0] + 1) // 2)
    solid = cv2.resize((alpha >= 1 - _SOFT).astype(np.float32), half, interpolation=cv2.INTER_AREA)
    return cv2.resize(image, half, interpolation=cv2.INTER_AREA), solid


def shown_edge_bands(image: np.ndarray, alpha: np.ndarray, fg_rows: Callable[[int, int], np.ndarray],
                     pixels: int = _EDGE_BAND_PIXELS) -> Iterator[tuple[int, int, np.ndarray, np.ndarray]]:
    """``shown_edge`` on a large crop box (a group's: the photo's size) a band of rows at a time: yields
    (y0, y1, alpha'[y0:y1], behind[y0:y1]) for consecutive bands of about ``pixels`` pixels, the same values as
    ``shown_edge`` on the whole box gives there (each band is worked on with the rows the rule reads around it,
    ``2 r + 4``: the far side's sums at half resolution reach 2 r; the reach ``r`` and the half-resolution photo are
    the whole box's), bit for bit but where ``_steepened``'s fade reads a distance that ``cv2.distanceTransform``
    sums in float over another crop (its last bits). Whole-box temporaries of that rule were ~12 photo-size arrays
    (4.9 GB for a 25-MP group).

    Args:
        image: (h, w, 3) float32 in [0, 1], the photo in the crop box (a view is fine).
        alpha: (h, w) float32 in [0, 1], the matte there, with a soft edge (the caller's to know).
        fg_rows: ``fg_rows(a, b)`` -> (b - a, w, 3) float32, the person's own colour in rows a to b of the box.
    """
    h, w = alpha.shape
    r = edge_reach(alpha)
    halves = _halves(image, alpha)
    margin = 2 * r + 4  # even, as every band's first row: the half-resolution rows line up with the box's
    rows = max(2, pixels // max(w, 1) // 2 * 2)
    for y0 in range(0, h, rows):
        y1 = min(y0 + rows, h)
        a0, a1 = max(y0 - margin, 0), min(y1 + margin, h)
        band = np.ascontiguousarray(alpha[a0:a1])
        soft = (band > _SOFT) & (band < 1 - _SOFT)
        half = tuple(x[a0 // 2 : (a1 + 1) // 2] for x in halves)
        shown, behind = _shown(np.ascontiguousarray(image[a0:a1]), band, fg_rows(a0, a1), soft, r, half)
        yield y0, y1, shown[y0 - a0 : y1 - a0], behind[y0 - a0 : y1 - a0]


def _shown(image: np.ndarray, alpha: np.ndarray, fg: np.ndarray, soft: np.ndarray, r: int,
           halves: tuple[np.ndarray, np.ndarray] | None) -> tuple[np.ndarray, np.ndarray]:
    """``shown_edge``'s rule with its reach ``r``, the soft pixels ``soft`` and ``_steepened``'s ``halves``."""
    b_sums, f_sums = _side_sums(image, alpha <= _SOFT, r), _side_sums(image, alpha >= 1 - _SOFT, r)
    ys, xs = np.nonzero(soft & (b_sums[0] > 0.5) & (f_sums[0] > 0.5))  # soft, with both sides within reach
    (b, b_var), (f, f_var) = _side_at(b_sums, ys, xs), _side_at(f_sums, ys, xs)
    i = image[ys, xs]
    d = f - b
    apart = (d * d).sum(axis=1)
    t = ((i - b) * d).sum(axis=1) / (apart + 1e-6)
    off = ((i - b - t[:, None] * d) ** 2).sum(axis=1)
    spread = b_var + f_var  # texture and noise on either side: colour tells them apart only beyond it
    w = apart / (apart + _SHOWN_TAU + _SHOWN_SPREAD * spread) * np.exp(-off / (_SHOWN_OFF_LINE * apart + 1e-6))
    shift = np.zeros(alpha.shape, np.float32)
    shift[ys, xs] = w * (np.clip(t, 0, 1) - alpha[ys, xs])
    # each pixel's reading carries its own noise: a 3 x 3 mean of the shifts (on the soft pixels) steadies it
    size = (2 * _SHOWN_STEADY + 1,) * 2
    total = cv2.boxFilter(shift, -1, size, normalize=False, borderType=cv2.BORDER_CONSTANT)
    count = cv2.boxFilter(soft.astype(np.float32), -1, size, normalize=False, borderType=cv2.BORDER_CONSTANT)
    shown = np.array(alpha, dtype=np.float32)
    shown[soft] = np.clip(alpha[soft] + total[soft] / np.maximum(count[soft], 1), 0, 1)
    outer = soft & (alpha < 0.5)  # the rim's outer half: no wider than the photo's own edge shows
    if outer.any():
        rim = _steepened(image, alpha, outer, r, b_sums) if halves is None else \
            _steepened(image, alpha, outer, r, b_sums, halves)
        shown[outer] = np.minimum(shown[outer], rim)
    # raised only as far as a colour behind in [0, 1] still gives the photo back: s F + (1 - s) behind = I needs
    # s <= I / F where F > I and s <= (1 - I) / (1 - F) where F < I
    up = soft & (shown > alpha)
    i, f = image[up], fg[up]
    reach = np.where(f > i, i / np.maximum(f, 1e-6), np.where(f < i, (1 - i) / np.maximum(1 - f, 1e-6), 1))
    shown[up] = np.minimum(shown[up], np.maximum(alpha[up], reach.min(axis=1)))
    behind = np.array(image, dtype=np.float32)
    mixed = (shown > 0) & (shown < 1)  # every partial pixel, so that the photo comes back to rounding
    s = shown[mixed][:, None]
    behind[mixed] = np.clip((image[mixed] - s * fg[mixed]) / (1 - s), 0, 1)
    return shown, behind


def backdrop_of(dec: Decomposition, bg: Background) -> np.ndarray | None:
    """The full-frame backdrop the relit person goes over (the photo itself for the original background:
    ``Composer.compose`` puts the colours behind the person's soft edge into it)."""
    return dec.image if bg.kind == "original" else bg.backdrop(dec.image)


def own_colours(dec: Decomposition, multilevel: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(h, w, 3) twice, in the crop box: the person's own colour F and the colour behind it B (read-only).

    At a soft matte's edge a pixel mixes both (I = a F + (1 - a) B); relighting or moving I would carry the
    old background along (a halo in a new scene, the new light's colour spilt onto the street). For a photo
    (``dec.photo``, or ``multilevel``) F and B come from relight_rt.image.foreground (multilevel foreground estimation);
    for a hard edge a pixel or two wide (anti-aliasing, feathering), and for video frames, the solid colours beside
    each soft pixel (relight_rt.image.foreground.nearest_colours); for a hard mask both are the photo (one array).
    """
    return colours_of(dec.geometry.crop(dec.image), dec.geometry.crop(dec.mask), dec.photo or multilevel)


def photo_colours(dec: Decomposition, automatic: bool) -> dict:
    """What a photo's Decomposition takes on for compositing (``Factor.derive``'s changes): ``foreground``
    (``own_colours``), and for the automatic matte (``automatic``) with a soft edge its ``edge`` as the photo
    shows it (``shown_edge``), ``foreground``'s B then the colour behind that edge. A mask or alpha channel given
    is the user's word and is kept as it is. A video frame's colours are the solid ones beside its soft edge
    (``own_colours``; ``FRAME_EDGE``)."""
    fg, bg = own_colours(dec)
    if not automatic or bg is fg:
        return {"foreground": (fg, bg)}
    geom = dec.geometry
    edge = shown_edge if dec.photo else shown_edge_near  # a frame's: its cost every frame
    shown, behind = edge(np.ascontiguousarray(geom.crop(dec.image)), geom.crop(dec.mask), fg)
    if behind is None:
        return {"foreground": (fg, bg)}
    return {"foreground": (fg, behind), "edge": shown}


def shown_mask(dec: Decomposition) -> np.ndarray:
    """(H, W) float32, new: the matte the relit person goes over their own photo with, ``dec.mask`` with its crop
    box's soft edge as the photo shows it (``dec.edge``, ``photo_colours``) where the Decomposition has one (the
    studio's preview composites with it, as ``Composer.compose`` does)."""
    out = np.array(dec.mask, dtype=np.float32)
    if dec.edge is not None:
        y0, y1, x0, x1 = dec.geometry.box
        out[y0:y1, x0:x1] = dec.edge
    return out


def colours_of(image: np.ndarray, alpha: np.ndarray, multilevel: bool) -> tuple[np.ndarray, np.ndarray]:
    """``own_colours``' rule on ``image`` (h, w, 3) under ``alpha`` (h, w): (F, B), read-only; ``multilevel``: the
    multilevel estimate for a soft edge wider than feathering (else the solid colours beside it). A group's person
    takes theirs from the group's matte in their box (relight_rt.relight.people: where two people meet neither is
    background)."""
    image, alpha = np.ascontiguousarray(image), np.ascontiguousarray(alpha)
    width = soft_edge_width(alpha)
    if multilevel and width > _THIN_EDGE:
        fg, bg = estimate_foreground(image, alpha, return_background=True)
        fg, bg = consistent(image, alpha, fg, bg)
    elif width > 0:
        fg, bg = nearest_colours(image, alpha)
    else:  # a hard mask: nothing of the background to take out
        fg = bg = image
    return readonly(fg), readonly(bg)


def skin_map(dec: Decomposition) -> SkinMap:
    """Where ``dec``'s person is skin, for its crop box (``kept_rim.SkinMap``): stage 1's skin map
    (``kept_rim.skin_share``), and each face mesh's outline filled as skin (a face the mesh found is skin to its
    edge, where stage 1's map at its resolution may blur into the background)."""
    geom = dec.geometry
    y0, _, x0, _ = geom.box
    share = skin_share(dec.skin, dec.network_mask)
    to_net = geom.net_affine()
    for mesh in dec.face_meshes or ():
        xy = (np.asarray(mesh)[:, :2] - (x0, y0)) @ to_net[:, :2].T + to_net[:, 2]
        cv2.fillConvexPoly(share, cv2.convexHull(np.round(xy * 16).astype(np.int32)), 1.0, cv2.LINE_AA, 4)
    return SkinMap(readonly(share), to_net)


class Composer:
    """A Relighter's relit person, at full resolution and put over a backdrop.

    Args:
        memo: where what is computed once per Decomposition is kept (the Relighter's).
        factor: the relighting factor (with detail).
        detail: the Relighter's ``detail``: the photo times the factor (True) or the network's image (False).
    """

    def __init__(self, memo: Memo, factor: Factor, detail: bool) -> None:
        self.memo, self.factor, self.detail = memo, factor, detail

    def person_colour(
        self, dec: Decomposition, light: np.ndarray, residual: np.ndarray | None, relit: np.ndarray,
        looks: tuple | None = None,
    ) -> np.ndarray:
        """(h, w, 3) straight (not premultiplied) colour of the relit person inside the crop box.

        ``light`` is the (exposed) new light, ``residual`` and ``relit`` stage 2's outputs under it (3, R, R).
        ``looks``: (``dark_colour``, ``knee``, ``neutral_darks``) of the person's own colour, when another's hold
        them (a group's person: the group's, relight_rt.relight.people); None: found from ``dec`` once.
        """
        geom = dec.geometry
        if not self.detail:
            premult = geom.to_crop(relit.transpose(1, 2, 0))
            alpha = geom.to_crop(dec.network_mask)[..., None]
            colour = np.divide(premult, alpha, out=np.zeros_like(premult), where=alpha > _ALPHA_MIN)
            np.clip(colour, 0, 1, out=colour)
            return colour
        image, _ = self.foreground(dec)
        gain, fill = self.factor.gain_and_fill(dec, light, image, residual)  # fill: deep shadow, the change added
        state = self.memo(dec)
        if dec.head is not None:
            self.factor.blend_head(dec, gain, light, fill)
        if looks is None:
            if "dark" not in state:  # once per photo: what steadying dark pixels' colour needs whatever the light
                state["dark"] = tuple(readonly(a) for a in dark_colour(image))
            if "knee" not in state:
                state["knee"] = readonly(knee(image))
            looks = state["dark"], state["knee"], self.neutral(dec)
        colour = steady_chroma(image, gain, looks[0])
        if fill is not None:
            colour[fill[0]] += fill[1]
        np.maximum(colour, 0, out=colour)
        colour = keep_neutral(colour, gain, looks[2])  # near-neutral darks: no more colour than the photo and light
        return shoulder(colour, looks[1])

    def foreground(self, dec: Decomposition, always: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """``dec.foreground`` (a photo's), or ``own_colours`` found once (a video frame's; multilevel with
        ``always``: that estimate costs about as much as the frame's relighting). Each kind is kept on its own, so
        that what was relit before cannot change a result."""
        if dec.foreground is not None and (dec.photo or not always):  # a frame's (FRAME_EDGE) are the solid colours
            return dec.foreground
        state = self.memo(dec)
        key = ("foreground", bool(always))
        if key not in state:
            state[key] = own_colours(dec, always)
        return state[key]

    def neutral(self, dec: Decomposition) -> NeutralDarks | None:
        """``person_neutral`` of ``dec`` (its beard from ``Factor.beard`` with detail), once per Decomposition."""
        state = self.memo(dec)
        if "neutral" not in state:  # read-only already
            state["neutral"] = person_neutral(dec, self.factor.beard(dec) if self.detail else None)
        return state["neutral"]

    def head_change(self, dec: Decomposition, light: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """What the head pass's blend does to the relit person's luminance under the exposed ``light`` (9, 3): (before,
        after) (H, W) float32, input frame (relight_rt.relight.head_blend ``head_change``, on ``foreground``'s
        colour); None without detail, a head pass or a blend."""
        if not self.detail or dec.head is None:
            return None
        return head_blend.head_change(self.factor, dec, np.asarray(light, np.float32), self.foreground(dec)[0])

    def kept_rim(self, dec: Decomposition, cover: np.ndarray | None = None) -> KeptRim | None:
        """``kept_rim.kept_rim`` of ``dec``'s background, matte and own colour in its crop box (``foreground``),
        once per Decomposition. The matte is the one ``compose`` lays the person over their photo with (the automatic
        matte's edge as the photo shows it, ``dec.edge``, where there is one); ``cover``: everyone's matte there, the
        same way (a group's person: the group's, ``shown_mask``), None: the person's."""
        state = self.memo(dec)
        key = ("kept_rim", cover is None)  # a group's person relit alone has no group round them
        if key not in state:
            fg, behind = self.foreground(dec)  # the colour behind a soft edge is the background's, not the person's
            alpha = dec.edge if dec.edge is not None and dec.foreground is not None else dec.geometry.crop(dec.mask)
            rim = kept_rim(behind, alpha, fg, cover, dec.geometry.crop(dec.image), skin_map(dec))  # read at points
            state[key] = None if rim is None else KeptRim(*(readonly(a) for a in rim))
        return state[key]

    def shown_rim(self, dec: Decomposition) -> KeptRim | None:
        """``kept_rim`` where ``compose`` puts it over the photo's own background: a photo's automatic matte with its
        edge as the photo shows it (``dec.edge``), a video frame's automatic matte with ``FRAME_RIM`` on
        (``dec.automatic``: the frame's matte as it is, the colours behind its soft edge those beside it,
        ``foreground``); None elsewhere (a mask or alpha given is the user's word, kept as it is, as the shown edge
        is)."""
        if dec.photo and not (dec.edge is not None and dec.foreground is not None):
            return None
        if not dec.photo and not (FRAME_RIM and dec.automatic):
            return None
        return self.kept_rim(dec)

    def own_light(self, dec: Decomposition) -> tuple[np.ndarray, float]:
        """``own_light_sum`` of ``dec``'s own colour over its matte in the crop box, found once per Decomposition."""
        state = self.memo(dec)
        if "own_light" not in state:
            state["own_light"] = own_light_sum(self.foreground(dec)[0], dec.geometry.crop(dec.mask))
        return state["own_light"]

    def grade_inputs(self, dec: Decomposition) -> GradeSample:
        """What ``compose``'s background grade reads of ``dec`` whatever the light, in the network frame (cached):
        every pixel the matte reaches there, weighted by it, with the person's own colour F (``foreground``, the
        colour ``compose`` relights and grades against, averaged under the matte over the pixel; not the network's
        image, whose edge pixels hold the backdrop behind the person). With detail, F times the relighting factor
        without stage 2's residual (relight_rt.relight.factor: lit = F albedo / own, steady = F missing / own), the
        factor's inputs taken from the solid person outward as ``Factor.gain`` takes the factor
        (``Factor.factor_inputs``), the shoulder at F's own peak (``knee``) and the head pass's blend on the pixels
        under it (``HeadBlend``, ``Factor.head_grade_inputs``); without, the network's albedo under the shading (no
        shoulder, no head pass)."""
        state = self.memo(dec)
        if "grade_inputs" not in state:
            geom = dec.geometry
            alpha = geom.crop(dec.mask)[..., None]
            near = np.zeros(alpha.shape, np.float32)  # the near-neutral darks' weight (``neutral``), with detail
            neutral = self.neutral(dec) if self.detail else None
            if neutral is not None:
                near.reshape(-1)[neutral.index[0] // 3] = neutral.weight
            net = geom.crop_to_network(np.concatenate([self.foreground(dec)[0] * alpha, alpha, near * alpha,
                                                       alpha * alpha], axis=2))
            head = None
            if self.detail:
                (y0, y1, x0, x1), maps = self.factor.factor_inputs(dec)
                net = net[y0:y1, x0:x1]
                scale, stays, transport = maps[..., :1], maps[..., 1:2], maps[..., 2:]
                head = self.factor.head_grade_inputs(dec)
            else:  # the network's picture, clip(A max(0, T·L), 0, 1) over the matte (``person_colour``)
                mask = dec.network_mask[..., None]
                transport = np.asarray(dec.transport, np.float32)
                scale = np.divide(dec.albedo, mask, out=np.zeros(dec.albedo.shape, np.float32), where=mask > _ALPHA_MIN)
                stays = None
            weight = net[..., 3]
            keep = weight > _ALPHA_MIN
            w = weight[keep]
            colour = net[..., :3][keep] / w[:, None]
            near = net[..., 4][keep] / w
            lit = colour * scale[keep] if self.detail else scale[keep]
            steady = colour * stays[keep] if self.detail else np.zeros_like(lit)
            peak = knee(colour) if self.detail else np.full(w.shape, np.inf, np.float32)
            blend = HeadBlend.empty()
            if head is not None:  # the blend's weight is its feather x the matte, so the matte's mean of it: the
                # feather x the mean of the matte squared over the matte's; its skin's, the skin x feather x matte
                feathered, skin, on_head = (a[keep] for a in head)
                share = feathered * net[..., 5][keep] / w
                at = np.flatnonzero(share > 0)
                if (skin[at] > 0).any():  # else no level to match (``head_level``), no blend
                    blend = HeadBlend(at.astype(np.int32), share[at], (skin * feathered * w)[at], scale[keep][at, 0],
                                      stays[keep][at, 0], on_head[at, 0], on_head[at, 1], on_head[at, 2:])
            state["grade_inputs"] = GradeSample(*(readonly(np.ascontiguousarray(a, np.float32)) for a in (
                lit, steady, transport[keep], w, peak, colour, near)), HeadBlend(readonly(blend.index), *(
                    readonly(np.ascontiguousarray(a, np.float32)) for a in blend[1:])))
        return state["grade_inputs"]

    def compose(
        self, dec: Decomposition, light: np.ndarray, outputs: tuple, backdrop: np.ndarray | None, clean: bool = False,
        grade: bool = False,
    ) -> np.ndarray:
        """The photo relit under the (exposed) ``light``, given stage 2's ``outputs`` (diffuse, residual, relit).

        ``clean``: a new backdrop. With detail on the person's colour is already its foreground colour relit
        (``person_colour``); the network image (``detail=False``) gets its soft edge cleaned of the old
        background here (relight_rt.image.compositing.clean_edge_colour). Over the photo's own background (not
        ``clean``) the soft edge's share of background is the colour behind it (``foreground``), so that the
        photo's own light gives the photo back. ``grade`` (the original backdrop only): it and the colour behind
        the soft edge follow the light, by the person's change (``background_grade``).
        """
        geom = dec.geometry
        _, residual, relit = outputs
        colour = self.person_colour(dec, light, residual, relit)
        alpha = geom.crop(dec.mask)
        behind = gain = None
        if clean and not self.detail:
            photo = np.ascontiguousarray(geom.crop(dec.image))
            fg, _ = self.foreground(dec, always=True)
            colour = clean_edge_colour(colour, photo, fg, alpha)
        elif not clean and backdrop is not None:
            fg, bg = self.foreground(dec)
            behind = None if bg is fg else bg
            if grade:  # over the matte, as ``own_light`` sums the own colour (the own light: a gain of 1)
                gain = grade_of_sums(light_sum(colour, alpha), *self.own_light(dec))
            if dec.edge is not None and dec.foreground is not None:  # the automatic matte's edge as the photo
                alpha = dec.edge  # shows it, with the colour behind it (``photo_colours``; a group relit as one
                # finds its colours from its matte: its people carry theirs, relight_rt.relight.people)
            # the kept background's light through the person's edge, which a new lamp leaves (the automatic matte's,
            # a photo's or a video frame's: ``shown_rim``), on the relit colour, its own
            colour = with_kept_rim(colour, self.shown_rim(dec), copy=False)
        return over_box(colour, alpha[..., None], geom.box, backdrop, dec.mask, behind, gain)

    def with_layers(self, dec: Decomposition, lit: np.ndarray, outputs: tuple, backdrop: np.ndarray | None,
                    clean: bool, grade: bool = False) -> RelightResult:
        """``compose`` and the input-frame layers that made the picture (stage 2's ``outputs`` under the exposed
        light ``lit`` with its layers: diffuse, residual or None when diffuse-only, relit)."""
        diffuse, residual, relit = outputs
        out = self.compose(dec, lit, (diffuse, residual, relit), backdrop, clean=clean, grade=grade)
        chw = lambda a: dec.to_input(np.ascontiguousarray(a.transpose(1, 2, 0)))  # noqa: E731
        layers = {
            "albedo": intrinsic_layers(dec)["albedo"],
            "shading": dec.to_input(dec.shading(lit)),
            "diffuse": chw(diffuse),
            "residual": chw(residual) if residual is not None else np.zeros(dec.image.shape, np.float32),
            "relit": chw(relit),
            "mask": np.array(dec.mask),
        }
        return RelightResult(out, layers, lit, residual is None)
