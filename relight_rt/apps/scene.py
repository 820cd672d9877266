"""Put a person into another scene, lit like that scene: ``composite``.

Steps (all colour arithmetic in linear light; both photos are read as sRGB, as cameras write them):

1. The background's light: ``relight_rt.light.from_background`` (its rule, its fitted numbers and the key light it finds
   are documented there; ``key_light=(azimuth, elevation)`` steers the key), unless a light is given.
2. The person photo is linearised and decomposed (stage 1); the new light is
   * white-balanced to the background (only when a light is given: the background's own light needs
     none): its colour is multiplied by per-channel gains so that the person's mean shading colour
     under it has the chromaticity it has under the background's light;
   * exposed (relight_rt.light.exposure): "auto" scales it so the person's mean luminance equals the one the
     background's light gives the person, i.e. the brightness the scene implies in the background
     photo's own units (for the background's own light "auto" and "physical" are the same); an EV
     number offsets that; "physical" keeps the light as given.
3. Relit with ``Relighter.relight(..., background="transparent", exposure="physical")`` (straight-alpha
   RGBA, the soft matte as alpha); over a transparent background the Relighter relights the person's
   foreground colour, so the old background does not ride along in the hair and soft edges.
4. Placed (``relight_rt.apps.scene_place``): a *full-body* person (the photo's bottom border does not cut them) stands
   with their feet (the matte's lowest rows) on the ground at ``position`` (default: x as in their own photo,
   y = ``DEFAULT_FEET``), as tall as perspective makes them for a level camera ``camera_height`` metres above the
   ground (default ``CAMERA_M``, a standing camera) whose horizon is the row ``horizon`` (default: where the
   background's verticals put it, below any sky where they see the camera turned up, else 0.5, a level camera's:
   ``scene_place.find_horizon``; with standing people in the background, their heads' and feet's, off people there:
   ``scene_people``);
   ``height`` (a fraction of the background's height) overrides that.
   A *cut-off* person (a half body or a portrait) is placed as their photo framed them: their relative height
   kept and every border that cut them on the same border of the background. Parts beyond the edges are cut off.
5. Matched to the background's camera: when the background camera's own blur (the blur of the photo's
   sharpest part, ``camera_blur``: the person is what the camera focuses on, so a background soft only in
   parts, by depth, lends it nothing) exceeds the placed full-body person's (edge-width estimate,
   ``blur_sigma``), the person is blurred by the difference (a cut-off person too: it is in focus, but the
   camera's own softness is everywhere). Where the plate's blur is known (``plate_blur``: a panorama's plate,
   soft by its map's resolution), a full body takes at least that: its feet stand on ground the plate shows at
   their distance, in the same focus; a cut-off person, close to the camera, does not (the plate reads as a
   background out of focus behind it). When the background around the person is noisier (``noise_sigma``,
   Immerkær's estimate), Gaussian noise of the missing standard deviation is added to the person (a fixed
   seed: the same inputs give the same picture).
6. Shadows (``shadow=True``, the default; full-body people only), multiplied into the background before the
   person is laid over it: a contact shadow (a soft ellipse under the feet, ``CONTACT_WIDTH`` of the person's
   height plus half their feet's width across, foreshortened as the ground is at the feet's distance, up to
   ``CONTACT_STRENGTH`` darker) and a cast shadow: the person's matte (widened
   a little: a body is deeper than its outline) projected onto the ground plane along the key light's
   direction (``relight_rt.light.from_background``'s key, or a given light's dominant direction), foreshortened
   by the same perspective, blurred more the farther it falls from the feet, as dark as the light's
   directionality (|band 1| / (√3 · band 0)) allows, at most ``CAST_STRENGTH``; and the sky the body hides from
   the ground around it (ambient occlusion, ``_Occluder``: a vertical cylinder ``OCCLUDER_RADIUS`` of the
   person's height in radius, placed on the ground by the same perspective; the ground loses that share of
   the light's non-directional part, a tenth or so a few body widths away).
7. Alpha blending of the premultiplied, resampled person over the linear background, then a light wrap
   (``light_wrap=True``, the default; ``_light_wrap``): inside the person's edge, within ``WRAP_RADIUS`` of the
   frame's height, the person is lifted toward the background's light behind the edge where that is brighter
   (``WRAP_STRENGTH`` of the excess at most), as a rim of back light and a lens's glare would; and a rim
   (``scene_rim.key_rim``; a degree-2 SH light spreads a small source behind the person over the whole body
   instead): the outline, within ``RIM_RADIUS`` of the person's height where the matte says strands (hair, fuzz:
   a soft, wide edge, ``scene_rim.fibre_share`` of the person's photo's matte) and in a thin grazing line where it
   says a smooth hard edge, gets the rim's radiance added as the fibres there would scatter it (all round for a
   source straight behind, on its side for one to the side), not on the matte's specks and pinholes. The wrap and the
   rim read the same light, the radiance just behind the outline scattered toward the camera: where both lift a
   pixel it takes the larger of the two, not their sum. The source and the radiance:
   ``relight_rt.apps.scene_rim``. ``rim="auto"``: a photo gets it where both say so, a compact clipped source in
   frame (a sun, a window, a lamp) and the background's light read as back-lit (the key a back key): either alone
   is wrong too often (a source in frame on 64 of the benchmark's 100 views, 35 of them back-lit; both, 28, 20
   back-lit and 1 clearly front-lit). ``rim=True``: the source in frame, else the back key's (its irradiance facing
   it over the front's, times the front's shading). ``rim=False`` (the default): none; the benchmark's renders hold
   no rim, and there "auto" costs 82 -> 76 % of pairs better than the paste (the exact rim of the same views'
   panoramas, 77 %). Then sRGB again.
8. Metering (``meter``): "frame" (default) exposes the composed frame as a camera that meters the whole
   frame would: one scale so its mean linear luminance equals the background photo's own (a large bright
   person darkens the frame a little), limited to ±``METER_LIMIT_EV``; "background" keeps the background's
   pixels (away from the person and its shadow) exactly as they were.

``composite`` runs the steps, each a function that can be used and tested alone: ``scene_lighting`` (1, 2's
light), ``relight_person`` (2's exposure, 3), ``place`` (4), ``camera_match`` (5), ``shadows`` and ``shade`` (6),
the blending of step 7, ``grade`` (8 and the encoding). ``scene.composite(relighter, ...)`` is the one
compositing verb (the Relighter has none: the relighting core never imports this module).
"""

from __future__ import annotations

import math
import numbers
import os
from dataclasses import dataclass, replace

import cv2
import numpy as np

from ..engine.errors import RelightError
from ..image.color import REC709, SRGB8_TO_LINEAR, linear_to_srgb, srgb8_to_linear, srgb_to_linear
from ..light import exposure as _exposure
from ..light import sh
from ..light.from_background import (
    AMBIENT_GAIN,
    FRONT_WEIGHTS,
    KEY_BACK,
    check_fov,
    key_direction,
    parse_key_light,
    read_background,
    scene_light,
)
from ..person.masks import AUTO, resolve_mask
from .scene_camera import blur_sigma, camera_blur, grey, noise_sigma
from .scene_people import people_finder, place_among_people
from .scene_place import (
    CAMERA_M,
    Placement,
    check_camera_height,
    check_height,
    check_horizon,
    parse_position,
    place,
)
from .scene_rim import fibre_patch, fibres_in, key_rim, photo_rim, wide_blur

__all__ = [
    "Placement", "SceneLighting", "Shadows", "camera_match", "composite", "grade", "parse_position", "place",
    "relight_person", "scene_lighting", "shade", "shadows",
]

CONTACT_STRENGTH = 0.85  #: darkest contact shadow (fraction of the ground's light taken away)
CONTACT_WIDTH = 0.08  #: the contact shadow's half-width: this fraction of the person's height + half their feet's width
CAST_STRENGTH = 0.7  #: darkest cast shadow
OCCLUDER_RADIUS = 0.1  #: the person as an occluder of the sky: a cylinder this fraction of its height in radius
OCCLUSION_STEP = 4  #: the sky's occlusion is computed on a grid this many pixels apart, then resized up
METER_LIMIT_EV = 1.0  #: the frame metering moves the exposure by at most this
METERS = ("frame", "background")
_MIN_KEY_ELEVATION = 15.0  # degrees: a lower key casts its shadow as if from this high (no endless shadows)
WRAP_RADIUS = 0.006  #: light wrap: its reach over the person's edge (Gaussian sigma), fraction of the frame's height
WRAP_STRENGTH = 0.25  #: light wrap: how much of the brighter background's excess reaches the edge band (at most)
RIM_RADIUS = 0.01  #: a back key's rim: its reach inside the person's edge (Gaussian sigma), fraction of its height
_NOISE_SEED = 36
_UNIT = np.arange(256, dtype=np.float32) / np.float32(255)  # 8-bit → float in [0, 1]


def matte_on_the_photo(relighter, image, mask, name: str | None = None):
    """The automatic matte, when one is needed, taken on the photo as it is (sRGB, what the matting graphs
    see in every other command), not on the linearised copy stage 1 gets here: linear values are darker and
    lose the person in dim photos. A given mask, or the alpha of an RGBA photo, passes through unchanged."""
    if mask is not None and not (isinstance(mask, str) and mask == AUTO):
        return mask
    from ..image.io import read_image

    shown = read_image(image, "image")
    if mask is None and shown.shape[2] == 4:
        return None  # the alpha channel is the mask; _linear_person keeps it
    if name is None:
        name = os.fspath(image) if isinstance(image, (str, os.PathLike)) else "image"
    return resolve_mask(shown, mask, matter=relighter.matter, name=name)


def decode_person(image):
    """(the person photo, its name): a path to an 8-bit RGB(A) file decoded once, as an RGB(A) uint8 array that
    both the matte and the linear copy read; anything else passes through as given."""
    if not isinstance(image, (str, os.PathLike)):
        return image, "image"
    from ..image.io import decode_file

    raw = decode_file(image, "image")
    if raw.dtype == np.uint8 and raw.ndim == 3 and raw.shape[2] in (3, 4) and min(raw.shape[:2]) >= 2:
        return cv2.cvtColor(raw, cv2.COLOR_BGR2RGB if raw.shape[2] == 3 else cv2.COLOR_BGRA2RGBA), os.fspath(image)
    return image, os.fspath(image)  # 16-bit, gray, CMYK...: the intake reads the file


def _linear_person(image):
    """The person photo (path or array) as linear float32 RGB(A); alpha (the matte) is kept as it is."""
    from ..image.io import decode_file, read_image

    if isinstance(image, (str, os.PathLike)):
        raw = decode_file(image, "image")
        if raw.dtype == np.uint8 and raw.ndim == 3 and raw.shape[2] in (3, 4):
            raw = cv2.cvtColor(raw, cv2.COLOR_BGR2RGB if raw.shape[2] == 3 else cv2.COLOR_BGRA2RGBA)
            if min(raw.shape[:2]) < 2:
                raise RelightError(f"image {os.fspath(image)}: image is too small, got {raw.shape}")
            out = srgb8_to_linear(raw)
            if raw.shape[2] == 4:
                out[..., 3] = raw[..., 3] * np.float32(1 / 255)
            return out
        img = read_image(image, "image")
    elif (
        isinstance(image, np.ndarray) and image.dtype == np.uint8 and image.ndim == 3 and image.shape[2] in (3, 4)
        and min(image.shape[:2]) >= 2
    ):  # fmt: skip
        out = srgb8_to_linear(image)
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
        s = sh.shading(t, lit)
        c = (m @ s) / m.sum()
        return c / max(float(c @ REC709), 1e-12)

    ref, cur = mean_shade(reference), mean_shade(light)
    if not (np.all(cur > 1e-6) and np.all(ref > 1e-6)):
        return light  # a channel without light: no meaningful balance
    return (light * (ref / cur)[None, :]).astype(np.float32)


def _light_wrap(
    composed: np.ndarray, behind: np.ndarray, alpha: np.ndarray, radius: float, strength: float = WRAP_STRENGTH
) -> np.ndarray:
    """The background's light wrapped a little over the person's edge ("light wrap"; step 7 of the module docstring).

    At a silhouette the body's surface turns away from the camera, toward what lies behind the person: there it
    is lit by the background's own light (a rim), and a lens spreads a bright background's light a few pixels
    over a dark edge. So, inside the matte and within ``radius`` of the outside, each pixel is lifted toward the
    background's light near it: ``composed + strength · band · max(near − composed, 0)``, where ``near`` is the
    background behind the edge (``behind`` averaged over the pixels outside the person, Gaussian of ``radius``),
    ``band`` = alpha × the share of outside pixels within reach (1/2 at a hard edge, falling to 0 inside the
    body) and the lift is per channel and only where the background is the brighter (a dark background takes
    nothing away: the person's own light is already in it).

    Args:
        composed: (h, w, 3) linear frame with the person laid over ``behind``.
        behind: (h, w, 3) linear background without the person (its shadows included).
        alpha: (h, w) the person's matte in this window.
        radius: Gaussian sigma of the reach, pixels (> 0).
        strength: in [0, 1].

    Returns:
        New (h, w, 3) float32.
    """
    a = np.clip(alpha, 0, 1).astype(np.float32)
    outside = 1 - a
    reach = wide_blur(outside, radius)
    out = np.array(composed, dtype=np.float32)
    edge = (a > 0) & (reach > 1e-3)  # the band: only these pixels change
    if not edge.any():
        return out
    near = wide_blur(behind * outside[..., None], radius)[edge]
    near /= reach[edge][:, None]
    band = (a[edge] * reach[edge])[:, None]
    c = out[edge]
    out[edge] = c + np.float32(strength) * band * np.maximum(near - c, 0)
    return out


def _rim_gain(parts, light: np.ndarray) -> float:
    """A back key's irradiance facing it (relight_rt.light.from_background's rule: ``KEY_BACK`` × the ambient) over the
    irradiance of the person's camera-facing side under ``light`` (its luminance): ``key_rim``'s gain."""
    front = float(FRONT_WEIGHTS @ (np.asarray(light, np.float64) @ REC709))
    return KEY_BACK * AMBIENT_GAIN * parts.level / front if front > 1e-12 else 0.0


def _dominant_direction(light: np.ndarray) -> tuple[np.ndarray | None, float]:
    """The unit direction the light mostly comes from and how directional it is (sh.dominant_direction of its
    Rec. 709 luminance)."""
    return sh.dominant_direction(np.asarray(light, np.float64) @ REC709.astype(np.float64))


class _Occluder:
    """The person as a vertical cylinder standing on the ground plane, for the sky it hides from the ground around
    its feet (step 6's ambient occlusion). Frame pixels ↔ ground metres by the level camera of step 4: a ground
    pixel ``r`` rows below the horizon lies ``CAMERA_M · focal / r`` metres away."""

    def __init__(self, foot_x: float, feet_y: float, height_px: float, horizon_y: float, focal: float, cx: float):
        self.horizon_y, self.focal, self.cx = horizon_y, focal, cx
        self.z0 = CAMERA_M * focal / max(feet_y - horizon_y, 1.0)  # the feet's distance, metres
        self.x0 = (foot_x - cx) * self.z0 / focal
        self.height = height_px * self.z0 / focal  # the person's height, metres
        self.radius = OCCLUDER_RADIUS * self.height

    def reach(self, frame_h: int) -> tuple[int, int, int, int]:
        """(y0, y1, x0, x1) of the frame where the occlusion is worth drawing (ground within 8 radii)."""
        d = 8 * self.radius
        near, far = self.z0 - d, self.z0 + d
        y1 = frame_h if near <= CAMERA_M * self.focal / max(frame_h - self.horizon_y, 1.0) else (
            int(math.ceil(self.horizon_y + CAMERA_M * self.focal / near)))  # fmt: skip
        y0 = int(self.horizon_y + CAMERA_M * self.focal / far)
        half = d * self.focal / max(near, self.z0 / 2)
        xc = self.cx + self.x0 * self.focal / self.z0
        return y0, y1, int(xc - half), int(math.ceil(xc + half))

    def occlusion(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """The share of a uniform sky's light on the ground at frame points (x, y) that the person hides: the
        cosine-weighted solid angle of a cylinder of radius R and height H seen from distance d,
        asin(R / d) · sin²(atan(H / d)) / π (a wall of 2·asin(R / d) radians of azimuth from the ground up to its
        top); 1/2 · sin² under it; 0 above the horizon."""
        rows = y - np.float32(self.horizon_y)
        ground = rows > 0.5
        z = np.float32(CAMERA_M * self.focal) / np.maximum(rows, 0.5)
        gx = (x - np.float32(self.cx)) * z / np.float32(self.focal)
        d = np.maximum(np.hypot(gx - np.float32(self.x0), z - np.float32(self.z0)), 1e-6)
        across = np.arcsin(np.minimum(np.float32(self.radius) / d, 1.0))
        up = self.height**2 / (self.height**2 + d * d)
        return np.where(ground, across * up / np.float32(math.pi), 0).astype(np.float32)


def _cast_shadow(alpha: np.ndarray, top: int, left: int, feet_y: float, horizon_y: float, focal: float,
                 direction: np.ndarray, shape: tuple[int, int]):  # fmt: skip
    """The person's matte ``alpha`` (placed at top, left) projected on the ground plane along ``direction`` (the
    light comes from it) and seen by the level camera (module docstring, step 6).

    Returns (y0, x0, shadow) with ``shadow`` an (h, w) float32 coverage in [0, 1] over that part of the frame,
    or None when the light is from below the horizon or the shadow misses the frame."""
    d = np.asarray(direction, np.float64)
    horiz = math.hypot(d[0], d[1])
    elevation = math.degrees(math.atan2(d[2], horiz))
    if elevation <= 0 or horiz < 1e-6:
        return None  # from below, or straight above: nothing cast beside the feet (the contact shadow stays)
    tan_el = math.tan(math.radians(max(elevation, _MIN_KEY_ELEVATION)))
    wx, wy = d[0] / horiz, d[1] / horiz
    a = -wy / tan_el  # columns per row of height
    b = -wx * max(feet_y - horizon_y, 0.05 * shape[0]) / (tan_el * focal)  # rows (toward the camera) per row
    if abs(b) < 0.08:
        b = math.copysign(0.08, b if b != 0 else 1.0)  # a side light: a thin shadow, not a line
    ph, pw = alpha.shape
    # forward map of a point (c, r) of the frame: c' = c + a (feet_y − r), r' = feet_y + b (feet_y − r)
    corners = np.array([[left, top], [left + pw, top], [left, top + ph], [left + pw, top + ph]], np.float64)
    cx = corners[:, 0] + a * (feet_y - corners[:, 1])
    cy = feet_y + b * (feet_y - corners[:, 1])
    pad = 0.08 * ph
    x0, x1 = max(0, int(cx.min() - pad)), min(shape[1], int(math.ceil(cx.max() + pad)))
    y0, y1 = max(0, int(cy.min() - pad)), min(shape[0], int(math.ceil(cy.max() + pad)))
    if x1 <= x0 or y1 <= y0:
        return None
    # work at a reduced scale (the shadow is soft): at most 256 px on the longer side
    s = min(1.0, 256 / max(x1 - x0, y1 - y0))
    small_alpha = cv2.resize(alpha, (max(1, round(pw * s)), max(1, round(ph * s))), interpolation=cv2.INTER_AREA)
    # in the small canvas: source point (c, r) of the small matte ↔ frame (left + c/s, top + r/s)
    fy = (feet_y - y0) * s
    m = np.array([[1.0, -a, (left - x0) * s + a * (feet_y - top) * s],
                  [0.0, -b, fy + b * (feet_y - top) * s]])  # fmt: skip
    # r' = fy + b (feet_y − top − r/s) s = fy + b (feet_y − top) s − b r
    size = (max(1, round((x1 - x0) * s)), max(1, round((y1 - y0) * s)))
    grow = max(1, round(0.025 * ph * s))  # a body is deeper than its outline: a fuller shadow than the matte's
    small_alpha = cv2.dilate(small_alpha, np.ones((grow, grow), np.uint8))
    shadow = cv2.warpAffine(small_alpha, m, size, flags=cv2.INTER_LINEAR, borderValue=0)
    near = cv2.GaussianBlur(shadow, (0, 0), max(0.5, 0.012 * ph * s))
    far = cv2.GaussianBlur(shadow, (0, 0), max(0.5, 0.05 * ph * s))
    rows = (np.arange(size[1], dtype=np.float32) + 0.5)[:, None]
    cols = (np.arange(size[0], dtype=np.float32) + 0.5)[None, :]
    feet_x = ((left + pw / 2) - x0) * s
    dist = np.hypot(rows - fy, cols - feet_x) / max(1.0, 0.6 * ph * s * math.hypot(a, b))
    w = np.clip(dist, 0, 1)
    soft = near + (far - near) * w
    soft *= 1 - 0.3 * w  # fading as it falls farther
    out = cv2.resize(soft, (x1 - x0, y1 - y0), interpolation=cv2.INTER_LINEAR)
    return y0, x0, np.clip(out, 0, 1)


@dataclass(frozen=True)
class SceneLighting:
    """What the scene's light does to the person (steps 1, 2 and 6): the light to relight them under (before
    exposure), the background's own light (the exposure's target; None when a light is used as it is), the
    direction their shadow falls away from (None: no dominant direction) and how directional the light is, and a
    rim (``relight_rt.apps.scene_rim``): the direction of the source behind the person (or None) and the rim's linear
    RGB radiance.
    """

    light: np.ndarray
    background_light: np.ndarray | None
    shadow_dir: np.ndarray | None
    directional: float
    rim_dir: np.ndarray | None = None
    rim_colour: np.ndarray | None = None


def scene_lighting(relighter, dec, parts, background_light: np.ndarray | None, key, light, *,
                   white_balance: bool = True, rim: bool | str = False, rim_key=None) -> SceneLighting:
    """Step 1 and 2's light for the person of ``dec`` in the scene whose light ``parts`` describes
    (relight_rt.light.from_background ``scene_light``; ``background_light`` = ``parts.light(key)``): the background's
    own light with its key (``key``: parse_key_light's), or ``light`` (anything ``Relighter.resolve_light`` accepts)
    white-balanced to it (``parts`` and ``background_light`` None: ``light`` as it is). With ``rim``: ``rim_key``
    = (direction (3,), rim RGB (3,)) of a source behind the person (``relight_rt.apps.scene_rim``: a panorama's, or
    one in the background photo) gives the rim; without one, the estimate's back key gives it (its irradiance
    facing it over the front's, ``_rim_gain``, times the front's shading: the light's own colour). ``rim`` "auto":
    ``rim_key`` gives the rim only when the background's own light is used and its key is a back key (step 7)."""
    bg_light = background_light
    rim_dir, rim_rgb = None, None
    back = False
    auto = isinstance(rim, str) and rim == "auto"
    rim = bool(rim) and not auto
    if light is None:
        lit = bg_light
        (az, el), back = parts.key(key)
        shadow_dir = key_direction(az, el)
        if back and rim and rim_key is None:
            front = FRONT_WEIGHTS @ np.asarray(bg_light, np.float64)
            rim_dir, rim_rgb = shadow_dir, _rim_gain(parts, bg_light) * np.maximum(front, 0)
        _, directional = _dominant_direction(bg_light)
        directional = max(directional, 0.35)  # the key is there by construction: never an invisible shadow
    else:
        lit = relighter.resolve_light(light)
        if white_balance and bg_light is not None:
            lit = _white_balance(dec, lit, bg_light)
        shadow_dir, directional = _dominant_direction(lit)
    if rim_key is not None and (rim or (auto and back)):  # a source read from the panorama or the photo
        rim_dir, rim_rgb = np.asarray(rim_key[0], np.float64), np.asarray(rim_key[1], np.float64)
    return SceneLighting(lit, bg_light, shadow_dir, directional, rim_dir, rim_rgb)


def relight_person(relighter, dec, lighting: SceneLighting, mode) -> np.ndarray:
    """Step 2's exposure and step 3: the person of ``dec`` relit under ``lighting.light``, exposed as ``mode``
    (relight_rt.light.exposure ``parse_exposure``'s) says against the brightness the background's light gives them;
    (H, W, 4) straight-alpha linear RGBA at the photo's size."""
    lit = lighting.light
    if mode != "physical":
        target = _exposure.mean_luminance(dec.albedo, dec.transport, dec.network_mask, lighting.background_light)
        lit = lit * np.float32(_exposure.exposure_scale(dec.albedo, dec.transport, dec.network_mask, lit, target,
                                                        mode))  # fmt: skip
    return relighter.relight(dec, lit, background="transparent", exposure="physical")


def camera_match(bg: np.ndarray, placed: Placement, known_blur: float = 0.0) -> tuple[Placement, float]:
    """Step 5: ``placed`` blurred by what the background ``bg``'s camera blurs more (its measured blur, at least
    ``known_blur`` px), and the standard deviation of the noise (sRGB) to add to the person after the encoding
    (0: none)."""
    premult, top, left = placed.premult, placed.top, placed.left
    new_h, new_w, feet_y = placed.height, placed.width, placed.feet_y
    hb, wb = bg.shape[:2]
    noise_add = 0.0
    ey0, ey1 = max(0, top - new_h // 2), min(hb, feet_y + new_h // 4)
    ex0, ex1 = max(0, left - new_w), min(wb, left + 2 * new_w)
    if ey1 - ey0 >= 8 and ex1 - ex0 >= 8:
        bg_region = bg[ey0:ey1, ex0:ex1].astype(np.float32)
        if bg.dtype == np.uint8:
            bg_region *= np.float32(1 / 255)
        alpha_p = premult[..., 3]
        inside = cv2.erode((alpha_p > 0.98).astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
        colour = np.divide(premult[..., :3], premult[..., 3:], out=np.zeros_like(premult[..., :3]),
                           where=premult[..., 3:] > 1e-3)  # fmt: skip
        p_srgb = linear_to_srgb(np.clip(colour, 0, 1))
        # the person's sharpness: its premultiplied colour, so that its outline counts too
        b_bg = max(camera_blur(grey(bg)), min(known_blur, 1e6))  # 1e6: far past the cap of 8 below; b_bg**2 finite
        b_p = blur_sigma(linear_to_srgb(premult[..., :3]).mean(axis=2))
        if b_bg > b_p + 0.25:  # the camera's own softness reaches a close portrait too
            sigma = min(math.sqrt(b_bg**2 - b_p**2), 8.0)
            pad = int(math.ceil(3 * sigma))  # room for the outline to soften outward
            premult = cv2.copyMakeBorder(premult, pad, pad, pad, pad, cv2.BORDER_CONSTANT, value=0)
            premult = cv2.GaussianBlur(premult, (0, 0), sigma)
            top, left = top - pad, left - pad
        n_bg, n_p = noise_sigma(bg_region), noise_sigma(p_srgb, inside)
        if n_bg > n_p + 0.5 / 255:
            noise_add = math.sqrt(n_bg**2 - n_p**2)
    return replace(placed, premult=premult, top=top, left=left), noise_add


@dataclass(frozen=True)
class Shadows:
    """Step 6's shadows of a placed full-body person: the contact ellipse (centre ``foot``, half-axes ``size``),
    the sky the body hides (``occluder``), the cast shadow (row, column, (h, w) cover) or None, the light's
    directionality and whether it has a direction, and the frame box (y0, y1, x0, x1) they reach."""

    foot: tuple[float, float]
    size: tuple[float, float]
    occluder: _Occluder
    cast: tuple | None
    directional: float
    has_direction: bool
    box: tuple[int, int, int, int]


def shadows(placed: Placement, background_shape: tuple[int, ...], horizon: float, fov: float,
            lighting: SceneLighting) -> Shadows:
    """Step 6: the shadows of ``placed`` on the ground of a background of ``background_shape`` (horizon row
    fraction, horizontal field of view in degrees) under ``lighting``."""
    hb, wb = background_shape[:2]
    hz, shadow_dir, directional = horizon, lighting.shadow_dir, lighting.directional
    top, left, premult, new_h, new_w, feet_y = (placed.top, placed.left, placed.premult, placed.height,
                                                placed.width, placed.feet_y)
    box_bottom, box_right = top + premult.shape[0], left + premult.shape[1]
    ry0, ry1, rx0, rx1 = top, box_bottom, left, box_right
    focal = (wb / 2) / math.tan(math.radians(float(fov)) / 2)
    feet_w = new_w if placed.feet_width is None else placed.feet_width
    sh_w = CONTACT_WIDTH * new_h + 0.5 * feet_w
    sh_h = max(2.0, sh_w * min(max((feet_y - hz * hb) / focal, 0.08), 1.0))  # the ground's foreshortening there
    foot_x = (left + box_right) / 2 if placed.feet_x is None else placed.feet_x
    foot_y = feet_y - 0.2 * sh_h
    cast = None
    ry0, ry1 = min(ry0, int(foot_y - 3 * sh_h)), max(ry1, int(math.ceil(foot_y + 3 * sh_h)))
    rx0, rx1 = min(rx0, int(foot_x - 1.5 * sh_w)), max(rx1, int(math.ceil(foot_x + 1.5 * sh_w)))
    occ = _Occluder(foot_x, feet_y, new_h, hz * hb, focal, wb / 2)
    oy0, oy1, ox0, ox1 = occ.reach(hb)
    ry0, ry1, rx0, rx1 = min(ry0, oy0), max(ry1, oy1), min(rx0, ox0), max(rx1, ox1)
    if shadow_dir is not None and directional > 0:
        cast = _cast_shadow(premult[..., 3], top, left, feet_y, hz * hb, focal, shadow_dir, (hb, wb))
        if cast is not None:
            cy0, cx0, cs = cast
            ry0, ry1 = min(ry0, cy0), max(ry1, cy0 + cs.shape[0])
            rx0, rx1 = min(rx0, cx0), max(rx1, cx0 + cs.shape[1])
    return Shadows((foot_x, foot_y), (sh_w, sh_h), occ, cast, directional, shadow_dir is not None,
                   (ry0, ry1, rx0, rx1))


def shade(lin: np.ndarray, origin: tuple[int, int], cast: Shadows) -> None:
    """Multiply ``cast``'s shadows into ``lin`` (linear RGB of the frame region whose top-left pixel is
    ``origin`` (row, column)), in place."""
    ry0, rx0 = origin
    ry1, rx1 = ry0 + lin.shape[0], rx0 + lin.shape[1]
    (foot_x, foot_y), (sh_w, sh_h), occ, directional = cast.foot, cast.size, cast.occluder, cast.directional
    light_left = np.ones(lin.shape[:2], np.float32)
    # the contact ellipse, within 3 half-axes of its centre (beyond, exp(-18): nothing)
    ey0, ey1 = max(ry0, int(foot_y - 3 * sh_h)), min(ry1, int(math.ceil(foot_y + 3 * sh_h)))
    ex0, ex1 = max(rx0, int(foot_x - 3 * sh_w)), min(rx1, int(math.ceil(foot_x + 3 * sh_w)))
    if ey1 > ey0 and ex1 > ex0:
        v = ((np.arange(ey0, ey1, dtype=np.float32) + np.float32(0.5 - foot_y)) / np.float32(sh_h))[:, None]
        u = ((np.arange(ex0, ex1, dtype=np.float32) + np.float32(0.5 - foot_x)) / np.float32(sh_w))[None, :]
        light_left[ey0 - ry0 : ey1 - ry0, ex0 - rx0 : ex1 - rx0] = 1 - CONTACT_STRENGTH * np.exp(-2 * (u * u + v * v))
    ambient = 1 - min(1.0, directional) if cast.has_direction else 1.0
    if ambient > 0:
        np.minimum(light_left, 1 - np.float32(ambient) * _occlusion_map(occ, ry0, ry1, rx0, rx1), out=light_left)
    if cast.cast is not None:
        cy0, cx0, cs = cast.cast
        cover = np.zeros(lin.shape[:2], np.float32)
        sy0, sx0 = max(cy0, ry0), max(cx0, rx0)
        sy1, sx1 = min(cy0 + cs.shape[0], ry1), min(cx0 + cs.shape[1], rx1)
        cover[sy0 - ry0 : sy1 - ry0, sx0 - rx0 : sx1 - rx0] = cs[sy0 - cy0 : sy1 - cy0, sx0 - cx0 : sx1 - cx0]
        dark = CAST_STRENGTH * min(1.0, 2 * directional)
        light_left = np.minimum(light_left, 1 - dark * cover)
    lin *= light_left[..., None]


def _occlusion_map(occ: _Occluder, y0: int, y1: int, x0: int, x1: int) -> np.ndarray:
    """``occ.occlusion`` over the frame rows y0:y1 and columns x0:x1, computed on a grid ``OCCLUSION_STEP`` times
    coarser (it varies over the occluder's radius, tens of pixels) and resized up: (y1 − y0, x1 − x0) float32."""
    h, w = y1 - y0, x1 - x0
    hs, ws = max(1, -(-h // OCCLUSION_STEP)), max(1, -(-w // OCCLUSION_STEP))
    if hs < 4 or ws < 4:
        hs, ws = h, w
    ys = (y0 + (np.arange(hs, dtype=np.float32) + 0.5) * np.float32(h / hs))[:, None]
    xs = (x0 + (np.arange(ws, dtype=np.float32) + 0.5) * np.float32(w / ws))[None, :]
    small = occ.occlusion(xs, ys)
    return small if (hs, ws) == (h, w) else cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR)


def grade(bg: np.ndarray, lin: np.ndarray, box: tuple[int, int, int, int], before: float, meter: str = "frame",
          noise: float = 0.0, alpha_region=None) -> np.ndarray:
    """Step 8 and the encoding: the frame ``bg`` (sRGB, uint8 or float) with its region ``box`` (y0, y1, x0, x1)
    replaced by ``lin`` (its linear RGB with the person, whose linear luminance was ``before`` without them),
    metered as ``meter`` says, back in sRGB; ``noise`` (sRGB standard deviation) added to the person where
    ``alpha_region`` (y0, y1, x0, x1, alpha) says. (H, W, 3) float32 sRGB in [0, 1]."""
    ry0, ry1, rx0, rx1 = box
    gain = 1.0
    if meter == "frame":
        if bg.dtype == np.uint8:  # the frame's linear luminance from the channels' histograms (fast)
            hist = [cv2.calcHist([bg], [c], None, [256], [0, 256]).reshape(-1) @ SRGB8_TO_LINEAR for c in range(3)]
            total = float(np.asarray(hist, np.float64) @ REC709.astype(np.float64))
        else:
            total = float((srgb_to_linear(bg) @ REC709).sum())
        after = total - before + float((lin @ REC709).sum())
        if after > 1e-9 and total > 1e-9:
            gain = float(np.clip(total / after, 2.0**-METER_LIMIT_EV, 2.0**METER_LIMIT_EV))
    if abs(math.log2(gain)) > 1e-3:
        if bg.dtype == np.uint8:
            table = np.clip(linear_to_srgb(np.clip(SRGB8_TO_LINEAR * np.float32(gain), 0, 1)), 0, 1).astype(np.float32)
            out = cv2.LUT(bg, table.reshape(256, 1))
        else:
            out = np.clip(linear_to_srgb(np.clip(srgb_to_linear(bg) * np.float32(gain), 0, 1)), 0, 1)
        lin *= np.float32(gain)
    elif bg.dtype == np.uint8:
        out = cv2.LUT(bg, _UNIT.reshape(256, 1))
    else:
        out = bg.astype(np.float32, copy=True)
    region = np.clip(linear_to_srgb(np.clip(lin, 0, None)), 0, 1)
    if noise > 0 and alpha_region is not None:
        qy0, qy1, qx0, qx1, a = alpha_region
        rng = np.random.default_rng(_NOISE_SEED)
        noise_px = rng.standard_normal(a.shape + (3,), dtype=np.float32) * np.float32(noise)
        sub = region[qy0 - ry0 : qy1 - ry0, qx0 - rx0 : qx1 - rx0]
        sub += noise_px * a[..., None]
        np.clip(sub, 0, 1, out=sub)
    out[ry0:ry1, rx0:rx1] = region
    return out


def composite(
    relighter,
    image,
    background,
    *,
    mask=None,
    light=None,
    position=None,
    height=None,
    shadow: bool = True,
    exposure="auto",
    fov: float = 60.0,
    white_balance: bool = True,
    key_light=None,
    horizon: float | None = None,
    meter: str = "frame",
    match_camera: bool = True,
    light_wrap: bool = True,
    rim: bool | str = False,
    rim_key=None,
    camera_height: float = CAMERA_M,
    plate_blur: float = 0.0,
) -> np.ndarray:
    """Relight the person of ``image`` for the scene of ``background`` and put it there (module docstring).

    Args:
        relighter: a ``relight_rt.Relighter``.
        image: the person photo (path or array, RGB or RGBA, as for ``Relighter.decompose``).
        background: the scene photo: path or (H, W, 3) RGB array (uint8 or float in [0, 1]), >= 64 px a side,
            not grayscale, not RGBA.
        mask: the person's mask (None: the image's alpha channel), binary or soft.
        light: None (the background's own light) or anything ``Relighter.resolve_light`` accepts.
        position: (x, y) or "X,Y": where the person's feet (a cut-off person's bottom centre) go, fractions of
            the background in [0, 1]; None: step 4 of the module docstring.
        height: the person's box height as a fraction of the background's height, in (0, 1]; None: from
            perspective (full body) or as in its own photo (cut off).
        shadow: contact and cast shadows on the ground (full-body people).
        exposure: "auto" (the brightness the background's light gives the person), an EV offset, or
            "physical" (relight_rt.light.exposure).
        fov: the background's horizontal field of view in degrees, (10, 170).
        white_balance: match a given light's colour to the background's (see the module docstring).
        key_light: (azimuth, elevation) degrees or "AZ,EL": where the background's key light comes from
            (relight_rt.light.from_background.parse_key_light); None: the key the view implies. Ignored with ``light``.
        horizon: the horizon's row, a fraction of the background's height in [0, 1]; None: where the background's
            verticals put it (``relight_rt.apps.scene_place.estimate_horizon``; where they see the camera turned
            up, no higher than the lowest sky, ``sky_line``), or 0.5 (a level camera) where they say nothing, at
            most ``HORIZON_ESTIMATE_MAX`` (``scene_place.find_horizon``); with standing people in the background
            (looked for unless the relighter's matting is "off"), as ``relight_rt.apps.scene_people`` combines both.
        meter: "frame" or "background" (step 8).
        match_camera: match the background camera's blur and noise (step 5).
        light_wrap: let the background's light wrap over the person's edge where it is brighter (step 7).
        rim: a source behind the person puts a rim of light on the outline on its side (step 7): ``rim_key``, else
            (the background's own light) a compact clipped source in the photo (``apps.scene_rim.photo_rim``),
            else a back key (automatic or ``key_light``). "auto": the source in the photo only where the
            background's light is read as back-lit (step 7). False (default): no rim.
        rim_key: with ``rim``: (direction (3,), rim RGB (3,)) of a source known exactly (``relight_rt.apps.scene_rim``;
            relight_rt.apps.panorama's sun or window).
        camera_height: the background camera's height above the ground, metres (step 4's perspective).
        plate_blur: the background's own blur where it is known (Gaussian σ, px; relight_rt.apps.panorama's plate):
            step 5 blurs a full-body person to at least that.

    Returns:
        (H_bg, W_bg, 3) float32 sRGB in [0, 1].

    Raises:
        RelightError: bad photos, masks or lights; fov outside (10, 170); position outside [0, 1]; a
            height outside (0, 1]; a bad key light, horizon, camera height or meter; a person larger than the background
            after scaling; feet on or above the horizon without a height.
    """
    pos = None if position is None else parse_position(position)
    frac = check_height(height)
    cam = check_camera_height(camera_height)
    mode = _exposure.parse_exposure(exposure)
    key = parse_key_light(key_light)
    hz = None if horizon is None else check_horizon(horizon)
    if meter not in METERS:
        raise RelightError(f"meter: expected one of {list(METERS)}, got {meter!r}")
    if not (isinstance(rim, (bool, np.bool_)) or (isinstance(rim, str) and rim == "auto")):
        raise RelightError(f"rim: expected True, False or 'auto', got {rim!r}")
    fov = check_fov(fov)
    if not (isinstance(plate_blur, numbers.Real) and math.isfinite(plate_blur) and plate_blur >= 0):
        raise RelightError(f"plate_blur: expected a finite blur >= 0 in pixels, got {plate_blur!r}")
    bg = read_background(background)
    # the background's own light: the light, its white balance or the exposure's target (not for a light used as
    # it is, as relight_rt.apps.panorama gives: "physical", no balance)
    parts = scene_light(bg, fov) if light is None or white_balance or mode != "physical" else None
    bg_light = None if parts is None else parts.light(key)
    image, name = decode_person(image)  # decoded once for the matte and the linear copy
    mask = matte_on_the_photo(relighter, image, mask, name)
    person = _linear_person(image)
    dec = relighter.decompose(person, mask)
    if rim and rim_key is None and light is None:  # a sun, window or lamp in frame (relight_rt.apps.scene_rim)
        rim_key = photo_rim(bg, fov)
    lighting = scene_lighting(relighter, dec, parts, bg_light, key, light, white_balance=white_balance, rim=rim,
                              rim_key=rim_key)
    rgba = relight_person(relighter, dec, lighting, mode)
    placed, hz = place_among_people(rgba, bg, pos, frac, hz, cam, fov, people_finder(relighter))
    # the rim's fibres: read on the photo's matte, placed with the person (before any blur); only where a rim is
    # drawn at all (a key from behind, of some colour: ``key_rim`` draws nothing otherwise)
    rims = lighting.rim_dir is not None and lighting.rim_dir[0] < 0 and float(np.max(lighting.rim_colour)) > 0
    fibres = (fibre_patch(rgba[..., 3], placed), (placed.top, placed.left)) if rims else None
    noise_add = 0.0
    if match_camera:  # blur now, noise after the sRGB encoding
        placed, noise_add = camera_match(bg, placed, float(plate_blur) if placed.full_body else 0.0)
    hb, wb = bg.shape[:2]
    top, left, premult = placed.top, placed.left, placed.premult
    box_bottom, box_right = top + premult.shape[0], left + premult.shape[1]
    # the region of the background that changes: the person's box and its shadows
    cast = shadows(placed, bg.shape, hz, fov, lighting) if shadow and placed.full_body else None
    ry0, ry1, rx0, rx1 = cast.box if cast is not None else (top, box_bottom, left, box_right)
    rim_dir = lighting.rim_dir
    wrap = bool(light_wrap)
    wrap_radius = max(0.5, WRAP_RADIUS * hb)
    rim_radius = max(0.5, RIM_RADIUS * placed.height)
    if wrap or rim_dir is not None:  # the light wrap reads the background around the person; the rim its outline
        margin = int(math.ceil(3 * max(wrap_radius if wrap else 0.0, rim_radius if rim_dir is not None else 0.0)))
        ry0, ry1, rx0, rx1 = (
            min(ry0, top - margin),
            max(ry1, box_bottom + margin),
            min(rx0, left - margin),
            max(rx1, box_right + margin),
        )
    ry0, ry1, rx0, rx1 = max(ry0, 0), min(ry1, hb), max(rx0, 0), min(rx1, wb)
    if ry1 <= ry0 or rx1 <= rx0:
        return bg.astype(np.float32) * np.float32(1 / 255) if bg.dtype == np.uint8 else bg.astype(np.float32, copy=True)
    region_bg = bg[ry0:ry1, rx0:rx1]
    lin = SRGB8_TO_LINEAR[region_bg] if region_bg.dtype == np.uint8 else srgb_to_linear(region_bg)
    before = float((lin @ REC709).sum())
    if cast is not None:
        shade(lin, (ry0, rx0), cast)
    # the person's pixels inside the region (step 7)
    py0, px0 = max(top, ry0), max(left, rx0)
    py1, px1 = min(box_bottom, ry1), min(box_right, rx1)
    alpha_region = None
    if py1 > py0 and px1 > px0:
        p = premult[py0 - top : py1 - top, px0 - left : px1 - left]
        behind = lin.copy() if wrap else None
        view = lin[py0 - ry0 : py1 - ry0, px0 - rx0 : px1 - rx0]
        view *= 1 - p[..., 3:]
        view += p[..., :3]
        alpha_region = (py0, py1, px0, px1, p[..., 3])
        if wrap or rim_dir is not None:  # step 7's light wrap and a back key's rim
            window_alpha = np.zeros(lin.shape[:2], np.float32)
            window_alpha[py0 - ry0 : py1 - ry0, px0 - rx0 : px1 - rx0] = p[..., 3]
            view = ((wb / 2) / math.tan(math.radians(fov) / 2), ry0 - hb / 2, rx0 - wb / 2)
            rimmed = None if fibres is None else key_rim(lin, window_alpha, rim_dir, lighting.rim_colour, rim_radius,
                                                         view, fibres_in(*fibres, (ry0, ry1, rx0, rx1)))  # fmt: skip
            if wrap:  # both read the light behind the outline: each pixel takes the larger lift, not the sum
                lin = _light_wrap(lin, behind, window_alpha, wrap_radius)
            if rimmed is not None:
                lin = np.maximum(lin, rimmed) if wrap else rimmed
    return grade(bg, lin, (ry0, ry1, rx0, rx1), before, meter, noise_add, alpha_region)
