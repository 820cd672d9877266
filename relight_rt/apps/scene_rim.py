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

A clipped source carries no colour (the clip cuts its largest channels: a sunrise reads white): its colour is its
halo's, the unclipped glow round it, where that is the more saturated (``halo_colour``; in a photo the pixels within
half the region's size whose brightest channel is at least ``HALO_LEVEL``; in a map that clips at a ceiling, those
beside the source at least that level of the ceiling, linearised). Against the rim of each benchmark view's own
brightest source in frame, the photo rim's colour errs by a median 4.6° with the halo, 8.6° from the clipped pixels
(21 views with a visible rim; 3.4° and 5.2° over all 64 with a region; ``benchmarks/scene_rim_photo.py``).

Where on the outline (``key_rim``): a back light glows through fine translucent fibres (hair, fuzz, a thin fabric's
edge) and only grazes smooth opaque cloth. The matte tells which (``fibre_share``): strands make a soft, wide alpha
transition, a smooth edge a hard one. Strands take the full rim, ``RIM_RADIUS`` of ``relight_rt.apps.scene`` deep;
a hard edge a thin grazing line (``GRAZE_WIDTH`` of it). A binary mask has no fibres anywhere (a thin line all round);
an automatic matte's softness follows its own uncertainty as much as the strands (on the contact sheet's four
people it calls one's legs hard and hair soft, another's smooth shirt soft and hair hard). The rim follows the body,
not the matte's holes and crumbs (``body``).
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from ..image.blur import wide_blur
from ..image.color import REC709
from ..image.fibres import FIBRE_RATIO, GRAZE_WIDTH, HARD_PX, WIDTH_REACH, fibre_share
from ..light import envmap

__all__ = ["FIBRE_DEG", "FIBRE_RATIO", "GRAZE_WIDTH", "HALO_LEVEL", "HARD_PX", "LOBE_DEG", "PHOTO_MAX_AREA", "RIM_MAX",
           "RIM_PHOTO", "SCATTER", "SOURCE_SHARE", "body", "brightest", "fibre_patch", "fibre_share", "fibres_in",
           "halo_colour", "key_rim", "panorama_rim", "photo_rim", "rim_colour", "rim_facing", "wide_blur"]  # fmt: skip

SOURCE_SHARE = 0.5  #: the source: pixels of at least this share of the peak luminance behind the person
LOBE_DEG = 5.0  #: half-angle of the forward-scattering lobe (a hair fibre's transmitted lobe: a few degrees wide)
SCATTER = 0.1  #: the share of the light seen through the lobe that the outline sends on into the camera
RIM_MAX = 1.0  #: the rim's luminance at most (linear, the plate's white)
PHOTO_MAX_AREA = 0.03  #: a photo's clipped region counts as a source when at most this share of the frame
RIM_PHOTO = 0.25  #: a photo's source: the rim's luminance (linear, the plate's units) for a source straight behind
FIBRE_DEG = 20.0  #: how far the outline's fibres stray from it (hair, fuzz): the rim's spread round the outline
# (chosen, not fitted: nothing here measures it, the renders have no fibres)
HALO_LEVEL = 160  #: a clipped source's halo: the pixels round it whose brightest channel is at least this (8-bit sRGB)
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
    found = brightest(
        env, within=lambda dirs: (dirs @ rot)[..., 0] < 0, halo=True
    )  # behind: x < 0 in the camera's frame
    if found is None:
        return None
    direction, power, solid_angle = found
    d = direction @ rot  # Rᵀ · ω: the camera's frame
    return d, rim_colour(power * scale, solid_angle, d)


def brightest(env, within=None, height: int = _SOURCE_HEIGHT, halo: bool = False
              ) -> tuple[np.ndarray, np.ndarray, float] | None:  # fmt: skip
    """A map's brightest source: its pixels of at least ``SOURCE_SHARE`` of the peak luminance (among the
    directions ``within`` keeps, a function of the (h, 2h, 3) pixel directions; all by default), found on a copy at
    most ``height`` rows high (area-averaged: the power kept).

    With ``halo``, a map that clips (its largest value reached again, by another channel or a pixel beside it: a
    ceiling, not a peak) gives the source the colour of its halo where that is the more saturated (``halo_colour``:
    the pixels beside it whose brightest channel is at least the share of the ceiling ``HALO_LEVEL`` is of 8-bit
    white, linearised), its power's luminance kept.

    Returns:
        (direction (3,) unit, luminance-weighted, the map's frame; power (3,) RGB ∫ radiance dω over those pixels;
        their solid angle), or None when nothing there is lit.
    """
    arr = np.asarray(env, np.float32)
    ceiling, clips = 0.0, False
    if halo and arr.size:  # a ceiling: the largest value reached twice within 4 pixels of where it is first reached
        i, j, _ = np.unravel_index(int(np.argmax(arr)), arr.shape)
        ceiling = float(arr[i, j].max())
        near = arr[max(0, i - 4) : i + 5, max(0, j - 4) : j + 5]
        clips = ceiling > 0 and int(np.count_nonzero(near >= np.float32(ceiling * 0.999))) >= 2
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
    if clips:
        near = cv2.dilate(keep.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
        bright = arr.max(axis=2) >= ceiling * (HALO_LEVEL / 255) ** 2.2
        power = halo_colour(power, arr[near & ~keep & bright])
    d = (dirs[keep] * (lum[keep] * d_omega)[:, None]).sum(0)
    return d / max(float(np.linalg.norm(d)), 1e-12), power, float(d_omega.sum())


def _halo(photo: np.ndarray, clipped: np.ndarray, labels: np.ndarray, k: int, box) -> np.ndarray:
    """Linear RGB (N, 3) of the halo of a photo's clipped region ``k`` (of ``labels``, inside ``box``: x, y, w, h):
    the unclipped pixels within half its size (2 px at least) of it whose brightest channel is at least
    ``HALO_LEVEL``."""
    from ..image.color import srgb8_to_linear, srgb_to_linear

    bx, by, bw, bh = box
    r = max(2, int(math.ceil(0.25 * (bw + bh))))
    y0, y1 = max(0, by - r), min(photo.shape[0], by + bh + r)
    x0, x1 = max(0, bx - r), min(photo.shape[1], bx + bw + r)
    region = (labels[y0:y1, x0:x1] == k).astype(np.uint8)
    near = cv2.dilate(region, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1)))
    pix = photo[y0:y1, x0:x1]
    level = HALO_LEVEL if pix.dtype == np.uint8 else HALO_LEVEL / 255
    px = pix[(near > 0) & ~clipped[y0:y1, x0:x1] & (pix.max(axis=2) >= level)]
    if not len(px):
        return np.zeros((0, 3), np.float32)
    return srgb8_to_linear(px) if px.dtype == np.uint8 else srgb_to_linear(np.clip(px, 0, 1))


def photo_rim(photo: np.ndarray, fov: float, halo: bool = True) -> tuple[np.ndarray, np.ndarray] | None:
    """The rim of a compact clipped source in a background photo (module docstring): ``RIM_PHOTO`` times how far
    behind the person the source stands, in its clipped pixels' colour, or its halo's where that is the more
    saturated (``halo_colour``; the halo: the unclipped pixels round it, within half its size, whose brightest channel
    is at least ``HALO_LEVEL``).

    Args:
        photo: (H, W, 3) uint8 sRGB, or float sRGB in [0, 1].
        fov: the photo's horizontal field of view, degrees.
        halo: False: the clipped pixels' colour as it is (what the rule was before; ``benchmarks/scene_rim_photo.py``).

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
    if halo:
        colour = halo_colour(colour, _halo(photo, clipped, labels, k, (x0, y0, bw, bh)))
    d = np.stack([-1 / norm, y / norm, z / norm], 1).T @ d_omega
    d /= max(float(np.linalg.norm(d)), 1e-12)
    lum = float(colour @ REC709)
    if not lum > 0:
        return None
    return d, colour * (RIM_PHOTO * max(0.0, -float(d[0])) / lum)


def halo_colour(source, halo) -> np.ndarray:
    """The colour of a source whose brightest pixels clipped: clipping cuts a pixel's largest channels, so a clipped
    sun reads whiter than it is, and its halo (the glow just outside the clip, lit by it) keeps the hue. ``source``:
    (3,) linear RGB of the source's pixels (any positive scale); ``halo``: (N, 3) linear RGB of the pixels just
    outside it bright enough to be its glow (N may be 0). Returns ``source``, or the halo's mean at ``source``'s
    luminance where that is the more saturated (1 − min/max): (3,) float64."""
    src = np.asarray(source, np.float64)
    ring = np.asarray(halo, np.float64).reshape(-1, 3)
    if not len(ring):
        return src
    around = ring.mean(0)

    def saturation(c):
        return 1 - float(c.min()) / float(c.max()) if c.max() > 0 else 0.0

    lum = float(around @ REC709)
    if saturation(around) <= saturation(src) or not lum > 0:
        return src
    return around * (float(src @ REC709) / lum)


def fibre_patch(alpha: np.ndarray, placed) -> np.ndarray:
    """``fibre_share`` of the person's matte ``alpha`` (their photo's resolution) as placed in the frame: cut to
    their box (``scene_place.box``) and resized to ``placed``'s (a ``scene_place.Placement``) height and width,
    its top-left corner at ``placed.top``, ``placed.left`` (as placed, before any blur).

    Returns:
        (placed.height, placed.width) float32 in [0, 1].
    """
    from .scene_place import box

    a = np.asarray(alpha, np.float32)
    y0, y1, x0, x1 = box(a)
    m = max(1, int(math.ceil(6 * WIDTH_REACH * (y1 - y0))))  # the outline's neighbours, for its averages
    cy0, cx0 = max(0, y0 - m), max(0, x0 - m)
    share = fibre_share(a[cy0 : y1 + m, cx0 : x1 + m])[y0 - cy0 : y1 - cy0, x0 - cx0 : x1 - cx0]
    small = placed.height < share.shape[0]
    return cv2.resize(share, (placed.width, placed.height), interpolation=cv2.INTER_AREA if small else cv2.INTER_LINEAR)


def fibres_in(patch: np.ndarray, at: tuple[int, int], window: tuple[int, int, int, int]) -> np.ndarray:
    """The fibre map ``patch`` (``fibre_patch``) whose top-left corner is at frame pixel ``at`` (row, column), cut to
    the frame's ``window`` (y0, y1, x0, x1); 0 where the patch does not reach.

    Returns:
        (y1 − y0, x1 − x0) float32.
    """
    y0, y1, x0, x1 = window
    out = np.zeros((y1 - y0, x1 - x0), np.float32)
    top, left = at
    py0, px0 = max(top, y0), max(left, x0)
    py1, px1 = min(top + patch.shape[0], y1), min(left + patch.shape[1], x1)
    if py1 > py0 and px1 > px0:
        out[py0 - y0 : py1 - y0, px0 - x0 : px1 - x0] = patch[py0 - top : py1 - top, px0 - left : px1 - left]
    return out


def body(alpha: np.ndarray, radius: float) -> np.ndarray:
    """The matte ``alpha`` ((h, w) float in [0, 1]) as the rim sees it: its holes (places not quite opaque, alpha
    under 0.99, cut off from the outside and from the border: a pinhole, a dip a blur left of one, an earring's loop)
    of fewer than (8 ``radius``)² pixels filled (alpha 1), its fragments (from 1/2) of fewer than (4 ``radius``)²
    emptied (0), and what lies beyond 2 ``radius`` of the rest emptied too (sizes chosen, not fitted: a gap between
    an arm and the body stays outside). Returns a new (h, w) float32."""
    a = np.array(alpha, dtype=np.float32)
    h, w = a.shape
    for value, mask, least in ((1.0, a < 0.99, (8 * radius) ** 2), (0.0, a >= 0.5, (4 * radius) ** 2)):
        n, labels, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
        x, y, bw, bh, area = (stats[1:, i] for i in range(5))
        border = (x == 0) | (y == 0) | (x + bw == w) | (y + bh == h)
        small = (area < max(4.0, least)) & (~border if value == 1.0 else True)
        if small.any():
            a[np.concatenate([[False], small])[labels]] = value
    r = max(1, int(math.ceil(2 * radius)))
    near = cv2.dilate((a >= 0.5).astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1)))
    a[near == 0] = 0
    return a


def key_rim(composed: np.ndarray, alpha: np.ndarray, direction: np.ndarray, colour, radius: float,
            view: tuple[float, float, float] | None = None, fibres=None) -> np.ndarray:  # fmt: skip
    """A source behind the person as a rim on their outline (``relight_rt.apps.scene``'s step 7; the rim's radiance:
    module docstring).

    The source (``direction``, the subject frame: x toward the camera, y the image's right, z up) lights the
    silhouette, and what grows there (hair, the fuzz of skin and cloth) scatters it forward, toward the camera: a
    rim on the source's side, all round for a source straight behind. So ``colour`` (linear RGB radiance) is
    added to each pixel inside the matte near the outside, times facing · band: facing = ``rim_facing`` of n, the
    outline's outward normal in the image plane (the gradient of the blurred matte); band, where the outline is
    fibres (``fibres``), 2 · alpha × the share of outside pixels within ``radius`` (1 at a hard edge, falling to 0 a
    few ``radius`` inside), and where it is a smooth opaque edge the same within ``GRAZE_WIDTH`` of ``radius``: a
    thin grazing line (a back light only grazes smooth cloth; across a soft transition both light its fractional
    pixels, the share sets how far the glow reaches into the opaque body). Added, not multiplied: a dark coat's rim
    is as bright as a light one's.

    The rim follows the body's outline, not the matte's fringes (``body``): a hole in the matte or a fragment of it
    a few times smaller than the rim's reach across (a pinhole, an earring's loop, a crumb of matte beside the body)
    is neither outside nor outline.

    Args:
        composed: (h, w, 3) linear frame with the person laid over the background.
        alpha: (h, w) the person's matte in this window.
        direction: (3,) unit direction the source is in (x < 0: behind the person; otherwise nothing).
        colour: (3,) linear RGB radiance of the rim (>= 0), or a scalar grey.
        radius: Gaussian sigma of the reach, pixels (> 0).
        view: (focal, top, left) in pixels, the window's corner relative to the frame's centre: each point's own
            ray from the camera (``rim_facing``'s rays); None: every point on the camera's axis.
        fibres: the outline's fibre share, (h, w) in [0, 1] or a number (``fibre_share``; composite gives the
            person's photo's, placed with them); None: ``fibre_share`` of ``alpha`` itself.

    Returns:
        New (h, w, 3) float32.
    """
    out = np.array(composed, dtype=np.float32)
    d = np.asarray(direction, np.float64)
    rgb = np.broadcast_to(np.maximum(np.asarray(colour, np.float32), 0), (3,))
    if not (d[0] < 0 and rgb.max() > 0):
        return out
    a0 = np.clip(alpha, 0, 1).astype(np.float32)
    a = body(a0, radius)
    soft = wide_blur(a, radius)
    outside = 1 - a
    reach = 1 - soft  # the blur of what lies outside (the blur is linear and keeps a constant)
    a = np.minimum(a, a0)  # a filled hole shows what is behind the person: no rim on it
    edge = (a > 0) & (reach > 1e-3)
    if not edge.any():
        return out
    gx = cv2.Sobel(soft, cv2.CV_32F, 1, 0)[edge]  # toward the image's right
    gy = cv2.Sobel(soft, cv2.CV_32F, 0, 1)[edge]  # toward its bottom
    norm = np.maximum(np.hypot(gx, gy), 1e-6)
    rays = None
    if view is not None:
        focal, top, left = view
        rows, cols = np.nonzero(edge)
        rays = ((left + cols + 0.5) / focal, -(top + rows + 0.5) / focal)
    facing = rim_facing(-gx / norm, gy / norm, d, rays)  # outward = −gradient; image up = −rows = +z
    share = fibre_share(a0) if fibres is None else np.broadcast_to(np.asarray(fibres, np.float32), a.shape)
    f = np.clip(share[edge], 0, 1)
    thin = cv2.GaussianBlur(outside, (0, 0), max(0.5, GRAZE_WIDTH * radius), borderType=cv2.BORDER_REFLECT)[edge]
    ae = a[edge]
    band = f * np.minimum(2 * ae * reach[edge], 1) + (1 - f) * np.minimum(2 * ae * thin, 1)
    out[edge] += (facing * band)[:, None] * rgb[None, :]
    return out
