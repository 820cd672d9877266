"""Light from one ordinary background photo: training-free, deterministic (DESIGN.md §3, "Background photos as light").

The photo shows what lies behind the subject as the camera sees it: directions around −x, the photo's
right toward +y, unmirrored (the orientation of an env map's centre), over a horizontal field of view
``fov`` (default 60°; the vertical one follows from the aspect ratio, square pixels, a level camera).
It shows the light that reaches the person's *back* and sides; what lights the person's camera-facing
side lies behind the camera, which the photo never shows. The rule (docs/RESULTS.md, "Into any scene",
measures it on 17 real panoramas; the fitted numbers below were fitted there, and are measured with one
scene left out at a time: eleven chosen by their errors, plus SHAPE_PRIOR, a mean):

1. Linearise (sRGB → linear) and area-average down to about the env map's angular resolution. Clipped
   highlights (brightest channel >= 250/255: lamps, windows, the sun, far brighter than 1 in truth) are
   multiplied by ``HIGHLIGHT_GAIN``.
2. The half of the sphere in front of the camera (x < 0, behind the person) is the photo itself: inside
   the field of view by perspective projection, beside it the side edges stretched sideways, above and
   below it the top rows stretched into a sky and the bottom rows into a floor, blurred more and more
   toward the poles (the mean colour of the photo's top / bottom eighth there).
3. The half behind the camera (x > 0) is not guessed from the photo's pixels (the rule before mirrored
   the photo there, which made every scene exactly as bright in front of the person as behind it, so a
   sunset looked front-lit). It is a uniform *ambient*: radiance ``AMBIENT_GAIN`` × the photo's median
   linear luminance (what the scene's ordinary surfaces reflect: a robust reading of how much light falls
   in the place that the sources in frame do not sway), in the photo's median colour (per channel: the
   colour of its ordinary surfaces, not of a lamp or a patch of sky) with its saturation scaled by
   ``COLOUR_SATURATION`` (a little of the place's cast in the photo's own white balance; 0 would be
   neutral; the photo's colours stay in step 2's half).
4. A key light, found from the view: the score z = a + b · (log2 of the top third's mean luminance over
   the bottom third's) + c · (spread of log2 luminance), (a, b, c) = ``BACKLIGHT``, says back-lit (z < 0:
   a bright top and a contrasty view, as with a sun, window or lamps in or above the frame, the near side
   of things in shadow) or front-lit (the light behind the camera, what the view shows is lit). ``BACKLIGHT``
   is the least-squares fit of the true front/back EV, clipped to ±1 EV (so that a sun's 5 EV does not
   outweigh the calls near the line), on the 100 benchmark maps. scene5 replaced the luminance spread by the
   view's colour share (``colour_share``: the chromaticity's spread over the luminance's; still computed,
   ``SceneLight.colour_share``); scene24 put the spread back: the colour share's fitted weight swung from 0.3
   to 2.7 with the scene set it was fitted on, and held out it called 62 % of the 68 places' clear maps right
   against the spread's 79 %, though 77 % against 67-70 % on the 100 maps (docs/RESULTS.md). An even view
   (log2 luminance spread < 0.1) shows neither a source nor shade and is read as front-lit. Back-lit:
   a back-side key from 135° (behind the person, 45° off the axis, on the view's brighter side),
   ``KEY_BACK`` × the ambient (``BACK_KEY = "source"`` puts it where the frame's brightest part is instead,
   ``SceneLight.bright``: a sun or window in frame; measured alike, so not the default: docs/RESULTS.md);
   front-lit: a soft front key, ``KEY_FRONT`` × the ambient, from
   ``KEY_GEOMETRY`` = (azimuth, elevation): fitted among 0°/45° off the camera (on the view's brighter side)
   and 35°/60° up, by the person's scale-invariant error; (0°, 35°) won: from the camera's direction, as
   the side cannot be read from the view reliably. Both in the ambient colour. The key is a degree-2 lobe (a
   light from one direction, band-limited: a soft clamped cosine) whose irradiance on a surface facing it is
   that many times the ambient. ``key_light=(azimuth, elevation)`` (degrees; ``parse_key_light``) puts it
   elsewhere: azimuth within ±90° takes ``KEY_FRONT``, beyond it ``KEY_BACK``. (No separate sun-plus-sky
   model: a sun out of frame is the front key; the sky is in step 2.)
5. Project with ``envmap.project_envmap`` and divide by π: the rule's raw light.
6. Its shape drawn toward the usual light's. One view says little about the light's shape (how much comes
   from above, from the sides, from behind): on the benchmark the mean shape of the *other* scenes' true
   lights gives the person a smaller scale-invariant error than the view's own. So the light's luminance
   shape (its SH scaled to a camera-facing irradiance of 1, ``FRONT_WEIGHTS``) is ``SHAPE_WEIGHT`` × the raw
   light's + (1 − ``SHAPE_WEIGHT``) × ``SHAPE_PRIOR`` (the benchmark's 68 true lights' mean shape); its
   x coefficient (front against back) is then set so that its back over front irradiance is the raw light's
   ratio to the power ``FRONT_BACK_POWER`` (its size damped), on the side of step 4's call: where the raw
   light's sum disagrees with the call (a weak back key against a bright view; a high key's lobe reaching the
   front), the same ratio the other way round, so that the light says what the rule read (front/back right on
   71 % → 79 % of the benchmark's directional maps, docs/RESULTS.md); times the raw light's camera-facing
   irradiance in RGB (so the exposure and colour on the person's front are the raw light's). With ``key_light``
   given, this step shapes the rest of the light and the key is added whole: a key the user knows is kept as
   given.

Scale: the light is in the photo's own linear units: a white diffuse surface that sees a uniform
radiance of linear value v all round gets shading v. So with ``exposure="physical"`` a person relit by
it has the brightness the same camera would have recorded in that scene.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import cv2
import numpy as np

from ..engine.errors import RelightError
from ..engine.number_pair import number_pair
from ..image.color import REC709, srgb8_to_linear, srgb_to_linear
from . import envmap, sh
from .presets import directional

__all__ = [
    "AMBIENT_GAIN", "BACKLIGHT", "BACK_WEIGHTS", "COLOUR_SATURATION", "FOV_RANGE", "FRONT_BACK_POWER",
    "FRONT_WEIGHTS", "GREY_SHARE", "HIGHLIGHT_GAIN", "KEY_BACK", "KEY_FRONT", "KEY_GEOMETRY", "MIN_SIZE",
    "SHAPE_PRIOR", "SHAPE_WEIGHT", "SceneLight", "colour_share", "envmap_view",
    "key_direction", "light_from_background", "parse_key_light", "read_background", "scene_light",
]  # fmt: skip

MIN_SIZE = 64  #: smallest accepted background side, pixels
HDR_SUFFIXES = (".hdr", ".pic", ".exr")  #: files that hold radiance (a panorama), not a background photo
FOV_RANGE = (10.0, 170.0)  #: open interval of accepted horizontal fields of view, degrees
#: linear gain on saturated pixels (see the module docstring; docs/RESULTS.md, issue 21: 1 and 3 measure alike)
HIGHLIGHT_GAIN = 3.0
# The fitted numbers (benchmarks/scene_eval.py on all 17 scenes; docs/RESULTS.md, "Into any scene"):
#: ambient radiance behind the camera = AMBIENT_GAIN × the photo's median linear luminance
AMBIENT_GAIN = 2.83
#: the key's irradiance facing it, × the ambient: the front key (front-lit views), the back-side key (back-lit)
KEY_FRONT = 1.5
KEY_BACK = 1.5
#: back-lit score z = a + b · top_bottom + c · contrast (SceneLight.backlight_score; least squares of the true
#: front/back EV clipped to ±1 EV on the 100 benchmark maps: benchmarks/scene_eval.py's fit_backlight)
BACKLIGHT = (0.412, -0.115, -0.148)
#: SceneLight.colour_share of a black-and-white photo: the median over the 100 benchmark maps (no evidence either way)
GREY_SHARE = 0.34
#: the ambient colour is the photo's median colour with its saturation scaled by this (0: neutral)
COLOUR_SATURATION = 0.1875
#: the usual light's shape (step 6): luminance SH coefficients, camera-facing irradiance 1 (the mean of the
#: benchmark scenes' true lights, each scaled so; the y, xy and yz terms set to 0: left-right symmetric). The side is
#: what loses most pairs to the paste (the true y alone: 78 -> 88 % on blender-data), but the view reads its sign on
#: 58-79 % of side-lit maps and every weight given to that reading costs (benchmarks/scene_losses.py)
SHAPE_PRIOR = (1.283, 0.0, 0.746, -0.216, 0.0, 0.0, -0.153, -0.148, 0.006)
#: step 6: the weight of the rule's own shape against SHAPE_PRIOR, and the power on its back/front ratio
SHAPE_WEIGHT = 0.25
FRONT_BACK_POWER = 0.25
#: the automatic key's geometry (degrees): the front-side key's azimuth from the camera, and the keys' elevation
KEY_GEOMETRY = (0.0, 35.0)
_BACK_AZIMUTH = 135.0  # degrees from the camera of the automatic back-side key (behind the person, to the side)
#: where the automatic back key comes from: "side" (from _BACK_AZIMUTH on the view's brighter side, KEY_GEOMETRY's
#: elevation) or "source" (from the frame's brightest part: SceneLight.bright)
BACK_KEY = "side"
_BRIGHT_SHARE = 0.01  # SceneLight.bright: the share of the frame's pixels that count as its brightest part
_STATS_WIDTH = 512  # the median, contrast, colour and halves are read on a copy at most this wide
_CLIP_LEVEL = 250  # 8-bit value from which a pixel counts as saturated
_GREY_CHROMA = 0.02  # chromaticity spread under which a photo is black and white (the benchmark's least: 0.059)
_EVEN = 0.1  # a view whose log2 luminance varies less (std) is even: no source, no shade, read as front-lit
_CLIP_LINEAR = float(srgb_to_linear(np.float32(_CLIP_LEVEL / 255)))  # the same level in linear light
_SIDE_BLUR = 0.35  # blur level of the parts beside the field of view (0 sharp, 0.5 blurred, 1 band mean)
_BAND = 8  # the sky / floor colour at the poles: the mean of the top / bottom 1/_BAND of the rows


def _side_weights(sign: int, n: int = 4000) -> np.ndarray:
    """(9,) SH light → the mean irradiance over the normals facing the camera (sign +1) or facing away from it
    (−1), each weighted by how much of it a camera on that side sees (|n_x|): a convex body's lit side."""
    d = sh.sphere_directions(n)
    d = d[d[:, 0] * sign > 0]
    w = d[:, 0] * sign
    return (sh.basis(d) * sh.cosine_lobe()).T @ w / w.sum()


#: (9,) each: light → the mean irradiance of a body's camera-facing side / of its back (benchmarks/scene_eval.py)
FRONT_WEIGHTS, BACK_WEIGHTS = _side_weights(+1), _side_weights(-1)


def _shrink(raw: np.ndarray, weight: float, power: float, prior, back_lit: bool | None = None) -> np.ndarray:
    """Step 6 of the module docstring: the light ``raw`` (9, 3) with its shape drawn toward ``prior``;
    ``back_lit`` (the rule's call: True back-lit, False front-lit; None: none) puts its back/front ratio on the
    call's side."""
    lum = raw @ REC709
    front, back = float(FRONT_WEIGHTS @ lum), float(BACK_WEIGHTS @ lum)
    if not front > 1e-12:  # a black photo: nothing to shape
        return raw
    pri = np.asarray(prior, np.float64)
    shape = weight * lum / front + (1 - weight) * pri / float(FRONT_WEIGHTS @ pri)
    ratio = max(back / front, 1e-6) ** power  # back over front, as the raw light has it, damped
    if back_lit is not None and (ratio > 1) != back_lit:  # on the call's side: the same size, the other way
        ratio = 1 / ratio
    # the x coefficient (front minus back) set so that the shape's back over front is that ratio
    fw, bw = FRONT_WEIGHTS, BACK_WEIGHTS
    shape[3] += (ratio * float(fw @ shape) - float(bw @ shape)) / (bw[3] - ratio * fw[3])
    shape /= float(fw @ shape)
    return shape[:, None] * (FRONT_WEIGHTS @ raw)[None, :]  # the raw light's camera-facing irradiance and colour


def check_fov(fov) -> float:
    """``fov`` as a float, checked against FOV_RANGE (degrees; RelightError otherwise)."""
    try:
        f = float(fov)
    except (TypeError, ValueError):
        raise RelightError(f"fov: expected a horizontal field of view in degrees, got {fov!r}") from None
    if not (FOV_RANGE[0] < f < FOV_RANGE[1]):
        raise RelightError(f"fov: expected a horizontal field of view between {FOV_RANGE[0]:g} and {FOV_RANGE[1]:g} "
                           f"degrees (exclusive), got {fov!r}")  # fmt: skip
    return f


def parse_key_light(value) -> tuple[float, float] | None:
    """'AZIMUTH,ELEVATION' (degrees) or a pair → (azimuth, elevation); None passes through.

    Azimuth 0 is a light from the camera (it lights the person's front), 90 from the image's right, −90 from
    its left, 180 from behind the person (a back light); elevation 0 is the horizon, 90 straight above.

    Raises:
        RelightError: not two finite numbers, or an elevation outside [−90, 90].
    """
    if value is None:
        return None
    az, el = number_pair(value, "key light", "AZIMUTH,ELEVATION in degrees", "45,30")
    if not (math.isfinite(az) and math.isfinite(el)) or not -90 <= el <= 90:
        raise RelightError(f"key light: expected a finite azimuth and an elevation in [-90, 90] degrees, got "
                           f"{az:g},{el:g}")  # fmt: skip
    return az, el


def key_direction(azimuth: float, elevation: float) -> np.ndarray:
    """The unit direction (subject frame, DESIGN.md §3) a key light at (azimuth, elevation) degrees comes from."""
    a, e = math.radians(azimuth), math.radians(elevation)
    return np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])


def hdr_background_error(path, name: str = "background") -> RelightError | None:
    """The error for a radiance file (.hdr/.pic/.exr) given as a background photo; None for any other file."""
    p = os.fspath(path)
    if not p.lower().endswith(HDR_SUFFIXES):
        return None
    return RelightError(
        f"{name} {p}: an HDR/EXR file holds radiance, not a photo; if it is an equirectangular panorama "
        "(width = 2 x height) give a view to render the scene from it (composite --view AZIMUTH,ELEVATION[,FOV], "
        "e.g. --view 0,0; relight_rt.apps.panorama.composite_panorama), otherwise tone-map it to an 8-bit photo "
        "(.png/.jpg) first"
    )


def read_background(src, name: str = "background") -> np.ndarray:
    """A background photo as given: (H, W, 3) RGB, uint8 (8-bit files) or float32 in [0, 1] (float arrays,
    16-bit files). Grayscale becomes colour; files are turned as their EXIF orientation says.

    Raises:
        RelightError: unreadable file, RGBA (an alpha channel has no meaning for a
            background: flatten it first), a side smaller than 64 px, bad values.
    """
    from ..image.io import as_colour, decode_file

    if isinstance(src, (str, os.PathLike)) and (err := hdr_background_error(src, name)) is not None:
        raise err
    if isinstance(src, (str, os.PathLike)):
        raw = as_colour(decode_file(src, name), bgr=True)  # gray becomes colour; turned as its EXIF tag says
        label = f"{name} {os.fspath(src)}"
    elif isinstance(src, np.ndarray):
        raw, label = as_colour(src, bgr=False), name
    else:
        raise RelightError(f"{name}: expected a path or an (H, W, 3) RGB array, got {type(src).__name__}")
    if raw.dtype == np.uint16:  # 16-bit files and arrays
        raw = np.multiply(raw, np.float32(1 / 65535), dtype=np.float32)
    if raw.ndim == 3 and raw.shape[2] == 4:
        raise RelightError(f"{label}: expected an (H, W, 3) colour photo, got RGBA {raw.shape}; "
                           "flatten the alpha channel first")  # fmt: skip
    if raw.ndim != 3 or raw.shape[2] != 3:
        raise RelightError(f"{label}: expected an (H, W, 3) RGB photo, got {raw.shape}")
    if min(raw.shape[:2]) < MIN_SIZE:
        raise RelightError(f"{label}: expected at least {MIN_SIZE} x {MIN_SIZE} pixels, got "
                           f"{raw.shape[1]} x {raw.shape[0]} (W x H)")  # fmt: skip
    if raw.dtype == np.uint8:
        return raw
    if raw.dtype.kind != "f":
        raise RelightError(f"{label}: expected uint8 or float in [0, 1], got {raw.dtype}")
    out = raw.astype(np.float32)
    if not np.isfinite(out).all() or out.min() < -1e-3 or out.max() > 1 + 1e-3:
        if np.isfinite(out).all() and out.max() > 1 + 1e-3:  # radiance (an HDR image), not a photo's values
            raise RelightError(
                f"{label}: expected float values in [0, 1], got values up to {float(out.max()):.3g}: an HDR image "
                "holds radiance, not a photo; for an equirectangular panorama use relight_rt.apps.panorama "
                "(composite --view), otherwise tone-map it to [0, 1] first"
            )
        raise RelightError(f"{label}: expected finite float values in [0, 1]")
    return np.clip(out, 0, 1)


def _linear_and_clipped(photo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Linear float32 RGB and the (H, W) float32 saturated-pixel indicator."""
    if photo.dtype == np.uint8:  # OpenCV's table look-up and channel maximum: several times numpy's speed
        r, g, b = cv2.split(photo)
        return srgb8_to_linear(photo), (cv2.max(cv2.max(r, g), b) >= _CLIP_LEVEL).astype(np.float32)
    return srgb_to_linear(photo), (photo.max(axis=2) >= _CLIP_LEVEL / 255).astype(np.float32)


def _fill_front(lin: np.ndarray, fov: float, height: int) -> np.ndarray:
    """The (H, 2H, C) env map of the half in front of the camera (x < 0) from the small linear photo ``lin``;
    zero behind the camera (module docstring, step 2). Linear in ``lin``."""
    ph, pw = lin.shape[:2]
    half = math.radians(fov) / 2
    tan_h = math.tan(half)
    tan_v = tan_h * ph / pw  # square pixels
    d = envmap.directions_envmap(height)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    psi = np.arctan2(y, -x)  # horizontal angle from the view axis, toward +y (image right)
    folded = np.clip(psi, -half, half)  # beside the field of view: the side edge stretched
    u = np.tan(folded) / tan_h  # −1 … 1 across the photo
    elev = np.arctan2(z, np.hypot(x, y))
    edge = np.arctan(tan_v * np.cos(folded))  # elevation of the photo's top edge at that column
    v = np.tan(np.clip(elev, -edge, edge)) / (np.cos(folded) * tan_v)  # −1 … 1, clamped: sky/floor stretch
    mapx = ((u + 1) * 0.5 * pw - 0.5).astype(np.float32)
    mapy = ((1 - v) * 0.5 * ph - 0.5).astype(np.float32)
    beta_v = np.clip((np.abs(elev) - edge) / (math.pi / 2 - edge), 0, 1)
    beside = np.where(np.abs(psi) > half, _SIDE_BLUR, 0.0)
    beta = np.maximum(beta_v, beside).astype(np.float32)[..., None]

    sigma = max(pw / 8, 0.5)
    blurred = cv2.GaussianBlur(lin, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)
    band = max(1, ph // _BAND)
    top, bottom = lin[:band].reshape(-1, 3).mean(0), lin[-band:].reshape(-1, 3).mean(0)
    pole = np.where((z >= 0)[..., None], top, bottom).astype(np.float32)

    def sample(img):
        return cv2.remap(img, mapx, mapy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)

    sharp, soft = sample(lin), sample(blurred)
    low = sharp + (soft - sharp) * np.minimum(2 * beta, 1)
    env = np.where(beta <= 0.5, low, soft + (pole - soft) * (2 * beta - 1))
    return np.where((x < 0)[..., None], env, 0).astype(np.float32)


@dataclass(frozen=True)
class SceneLight:
    """What ``scene_light`` reads from a background photo; ``light()`` puts it together (module docstring).

    Attributes:
        view: (9, 3) the front half (step 2) without the clipped sources, photo units.
        source: (9, 3) the clipped sources' part of the front half (with the highlight gain).
        behind: (9,) a uniform radiance 1 over the half behind the camera.
        level: the photo's median linear luminance.
        colour: (3,) the photo's median linear colour (per channel), luminance 1.
        top_bottom: log2 of the mean luminance of the photo's top third over its bottom third.
        contrast: the standard deviation of log2 luminance over the photo (floor 2**-13).
        colour_share: the spread of the photo's chromaticity over ``contrast`` (``colour_share``; not in the call:
            step 4).
        side: +1 when the view's right half is the brighter, else −1 (the side of the automatic key).
        view_env, source_env: (H, 2H, 3) the front half without / only the sources, as env maps (previews).
        bright: (azimuth, elevation) in degrees of the frame's brightest part (its top ``_BRIGHT_SHARE`` of pixels
            and at least half the peak, luminance-weighted), the azimuth from the view's axis toward the image's
            right: a sun, window or lamp.
    """

    view: np.ndarray
    source: np.ndarray
    behind: np.ndarray
    level: float
    colour: np.ndarray
    top_bottom: float
    contrast: float
    side: float
    view_env: np.ndarray
    source_env: np.ndarray
    bright: tuple[float, float] = (0.0, 0.0)
    colour_share: float = 0.0

    def backlight_features(self) -> np.ndarray:
        """(3,) [1, top_bottom, contrast]: what ``BACKLIGHT`` weighs (benchmarks fit it on these)."""
        return np.array([1.0, self.top_bottom, self.contrast])

    def backlight_score(self, backlight=None) -> float:
        """z = a + b · top_bottom + c · contrast with (a, b, c) = ``BACKLIGHT``: < 0 reads the scene as back-lit."""
        return float(np.asarray(BACKLIGHT if backlight is None else backlight, np.float64) @ self.backlight_features())

    def ambient_colour(self, saturation=None) -> np.ndarray:
        """(3,) the ambient and key colour: the photo's median colour with its saturation scaled, luminance 1."""
        s = COLOUR_SATURATION if saturation is None else saturation
        c = np.maximum(self.colour.astype(np.float64), 1e-6) ** s
        return c / float(c @ REC709)

    @staticmethod
    def key_unit(direction) -> np.ndarray:
        """(9,) a lobe from ``direction`` whose irradiance facing it is 1 (a point lamp of lights.directional)."""
        return directional(np.asarray(direction, np.float64))[:, 0]

    def key(self, key_light=None, backlight=None, geometry=None, back_key=None) -> tuple[tuple[float, float], bool]:
        """((azimuth, elevation), back): where the key comes from (degrees) and whether it is a back key."""
        given = parse_key_light(key_light)
        if given is not None:
            return given, abs((given[0] + 180) % 360 - 180) > 90
        front_azimuth, elevation = KEY_GEOMETRY if geometry is None else geometry
        if self.backlight_score(backlight) < 0 and self.contrast >= _EVEN:
            if (BACK_KEY if back_key is None else back_key) == "source":  # from the bright part in frame
                psi, el = self.bright
                return (math.copysign(180.0 - abs(psi), psi if psi else self.side), max(el, 0.0)), True
            return (_BACK_AZIMUTH * self.side, elevation), True
        return (front_azimuth * self.side, elevation), False

    def light(self, key_light=None, *, ambient_gain=None, key_front=None, key_back=None, backlight=None,
              saturation=None, geometry=None, shape_weight=None, front_back_power=None,
              prior=None, back_key=None) -> np.ndarray:  # fmt: skip
        """(9, 3) float64 light in the photo's units; ``key_light`` (azimuth, elevation) steers the key (step 6
        then shapes the rest and adds the key whole: a key the user gives is kept as given); the keyword
        numbers override the module's fitted ones (benchmarks/scene_eval.py's tuning;
        ``shape_weight=1, front_back_power=1`` skips step 6: the raw light)."""
        ambient = (AMBIENT_GAIN if ambient_gain is None else ambient_gain) * self.level
        colour = self.ambient_colour(saturation)
        (az, el), back = self.key(key_light, backlight, geometry, back_key)
        if back:
            strength = KEY_BACK if key_back is None else key_back
        else:
            strength = KEY_FRONT if key_front is None else key_front
        rest = self.view + self.source + ambient * self.behind[:, None] * colour[None, :]
        key = ambient * strength * self.key_unit(key_direction(az, el))[:, None] * colour[None, :]
        weight = SHAPE_WEIGHT if shape_weight is None else shape_weight
        power = FRONT_BACK_POWER if front_back_power is None else front_back_power
        if weight == 1 and power == 1:  # the raw light (steps 1-5)
            return rest + key
        pri = SHAPE_PRIOR if prior is None else prior
        if key_light is None:
            return _shrink(rest + key, weight, power, pri, back)
        return _shrink(rest, weight, power, pri) + key  # a key the user gives is added whole


def colour_share(lin: np.ndarray, lum: np.ndarray, contrast: float) -> float:
    """The colour share (scene5's front/back statistic, out of step 4's call since scene24) of the (h, w, 3)
    linear photo ``lin`` with luminance ``lum`` and log2-luminance spread ``contrast``: sqrt(var log2 R/G + var
    log2 B/G) over max(contrast, 0.05), on the pixels neither clipped nor darker than 1/16 of the median (their
    colour is noise) and with no black channel; 0 with fewer than 64; ``GREY_SHARE`` where the chromaticity's spread
    is under 0.02 (a black-and-white photo)."""
    ok = (lin.max(axis=2) < _CLIP_LINEAR) & (lum >= float(np.median(lum)) / 16) & (lin.min(axis=2) > 0)
    if int(ok.sum()) < 64:
        return 0.0
    px = lin[ok].astype(np.float64)
    spread = math.sqrt(float(np.log2(px[:, 0] / px[:, 1]).var() + np.log2(px[:, 2] / px[:, 1]).var()))
    if spread < _GREY_CHROMA:  # a black-and-white photo: its colour tells nothing
        return GREY_SHARE
    return spread / max(contrast, 0.05)


def _brightest(lum: np.ndarray, fov: float) -> tuple[float, float]:
    """(azimuth, elevation) in degrees of the luminance-weighted centre of the brightest ``_BRIGHT_SHARE`` of the
    (h, w) linear luminance ``lum`` (and at least half its peak: a sun, not the sky around it) seen over the
    horizontal field of view ``fov`` (a level camera; azimuth from the view's axis, positive toward the image's
    right)."""
    h, w = lum.shape
    top = lum >= max(float(np.quantile(lum, 1 - _BRIGHT_SHARE)), 0.5 * float(lum.max()))
    wt = np.where(top, lum, 0.0)
    total = float(wt.sum())
    if not total > 0:
        return 0.0, 0.0
    tan_h = math.tan(math.radians(fov) / 2)
    u = ((np.arange(w) + 0.5) / w * 2 - 1) * tan_h  # y / −x of each column
    v = (1 - (np.arange(h) + 0.5) / h * 2) * tan_h * h / w  # z / −x of each row
    y, z = float(wt.sum(0) @ u) / total, float(wt.sum(1) @ v) / total
    return math.degrees(math.atan(y)), math.degrees(math.atan2(z, math.hypot(1.0, y)))


def scene_light(image, fov: float = 60.0, *, height: int = 64) -> SceneLight:
    """Read a background photo's light into its parts (module docstring); ``light_from_background`` combines them.

    Args / Raises: as ``light_from_background``.
    """
    f = check_fov(fov)
    if isinstance(height, bool) or not isinstance(height, (int, np.integer)) or not 8 <= height <= 1024:
        raise RelightError(f"height: expected an integer from 8 to 1024, got {height!r}")
    photo = read_background(image)
    lin, clipped = _linear_and_clipped(photo)
    ph, pw = photo.shape[:2]
    # the statistics on a copy at most _STATS_WIDTH wide (area-averaged in linear light): plenty, and fast
    stats = lin
    if pw > _STATS_WIDTH:
        stats = cv2.resize(lin, (_STATS_WIDTH, max(3, round(ph * _STATS_WIDTH / pw))), interpolation=cv2.INTER_AREA)
    lum = stats @ REC709
    ph, pw = lum.shape
    median = np.median(stats.reshape(-1, 3), axis=0)
    median_lum = float(median @ REC709)
    colour = (median / median_lum).astype(np.float32) if median_lum > 1e-6 else np.ones(3, np.float32)
    third = max(1, ph // 3)
    top_bottom = math.log2(max(float(lum[:third].mean()), 1e-6) / max(float(lum[-third:].mean()), 1e-6))
    contrast = float(np.log2(np.maximum(lum, 2.0**-13)).std())
    half = pw // 2
    side = 1.0 if float(lum[:, half:].mean()) >= float(lum[:, :half].mean()) else -1.0
    bright = _brightest(lum, f)
    share = colour_share(stats, lum, contrast)

    # about two samples per env-map pixel across the field of view
    ph, pw = photo.shape[:2]
    width = int(min(pw, max(16, round(2 * (2 * height) * f / 360))))
    size = (width, max(4, int(round(width * ph / pw))))
    small = cv2.resize(lin, size, interpolation=cv2.INTER_AREA)
    small_clip = cv2.resize(clipped, size, interpolation=cv2.INTER_AREA)[..., None]
    env_rest = _fill_front(small * (1 - small_clip), f, int(height))
    env_src = _fill_front(small * small_clip * np.float32(HIGHLIGHT_GAIN), f, int(height))
    behind = (envmap.directions_envmap(int(height))[..., 0:1] >= 0).astype(np.float32)
    return SceneLight(
        view=envmap.project_envmap(env_rest) / math.pi,
        source=envmap.project_envmap(env_src) / math.pi,
        behind=envmap.project_envmap(np.repeat(behind, 3, axis=2))[:, 0] / math.pi,
        level=float(np.median(lum)),
        colour=colour,
        top_bottom=top_bottom,
        contrast=contrast,
        side=side,
        view_env=env_rest,
        source_env=env_src,
        bright=bright,
        colour_share=share,
    )


def light_from_background(
    image, fov: float = 60.0, *, height: int = 64, key_light=None
) -> tuple[np.ndarray, np.ndarray]:
    """Estimate the SH light of a scene from one ordinary photo of it (the module docstring has the rule).

    Args:
        image: the background photo: a path or an (H, W, 3) RGB array (uint8, or float in [0, 1]),
            sRGB-encoded as cameras write them; at least 64 px on each side.
        fov: its horizontal field of view in degrees, in (10, 170).
        height: height H of the env map it fills (width 2H); 64 is plenty for degree-2 SH.
        key_light: None (the key the view implies) or (azimuth, elevation) in degrees, or "AZ,EL"
            (``parse_key_light``): where the key light comes from.

    Returns:
        (light, envmap): the (9, 3) float32 RGB SH light (in the photo's linear units, see the module
        docstring) and an (H, 2H, 3) float32 linear env map for previews: the front half, the ambient behind
        the camera and the key (its SH lobe, clipped at 0): what the rule read, before step 6 reshapes the
        SH light.

    Raises:
        RelightError: bad image (see ``read_background``), fov outside (10°, 170°), bad height or key light.
    """
    key = parse_key_light(key_light)
    parts = scene_light(image, fov, height=height)
    light = parts.light(key)
    h = int(height)
    ambient = AMBIENT_GAIN * parts.level * parts.ambient_colour()
    behind = envmap.directions_envmap(h)[..., 0:1] >= 0
    env = parts.view_env + parts.source_env + np.where(behind, ambient, 0)
    raw = parts.light(key, shape_weight=1.0, front_back_power=1.0)  # steps 1-5: what the preview shows
    added = raw - parts.view - parts.source - parts.behind[:, None] * ambient[None, :]  # the key
    env = env + np.maximum(envmap.envmap_from_light(added * math.pi, h), 0)
    return light.astype(np.float32), env.astype(np.float32)


def envmap_view(env, size: tuple[int, int], fov: float = 60.0, rotation: np.ndarray | None = None) -> np.ndarray:
    """A perspective view of an equirectangular map, as a level camera at the subject looking along −x sees it.

    The inverse of the photo placement above: image right = +y, up = +z, unmirrored, horizontal field of
    view ``fov``. Bilinear look-up (wrapping in azimuth). ``rotation``: (3, 3) R taking the camera's frame into
    the map's (a camera turned away from −x; relight_rt.apps.panorama.view_rotation), default none.

    Args:
        env: (H, 2H, 3) float linear RGB map (DESIGN.md §3 layout).
        size: (height, width) of the view in pixels.
        fov: horizontal field of view in degrees, in (10, 170).

    Returns:
        (height, width, 3) float32 linear RGB.
    """
    f = check_fov(fov)
    arr = np.asarray(env, np.float32)
    if arr.ndim != 3 or arr.shape[2] != 3 or arr.shape[1] != 2 * arr.shape[0]:
        raise RelightError(f"env: expected an equirectangular (H, 2H, 3) map, got {arr.shape}")
    vh, vw = (int(s) for s in size)
    if vh < 1 or vw < 1:
        raise RelightError(f"size: expected a positive (height, width), got {size!r}")
    tan_h = math.tan(math.radians(f) / 2)
    cols = (((np.arange(vw) + 0.5) / vw * 2 - 1) * tan_h).astype(np.float32)[None, :]  # y of the ray (−x = 1)
    rows = ((1 - (np.arange(vh) + 0.5) / vh * 2) * tan_h * vh / vw).astype(np.float32)[:, None]  # its z
    r = np.eye(3, dtype=np.float32) if rotation is None else np.asarray(rotation, np.float32)
    wx, wy, wz = (-r[i, 0] + r[i, 1] * cols + r[i, 2] * rows for i in range(3))  # the rays in the map's frame
    theta = np.arctan2(np.hypot(wx, wy), wz)
    phi = np.arctan2(-wy, wx)  # ω = (sinθ cosφ, −sinθ sinφ, cosθ)
    phi += np.float32(2 * np.pi) * (phi < 0)
    eh, ew = arr.shape[:2]
    mapx = (phi / (2 * np.pi) * ew - 0.5 + 1).astype(np.float32)  # + 1: the wrapped column padded on the left
    mapy = np.clip(theta / np.pi * eh - 0.5, 0, eh - 1).astype(np.float32)
    padded = np.concatenate([arr[:, -1:], arr, arr[:, :1]], axis=1)  # wrap in azimuth
    return cv2.remap(padded, mapx, mapy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
