"""A small bright source behind the person as a rim of light on their outline: which source, how bright.

A degree-2 SH light (the relighting's) spreads a sun or a window behind the person over the whole body, and
lights the body's silhouette no more than its front. In a photo such a source puts a rim on the outline on its
side: at the silhouette the surface is seen edge-on, and the light that reaches the camera from there has come
from behind at a grazing angle, scattered forward by what grows or hangs there (hair, the fuzz of skin and
cloth). Forward scattering keeps direction: that light is the radiance of the few degrees behind the outline,
not the scene's mean (a sun holding 1 % of a map's light is still the brightest thing along those directions).

The rule (``rim_colour``): the source is the brightest part of the half of the sphere behind the person (x < 0
in the subject frame, DESIGN.md §3: +x toward the camera, +y the image's right, +z up), its pixels of at least
``SOURCE_SHARE`` of that half's peak luminance; it is seen through a forward-scattering lobe of ``LOBE_DEG``
(half-angle) around the grazing direction, so the radiance the outline scatters is the source's power averaged
over the lobe's solid angle (or over its own, when it is wider than the lobe: then its mean radiance), times
``SCATTER`` (the share a fibre sends on into the camera), times how far behind the person it stands (−x: a
source beside the person lights the side, which the SH light already does). The result is a linear RGB radiance
in the plate's units, *added* to the outline where its fibres scatter it (``rim_facing``: all round for a source
straight behind, on its side for one to the side; ``relight_rt.scene``'s step 7), so a dark
coat gets a rim as bright as a light one, in the source's colour; its luminance is at most ``RIM_MAX`` (the
plate's white: a rim clips as a camera's does).

Where the source is read:
- a panorama (``panorama_rim``): from the map itself, exactly, in the view's camera frame;
- a background photo (``photo_rim``): from the frame, a compact clipped region (brightest channel >= 250/255)
  no larger than ``PHOTO_MAX_AREA`` of the frame (a sun, a window, a lamp; not an overcast sky or a white wall),
  its direction through the camera of field of view ``fov``. The clip hides the source's power: a sun clips at the
  plate's white as a lamp does. Read as that white (times ``light.from_background.HIGHLIGHT_GAIN``) over its few
  clipped pixels, it gave rims of a median 0.08 of the plate's white (0.06 on the views read as back-lit; 0.03 on a
  sunset toward the sun), a third to a quarter of what the same views' panoramas give (median 0.25), and unrelated
  to it (correlation of the logs 0.05 over the benchmark's 64 views with such a region). So a photo's source gives a
  rim of a fixed luminance, ``RIM_PHOTO`` (the median the panoramas give over those views: the value with the least
  mean |log| error; 0.21-0.33 leaving each scene out), times how far behind the person it stands, in the clipped
  pixels' colour (``benchmarks/scene_rim_photo.py``). The panoramas' rims spread widely (quartiles 0.07 and 0.75):
  a photo's is right within a factor of 3 (1.7 EV, median), the old reading within 2.4 EV, biased low.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from ..image.color import REC709
from ..light import envmap

__all__ = ["FIBRE_DEG", "LOBE_DEG", "PHOTO_MAX_AREA", "RIM_MAX", "RIM_PHOTO", "SCATTER", "SOURCE_SHARE", "brightest",
           "panorama_rim", "photo_rim", "rim_colour", "rim_facing"]  # fmt: skip

SOURCE_SHARE = 0.5  #: the source: pixels of at least this share of the peak luminance behind the person
LOBE_DEG = 5.0  #: half-angle of the forward-scattering lobe (a hair fibre's transmitted lobe: a few degrees wide)
SCATTER = 0.1  #: the share of the light seen through the lobe that the outline sends on into the camera
RIM_MAX = 1.0  #: the rim's luminance at most (linear, the plate's white)
PHOTO_MAX_AREA = 0.03  #: a photo's clipped region counts as a source when at most this share of the frame
RIM_PHOTO = 0.25  #: a photo's source: the rim's luminance (linear, the plate's units) for a source straight behind
FIBRE_DEG = 20.0  #: how far the outline's fibres stray from it (hair, fuzz): the rim's spread round the outline
# (chosen, not fitted: nothing here measures it, the renders have no fibres)
_MIN_PIXELS = 2  # a photo's clipped region of fewer pixels is noise
_CLIP_LEVEL = 250
_SOURCE_HEIGHT = 128  # a panorama's source is found on a copy at most this many rows high (area-averaged: its
# power kept; 1.4° a row)
LOBE_SR = 2 * math.pi * (1 - math.cos(math.radians(LOBE_DEG)))  #: the lobe's solid angle, steradians


def rim_colour(power, solid_angle: float, direction) -> np.ndarray:
    """The rim's linear RGB radiance (module docstring) of a source of RGB ``power`` (∫ radiance dω over it, in
    the plate's units) spread over ``solid_angle`` steradians, coming from the unit ``direction`` (subject frame);
    zeros for a source not behind the person (x >= 0)."""
    d = np.asarray(direction, np.float64)
    behind = max(0.0, -float(d[0]))
    rgb = SCATTER * behind * np.asarray(power, np.float64) / max(LOBE_SR, float(solid_angle))
    lum = float(rgb @ REC709)
    if lum > RIM_MAX:
        rgb *= RIM_MAX / lum
    return np.maximum(rgb, 0)


def rim_facing(normal_y, normal_z, direction, rays=None) -> np.ndarray:
    """How much of the rim each point of the outline gets (0-1): the share of the source's forward-scattered light
    that reaches the camera from there, its peak over the outline's directions 1 for the source as seen along the
    camera's axis (so a source to one side puts ``rim_colour`` on that side, as before).

    A fibre lying along the outline (its tangent t in the image plane; outward normal n; the camera along +x)
    scatters forward a source in the plane of x and n: a source out of that plane by β reaches it only through
    how far the fibres stray from the outline (a Gaussian of ``FIBRE_DEG`` in β); within the plane, a source on the
    body's side of the grazing direction (azimuth ψ < 0 from straight behind toward n) is hidden by the body,
    on the outward side it is not (a ramp over ±``FIBRE_DEG``). So a source straight behind (β = ψ = 0 all round)
    lights the whole outline evenly; one a little off it, all round, most where the outline faces its projection;
    one to the side, that side only. The old weight, max(0, n · p̂) with p̂ the source's unit projection, jumped
    from one half of the outline to the other as the source crossed straight behind. "Straight behind" is along
    each point's own ray from the camera (``rays``): a low sun straight behind a standing person's head is above
    the rays through their legs, so the head glows all round and the legs only on their upper edges.

    Args:
        normal_y, normal_z: the outline's outward unit normals in the image plane (toward the right, up), arrays.
        direction: (3,) unit direction to the source (subject frame: +x toward the camera).
        rays: None (every point seen along the camera's axis) or (y, z), arrays like normal_y: each point's ray
            from the camera, (−1, y, z) before normalising (its image position over the focal length).

    Returns:
        float32 array of normal_y's shape (at most 1: off the axis a point may see the source more to one side).
    """
    d = np.asarray(direction, np.float64)
    spread = math.radians(FIBRE_DEG)

    def share(ny, nz, dx, dy, dz):
        a = ny * dy + nz * dz  # toward the outline's outside
        out_of_plane = np.arctan2(np.abs(ny * dz - nz * dy), np.hypot(a, -dx))
        azimuth = np.arctan2(a, -dx)
        return np.clip(0.5 + azimuth / (2 * spread), 0, 1) * np.exp(-0.5 * (out_of_plane / spread) ** 2)

    if not d[0] < 0:
        return np.zeros(np.shape(normal_y), np.float32)
    round_ = np.linspace(0, 2 * math.pi, 360, endpoint=False)
    peak = float(share(np.cos(round_), np.sin(round_), *d).max())
    ny, nz = np.asarray(normal_y, np.float64), np.asarray(normal_z, np.float64)
    if rays is None:
        local = d
    else:  # d in each point's frame: x back along its ray, y and z across it (y kept in the horizontal plane)
        ry, rz = np.asarray(rays[0], np.float64), np.asarray(rays[1], np.float64)
        norm = np.sqrt(1 + ry * ry + rz * rz)
        ex = np.stack([1 / norm, -ry / norm, -rz / norm])  # toward the camera
        ey = np.stack([ry, np.ones_like(ry), np.zeros_like(ry)]) / np.sqrt(1 + ry * ry)  # ⟂ ex, horizontal
        ez = np.stack([ex[1] * ey[2] - ex[2] * ey[1], ex[2] * ey[0] - ex[0] * ey[2], ex[0] * ey[1] - ex[1] * ey[0]])
        local = tuple(np.tensordot(d, e, axes=(0, 0)) for e in (ex, ey, ez))
    f = share(ny, nz, *local)
    return np.minimum(f / peak, 1).astype(np.float32) if peak > 0 else np.zeros(f.shape, np.float32)


def panorama_rim(env, rotation: np.ndarray, scale: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The rim of the panorama's brightest source behind the person seen by a camera turned by ``rotation``
    (ω_pano = R · ω_camera, ``relight_rt.panorama.view_rotation``), the plate being ``scale`` × the map.

    Args:
        env: (H, 2H, 3) float linear RGB map.
        rotation: (3, 3).
        scale: the plate's linear value per unit of the map's radiance.

    Returns:
        (direction (3,) in the camera frame, rim RGB (3,)), or None when nothing behind the person is lit.
    """
    rot = np.asarray(rotation, np.float64)
    found = brightest(env, within=lambda dirs: (dirs @ rot)[..., 0] < 0)  # behind: x < 0 in the camera's frame
    if found is None:
        return None
    direction, power, solid_angle = found
    d = direction @ rot  # Rᵀ · ω: the camera's frame
    return d, rim_colour(power * scale, solid_angle, d)


def brightest(env, within=None, height: int = _SOURCE_HEIGHT) -> tuple[np.ndarray, np.ndarray, float] | None:
    """A map's brightest source: its pixels of at least ``SOURCE_SHARE`` of the peak luminance (among the
    directions ``within`` keeps, a function of the (h, 2h, 3) pixel directions; all by default), found on a copy at
    most ``height`` rows high (area-averaged: the power kept).

    Returns:
        (direction (3,) unit, luminance-weighted, the map's frame; power (3,) RGB ∫ radiance dω over those pixels;
        their solid angle), or None when nothing there is lit.
    """
    arr = np.asarray(env, np.float32)
    if arr.shape[0] > height:
        arr = cv2.resize(arr, (2 * height, height), interpolation=cv2.INTER_AREA)
    h = arr.shape[0]
    dirs = envmap.directions_envmap(h)
    lum = np.maximum(arr @ REC709.astype(np.float32), 0)
    if within is not None:
        lum = np.where(within(dirs), lum, 0)
    peak = float(lum.max())
    if not peak > 0:
        return None
    keep = lum >= SOURCE_SHARE * peak
    d_omega = envmap.solid_angles_envmap(h)[keep]
    power = (arr[keep].astype(np.float64) * d_omega[:, None]).sum(0)
    d = (dirs[keep] * (lum[keep] * d_omega)[:, None]).sum(0)
    return d / max(float(np.linalg.norm(d)), 1e-12), power, float(d_omega.sum())


def photo_rim(photo: np.ndarray, fov: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The rim of a compact clipped source in a background photo (module docstring): ``RIM_PHOTO`` times how far
    behind the person the source stands, in its clipped pixels' colour.

    Args:
        photo: (H, W, 3) uint8 sRGB, or float sRGB in [0, 1].
        fov: the photo's horizontal field of view, degrees.

    Returns:
        (direction (3,) in the subject frame, rim RGB (3,) in the photo's linear units), or None: no clipped
        region, or none small enough to be a source.
    """
    from ..image.color import srgb8_to_linear, srgb_to_linear

    h, w = photo.shape[:2]
    if photo.dtype == np.uint8:  # OpenCV's channel maximum: several times numpy's
        r, g, b = cv2.split(photo)
        clipped = cv2.max(cv2.max(r, g), b) >= _CLIP_LEVEL
    else:
        clipped = photo.max(axis=2) >= _CLIP_LEVEL / 255
    n, labels, stats, _ = cv2.connectedComponentsWithStats(clipped.astype(np.uint8), connectivity=8)
    if n <= 1:
        return None
    areas = stats[1:, cv2.CC_STAT_AREA]
    ok = (areas >= _MIN_PIXELS) & (areas <= PHOTO_MAX_AREA * h * w)
    if not ok.any():
        return None
    focal = (w / 2) / math.tan(math.radians(fov) / 2)
    k = 1 + int(np.argmax(np.where(ok, areas, 0)))  # the largest such region, read inside its box
    x0, y0, bw, bh = (int(v) for v in stats[k, :4])
    ys, xs = np.nonzero(labels[y0 : y0 + bh, x0 : x0 + bw] == k)
    ys, xs = ys + y0, xs + x0
    y = (xs + 0.5 - w / 2) / focal  # toward the image's right, per unit behind
    z = (h / 2 - ys - 0.5) / focal  # up
    norm = np.sqrt(1 + y * y + z * z)
    d_omega = 1 / (focal * focal * norm**3)  # a pixel's solid angle
    pixels = photo[ys, xs]  # only the source's pixels are linearised
    lin = srgb8_to_linear(pixels) if pixels.dtype == np.uint8 else srgb_to_linear(np.clip(pixels, 0, 1))
    colour = (lin.astype(np.float64) * d_omega[:, None]).sum(0)
    d = np.stack([-1 / norm, y / norm, z / norm], 1).T @ d_omega
    d /= max(float(np.linalg.norm(d)), 1e-12)
    lum = float(colour @ REC709)
    if not lum > 0:
        return None
    return d, colour * (RIM_PHOTO * max(0.0, -float(d[0])) / lum)
