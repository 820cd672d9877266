"""The face's cast shadows: where the nose and the brows hide a face's skin from a light's lamp.

Stage 1's transport is degree-2 SH: it cannot hold a hard shadow that moves with the light. A lamp 25 degrees to one
side of a face throws the nose's shadow onto the cheek and the brow's over the eye; on Extended Yale B those
shadows are most of what the real photo changes (the 8 worst relit pairs, benchmarks/yale_eval.py). The face mesh
(relight_rt.person.face_mesh, 468 points with depth) knows the nose's and the brows' relief, so the skin it covers
is tested for visibility toward the light's lamp: the mesh drawn as a depth map seen from the lamp (``Occluder``),
each skin pixel's point on the mesh looked up in it.

The light's lamp (``lamp``) is read from its SH: the degree-1 band gives its direction and strength, the degree-2
band along that direction its size (a uniform cap of half-angle a has degree-2 / degree-1 zonal ratio
sqrt(5/3) cos a, a point lamp sqrt(5/3)); what a lamp of that direction, strength and size leaves of the light
(ambient, sky, other lamps) casts no shadow here. At each pixel the shadow takes away the lamp's share of the
shading there (the lamp's transported light over the whole light's, in [0, 1]): a soft, even light casts almost
nothing, a skin pixel turned away from the lamp is not darkened twice. A lamp wider than ``CAP_SAMPLED`` is tested
from several directions over its disc (its shadow fades with the distance from what casts it); the border is then
softened by what the samples leave and never sharper than ``MIN_SOFT`` of the face's size (the mesh is a
regression: its nose tip is not exact to a pixel). About 10 ms per light on a face 256 network pixels tall
(benchmarks/cast_shadow_speed.py); the Relighter keeps it per light direction (relight_rt.relight.factor
``Factor.cast``).
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from ..light import sh
from ..person.face_mesh import on_planes, triangle_ids, triangle_planes

MIN_SHARE = 0.15  # a light whose lamp is below this share of its degree-0 band casts no shadow (nothing computed)
MAX_ANGLE = math.radians(60)  # a lamp wider than this (half-angle) casts no shadow here
BIAS = 0.015  # a point is shadowed where the mesh lies this share of the face's size nearer the lamp than it ...
SLOPE_BIAS = 1.5  # ... plus this many pixels times the tangent of its angle to the lamp (the map's steps)
RAMP = 0.02  # ... fully shadowed past that depth plus this share of the face's size
GRAZING = (0.05, 0.15)  # a shadow is trusted from the first to the second cosine of the lamp's angle to the surface
STRIDE_SIZE = 100  # a face at least this large (window pixels) is tested at every other pixel
CAP_SAMPLED = math.radians(4)  # a lamp wider than this (half-angle) is tested from several directions over its disc:
CAP_RING = 4  # ... its centre and this many around it
MIN_SOFT = 0.02  # the shadow's border: blurred over at least this share of the face's size
MAX_COS = 0.25  # lamps within ~75 degrees of the camera's axis only: a lamp from behind lights the mesh's back


def lamp(light: np.ndarray) -> tuple[np.ndarray, np.ndarray, float] | None:
    """The lamp of a light (its directional part), or None when it has none worth a shadow.

    Args:
        light: (9,) one channel's SH (a light's luminance), DESIGN.md §3 order.

    Returns:
        (direction (3,) unit, toward the lamp, subject frame; its SH (9,) float64, a uniform cap of that
        direction whose degree-1 band is the light's; its half-angle in radians).
    """
    c = np.asarray(light, np.float64).reshape(9)
    direction, share = sh.dominant_direction(c)
    if direction is None or share < MIN_SHARE:
        return None
    y = sh.basis(direction)
    z1 = float(np.linalg.norm([c[1], c[2], c[3]]))
    # the degree-2 band's zonal part along the direction: sum_m L2m Y2m(d) / sqrt(5 / 4 pi)
    c2 = math.sqrt(5 / (4 * math.pi))
    z2 = float(c[4:] @ y[4:]) / c2
    ratio = (z2 / z1) / math.sqrt(5 / 3)  # cos a for a cap
    if ratio < math.cos(MAX_ANGLE):
        return None
    cos_a = min(ratio, 1.0)
    # a cap around d has SH Omega g_l Y_k(d) (sh.cap_zonal), scaled so that its degree-1 band is the light's
    g = sh.cap_zonal(cos_a)[list(sh.BAND)]
    cap = g * y * (z1 / (g[1] * math.sqrt(3 / (4 * math.pi))))
    return direction, cap, math.acos(cos_a)


class MeshView:
    """A face mesh as the camera sees it in a window: the point of the mesh at each pixel it covers (made once per
    Decomposition; ``visibility`` tests it against each light's lamp).

    Args:
        points: (N, 3) mesh vertices in the window's pixels (x right, y down, z away from the camera, same units).
        triangles: (T, 3) vertex indices.
        shape: (h, w) of the window.
        where: (h, w) bool, the pixels a shadow may fall on (the face's skin and a margin; None: all); the mesh
            casts its shadow from all of its surface.
    """

    def __init__(self, points: np.ndarray, triangles: np.ndarray, shape: tuple[int, int],
                 where: np.ndarray | None = None) -> None:
        self.points = np.asarray(points, np.float64)
        self.triangles = np.asarray(triangles, np.int64)
        self.shape = shape
        self.size = float(max(np.ptp(self.points[:, :2], axis=0).max(), 1.0))
        p, tri = self.points, self.triangles
        cam = triangle_ids(p[:, :2], -p[:, 2], tri, shape)  # the nearest (least z) drawn last
        # a large face is tested at every other pixel: its shadow's border is blurred over MIN_SOFT of its size
        stride = 2 if self.size >= STRIDE_SIZE else 1
        sampled = np.zeros(shape, bool)
        sampled[::stride, ::stride] = True
        if where is not None:
            sampled &= where
        self.cover = ((cam >= 0) & sampled).astype(np.float32)
        py, px = np.nonzero(self.cover > 0)
        self.ids = cam[py, px]
        self.x, self.y = px.astype(np.float64), py.astype(np.float64)
        self.z = on_planes(triangle_planes(p[:, :2], p[:, 2], tri), self.ids, self.x, self.y)
        v = p[tri]
        n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
        n[n[:, 2] > 0] *= -1  # toward the camera: the side of the surface it sees
        self.normals = n


def _hidden(view: MeshView, toward: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per pixel the mesh covers (``view``'s order): how far it is hidden from a point lamp in direction ``toward``
    (window axes: x right, y down, z away), in [0, 1], and the height of what hides it above it along ``toward``
    (window pixels; -inf where nothing lies above it)."""
    p, size = view.points, view.size
    facing = view.normals @ toward
    cos = np.abs(facing)[view.ids]
    # the lamp's view: an orthographic depth map along ``toward``, one window pixel per map pixel, of the triangles
    # turned to the lamp (a ray from the lamp meets one of those first)
    helper = np.array([0.0, 0.0, 1.0]) if abs(toward[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    u = np.cross(toward, helper)
    u /= np.linalg.norm(u)
    vv = np.cross(toward, u)
    uv = np.stack([p @ u, p @ vv], axis=1)
    lo = uv.min(axis=0) - 2
    uv -= lo
    mh, mw = int(math.ceil(uv[:, 1].max())) + 3, int(math.ceil(uv[:, 0].max())) + 3
    height = p @ toward  # greater: nearer the lamp
    lit = np.flatnonzero(facing > 0)
    lamp_ids = triangle_ids(uv, height, view.triangles[lit], (mh, mw))
    # each skin point's place in the lamp's map (nearest map pixel) and the mesh's height there
    x, y, z = view.x, view.y, view.z
    mx = np.clip(np.round(x * u[0] + y * u[1] + z * u[2] - lo[0]).astype(np.int64), 0, mw - 1)
    my = np.clip(np.round(x * vv[0] + y * vv[1] + z * vv[2] - lo[1]).astype(np.int64), 0, mh - 1)
    seen = lamp_ids[my, mx]
    top = np.full(x.size, -np.inf)
    hit = seen >= 0
    if hit.any():
        top[hit] = on_planes(triangle_planes(uv, height, view.triangles[lit]), seen[hit], mx[hit].astype(np.float64),
                              my[hit].astype(np.float64))
    above = top - (x * toward[0] + y * toward[1] + z * toward[2])
    tangent = np.sqrt(np.maximum(1 - cos * cos, 0)) / np.maximum(cos, 0.2)
    gap = above - (BIAS * size + SLOPE_BIAS * tangent)
    # where the lamp grazes the surface its map is a thin strip whose steps no bias covers
    trust = np.clip((cos - GRAZING[0]) / (GRAZING[1] - GRAZING[0]), 0, 1)
    return np.clip(gap / (RAMP * size), 0, 1) * np.where(facing[view.ids] > 0, trust, 1), above


def _cap_directions(direction: np.ndarray, angle: float) -> np.ndarray:
    """(K, 3) unit directions spread over a cap of half-angle ``angle`` around ``direction``: the centre alone for
    a small lamp, else the centre and ``CAP_RING`` around it at 0.76 ``angle`` (equal shares of the cap's area)."""
    d = np.asarray(direction, np.float64) / np.linalg.norm(direction)
    if angle < CAP_SAMPLED:
        return d[None]
    helper = np.array([0.0, 0.0, 1.0]) if abs(d[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    a = np.cross(d, helper)
    a /= np.linalg.norm(a)
    b = np.cross(d, a)
    r = 0.76 * angle
    phi = 2 * np.pi * (np.arange(CAP_RING) + 0.5) / CAP_RING
    ring = math.cos(r) * d + math.sin(r) * (np.cos(phi)[:, None] * a + np.sin(phi)[:, None] * b)
    return np.concatenate([d[None], ring])


def visibility(view: MeshView, direction: np.ndarray, angle: float) -> np.ndarray:
    """(h, w) float32 in [0, 1]: how much of a lamp each pixel of a face mesh sees past the mesh itself (1 off the
    mesh and where the lamp is seen; the mesh's openings, the eyes and the lips, take it from around).

    A lamp wider than ``CAP_SAMPLED`` is tested from several directions over its disc (``_cap_directions``), the
    share of them hidden kept: a wide lamp's shadow fades with the distance from what casts it. The border is then
    softened by what the samples leave (the occluders' height over the skin times the samples' spacing), never
    less than ``MIN_SOFT`` of the face's size.

    Args:
        view: the mesh as the camera sees it.
        direction: (3,) unit, toward the lamp, subject frame (DESIGN.md §3).
        angle: the lamp's half-angle (radians).
    """
    h, w = view.shape
    vis = np.ones((h, w), np.float32)
    if view.ids.size == 0:
        return vis
    samples = _cap_directions(direction, angle)
    hidden = np.zeros(view.ids.size)
    heights = []
    for d in samples:  # toward the lamp in the window's axes (x right, y down, z away)
        part, above = _hidden(view, np.array([d[1], -d[2], -d[0]], np.float64))
        hidden += part / len(samples)
        heights.append(above[part > 0.5])
    vis[view.y.astype(np.int64), view.x.astype(np.int64)] = 1 - hidden
    # the penumbra the samples leave: the occluders' height over the skin they shadow times the samples' spacing
    above = np.concatenate(heights)
    height_over = float(np.median(above)) if above.size else 0.0
    spread = angle if len(samples) == 1 else angle / math.sqrt(len(samples))
    sigma = max(MIN_SOFT * view.size, 0.5 * height_over * math.tan(min(spread, MAX_ANGLE)))
    # soften over the mesh only (its openings filled from around), a normalised blur
    cover = view.cover
    num = cv2.GaussianBlur(vis * cover, (0, 0), sigma)
    den = cv2.GaussianBlur(cover, (0, 0), sigma)
    return np.where(den > 1e-3, num / np.maximum(den, 1e-3), 1.0).astype(np.float32)


def shadow_factor(transport: np.ndarray, light_lum: np.ndarray, views: tuple[MeshView, ...],
                  weight: np.ndarray) -> np.ndarray | None:
    """(h, w) float32 in (0, 1]: what the lamp's cast shadows leave of the shading under a light, or None (no lamp
    worth a shadow, one from beside or behind, no mesh).

    Args:
        transport: (h, w, 9) the window's transport (unpremultiplied), the one the shading is made with.
        light_lum: (9,) the light's luminance SH.
        views: the faces' meshes as the camera sees them in the window.
        weight: (h, w) float32 in [0, 1]: where the shadow applies (a face's skin, its edge soft).
    """
    found = lamp(light_lum)
    if found is None or not views:
        return None
    direction, cap, angle = found
    if direction[0] < MAX_COS:  # from behind or beside: the mesh's open back would cast nonsense
        return None
    hidden = np.zeros(weight.shape, np.float32)
    for view in views:
        hidden = np.maximum(hidden, 1 - visibility(view, direction, angle))
    total = transport @ np.asarray(light_lum, np.float32)
    from_lamp = transport @ cap.astype(np.float32)
    share = np.clip(from_lamp / np.maximum(total, 1e-4), 0, 1)
    return (1 - weight * hidden * share).astype(np.float32)
