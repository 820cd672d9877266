"""The deep shadow's fill where no face mesh covers it: its albedo is its rim's, so that it meets the ratio unseen.

Where the photo's own shading is near zero the relighting factor adds the new light's change instead of multiplying the
photo (relight_rt.relight.shadow_fill ``ShadowFill.shadow_weight``, relight_rt.relight.factor ``Factor.gain_and_fill``);
around it the photo is multiplied by the ratio. The two agree at the handover only where they see the same albedo: the
ratio the photo's own, A x photo / own (``own`` the pipeline's luminance under the photo's own light), the fill
stage 1's A. Stage 1 often takes a hard shadow for a dark albedo (on Extended Yale B's side-lit faces the shaded cheek's
albedo came out at 0.16-0.23 beside 0.55-0.7 lit), so a fill on its albedo stays dark while the ratio just outside lifts
the dim photo 10-20x: the weight's contour, a threshold's inside a black area where the photo has no edge, becomes a
hard edge around a dark patch (yaleB21 from -50 degrees, which no face mesh is found for: ``FacePass.find``).

On a face mesh's skin the fill takes the albedo of the lit skin around (``ShadowFill.shadow_weight``). Elsewhere
``rim_lift`` gives it the albedo the ratio shows at the fill's own rim (the trusted pixels within ``RIM_REACH``
network pixels of it), spread inward over ``RIM_SPREAD`` of the window's side: the fill then joins the ratio at its
border whatever the threshold, and the shadow's interior takes the surface that borders it. The rim is read where
the photo is as bright as the pipeline's own image says (``RIM_SHOWN``): in the penumbra just outside the fill the
transport's shading is smoother than the photo's edge, the photo falls short of it and shows a darker albedo (beside
yaleB21's fill from -50, 0.38-0.44 against the lit cheek's 0.6-0.7: a dark fill, the photo-lit triangle on the lower
cheek left standing out). A shadow's rim is the
same surface as the shadow far more often than another material, but not always (dark hair in shade beside lit skin,
a black jacket beside a white shirt): the rim's albedo is taken only as far as stage 1 sees skin there (its skin
probability times ``RIM_SKIN_GATE``, smoothed: skin is one material, hair and cloth keep stage 1's albedo) and, in a
photo with colour, as far as the rim's own colour is a skin's (relight_rt.relight.look ``skin_chroma``'s rule):
stage 1 gives clothes a skin probability up to about 0.5, where the gate is open, and a black jacket in shade
beside a lit white shirt was lifted 3.8x (dark clothes glowing in the shadow). A grey photo (Extended Yale B) has
no colour to tell by: there the skin probability alone decides.
"""

from __future__ import annotations

import cv2
import numpy as np

from ..image.color import REC709, channel_max
from .look import skin_chroma

RIM_REACH = 3.0  # the fill's rim: trusted pixels within about this many network pixels of its weight (a Gaussian)
RIM_SPREAD = 0.08  # ... their albedo spread inward over this share of the window's side
# ... each counted from none to all as photo / own goes from the first to the second share of its median over the lit
# person (a penumbra, where the photo falls short of the model's smooth shading, is not the rim); None: all count
RIM_SHOWN: tuple[float, float] | None = (0.5, 0.9)
RIM_RANGE: float | None = 4.0  # ... at most this factor from stage 1's albedo (None: the rule off)
RIM_SKIN_GATE = 2.0  # ... taken as far as stage 1's skin probability times this (1: all; a shaded cheek reads 0.3-0.5)
RIM_SKIN_SIGMA = 2.5  # ... that probability smoothed over this many network pixels
RIM_GREY = 0.02  # ... a photo whose lit person shows no channel spread past this (its 99th percentile) is grey
SPREAD_PRIOR = 1e-3  # spread_mean: the window's mean counts as this much weight at every pixel


def spread_mean(values: np.ndarray, weight: np.ndarray, sigma: float, fallback: np.ndarray) -> np.ndarray:
    """(r, r') float32: the ``weight``-weighted mean of ``values`` around each pixel (a Gaussian of ``sigma``), leaning
    on their mean over the whole window (``SPREAD_PRIOR``) where little weight is near; ``fallback`` where there is
    no weight at all.

    A plain normalised convolution falls back at the blur's reach (OpenCV cuts its kernel at 4 sigma): the far side
    of a face lit from 70 degrees, 80 px from any lit skin, kept stage 1's albedo beyond a straight line down the
    cheek (Extended Yale B yaleB08 and yaleB33 from -70: a vertical step in the fill, 0.14 of the pair's new edges).
    Skin is one material: far from its lit part the best guess is that part's albedo as a whole.
    """
    total = float(weight.sum())
    if total <= 1e-6:
        return np.asarray(fallback, np.float32).copy()
    prior = float((values * weight).sum()) / total
    num = cv2.GaussianBlur((values * weight).astype(np.float32), (0, 0), sigma)
    den = cv2.GaussianBlur(weight.astype(np.float32), (0, 0), sigma)
    return ((num + SPREAD_PRIOR * prior) / (den + SPREAD_PRIOR)).astype(np.float32)


def rim_colour_gate(rgb: np.ndarray, rim: np.ndarray, lit: np.ndarray, sigma: float) -> np.ndarray | None:
    """(r, r') in [0, 1]: how far the colour of the ``rim`` pixels (weights, in [0, 1]) spread over ``sigma`` pixels
    around each pixel, at the lit person's luminance, is a skin's (``skin_chroma``'s YCrCb rule on the network image
    ``rgb``, (r, r', 3)); None where the photo is grey (the ``lit`` person's channel spread under ``RIM_GREY``: a
    black jacket and a white shirt are grey in any photo, the skin elsewhere is not) or there is no rim."""
    rim = rim.astype(np.float32)
    spread = (channel_max(rgb) - np.minimum(np.minimum(rgb[..., 0], rgb[..., 1]), rgb[..., 2]))[lit]
    if spread.size == 0 or float(rim.sum()) <= 1e-6 or float(np.percentile(spread, 99)) < RIM_GREY:
        return None
    # spread_mean's rule, the three channels in one blur, at a quarter of the size (a colour spread over sigma >= 8
    # pixels loses nothing there; the whole weight took 17 ms instead of 7 on the 2.5-MP reference photo's network
    # window at full size)
    weighted = np.dstack([rgb * rim[..., None], rim]).astype(np.float32)
    prior = weighted[..., :3].reshape(-1, 3).sum(axis=0) / float(rim.sum())
    step = 4 if sigma >= 8 else 1
    small = cv2.resize(weighted, None, fx=1 / step, fy=1 / step, interpolation=cv2.INTER_AREA) if step > 1 else weighted
    small = cv2.GaussianBlur(small, (0, 0), sigma / step)
    both = cv2.resize(small, rim.shape[::-1], interpolation=cv2.INTER_LINEAR) if step > 1 else small
    colour = ((both[..., :3] + SPREAD_PRIOR * prior) / (both[..., 3:] + SPREAD_PRIOR)).astype(np.float32)
    # the rule is for a lit colour (a dim one reads grey by it: its Cr, Cb scale with its luminance): the rim's
    # colour at the lit person's median luminance (the rim's own pixels are partly shaded)
    level = float(np.median(rgb[lit] @ REC709))
    colour *= (level / np.maximum(colour @ REC709, 1e-4))[..., None]
    # skin_chroma blurs this already-spread colour once more (its own 1.5-px spread, a plain blur under a weight of
    # ones): kept, since its YCrCb ramp read straight off the colour moves the gate by up to 0.008 (mean 1e-4) on the
    # bundled example and two real portraits (tidy17): not the same result to float rounding
    return skin_chroma(np.clip(colour, 0, 1), np.ones(rim.shape, np.float32))[1]


def skin_gate(skin: np.ndarray) -> np.ndarray:
    """(r, r') float32 in [0, 1]: how far stage 1 sees skin around each pixel: its skin probability (unpremultiplied)
    smoothed over ``RIM_SKIN_SIGMA`` network pixels, times ``RIM_SKIN_GATE``, at most 1 (a shaded cheek reads 0.3-0.5:
    open; hair and cloth closed, the rule's edge soft)."""
    return np.clip(cv2.GaussianBlur(skin.astype(np.float32), (0, 0), RIM_SKIN_SIGMA) * RIM_SKIN_GATE, 0, 1)


def rim_lift(albedo: np.ndarray, photo: np.ndarray, own: np.ndarray, weight: np.ndarray, trust: np.ndarray,
             gate: np.ndarray, floor: float, rgb: np.ndarray | None = None) -> np.ndarray | None:
    """(r, r') float32: the factor on the fill's albedo that gives it its rim's (module docstring), 1 where stage 1
    sees no skin; None when the rule is off (``RIM_RANGE`` None).

    Args:
        albedo: (r, r') stage 1's albedo luminance (what the fill multiplies the change of shading by).
        photo, own: (r, r') the photo's luminance and the pipeline's under the photo's own light (> 0).
        weight: (r, r') the fill's weight in [0, 1] (``ShadowFill.shadow_weight``'s w).
        trust: (r, r') in [0, 1], the pixels whose photo / own is measured (the person's, lit enough, off the fill).
        gate: (r, r') in [0, 1], how far stage 1 sees skin (``skin_gate`` of its skin probability, unpremultiplied).
        floor: the albedo the lift is measured against is floored here (black cloth, hair).
        rgb: (r, r', 3) the network image there: the rim's colour must be a skin's (``rim_colour_gate``); None: not
            asked.
    """
    if RIM_RANGE is None:
        return None
    shows = (photo / own).astype(np.float32)
    lit = trust > 0.5
    # only where the photo is as bright as the model says (against the lit person's median): in a penumbra the
    # transport's shading is smoother than the photo's, the photo falls short of it and shows a darker albedo
    bright = np.float32(1)
    if RIM_SHOWN is not None:
        norm = float(np.median(shows[lit])) if lit.any() else 1.0
        bright = np.clip((shows / max(norm, 1e-6) - RIM_SHOWN[0]) / (RIM_SHOWN[1] - RIM_SHOWN[0]), 0, 1)
    rim = (trust * bright * cv2.GaussianBlur(weight.astype(np.float32), (0, 0), RIM_REACH)).astype(np.float32)
    seen = albedo * shows  # the albedo the ratio shows: photo x new / own = seen x new / A
    around = spread_mean(seen, rim, RIM_SPREAD * max(weight.shape), albedo)
    # a lift, never past the albedo the person's trusted pixels show (their median): the rim of a stage 1 error
    # (a bright albedo around an eye, the ratio blowing it out) is not spread into the shadow it borders
    level = float(np.median(seen[lit])) if lit.any() else float(np.max(albedo))
    around = np.minimum(around, np.maximum(albedo, level))
    lift = np.clip(around / np.maximum(albedo, floor), 1, RIM_RANGE)
    asked = rgb is not None and bool(((lift > 1) & (gate > 0)).any())  # (nothing to gate: not measured)
    colour = rim_colour_gate(rgb, rim, lit, RIM_SPREAD * max(weight.shape)) if asked else None
    gate = gate if colour is None else gate * colour
    return (lift ** gate).astype(np.float32)
