"""Put a person into another scene, lit like that scene: ``composite``.

Steps (all colour arithmetic in linear light; both photos are read as sRGB, as cameras write them):

1. The background's light: ``relight_rt.background.light_from_background`` (its rule and scale are
   documented there), unless a light is given.
2. The person photo is linearised and decomposed (stage 1); the new light is
   * white-balanced to the background (only when a light is given: the background's own light needs
     none): its colour is multiplied by per-channel gains so that the person's mean shading colour
     under it has the chromaticity it has under the background's light (the light's direction and
     its colour differences between directions stay);
   * exposed (relight_rt.exposure): "auto" scales it so the person's mean luminance equals the one the
     background's light gives the person, i.e. the brightness the scene implies in the background
     photo's own units (for the background's own light "auto" and "physical" are the same); an EV
     number offsets that; "physical" keeps the light as given.
3. Relit with ``Relighter.relight(..., background="transparent", exposure="physical")`` (straight-alpha
   RGBA, the soft matte as alpha).
4. Placed: its bounding box (where the matte is > 0.5 %) is scaled to ``height`` × the background's
   height and its bottom centre (the feet) put at ``position`` (x, y) in fractions of the background's
   width and height. Default: the same relative height and bottom-centre position as in its own photo.
   Parts beyond the background's edges are cut off.
5. Optional contact shadow (``shadow=True``): a soft dark ellipse on the ground under the feet
   (Gaussian falloff, half as wide as the person's box, 1/25 of its height, darkening at most 55 %),
   multiplied into the background before the person is laid over it.
6. Alpha blending of the premultiplied, resampled person over the linear background, then sRGB again.
   Pixels away from the person (and its shadow) are the background's, unchanged.
"""

from __future__ import annotations

import math
import os

import cv2
import numpy as np

from . import exposure as _exposure
from ._errors import RelightError
from .background import _LUT, light_from_background, read_background
from .color import linear_to_srgb, srgb_to_linear
from .masks import AUTO, resolve_mask

__all__ = ["composite", "parse_position"]

_ALPHA_BOX = 0.005  # the person's box: matte above this
SHADOW_STRENGTH = 0.55


def parse_position(value) -> tuple[float, float]:
    """'X,Y' (or a pair) → (x, y), each a fraction of the background in [0, 1]."""
    if isinstance(value, str):
        parts = value.replace(" ", "").split(",")
        if len(parts) != 2:
            raise RelightError(f"position: expected X,Y (fractions of the background, e.g. 0.5,0.9), got {value!r}")
        value = parts
    try:
        x, y = (float(v) for v in value)
    except (TypeError, ValueError):
        raise RelightError(f"position: expected two numbers X,Y in [0, 1], got {value!r}") from None
    if not (0 <= x <= 1 and 0 <= y <= 1):  # also rejects NaN
        raise RelightError(f"position: expected X,Y each in [0, 1] (fractions of the background), got {x:g},{y:g}")
    return x, y


def _check_height(height) -> float | None:
    if height is None:
        return None
    try:
        h = float(height)
    except (TypeError, ValueError):
        raise RelightError(f"height: expected a fraction of the background height in (0, 1], got {height!r}") from None
    if not 0 < h <= 1:
        raise RelightError(f"height: expected a fraction of the background's height in (0, 1], got {height!r}")
    return h


def _matte_on_the_photo(relighter, image, mask):
    """The automatic matte, when one is needed, taken on the photo as it is (sRGB, what the matting graphs
    see in every other command), not on the linearised copy stage 1 gets here: linear values are darker and
    lose the person in dim photos. A given mask, or the alpha of an RGBA photo, passes through unchanged."""
    if mask is not None and not (isinstance(mask, str) and mask == AUTO):
        return mask
    from ._io import read_image

    shown = read_image(image, "image")
    if mask is None and shown.shape[2] == 4:
        return None  # the alpha channel is the mask; _linear_person keeps it
    name = os.fspath(image) if isinstance(image, (str, os.PathLike)) else "image"
    return resolve_mask(shown, mask, matter=relighter.matter, name=name)


def _linear_person(image):
    """The person photo (path or array) as linear float32 RGB(A); alpha (the matte) is kept as it is."""
    from ._io import _decode, read_image

    if isinstance(image, (str, os.PathLike)):
        raw = _decode(image, "image")
        if raw.dtype == np.uint8 and raw.ndim == 3 and raw.shape[2] in (3, 4):
            raw = cv2.cvtColor(raw, cv2.COLOR_BGR2RGB if raw.shape[2] == 3 else cv2.COLOR_BGRA2RGBA)
            if min(raw.shape[:2]) < 2:
                raise RelightError(f"image {os.fspath(image)}: image is too small, got {raw.shape}")
            out = _LUT[raw]
            if raw.shape[2] == 4:
                out[..., 3] = raw[..., 3] * np.float32(1 / 255)
            return out
        img = read_image(image, "image")
    elif (
        isinstance(image, np.ndarray) and image.dtype == np.uint8 and image.ndim == 3 and image.shape[2] in (3, 4)
        and min(image.shape[:2]) >= 2
    ):  # fmt: skip
        out = _LUT[image]
        if image.shape[2] == 4:
            out[..., 3] = image[..., 3] * np.float32(1 / 255)
        return out
    else:
        img = read_image(image, "image")
    rgb = srgb_to_linear(img[..., :3])
    return np.concatenate([rgb, img[..., 3:]], axis=2) if img.shape[2] == 4 else rgb


def _white_balance(dec, light: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """``light`` with per-channel gains giving the person's mean shading the chromaticity it has under ``reference``."""
    t = np.asarray(dec.transport, np.float32).reshape(-1, 9)
    m = np.asarray(dec.network_mask, np.float32).reshape(-1)
    if m.sum() <= 0:
        return light

    def mean_shade(lit):
        s = np.maximum(t @ np.asarray(lit, np.float32), 0)
        c = (m @ s) / m.sum()
        return c / max(float(c @ _exposure.REC709), 1e-12)

    ref, cur = mean_shade(reference), mean_shade(light)
    if not (np.all(cur > 1e-6) and np.all(ref > 1e-6)):
        return light  # a channel without light: no meaningful balance
    return (light * (ref / cur)[None, :]).astype(np.float32)


def _box(alpha: np.ndarray) -> tuple[int, int, int, int]:
    rows = np.flatnonzero((alpha > _ALPHA_BOX).any(axis=1))
    cols = np.flatnonzero((alpha > _ALPHA_BOX).any(axis=0))
    if rows.size == 0:
        raise RelightError("mask: the person's matte is empty")
    return int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1


def composite(
    relighter,
    image,
    background,
    *,
    mask=None,
    light=None,
    position=None,
    height=None,
    shadow: bool = False,
    exposure="auto",
    fov: float = 60.0,
    white_balance: bool = True,
) -> np.ndarray:
    """Relight the person of ``image`` for the scene of ``background`` and put it there (module docstring).

    Args:
        relighter: a ``relight_rt.Relighter``.
        image: the person photo (path or array, RGB or RGBA, as for ``Relighter.decompose``).
        background: the scene photo: path or (H, W, 3) RGB array (uint8 or float in [0, 1]), >= 64 px a side,
            not grayscale, not RGBA.
        mask: the person's mask (None: the image's alpha channel), binary or soft.
        light: None (the background's own light) or anything ``Relighter.resolve_light`` accepts.
        position: (x, y) or "X,Y": where the person's bottom centre goes, fractions of the background
            in [0, 1]; None: as in its own photo.
        height: the person's box height as a fraction of the background's height, in (0, 1]; None: as in
            its own photo.
        shadow: add a soft contact shadow under the feet.
        exposure: "auto" (the brightness the background's light gives the person), an EV offset, or
            "physical" (relight_rt.exposure).
        fov: the background's horizontal field of view in degrees, (10, 170).
        white_balance: match a given light's colour to the background's (see the module docstring).

    Returns:
        (H_bg, W_bg, 3) float32 sRGB in [0, 1].

    Raises:
        RelightError: bad photos, masks or lights; fov outside (10, 170); position outside [0, 1]; a
            height outside (0, 1]; a person larger than the background after scaling.
    """
    pos = None if position is None else parse_position(position)
    frac = _check_height(height)
    mode = _exposure.parse_exposure(exposure)
    bg = read_background(background)
    bg_light, _ = light_from_background(bg, fov)
    mask = _matte_on_the_photo(relighter, image, mask)
    person = _linear_person(image)
    dec = relighter.decompose(person, mask)
    if light is None:
        lit = bg_light
    else:
        lit = relighter.resolve_light(light)
        if white_balance:
            lit = _white_balance(dec, lit, bg_light)
    target = _exposure.mean_luminance(dec.albedo, dec.transport, dec.network_mask, bg_light)
    lit = lit * np.float32(_exposure.exposure_scale(dec.albedo, dec.transport, dec.network_mask, lit, target, mode))
    rgba = relighter.relight(dec, lit, background="transparent", exposure="physical")

    # placement
    hb, wb = bg.shape[:2]
    hp, wp = rgba.shape[:2]
    y0, y1, x0, x1 = _box(rgba[..., 3])
    box_h, box_w = y1 - y0, x1 - x0
    if frac is None:
        frac = box_h / hp
    if pos is None:
        pos = ((x0 + x1) / 2 / wp, y1 / hp)
    scale = frac * hb / box_h
    new_h, new_w = max(1, round(box_h * scale)), max(1, round(box_w * scale))
    if new_h > hb or new_w > wb:
        raise RelightError(
            f"height: the person would be {new_w} x {new_h} px (W x H) after scaling, larger than the background "
            f"({wb} x {hb}); give a smaller --height"
        )
    crop = rgba[y0:y1, x0:x1]
    premult = np.concatenate([crop[..., :3] * crop[..., 3:], crop[..., 3:]], axis=2)
    interp = cv2.INTER_AREA if scale < 1 else cv2.INTER_LINEAR
    premult = cv2.resize(premult, (new_w, new_h), interpolation=interp)
    np.clip(premult, 0, 1, out=premult)
    top = int(round(pos[1] * hb)) - new_h
    left = int(round(pos[0] * wb - new_w / 2))

    # the region of the background that changes: the person's box and its shadow
    sh_w, sh_h = 0.5 * new_w, max(2.0, new_h / 25)
    foot_x, foot_y = left + new_w / 2, top + new_h - 0.25 * sh_h
    ry0, ry1, rx0, rx1 = top, top + new_h, left, left + new_w
    if shadow:
        ry0, ry1 = min(ry0, int(foot_y - 3 * sh_h)), max(ry1, int(math.ceil(foot_y + 3 * sh_h)))
        rx0, rx1 = min(rx0, int(foot_x - 1.5 * sh_w)), max(rx1, int(math.ceil(foot_x + 1.5 * sh_w)))
    ry0, ry1, rx0, rx1 = max(ry0, 0), min(ry1, hb), max(rx0, 0), min(rx1, wb)
    out = bg.astype(np.float32) * np.float32(1 / 255) if bg.dtype == np.uint8 else bg.astype(np.float32, copy=True)
    if ry1 <= ry0 or rx1 <= rx0:
        return out  # nothing of the person lands inside (feet on the top edge: y = 0)
    region_bg = bg[ry0:ry1, rx0:rx1]
    lin = _LUT[region_bg] if region_bg.dtype == np.uint8 else srgb_to_linear(region_bg)
    if shadow:
        yy, xx = np.mgrid[ry0:ry1, rx0:rx1].astype(np.float32)
        d2 = ((xx + 0.5 - foot_x) / sh_w) ** 2 + ((yy + 0.5 - foot_y) / sh_h) ** 2
        lin *= (1 - SHADOW_STRENGTH * np.exp(-2 * d2))[..., None]
    # the person's pixels inside the region
    py0, px0 = max(top, ry0), max(left, rx0)
    py1, px1 = min(top + new_h, ry1), min(left + new_w, rx1)
    if py1 > py0 and px1 > px0:
        p = premult[py0 - top : py1 - top, px0 - left : px1 - left]
        view = lin[py0 - ry0 : py1 - ry0, px0 - rx0 : px1 - rx0]
        view *= 1 - p[..., 3:]
        view += p[..., :3]
    out[ry0:ry1, rx0:rx1] = np.clip(linear_to_srgb(lin), 0, 1)
    return out
