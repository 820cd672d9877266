"""A panorama used exactly as the scene: its view as the background plate, its own SH light on the person.

When the user has the scene as an equirectangular HDR panorama (DESIGN.md §3, "Environment maps"), nothing needs
to be guessed: ``panorama_view`` renders what a camera at the subject sees in the direction ``view`` =
(azimuth, elevation, fov) and rotates the panorama's SH light into that camera's frame, in the plate's units;
``composite_panorama`` puts a person there with ``relight_rt.apps.scene.composite``, lit by that light exactly.

The view (degrees). Azimuth 0 looks at the panorama's centre column (where viewers and HDRI libraries open it;
in the subject frame the camera's −x); positive azimuths turn to the right (toward the panorama's right).
Elevation 0 is a level camera, positive looks up (at most ``MAX_ELEVATION``). fov is the horizontal field of view
(``relight_rt.light.from_background.FOV_RANGE``; default 60°). The camera does not roll.

The camera's frame. The camera looks along d = R · (−1, 0, 0) with R = R_z(−azimuth) · R_y(elevation) (R_y(e)
tilts −x toward +z); the person's frame is the camera's (DESIGN.md §3: +x toward the camera, +y the image's
right, +z the image's up), so a direction ω in the camera frame is R · ω in the panorama's and the light is
``sh.rotate(project_envmap(pano), Rᵀ)``.

The plate's camera (``METER_GREY``). The view is exposed like a camera metering the place: one scale k so that
the view's mean linear luminance is 0.18 (as benchmarks/scene_eval.py's background photos), clipped at 1 (a
camera's highlights clip) and written as 8-bit sRGB. The light is the panorama's SH light times k / π: the units
of ``relight_rt.light.from_background`` (a white diffuse surface under a uniform radiance that the plate shows as v gets
shading v), so the person is exactly as bright as the place's light makes a white surface in that plate.

The plate's blur (``plate_blur``). A view magnifies the map: a map H rows high spans π/H radians a pixel, a plate
pixel 2·tan(fov/2)/width at its centre, so m = π·width / (2·H·tan(fov/2)) plate pixels show one map pixel (7 for a
512 x 256 map seen 60° wide on 640 pixels). The map's pixels (boxes: variance 1/12) read by bilinear look-up (a
triangle: 1/6) blur the plate by a Gaussian σ = m/2 plate pixels on average over where an edge falls. That is
known exactly, so a full-body person, whose feet stand on ground the plate shows at their distance, is blurred to
it (``relight_rt.apps.scene``'s step 5 takes the larger of it and the blur it measures): a sharp figure on a soft
plate looks pasted. A half body or a portrait, close to the camera, stays sharp before a plate that reads as out
of focus.

Round suns (``round_sources``). Where the map holds more than the plate's white (a sun, a lamp: pixels brighter than
1/k), the clipped outline in the plate is a level set of the look-up's kernel around those few pixels, and
bilinear look-up's kernel is a square pyramid: a one-pixel sun clips as a square. Those pixels' excess over white
is drawn instead with the isotropic Gaussian of the same variance (σ = half a map pixel, π/(2H) radians: the same
blur, ``plate_blur``) by the angle to each pixel's centre, its power (radiance × solid angle) kept: the sun clips
as a disc. Only compact regions (at most ``ROUND_MAX_AREA`` map pixels: a large bright area's outline is the scene's
own, not the kernel's) in or near the view, at most ``ROUND_MAX_PIXELS`` pixels in all (the time it takes); the
light and the exposure are the map's as before.

The rim (``rim=True``, the default here: the light is known). A degree-2 SH light spreads a small bright source over
the whole body; behind the person (a sun or window in or near the view) it should light the outline on its side.
``relight_rt.apps.scene_rim.panorama_rim`` finds the brightest source behind the person in the map and the radiance
its outline scatters forward (the source's power over a grazing lobe, not the map's mean; in its halo's colour where the
map clips there); ``relight_rt.apps.scene``'s step 7 adds it to the outline on that side, wide where the matte says
strands, a thin line where it says a smooth edge. ``source`` (the brightest source anywhere) is kept for its shading.
"""

from __future__ import annotations

import math
import numbers
import os
import re
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from ..engine.errors import RelightError
from ..image.color import REC709, linear_to_srgb
from ..light import envmap, sh
from ..light.from_background import FOV_RANGE, MIN_SIZE, check_fov, envmap_view
from .scene_place import CAMERA_M
from .scene_rim import SOURCE_SHARE, brightest, panorama_rim

__all__ = [
    "MAX_ELEVATION",
    "MAX_SIDE",
    "METER_GREY",
    "PanoramaView",
    "ROUND_MAX_AREA",
    "ROUND_MAX_PIXELS",
    "SOURCE_SHARE",
    "check_panorama_file",
    "composite_panorama",
    "load_panorama",
    "panorama_view",
    "parse_size",
    "parse_view",
    "plate_blur",
    "render_view",
    "round_sources",
    "source",
    "view_rotation",
]

METER_GREY = 0.18  #: the plate's camera exposes the view's mean linear luminance to this
ROUND_MAX_AREA = 64  #: round_sources: a region of the map brighter than white of at most this many pixels is a source
ROUND_MAX_PIXELS = 1024  #: round_sources: at most this many such pixels in or near the view (else none is redrawn)
_SOURCE_HEIGHT = 256  # the source is found on a copy at most this many rows high
MAX_ELEVATION = 80.0  #: |elevation| limit of a view, degrees
MAX_SIDE = 32766  #: a view's longest side, pixels: OpenCV's remap takes maps under 32767 (SHRT_MAX) a side
_DEFAULT_FOV = 60.0
_VIEW_FORM = "AZIMUTH,ELEVATION[,FOV] in degrees (e.g. 30,0 or -90,10,75)"


def parse_view(value) -> tuple[float, float, float]:
    """'AZIMUTH,ELEVATION[,FOV]' (degrees) or a sequence of 2 or 3 numbers → (azimuth, elevation, fov).

    Azimuth: any finite number (turned into (−180, 180]); elevation in [−MAX_ELEVATION, MAX_ELEVATION]; fov
    inside FOV_RANGE, 60 when left out (module docstring).

    Raises:
        RelightError: anything else, one message saying what was expected.
    """
    if isinstance(value, str):
        parts = value.replace(" ", "").split(",")
    elif isinstance(value, (list, tuple, np.ndarray)):
        parts = list(value)
        # numbers only: a request's true/false or "10" is not an angle
        if not all(isinstance(p, numbers.Real) and not isinstance(p, (bool, np.bool_)) for p in parts):
            raise RelightError(f"view: expected numbers {_VIEW_FORM}, got {_shown(value)}")
    else:  # a mapping would give its keys, a number no pair
        raise RelightError(f"view: expected {_VIEW_FORM}, got {_shown(value)}")
    if len(parts) not in (2, 3):
        raise RelightError(f"view: expected {_VIEW_FORM}, got {_shown(value)}")
    try:
        nums = [float(p) for p in parts]
    except (TypeError, ValueError, OverflowError):  # OverflowError: a JSON integer of hundreds of digits
        raise RelightError(f"view: expected finite numbers {_VIEW_FORM}, got {_shown(value)}") from None
    if not all(math.isfinite(v) for v in nums):
        raise RelightError(f"view: expected finite numbers {_VIEW_FORM}, got {_shown(value)}")
    az, el = nums[0], nums[1]
    fov = nums[2] if len(nums) == 3 else _DEFAULT_FOV
    if abs(el) > MAX_ELEVATION:
        raise RelightError(f"view: elevation must lie in [-{MAX_ELEVATION:g}, {MAX_ELEVATION:g}] degrees, got {el:g}")
    if not FOV_RANGE[0] < fov < FOV_RANGE[1]:
        raise RelightError(f"view: field of view must lie in ({FOV_RANGE[0]:g}, {FOV_RANGE[1]:g}) degrees, got {fov:g}")
    az = -((-az + 180.0) % 360.0 - 180.0) + 0.0  # (−180, 180]; + 0.0: never −0
    return az, el, fov


def _shown(value) -> str:
    """``value`` as an error message quotes it: at most 80 characters (a request may send megabytes)."""
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def parse_size(value) -> tuple[int, int]:
    """'WxH' (or a (width, height) pair of integers) → (width, height) in pixels, each at least ``MIN_SIZE`` and at
    most ``MAX_SIDE``, within the pixel limit (relight_rt.engine.limits)."""
    form = f"WxH in pixels, each >= {MIN_SIZE} (e.g. 1280x720)"
    if isinstance(value, str):
        m = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", value)
        pair = (int(m.group(1)), int(m.group(2))) if m else None
    else:
        try:
            pair = tuple(value)
        except TypeError:
            pair = None
        ok = pair is not None and len(pair) == 2
        ok = ok and all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in pair)
        pair = (int(pair[0]), int(pair[1])) if ok else None
    if pair is None or min(pair) < MIN_SIZE:
        raise RelightError(f"size: expected {form}, got {_shown(value)}")
    from ..engine.limits import check_pixels

    check_pixels(pair[0], pair[1], "size")
    if max(pair) > MAX_SIDE:
        raise RelightError(f"size: each side at most {MAX_SIDE} pixels, got {pair[0]}x{pair[1]}")
    return pair


def view_rotation(azimuth: float, elevation: float) -> np.ndarray:
    """(3, 3) float64 R taking the camera frame of the view into the panorama's: ω_pano = R · ω_camera.

    R = R_z(−azimuth) · R_y(elevation) (degrees; module docstring): R · (−1, 0, 0) is the view's direction.
    """
    return sh.rotation_matrix(yaw=-azimuth, pitch=elevation, degrees=True)


def plate_blur(map_height: int, width: int, fov: float) -> float:
    """The blur (Gaussian σ, plate pixels) at the centre of a ``width``-pixel view ``fov`` degrees wide of a map
    ``map_height`` rows high: half the plate pixels one map pixel spans (module docstring, "The plate's blur")."""
    if not all(isinstance(v, numbers.Integral) and not isinstance(v, bool) and v >= 1 for v in (map_height, width)):
        raise RelightError(f"plate_blur: expected a map height and a view width of at least 1 pixel, got "
                           f"{map_height!r} and {width!r}")  # fmt: skip
    fov = check_fov(fov)
    return math.pi * width / (4 * map_height * math.tan(math.radians(fov) / 2))


def render_view(env, size: tuple[int, int], azimuth: float = 0.0, elevation: float = 0.0,
                fov: float = _DEFAULT_FOV) -> np.ndarray:  # fmt: skip
    """The perspective view of an equirectangular map from the subject (bilinear, wrapping in azimuth).

    At azimuth 0, elevation 0 this is ``relight_rt.light.from_background.envmap_view``: image right = +y, up = +z,
    unmirrored.

    Args:
        env: (H, 2H, 3) float linear RGB map (DESIGN.md §3 layout).
        size: (height, width) of the view, pixels.
        azimuth, elevation: the view's direction, degrees (module docstring).
        fov: horizontal field of view, degrees.

    Returns:
        (height, width, 3) float32 linear RGB.
    """
    return envmap_view(envmap._check_envmap(env, "panorama"), size, fov, view_rotation(azimuth, elevation))


def round_sources(linear: np.ndarray, env: np.ndarray, white: float, rotation: np.ndarray, fov: float) -> np.ndarray:
    """The view ``linear`` (``render_view`` of ``env`` with ``rotation`` and ``fov``) with the map's excess over
    ``white`` drawn by an isotropic Gaussian instead of bilinear look-up (module docstring, "Round suns").

    Args:
        linear: (h, w, 3) float32 linear view of ``env``.
        env: (H, 2H, 3) float linear map.
        white: the map's value that the plate shows as white (1/k).
        rotation: (3, 3) the view's ``view_rotation``.
        fov: the view's horizontal field of view, degrees.

    Returns:
        (h, w, 3) float32: a new array, or ``linear`` itself when no compact region of the map in or near the view
        exceeds ``white``.
    """
    env = envmap._check_envmap(env, "panorama")
    fov = check_fov(fov)
    if not (isinstance(white, numbers.Real) and math.isfinite(white) and white > 0):
        raise RelightError(f"white: expected a finite positive value, got {white!r}")
    linear = np.asarray(linear)
    if linear.ndim != 3 or linear.shape[2] != 3 or np.shape(rotation) != (3, 3):
        raise RelightError(f"expected an (h, w, 3) view and a (3, 3) rotation, got {linear.shape} and "
                           f"{np.shape(rotation)}")  # fmt: skip
    excess = np.maximum(env - np.float32(white), 0)
    top = excess.max(axis=2)
    if not np.isfinite(top.max(initial=0.0)):  # an Inf (or NaN) would give the Gaussian an endless reach
        raise RelightError("panorama: holds NaN or Inf values")
    hot = (top > 0).astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(hot, connectivity=8)
    if n <= 1:
        return linear
    compact = np.zeros(n, bool)
    compact[1:] = stats[1:, cv2.CC_STAT_AREA] <= ROUND_MAX_AREA  # a larger bright area's outline is the scene's
    ys, xs = np.nonzero(compact[labels])
    eh = env.shape[0]
    d_cam = envmap.directions_envmap(eh)[ys, xs] @ np.asarray(rotation, np.float64)  # ω_camera = Rᵀ ω_map
    vh, vw = linear.shape[:2]
    focal = (vw / 2) / math.tan(math.radians(fov) / 2)
    keep = -d_cam[:, 0] > 0.05  # ahead of the camera, and within the frame or just outside it
    keep &= np.abs(d_cam[:, 1]) < -d_cam[:, 0] * 1.2 * vw / (2 * focal)
    keep &= np.abs(d_cam[:, 2]) < -d_cam[:, 0] * (vh / 2 + 0.1 * vw) / focal
    if not keep.any() or np.count_nonzero(keep) > ROUND_MAX_PIXELS:
        return linear
    ys, xs, d_cam, region = ys[keep], xs[keep], d_cam[keep], labels[ys[keep], xs[keep]]
    sigma = math.pi / (2 * eh)  # radians: half a map pixel
    power = excess[ys, xs].astype(np.float64) * envmap.solid_angles_envmap(eh)[ys, xs][:, None]  # radiance × sr
    # where each lands (pixels) and how far its Gaussian reaches: to under 1 % of white (a sun's tail stays above
    # white for 5 σ), σ magnified as the view stretches off its axis
    cx, cy = d_cam[:, 1] / -d_cam[:, 0] * focal + vw / 2, vh / 2 - d_cam[:, 2] / -d_cam[:, 0] * focal
    peak = power.max(axis=1) / (2 * math.pi * sigma**2)
    tail = np.sqrt(2 * np.log(np.maximum(peak / (0.01 * white), math.e)))
    reach = (tail + 1) * sigma * focal * (1 + ((cx - vw / 2) ** 2 + (cy - vh / 2) ** 2) / focal**2) + 2
    rot = np.asarray(rotation, np.float64)
    out = linear.copy()
    for label in np.unique(region):  # one window per source: its rays and their map coordinates once
        mine = np.flatnonzero(region == label)
        x0, x1 = max(0, int((cx - reach)[mine].min())), min(vw, int((cx + reach)[mine].max()) + 1)
        y0, y1 = max(0, int((cy - reach)[mine].min())), min(vh, int((cy + reach)[mine].max()) + 1)
        if x1 <= x0 or y1 <= y0:
            continue
        cols = (np.arange(x0, x1) + 0.5 - vw / 2) / focal
        rows = (vh / 2 - np.arange(y0, y1) - 0.5) / focal
        rays = np.stack(np.broadcast_arrays(-1.0, cols[None, :], rows[:, None]), axis=-1)
        rays /= np.linalg.norm(rays, axis=-1, keepdims=True)
        w_map = rays @ rot.T  # envmap_view's map coordinates of the rays (wrapping in azimuth)
        mx = np.mod(np.arctan2(-w_map[..., 1], w_map[..., 0]), 2 * np.pi) / (2 * np.pi) * (2 * eh) - 0.5
        my = np.clip(np.arctan2(np.hypot(w_map[..., 0], w_map[..., 1]), w_map[..., 2]) / np.pi * eh - 0.5, 0, eh - 1)
        delta = np.zeros((y1 - y0, x1 - x0, 3))
        for k in mine:  # each pixel on its own part of the window
            r0, c0 = max(0, int(cy[k] - reach[k]) - y0), max(0, int(cx[k] - reach[k]) - x0)
            r1, c1 = min(vh, int(cy[k] + reach[k]) + 1) - y0, min(vw, int(cx[k] + reach[k]) + 1) - x0
            win = np.s_[r0 : max(r0, r1), c0 : max(c0, c1)]
            # the pixel's part in the bilinear look-up taken out ...
            dx = np.abs(np.mod(mx[win] - xs[k] + eh, 2 * eh) - eh)
            bilinear = np.maximum(1 - dx, 0) * np.maximum(1 - np.abs(my[win] - ys[k]), 0)
            # ... and its power spread by the Gaussian of the angle to its centre (the chord: small angles)
            chord2 = np.maximum(2 - 2 * (rays[win] @ d_cam[k]), 0)
            gauss = np.exp(-chord2 / (2 * sigma**2)) / (2 * math.pi * sigma**2)
            delta[win] += gauss[..., None] * power[k] - bilinear[..., None] * excess[ys[k], xs[k]]
        out[y0:y1, x0:x1] += delta.astype(np.float32)
    return np.maximum(out, 0)


@dataclass(frozen=True)
class PanoramaView:
    """A panorama seen in one direction (``panorama_view``).

    Attributes:
        plate: (height, width, 3) uint8 sRGB: the background photo.
        light: (9, 3) float64 RGB SH light in the camera's frame, in the plate's linear units.
        exposure: k, the scale from the panorama's radiance to the plate's linear values (before clipping).
        horizon: the row of the level horizon, a fraction of the plate's height (may lie outside [0, 1]).
        view: (azimuth, elevation, fov), degrees.
        source_direction: (3,) unit direction, in the camera's frame, of the panorama's brightest source (``source``).
        source_shading: (3,) RGB shading that source alone gives a surface facing it, in the plate's units.
        rim: (direction (3,) in the camera's frame, rim RGB (3,) in the plate's linear units) of the brightest
            source behind the person (``relight_rt.apps.scene_rim.panorama_rim``), or None.
        blur: the plate's own blur at its centre, Gaussian σ in pixels (``plate_blur``).
    """

    plate: np.ndarray
    light: np.ndarray
    exposure: float
    horizon: float
    view: tuple[float, float, float]
    source_direction: np.ndarray
    source_shading: np.ndarray
    rim: tuple | None = None
    blur: float = 0.0


def source(env) -> tuple[np.ndarray, np.ndarray]:
    """The panorama's brightest source: its pixels of at least half the peak luminance (``SOURCE_SHARE``), on a copy
    at most ``_SOURCE_HEIGHT`` rows high (area-averaged: the energy kept).

    Args:
        env: (H, 2H, 3) float linear RGB map.

    Returns:
        (direction, power): the (3,) unit luminance-weighted mean direction of those pixels (the panorama's frame) and
        the (3,) RGB ∫ radiance dω over them (the irradiance they give a surface facing them, if small).
    """
    found = brightest(envmap._check_envmap(env, "panorama"), height=_SOURCE_HEIGHT)
    if found is None:
        return np.array([-1.0, 0.0, 0.0]), np.zeros(3)
    return found[0], found[1]


def check_panorama_file(path, name: str = "panorama") -> Path:
    """``path`` as a panorama file, checked from its name and header only (no decoding): a file, of a map's type
    (envmap's), 2:1 where its header says its size. Returns it as a Path.

    Raises:
        RelightError: any of those not so; a 2:1-less file gets an error that says what to do.
    """
    from ..engine.limits import header_size

    p = Path(path)
    if not p.is_file():
        raise RelightError(f"{name} {p}: {'not a regular file' if p.exists() else 'file not found'}")
    if p.suffix.lower() not in envmap._ENV_EXTS:
        raise RelightError(f"{name} {p}: expected an equirectangular panorama file ({', '.join(envmap._ENV_EXTS)})")
    wh = header_size(p, f"{name} {p}")
    if wh is not None and wh[0] != 2 * wh[1]:
        raise RelightError(
            f"{name} {p}: {wh[0]} x {wh[1]} (W x H) is not an equirectangular panorama (width = 2 x height), "
            "which a view needs; give an ordinary 8-bit photo of the place without a view instead (tone-map an "
            "HDR photo to .png/.jpg first)"
        )
    return p


def load_panorama(panorama, name: str = "panorama") -> np.ndarray:
    """The panorama as (H, 2H, 3) float linear RGB; a file of another shape gets an error that says what to do
    (``check_panorama_file``)."""
    if not isinstance(panorama, (str, os.PathLike)):
        return envmap._check_envmap(panorama, name)
    return envmap.load_envmap(check_panorama_file(panorama, name))


def panorama_view(panorama, size: tuple[int, int], view) -> PanoramaView:
    """The background plate and the light of a panorama seen in direction ``view`` (module docstring).

    Args:
        panorama: an equirectangular map: a path (``envmap.load_envmap``: .hdr, .exr, ...) or an (H, 2H, 3) float
            linear RGB array.
        size: (width, height) of the plate, pixels.
        view: (azimuth, elevation[, fov]) or 'AZ,EL[,FOV]' (``parse_view``).

    Returns:
        A ``PanoramaView``.

    Raises:
        RelightError: a bad view, size or panorama (not 2:1, unreadable, NaN), or a view that is black.
    """
    az, el, fov = parse_view(view)
    width, height = parse_size(size)
    env = np.maximum(load_panorama(panorama), 0)
    peak = float(env.max())
    if not math.isfinite(peak):
        raise RelightError("panorama: holds NaN or Inf values")
    if peak > 0:  # everything below is linear in the radiance: on env / peak no sum overflows, none underflows
        env /= env.dtype.type(peak)
    linear = render_view(env, (height, width), az, el, fov)
    mean = float((linear @ REC709).mean(dtype=np.float64))
    if not mean > 0:
        raise RelightError(f"panorama: the view {az:g},{el:g} is black (nothing to expose); choose another --view")
    k = METER_GREY / mean
    if not math.isfinite(k / peak):  # a map of subnormal values: its exposure does not fit a float
        raise RelightError(f"panorama: its values are too small to expose (brightest {peak:g}); scale the map up")
    rot = view_rotation(az, el)
    plate = _encode8(round_sources(linear, env, 1 / k, rot, fov), k)
    light = sh.rotate(envmap.project_envmap(env), rot.T) * (k / math.pi)
    tan_v = math.tan(math.radians(fov) / 2) * height / width
    horizon = 0.5 + math.tan(math.radians(el)) / (2 * tan_v)  # a level world's horizon, seen by the tilted camera
    direction, power = source(env)
    return PanoramaView(plate=plate, light=light, exposure=k / peak, horizon=horizon, view=(az, el, fov),
                        source_direction=rot.T @ direction, source_shading=power * (k / math.pi),
                        rim=panorama_rim(env, rot, k), blur=plate_blur(env.shape[0], width, fov))  # fmt: skip


_LEVELS = 65535  # the plate's linear values are read at this many steps for the 8-bit encoding (_encode8)
_SRGB8 = (linear_to_srgb(np.arange(_LEVELS + 1, dtype=np.float64) / _LEVELS) * 255 + 0.5).astype(np.uint8)


def _encode8(linear: np.ndarray, k: float) -> np.ndarray:
    """8-bit sRGB of k · ``linear`` clipped to [0, 1], by a table over 65,536 linear steps (a step moves an 8-bit
    level by at most 0.05, in the darks: the power law's 8-bit value, or one level off for ~0.3 % of pixels;
    2.5 times as fast on 2 MP)."""
    idx = np.empty(linear.shape, np.uint16)
    scaled = np.clip(linear * np.float32(k * _LEVELS) + np.float32(0.5), 0, _LEVELS)  # + 0.5: rounds as it truncates
    np.copyto(idx, scaled, casting="unsafe")
    return _SRGB8[idx]


def _photo_size(image) -> tuple[int, int]:
    """(width, height) of the person photo (path or array)."""
    if isinstance(image, np.ndarray):
        return int(image.shape[1]), int(image.shape[0])
    from ..image.io import read_image

    img = read_image(image, "image")
    return int(img.shape[1]), int(img.shape[0])


def composite_panorama(
    relighter,
    image,
    panorama,
    view,
    *,
    size=None,
    mask=None,
    exposure="auto",
    position=None,
    height=None,
    horizon=None,
    shadow: bool = True,
    meter: str = "frame",
    match_camera: bool = True,
    light_wrap: bool = True,
    rim: bool = True,
    camera_height: float = CAMERA_M,
) -> np.ndarray:
    """Put the person of ``image`` into a panorama seen in direction ``view``, lit by the panorama's own light.

    The plate and the light come from ``panorama_view``; the person is relit by that light as it is (no white
    balance, "auto" exposure = the light's own brightness in the plate's units) and placed by
    ``relight_rt.apps.scene.composite`` (its steps 4-8).

    Args:
        relighter: a ``relight_rt.Relighter``.
        image: the person photo (path or array, as for ``relight_rt.apps.scene.composite``).
        panorama: a path or an (H, 2H, 3) float linear RGB array (``panorama_view``).
        view: (azimuth, elevation[, fov]) or 'AZ,EL[,FOV]' in degrees (``parse_view``).
        size: the plate's (width, height) or 'WxH'; None: the person photo's size.
        mask, position, height, shadow, meter, match_camera, light_wrap, camera_height: as
            ``relight_rt.apps.scene.composite`` (the camera height: where the panorama was shot from; the camera's
            blur of a full body: at least the plate's own, ``plate_blur``).
        exposure: "auto" or "physical" (the panorama's light as it is in the plate's units: the same here) or an EV
            offset to it.
        horizon: the horizon's row (fraction of the height); None: where the view's elevation puts it (clipped
            to [0, 1]).
        rim: the panorama's brightest source behind the person (a sun or window in or near the view) puts a rim
            of light on the outline on its side (``relight_rt.apps.scene_rim``, ``relight_rt.apps.scene``'s step 7).

    Returns:
        (height, width, 3) float32 sRGB in [0, 1].
    """
    from ..light import exposure as _exposure
    from .scene import METERS, composite, decode_person, matte_on_the_photo
    from .scene_place import check_camera_height, check_height, check_horizon, parse_position

    mode = _exposure.parse_exposure(exposure)
    az, el, fov = parse_view(view)
    plate_size = parse_size(size) if size is not None else None
    # the placement's values are checked before the matte and the view are made (composite checks them there)
    position = None if position is None else parse_position(position)
    height = check_height(height)
    horizon = None if horizon is None else check_horizon(horizon)
    camera_height = check_camera_height(camera_height)
    if meter not in METERS:
        raise RelightError(f"meter: expected one of {list(METERS)}, got {meter!r}")
    image, name = decode_person(image)  # decoded once: its size, its matte and the person all read this copy
    if plate_size is None:
        plate_size = _photo_size(image)
    mask = matte_on_the_photo(relighter, image, mask, name)
    pv = panorama_view(panorama, plate_size, (az, el, fov))
    light = pv.light if mode in ("auto", "physical") else pv.light * 2.0**mode
    hz = min(max(pv.horizon, 0.0), 1.0) if horizon is None else horizon
    rim_key = pv.rim if rim else None
    if rim_key is not None and mode not in ("auto", "physical"):
        rim_key = (rim_key[0], rim_key[1] * 2.0**mode)  # the rim is the person's light: the same offset
    return composite(relighter, image, pv.plate, mask=mask, light=light.astype(np.float32), position=position,
                     height=height, shadow=shadow, exposure="physical", fov=fov, white_balance=False, horizon=hz,
                     meter=meter, match_camera=match_camera, light_wrap=light_wrap, rim=rim_key is not None,
                     rim_key=rim_key, camera_height=camera_height, plate_blur=pv.blur)  # fmt: skip
