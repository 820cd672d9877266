"""The face's shape for the relighting factor: normals from a face mesh, where stage 1's transport is a blur.

Stage 1 regresses the transport of the whole person from one 256-px square; on a face its normals are a smooth
blob (the nose, the eye sockets, the cheekbones' turn are not in it), so a new light changes a face far less, and
less precisely, than a relighter trained on faces (DPR). A face has a known shape: MediaPipe's face landmarker
(``face_mesh.onnx``, Apache-2.0, ``python -m export face-mesh``) gives 468 3D points of a dense mesh for a face
found by the bundled face detector (``matte_face.onnx``), and the mesh's triangles
(``face_mesh_triangles.txt``) give its normals.

The normals are drawn into the network frame (flat per triangle, nearest last, the mesh's openings at the eyes
and the lips closed with the normals around them, then smoothed over about a nose's half-width), turned into
transport with DESIGN.md §3's unoccluded cosine lobe, and scaled by stage 1's own degree-0 coefficient (so the
network's visibility, hence exposure, is kept). The Relighter blends that transport into
stage 1's over the face, feathered at the mesh's border (relight_rt.relight.relighter ``_own``); both sides of the
relighting factor use the result, so the photo's own light still gives the photo back. Around the mesh (hair,
skull, ears) an ellipsoid head fitted to the mesh's extent lends its normals, at HEAD_STRENGTH: without it a side
light darkened half a close face in a patch bounded by the mesh while the hair beside it, left to stage 1's blur,
stayed lit (docs/RESULTS.md, "A head around the face mesh").

Optional: without the three files in the models folder nothing changes. Upright faces only (the landmarker's crop
is not rotated): a face tilted far from upright gives a poor mesh, which the landmarker's face flag rejects.
"""

from __future__ import annotations

import functools
import logging
import math
import numbers
from pathlib import Path

import cv2
import numpy as np

from ..engine.errors import RelightError
from ..image.regions import Region, crop_region
from ..light import sh
from .face_detector import FACE_SIZE, decode, weighted_nms

log = logging.getLogger(__name__)

MESH_FILE = "face_mesh.onnx"
TRIANGLES_FILE = "face_mesh_triangles.txt"
DETECTOR_FILE = "matte_face.onnx"
MESH_SIZE = 192  # the landmarker's input side
N_POINTS = 468
ROI_SCALE = 1.5  # the landmarker's square: this many face-box sides around the detected face (MediaPipe's)
MIN_FACE_NET = 24  # a face smaller than this in network pixels is left to stage 1 (and the head pass)
MIN_FLAG = 0.5  # the landmarker's face probability needed to trust its mesh
MESH_REACH = 3.0  # ... and its mesh at most this many of its crop's sides across on every axis, all finite (a face
# spans 0.60-0.77 of it: 185 meshes on Yale and people photos; one blown up 1000x had the cast shadow's lamp map ask
# for 309 GB, one Inf point failed in OpenCV: fuzz8)
CLOSE_UP_SCALE = 2.0  # no face in the box's square: look again at a square this many times as large (FaceMesh.faces)
# the detector and landmarker shown their crop and its mirror image, the answers averaged (``FaceMesh.boxes``,
# ``FaceMesh.landmarks``; the mirror's landmarks re-indexed by ``MIRROR_FILE``). Without it, on Extended Yale B's
# close-ups the graphs read a face as turned 2.8 deg (median) the same way on a photo and on its mirror image (face31,
# benchmarks/mesh_mirror.py). Alone it failed face31's criterion (Yale's odd de-light relerr 0.4069 -> 0.4186:
# stage 1's own lean had been partly offset by the mesh's), and with stage 1's mirror averaging alone mirror31's; on
# since mirror34 with all four parts of the mirror-symmetric chain (relight_rt.relight.network ``STAGE1_MIRROR``,
# ``STAGE2_MIRROR``, relight_rt.image.crop ``SYMMETRIC_CROP``), c751cea's criterion met (docs/RESULTS.md: "Shipped:
# the mirror-symmetric chain").
# ``benchmarks/mesh_flip.py`` runs any benchmark with either on or off.
MESH_FLIP = True
MIRROR_FILE = Path(__file__).resolve().parents[1] / "data" / "face_mesh_mirror.txt"  # landmark i's partner on
# the face's other half (the mid-line's its own): nearest mirrored landmark on the mean of 24 frontal meshes
# (benchmarks/mesh_mirror.py --build-map)
SMOOTH = 0.055  # normals smoothed over this fraction of the face's size (0.04: a hard nose edge, a dark blob)
HOLE_SPREAD = 0.05  # the eyes' and mouth's normals: spread in from this fraction of the face's size around
FEATHER = 0.25  # the face transport fades in over this fraction of the face's size inside the mesh's border
# (0.12 drew the mesh's outline as a line: docs/RESULTS.md, "Face mesh artefacts")
HEAD_WIDTH = 1.1  # the head's ellipse: this many mesh widths across (the mesh stops short of the ears)
HEAD_TOP = 0.35  # ... and reaching this fraction of the mesh's height above its top (the skull under the hair)
HEAD_REACH = 1.35  # the head's normals fade out between the ellipse and this many times its size
SKIN_INSET = 0.12  # face_transport's skin: the mesh's pixels at least this share of the face's size inside its border
HEAD_STRENGTH = 0.4  # how far they replace stage 1's transport there (0.7 looks best, but DPR agreement 0.79)
# the mesh's own occlusion (``occlusion_loss``): a recess (under the brow, beside the nose) gets less light than its
# normals say. On Extended Yale B it raised the relight contrast 0.734 -> 0.760 (25 deg pairs 0.705 -> 0.731: the
# nose's shaded side darker, as in the real photos) and the lit eye socket's error 0.371 -> 0.344; the de-lit dark
# socket stays as bright (0.442 -> 0.450: a frontal lamp sees what the camera sees; its error is stage 1's albedo)
# (faces12; ``benchmarks/yale_eval.py``, ``--no-mesh-occlusion`` for the figures without it)
MESH_OCCLUSION = True
# set by geometry, not fitted to any photo:
OCCLUSION_REACH = 0.25  # occluders looked for within this fraction of the face's size (the brow over the eye)
OCCLUSION_AZIMUTHS = 16  # directions in the image plane along which the depth map's horizon is found
OCCLUSION_STEPS = 8  # ... sampled at this many distances each
OCCLUSION_DIRECTIONS = 128  # directions of the sphere the transport is summed over
OCCLUSION_SOFT = math.radians(10)  # a direction fades from seen to hidden over this angle below the horizon
OCCLUSION_SMOOTH = SMOOTH  # the loss smoothed over this fraction of the face's size, as the normals are
OCCLUSION_GRID = 96  # ... so it is found on a grid where the face is at most this many pixels (4x faster at 200)
# ``mirror_held``: a value is held to its mirror image's only where the photo is in shadow against its mirror image:
# its luminance over the mirror's, from the second share down to the first, from none of the lift to all of it
# (shadow_fill.MIRROR_DARK's shares, not fitted again; a face lit from the front keeps its own), that luminance smoothed
# over this many pixels first (texture is no shadow)
MIRROR_SHADOW = (0.35, 0.7)
MIRROR_SHADOW_SIGMA = 1.5
# ... and only as far as the value is at least this share of its mirror image's, from none of the lift to all of it:
# stage 1 takes part of a shadow for a dark albedo (Extended Yale B's lifted pixels: median 0.84 of the mirror's,
# 2 % under 0.4), while a far darker one is another material over one half (a fringe of hair over a brow, an iris
# looking sideways onto the other eye's white, a mole), not the same skin (faces23r: a fringe lifted by 40 levels)
MIRROR_OWN_SHARE = (0.3, 0.5)
# ... and only as far as the mirror lands on the face: where it misses the cheeks' landmark pairs (left out of its fit)
# by more than the first share of the face's size, less, to none past the second (faces23r, the mirror then fitted to
# the eyes' contours: a head turned 30-45 degrees 0.18-0.30, Extended Yale B's faces at most 0.047; fitted to the whole
# symmetry map since mesh37: Yale's frontal and +-25 deg faces at most 0.018, the first look's 25 faces median 0.020,
# max 0.165; benchmarks/mirror_fit.py)
MIRROR_CHEEK_PAIRS = ((50, 280), (205, 425), (187, 411))
MIRROR_MISS = (0.1, 0.2)
_FIT_POINTS = np.setdiff1d(np.arange(N_POINTS), np.array(MIRROR_CHEEK_PAIRS).ravel())  # ``mirror``'s fit

def lobe_transport(normals: np.ndarray) -> np.ndarray:
    """(..., 9) float32 unoccluded transport A_l * Y_k(n) of unit normals (..., 3) in the subject frame (§3)."""
    return (sh.basis(np.asarray(normals, np.float32)) * _LOBE).astype(np.float32)


_LOBE = sh.cosine_lobe().astype(np.float32)
_T0 = float(_LOBE[0] * sh.basis(np.array([0.0, 0.0, 1.0]))[0])  # degree 0 of any unit normal: π · Y00


def rasterise_normals(
    points: np.ndarray, triangles: np.ndarray, shape: tuple[int, int]
) -> tuple[np.ndarray, np.ndarray]:
    """Normals and coverage of a triangle mesh seen from the camera, in the subject frame (DESIGN.md §3).

    Args:
        points: (N, 3) vertices in pixels of the target image: x right, y down, z away from the camera (the same
            units as x, y).
        triangles: (T, 3) vertex indices.
        shape: (h, w) of the target image.

    Returns:
        normals (h, w, 3) float32, unit length where covered, zero elsewhere: each triangle's normal turned toward
        the camera (a triangle the camera sees faces it), the nearest triangle drawn last; coverage (h, w) float32
        in {0, 1}.
    """
    h, w = shape
    p = np.asarray(points, np.float64)
    tri = np.asarray(triangles, np.int64)
    v = p[tri]  # (T, 3, 3)
    n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    n[n[:, 2] > 0] *= -1  # toward the camera (negative z)
    length = np.linalg.norm(n, axis=1)
    keep = length > 1e-9
    n = n[keep] / length[keep, None]
    v = v[keep]
    # image axes (x right, y down, z away) -> subject frame (+x toward the camera, +y image right, +z up)
    subj = np.stack([-n[:, 2], n[:, 0], -n[:, 1]], axis=1).astype(np.float32)
    order = np.argsort(-v[:, :, 2].mean(axis=1))  # far first: the nearest triangle is drawn last
    normals = np.zeros((h, w, 3), np.float32)
    cover = np.zeros((h, w), np.float32)
    shift = 4
    corners = np.round(v[:, :, :2] * (1 << shift)).astype(np.int32)
    for i in order:
        c = corners[i]
        cv2.fillConvexPoly(normals, c, subj[i].tolist(), lineType=cv2.LINE_8, shift=shift)
        cv2.fillConvexPoly(cover, c, 1.0, lineType=cv2.LINE_8, shift=shift)
    return normals, cover


def face_transport(
    points: np.ndarray, triangles: np.ndarray, t0: np.ndarray, occlusion: bool | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The face's transport, its blending weight, its skin and its openings in a network-frame window.

    Args:
        points: (468, 3) mesh vertices in the window's pixels (x right, y down, z away, same units).
        triangles: (T, 3) the mesh's triangles.
        t0: (h, w) stage 1's degree-0 transport coefficient there (unpremultiplied): the visibility kept.
        occlusion: take out the light the mesh's own relief hides (``occlusion_loss``: the brow and the nose over
            an eye's socket), where the mesh is; None: ``MESH_OCCLUSION``.

    Returns:
        transport (h, w, 9) float32, weight (h, w) float32 in [0, 1] (0 off the face), and skin (h, w) bool:
        the face's skin well inside its mesh (``SKIN_INSET`` of its size from the border) without the mesh's
        openings (eyes, an open mouth), where a light fit can take the skin as one colour
        (relight_rt.relight.strength ``face_refit``), and openings (h, w) bool: the face inside its outline (the mesh
        with its enclosed openings closed: a hole that reaches the window's border stays open) by as much as the skin
        is, off that skin: the eyes' sockets and an open mouth, not
        the outline's ring (hair, the jaw's edge).
    """
    h, w = t0.shape
    normals, cover = rasterise_normals(points, triangles, (h, w))
    span = np.ptp(points[:, :2], axis=0)
    size = float(max(span.max(), 1.0))
    skin = cv2.distanceTransform((cover > 0).astype(np.uint8), cv2.DIST_L2, 3) > SKIN_INSET * size
    normals, cover = _fill_holes(normals, cover, size)
    sigma = max(SMOOTH * size, 0.5)
    normals = cv2.GaussianBlur(normals, (0, 0), sigma)
    normals = normals / np.maximum(np.linalg.norm(normals, axis=2, keepdims=True), 1e-6)
    # weight: inside the mesh, rising smoothly from 0 at its border to 1 at FEATHER of the face's size inside
    dist = cv2.distanceTransform((cover > 0).astype(np.uint8), cv2.DIST_L2, 3)
    mesh_weight = _smooth_step(dist / max(FEATHER * size, 1.0))
    # around the mesh (hair, skull, ears) the head's rounded shape: without it a side light darkens half the face
    # while the hair beside it, left to stage 1's blur, stays lit
    head, head_weight = head_normals(points, (h, w))
    m = mesh_weight[..., None]
    # the light the mesh's relief hides, found with the mesh's own normals (the head's, blended in toward the
    # border, do not lie on its depth map: they would take the mesh's own slope for an occluder) and faded as they are
    hidden = 0
    if MESH_OCCLUSION if occlusion is None else occlusion:
        hidden = m * _mesh_occlusion(points, triangles, normals, size)
    normals = m * normals + (1 - m) * head
    normals = normals / np.maximum(np.linalg.norm(normals, axis=2, keepdims=True), 1e-6)
    transport = lobe_transport(normals) - hidden
    transport = transport * (np.maximum(t0, 0) / _T0)[..., None]
    weight = mesh_weight + (1 - mesh_weight) * HEAD_STRENGTH * head_weight
    openings = (dist > SKIN_INSET * size) & ~skin
    return transport, np.clip(weight, 0, 1).astype(np.float32), skin, openings


def triangle_ids(xy: np.ndarray, depth: np.ndarray, triangles: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """(h, w) int32: the index of the triangle seen at each pixel (-1: none), the one of greatest ``depth`` (mean
    over its corners) drawn last. ``xy`` (N, 2) vertices in the image's pixels (centres at integers)."""
    h, w = shape
    ids = np.full((h, w), -1, np.int32)
    order = np.argsort(depth[triangles].mean(axis=1))
    shift = 4
    corners = np.round(xy[triangles] * (1 << shift)).astype(np.int32)
    for i in order:
        cv2.fillConvexPoly(ids, corners[i], int(i), lineType=cv2.LINE_8, shift=shift)
    return ids


def triangle_planes(xy: np.ndarray, values: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(T, 3) per triangle the plane (a, b, c) with value = a x + b y + c through its corners' ``values`` (N,) at
    ``xy`` (N, 2); a triangle seen edge-on (no area) takes its corners' mean."""
    a, b, c = (xy[triangles[:, i]] for i in range(3))
    va, vb, vc = (values[triangles[:, i]] for i in range(3))
    e1, e2 = b - a, c - a
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    ok = np.abs(det) > 1e-9
    safe = np.where(ok, det, 1.0)
    d1, d2 = vb - va, vc - va
    ga = np.where(ok, (d1 * e2[:, 1] - d2 * e1[:, 1]) / safe, 0.0)
    gb = np.where(ok, (d2 * e1[:, 0] - d1 * e2[:, 0]) / safe, 0.0)
    gc = np.where(ok, va - ga * a[:, 0] - gb * a[:, 1], (va + vb + vc) / 3)
    return np.stack([ga, gb, gc], axis=1)


def on_planes(planes: np.ndarray, ids: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The value of each point (x, y) on the plane of its triangle ``ids`` (``triangle_planes``)."""
    q = planes[ids]
    return q[:, 0] * x + q[:, 1] * y + q[:, 2]


def rasterise_depth(
    points: np.ndarray, triangles: np.ndarray, shape: tuple[int, int]
) -> tuple[np.ndarray, np.ndarray]:
    """The depth of a triangle mesh seen from the camera, its openings closed.

    Args:
        points: (N, 3) vertices in pixels (x right, y down, z away from the camera, same units).
        triangles: (T, 3) vertex indices.
        shape: (h, w) of the target image.

    Returns:
        depth (h, w) float32, z (away from the camera) of the nearest triangle's plane at each pixel centre, the
        mesh's openings (eyes, an open mouth: ``_fill_holes``) given the depth around them, +inf off the mesh; and
        seen (h, w) bool, where the depth is finite.
    """
    h, w = shape
    p = np.asarray(points, np.float64)
    tri = np.asarray(triangles, np.int64)
    e1, e2 = p[tri[:, 1], :2] - p[tri[:, 0], :2], p[tri[:, 2], :2] - p[tri[:, 0], :2]
    tri = tri[np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]) > 1e-9]  # a triangle seen edge-on covers nothing
    ids = triangle_ids(p[:, :2], -p[:, 2], tri, (h, w))  # the nearest (least z) drawn last
    covered = ids >= 0
    yy, xx = np.nonzero(covered)
    depth = np.full((h, w), np.inf, np.float32)
    depth[covered] = on_planes(triangle_planes(p[:, :2], p[:, 2], tri), ids[covered], xx, yy)
    holes = _holes(covered)
    if holes.any():  # the eyes' and the mouth's surface: the depth around them spread in
        sigma = max(HOLE_SPREAD * float(np.ptp(p[:, :2], axis=0).max()), 0.5)
        near = np.where(covered, depth, 0).astype(np.float32)
        spread = cv2.GaussianBlur(near, (0, 0), sigma)
        share = cv2.GaussianBlur(covered.astype(np.float32), (0, 0), sigma)
        depth = np.where(holes, spread / np.maximum(share, 1e-6), depth).astype(np.float32)
    return depth, covered | holes


def occlusion_loss(depth: np.ndarray, seen: np.ndarray, normals: np.ndarray, size: float) -> np.ndarray:
    """The transport a surface's own relief hides: subtract it from the unoccluded lobe (``lobe_transport``).

    Screen-space horizons: along ``OCCLUSION_AZIMUTHS`` directions of the image plane, the steepest rise of the
    depth map toward the camera within ``OCCLUSION_REACH`` of the face's size; a direction of the sphere is hidden
    where it leaves the surface below its azimuth's horizon (fully ``OCCLUSION_SOFT`` below it). The loss is the
    sum over ``OCCLUSION_DIRECTIONS`` of the hidden directions' clamped cosine times the SH basis (DESIGN.md §3's
    transport, with the visibility the unoccluded lobe leaves out). A plane hides nothing of its front (its own
    horizon is its tangent, and the directions below that are behind its normal); a socket under a brow loses part
    of its light from above and the side. Directions away from the camera are never taken as hidden (the depth map
    cannot see behind the face).

    Args:
        depth: (h, w) z away from the camera in pixels, +inf where nothing is (``rasterise_depth``).
        seen: (h, w) bool, where the loss is wanted (finite depth).
        normals: (h, w, 3) unit normals in the subject frame (+x toward the camera, +y image right, +z up).
        size: the face's size in pixels (the reach's unit).

    Returns:
        (h, w, 9) float32, zero where not ``seen``.
    """
    h, w = depth.shape
    out = np.zeros((h, w, 9), np.float32)
    reach = OCCLUSION_REACH * size
    if not seen.any() or reach < 1:
        return out
    # only the face's box, the horizons' reach and the final blur's: the depth beyond it is never read
    m = max(int(math.ceil(4 * max(OCCLUSION_SMOOTH * size, 0.5))), int(math.ceil(reach))) + 2
    rows, cols = np.nonzero(seen.any(axis=1))[0], np.nonzero(seen.any(axis=0))[0]
    y0, y1 = max(int(rows[0]) - m, 0), min(int(rows[-1]) + 1 + m, h)
    x0, x1 = max(int(cols[0]) - m, 0), min(int(cols[-1]) + 1 + m, w)
    out[y0:y1, x0:x1] = _window_loss(depth[y0:y1, x0:x1], seen[y0:y1, x0:x1], normals[y0:y1, x0:x1], size, reach)
    return out


def _window_loss(depth: np.ndarray, seen: np.ndarray, normals: np.ndarray, size: float, reach: float) -> np.ndarray:
    """``occlusion_loss`` on a box holding all of ``seen``."""
    h, w = depth.shape
    out = np.zeros((h, w, 9), np.float32)
    pad = int(math.ceil(reach)) + 1
    padded = np.pad(depth.astype(np.float32), pad, constant_values=np.inf)
    z = np.where(seen, depth, 0).astype(np.float32)
    n_az = OCCLUSION_AZIMUTHS
    horizon = np.full((n_az, h, w), -np.inf, np.float32)  # tan of the horizon's angle above the image plane
    for k in range(n_az):
        angle = 2 * math.pi * k / n_az
        for j in range(1, OCCLUSION_STEPS + 1):
            r = reach * j / OCCLUSION_STEPS
            dx, dy = int(round(r * math.cos(angle))), int(round(r * math.sin(angle)))
            if dx == 0 and dy == 0:
                continue
            far = padded[pad + dy:pad + dy + h, pad + dx:pad + dx + w]
            np.maximum(horizon[k], (z - far) * np.float32(1 / math.hypot(dx, dy)), out=horizon[k])
    rows, cols = np.nonzero(seen)
    above = np.arctan(horizon[:, rows, cols])  # (K, P): each azimuth's horizon angle, -pi/2 where nothing rises
    dirs = sh.sphere_directions(OCCLUSION_DIRECTIONS)
    dirs = dirs[dirs[:, 0] > 0]  # toward the camera: the depth map says nothing of those away from it
    rise = np.arctan2(dirs[:, 0], np.hypot(dirs[:, 1], dirs[:, 2])).astype(np.float32)  # above the image plane
    az = np.round(np.arctan2(-dirs[:, 2], dirs[:, 1]) / (2 * math.pi / n_az)).astype(int) % n_az  # x right, y down
    hidden = above[az]  # (D, P): (horizon - rise) / soft, in [0, 1]
    hidden -= rise[:, None]
    hidden *= np.float32(1 / OCCLUSION_SOFT)
    np.clip(hidden, 0, 1, out=hidden)
    hidden *= np.maximum(dirs.astype(np.float32) @ normals[rows, cols].T, 0)  # times the clamped cosine
    weights = (4 * math.pi / OCCLUSION_DIRECTIONS) * sh.basis(dirs).astype(np.float32)  # (D, 9)
    out[rows, cols] = hidden.T @ weights
    # as smooth as the normals it is taken from (face_transport's SMOOTH): the flat triangles' steps are no relief
    sigma = max(OCCLUSION_SMOOTH * size, 0.5)
    share = cv2.GaussianBlur(seen.astype(np.float32), (0, 0), sigma)
    out = cv2.GaussianBlur(out, (0, 0), sigma) / np.maximum(share, 1e-6)[..., None]
    return np.where(seen[..., None], out, 0).astype(np.float32)


def _mesh_occlusion(points: np.ndarray, triangles: np.ndarray, normals: np.ndarray, size: float) -> np.ndarray:
    """``occlusion_loss`` of a mesh (window pixels) for ``normals`` (h, w, 3), found where the face is at most
    ``OCCLUSION_GRID`` pixels across (the loss is smoothed over more than a pixel there) and resized back."""
    h, w = normals.shape[:2]
    k = min(1.0, OCCLUSION_GRID / max(size, 1.0))
    if k == 1.0:
        depth, seen = rasterise_depth(points, triangles, (h, w))
        return occlusion_loss(depth, seen, normals, size)
    small = (max(1, round(h * k)), max(1, round(w * k)))
    ky, kx = small[0] / h, small[1] / w
    p = np.asarray(points, np.float64).copy()  # pixel centres as cv2.resize maps them: (x + 0.5) k - 0.5
    p[:, 0] = (p[:, 0] + 0.5) * kx - 0.5
    p[:, 1] = (p[:, 1] + 0.5) * ky - 0.5
    p[:, 2] *= (kx + ky) / 2
    depth, seen = rasterise_depth(p, triangles, small)
    n = cv2.resize(normals, small[::-1], interpolation=cv2.INTER_AREA)
    n /= np.maximum(np.linalg.norm(n, axis=2, keepdims=True), 1e-6)
    loss = occlusion_loss(depth, seen, n, size * (kx + ky) / 2)
    return cv2.resize(loss, (w, h), interpolation=cv2.INTER_LINEAR)


def mirror(points: np.ndarray) -> np.ndarray | None:
    """The face's mirror in the image plane: a (2, 3) affine map taking a pixel (x, y, 1) to where the same place of
    the face's other half lies, fitted by least squares to every landmark of ``points`` ((468, >= 2) pixels) mapped
    onto its partner (``MIRROR_FILE``: the mid-line's onto themselves), the cheeks' ``MIRROR_CHEEK_PAIRS`` left out
    (``mirror_held`` checks the fit on them). An affine map, not a plane's reflection: a face turned a little is
    foreshortened unequally, which the fit's shear and scale take up. None where there is no symmetry map (the file
    absent or broken: logged once) or ``points`` is not the landmarker's mesh.
    """
    partner = _fit_partners()
    p = np.asarray(points, np.float64)
    if partner is None or p.ndim != 2 or len(p) != N_POINTS or p.shape[1] < 2:
        return None
    src = p[_FIT_POINTS, :2]
    design = np.concatenate([src, np.ones((len(src), 1))], axis=1)
    fit, *_ = np.linalg.lstsq(design, p[partner[_FIT_POINTS], :2], rcond=None)
    return fit.T.astype(np.float32)


def reflection(points: np.ndarray) -> np.ndarray | None:
    """``mirror(points)`` where it is a reflection (its linear part's determinant below -0.5), else None: no
    symmetry map, or a mesh collapsed to a line or a point, has no other half to read."""
    m = mirror(points)
    return m if m is not None and np.linalg.det(m[:, :2]) < -0.5 else None


@functools.cache
def _fit_partners() -> np.ndarray | None:
    """``read_partners()`` once, read-only (``mirror`` is called per face and per decomposition)."""
    partner = read_partners()
    if partner is not None:
        partner.setflags(write=False)
    return partner


def mirror_held(values: np.ndarray, points: np.ndarray, weight: np.ndarray | None = None,
                photo: np.ndarray | None = None) -> np.ndarray:
    """(h, w) float32: ``values`` (h, w) held to at least their mirror image's through the face (``mirror``), where
    that image lands in the window; as they are where it does not, or where ``mirror`` gives none (no symmetry map, a
    mesh of other than the landmarker's ``N_POINTS``, or one collapsed to a line).

    Args:
        values: (h, w) float, the map to hold (relight_rt.relight.factor ``MIRROR_ALBEDO``: the albedo luminance).
        points: (468, >= 2) the face mesh in the window's pixels.
        weight: (h, w) in [0, 1], how far a pixel is the face's skin: held only as far as both the pixel and its mirror
            image are, and both inside this face's mesh (its convex hull: another face beside it is not its mirror, the
            hair beside a turned face not the cheek's); None: everywhere.
        photo: (h, w) the photo's luminance there: held only as far as the pixel is in shadow against its mirror
            image (``MIRROR_SHADOW``); None: everywhere.

    A face's skin is one material on both halves. In a side-lit photo stage 1 takes part of a hard shadow for a dark
    albedo, on the shaded half only (the nose's cast shadow on the far cheek from +50 degrees on Extended Yale B:
    0.72-0.78 of the lit skin's), and a new light on it keeps the shadow (benchmarks/nose_triangle.py); the photo's lit
    mirror image shows the skin's own. Only a lift: a pixel brighter than its mirror keeps its value; one far darker
    than its mirror (under ``MIRROR_OWN_SHARE`` of it: hair, an iris, a mole) is another material and keeps it too, and
    a face whose mirror misses its cheeks (``MIRROR_MISS``: a turned head) is held less, or not at all.
    """
    v = np.ascontiguousarray(values, np.float32)
    m = reflection(points)
    if m is None:
        return v.copy()
    p = np.asarray(points, np.float64)[:, :2]
    a, b = np.array(MIRROR_CHEEK_PAIRS).T
    size = max(float(np.ptp(p, axis=0).max()), 1e-6)
    miss = max(float(np.linalg.norm(p[a] @ m[:, :2].T + m[:, 2] - p[b], axis=1).max()),
               float(np.linalg.norm(p[b] @ m[:, :2].T + m[:, 2] - p[a], axis=1).max())) / size
    landed = _smooth_step((MIRROR_MISS[1] - miss) / (MIRROR_MISS[1] - MIRROR_MISS[0]))
    if not landed > 0:  # a turned head: the mirror lands beside the other half's place
        return v.copy()
    h, w = v.shape
    flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    there = cv2.warpAffine(v, m.astype(np.float64), (w, h), flags=flags, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    lo, hi = MIRROR_OWN_SHARE  # far darker than its mirror: another material, not the same skin in a shadow
    lift = np.maximum(there - v, 0) * landed * _smooth_step((v / np.maximum(there, 1e-4) - lo) / (hi - lo))
    if photo is not None:  # only where the photo's own shadow can have lowered it: darker than its mirror image
        lo, hi = MIRROR_SHADOW
        y = cv2.GaussianBlur(np.ascontiguousarray(photo, np.float32), (0, 0), MIRROR_SHADOW_SIGMA)
        y_there = cv2.warpAffine(y, m.astype(np.float64), (w, h), flags=flags, borderMode=cv2.BORDER_CONSTANT,
                                 borderValue=0)
        lift *= np.where(y_there > 1e-3, _smooth_step((hi - y / np.maximum(y_there, 1e-4)) / (hi - lo)), 0)
    if weight is not None:
        hull = np.zeros((h, w), np.uint8)
        corners = cv2.convexHull(np.ascontiguousarray(np.asarray(points)[:, :2], np.float32))
        cv2.fillConvexPoly(hull, np.round(corners * 16).astype(np.int32), 1, shift=4)
        k = np.ascontiguousarray(weight, np.float32) * hull
        lift *= k * cv2.warpAffine(k, m.astype(np.float64), (w, h), flags=flags, borderMode=cv2.BORDER_CONSTANT,
                                   borderValue=0)
    return (v + lift).astype(np.float32)


def _smooth_step(x):
    """3 x^2 - 2 x^3 of ``x`` clipped to [0, 1] (array or float)."""
    q = np.clip(x, 0, 1)
    return q * q * (3 - 2 * q)


def _holes(covered: np.ndarray) -> np.ndarray:
    """(h, w) bool: the pixels neither covered nor reached from the window's border (a mesh's openings)."""
    outside = np.pad(covered.astype(np.uint8), 1)  # a free ring round the window
    cv2.floodFill(outside, None, (0, 0), 2)
    return outside[1:-1, 1:-1] == 0


def _fill_holes(normals: np.ndarray, cover: np.ndarray, size: float) -> tuple[np.ndarray, np.ndarray]:
    """The mesh with its openings (the eyes, an open mouth) closed: covered, with normals spread in from around.

    The landmarker's mesh leaves the eyes and the lips' gap uncovered; the eyes and the mouth are part of the
    face's surface, so they take the surrounding normals (a normalised blur over HOLE_SPREAD of the face's size)
    instead of the fade to the head and stage 1 that an opening would otherwise cut into the face (a mask's eye
    holes: docs/RESULTS.md, "Face mesh artefacts").
    """
    covered = (cover > 0).astype(np.uint8)
    holes = _holes(covered > 0)
    if not holes.any() or HOLE_SPREAD <= 0:
        return normals, cover
    sigma = max(HOLE_SPREAD * size, 0.5)
    spread = cv2.GaussianBlur(normals * covered[..., None], (0, 0), sigma)
    weight = cv2.GaussianBlur(covered.astype(np.float32), (0, 0), sigma)
    fill = spread / np.maximum(weight, 1e-6)[..., None]
    fill /= np.maximum(np.linalg.norm(fill, axis=2, keepdims=True), 1e-6)
    normals = np.where(holes[..., None], fill, normals).astype(np.float32)
    return normals, np.maximum(cover, holes.astype(np.float32))


def head_normals(points: np.ndarray, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Normals of an ellipsoid head around a face mesh, in the subject frame, and where to trust them.

    The ellipse spans the mesh's width (times HEAD_WIDTH) and runs from the chin to HEAD_TOP of the mesh's height
    above its top (the skull above the landmarks); inside it the normal is the ellipsoid's, beyond it the
    outline's (horizontal, pointing away). The weight is 1 inside, falls to 0 at HEAD_REACH times the ellipse and
    below the chin (the neck is not the head's surface).

    Returns:
        normals (h, w, 3) float32 unit, weight (h, w) float32 in [0, 1].
    """
    h, w = shape
    p = np.asarray(points, np.float64)
    (x0, y0), (x1, y1) = p[:, :2].min(0), p[:, :2].max(0)
    cx, a = (x0 + x1) / 2, max((x1 - x0) / 2 * HEAD_WIDTH, 1.0)
    top = y0 - HEAD_TOP * (y1 - y0)
    cy, b = (top + y1) / 2, max((y1 - top) / 2, 1.0)
    yy, xx = np.ogrid[0:h, 0:w]
    u, v = (xx - cx) / a, (yy - cy) / b  # (1, w) and (h, 1)
    r = np.sqrt(u * u + v * v)
    scale = 1.0 / np.maximum(r, 1.0)  # beyond the ellipse: onto its outline
    u, v = u * scale, v * scale
    toward = np.sqrt(np.maximum(1 - u * u - v * v, 0))  # u² + v² + toward² = 1: unit already
    normals = np.stack([toward, u, -v], axis=2).astype(np.float32)  # +x toward the camera, +y right, +z up
    t = np.clip((HEAD_REACH - r) / (HEAD_REACH - 1), 0, 1)
    below = np.clip((yy - y1) / max(0.08 * (y1 - y0), 1.0), 0, 1)  # fades out over the chin's last rows
    return normals, _smooth_step(t * (1 - below)).astype(np.float32)


def read_partners(path: Path = MIRROR_FILE) -> np.ndarray | None:
    """``MIRROR_FILE``: (468,) int64, landmark i's partner on the face's other half (an involution; the mid-line's
    landmarks their own); None, logged, where the file is absent or no such map (the meshes are then not
    averaged with their mirror's)."""
    try:
        partner = np.loadtxt(path, dtype=np.int64, ndmin=1)
    except (OSError, ValueError) as exc:
        log.warning("%s: no face mesh symmetry (%s); meshes not averaged with their mirror's", path, exc)
        return None
    if partner.shape != (N_POINTS,) or partner.min() < 0 or partner.max() >= N_POINTS or \
            (partner[partner] != np.arange(N_POINTS)).any():
        log.warning("%s: expected %d partner indices, each its partner's partner; meshes not averaged", path, N_POINTS)
        return None
    return partner


def _lifted(crop: np.ndarray, power: float) -> np.ndarray:
    """``crop`` (values in [0, 1]) raised to ``power`` as float32, a new array; ``crop`` itself for 1."""
    return crop if power == 1 else np.power(np.clip(crop, 0, 1), np.float32(power), dtype=np.float32)


def _check_finite(crop: np.ndarray) -> None:
    """RelightError where a crop the graphs are shown holds NaN or Inf (the graphs' output would be blamed)."""
    if not np.isfinite(crop).all():
        raise RelightError("face search: the image holds NaN or Inf values")


class FaceMesh:
    """The face detector and landmarker of a models folder, or nothing (``available`` False) without them."""

    def __init__(self, folder: Path, device: str = "cpu"):
        self.detector = self.mesh = self.triangles = None
        self.partner = read_partners()
        files = [folder / f for f in (DETECTOR_FILE, MESH_FILE, TRIANGLES_FILE)]
        if not all(f.is_file() for f in files):
            return
        import onnxruntime as ort

        from ..engine.graph_cache import open_session
        from ..engine.session import load_model

        self.detector = load_model(files[0], "matte_face", device=device, warmup=False)
        opts = ort.SessionOptions()
        opts.intra_op_num_threads = 1
        try:
            self.mesh = open_session(files[1], opts, ["CPUExecutionProvider"])
        except Exception as exc:  # a broken file: one clear error
            raise RelightError(f"{files[1]}: cannot load the face landmarker ({exc})") from None
        try:
            tri = np.loadtxt(files[2], dtype=np.int64, ndmin=2)
        except ValueError as exc:
            raise RelightError(f"{files[2]}: expected rows of three vertex indices ({exc})") from None
        if tri.ndim != 2 or tri.shape[1] != 3 or tri.size == 0 or tri.min() < 0 or tri.max() >= N_POINTS:
            raise RelightError(f"{files[2]}: expected (T, 3) vertex indices below {N_POINTS}, got shape {tri.shape}")
        self.triangles = tri.astype(np.int64)

    @property
    def available(self) -> bool:
        return self.mesh is not None

    def faces(self, rgb: np.ndarray, box: tuple[int, int, int, int], lift: float = 1.0) -> list[np.ndarray]:
        """Meshes of the faces in ``rgb`` inside ``box`` (y0, y1, x0, x1): [(468, 3) x, y, z in input pixels].

        ``lift``: the graphs are shown their crops raised to this power (< 1 lifts the shadows: a face half in
        deep shadow, relight_rt.relight.face_pass ``SHADOW_LIFTS``); only the small crops are raised, not the photo.

        The detector looks at the box's square first; where it finds no face there it looks once more at a square
        ``CLOSE_UP_SCALE`` times as large (zero past the photo's edge): a face that fills the photo (a close-up
        portrait, a face crop) is too large for the short-range detector, which found none on any of the 12 Yale
        faces (168 x 192, the face filling the frame) and one on each with the photo padded (issue 48).
        """
        rgb = np.asarray(rgb)
        if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype.kind != "f":
            raise RelightError(f"face search: expected an (H, W, 3) float RGB image in [0, 1], got {rgb.dtype} of "
                               f"shape {rgb.shape}")  # fmt: skip
        if not (isinstance(lift, numbers.Real) and math.isfinite(lift) and lift > 0):
            raise RelightError(f"face search: lift must be a finite power > 0, got {lift!r}")
        meshes = []
        for found in self.boxes(rgb, box, lift):
            pts = self.landmarks(rgb, Region.around(*found, scale=ROI_SCALE), lift)
            if pts is not None:
                meshes.append(pts)
        return meshes

    def boxes(self, rgb: np.ndarray, box: tuple[int, int, int, int], lift: float = 1.0) -> list[list[float]]:
        """The detector's face boxes [x0, y0, x1, y1] (input pixels, best first) inside ``box`` (y0, y1, x0, x1):
        the box's square first, else one ``CLOSE_UP_SCALE`` times as large (``faces``); ``rgb`` and ``lift`` as
        ``faces`` takes them, checked there."""
        y0, y1, x0, x1 = box
        found: list[list[float]] = []
        for scale in (1.0, CLOSE_UP_SCALE):
            region = Region.around(x0, y0, x1, y1, scale=scale)
            look = _lifted(crop_region(rgb, region, FACE_SIZE), lift)
            _check_finite(look)
            out = self.detector.run({"image": look.transpose(2, 0, 1)[None]})
            seen = decode(out["boxes"][0], out["scores"][0])
            if MESH_FLIP:  # the mirror's boxes mapped back join the photo's in the weighted merge
                out = self.detector.run({"image": np.ascontiguousarray(look[:, ::-1].transpose(2, 0, 1)[None])})
                seen += [(b[[2, 1, 0, 3]] * (-1, 1, -1, 1) + (1, 0, 1, 0), score)
                         for b, score in decode(out["boxes"][0], out["scores"][0])]
            rx0, ry0, _, _ = region.box()
            found = [(np.array([rx0, ry0, rx0, ry0]) + fbox * region.side).tolist()
                     for fbox, _score in weighted_nms(seen)]
            # the wider look keeps only faces centred in the box (not a neighbour's beside it)
            if scale > 1:
                found = [f for f in found if x0 <= (f[0] + f[2]) / 2 < x1 and y0 <= (f[1] + f[3]) / 2 < y1]
            if found:
                break
        return found

    def landmarks(self, rgb: np.ndarray, roi: Region, lift: float = 1.0) -> np.ndarray | None:
        """The landmarker's mesh on the square ``roi`` of ``rgb`` ((468, 3) x, y, z in input pixels; zeros past
        the photo's edge); None where its face flag or the mesh's extent says no face."""
        crop = _lifted(crop_region(rgb, roi, MESH_SIZE), lift)
        _check_finite(crop)
        lm, flag = self.mesh.run(["landmarks", "face_flag"], {"image": crop.transpose(2, 0, 1)[None]})
        pts = lm.reshape(N_POINTS, 3).astype(np.float64)
        prob = 1.0 / (1.0 + math.exp(-float(flag.reshape(-1)[0])))
        if MESH_FLIP and self.partner is not None:  # the mirror's mesh mapped back, each landmark its partner's
            lm, flag = self.mesh.run(["landmarks", "face_flag"],
                                     {"image": np.ascontiguousarray(crop[:, ::-1].transpose(2, 0, 1)[None])})
            other = lm.reshape(N_POINTS, 3).astype(np.float64)[self.partner]
            other[:, 0] = MESH_SIZE - other[:, 0]
            with np.errstate(invalid="ignore", over="ignore"):  # a graph's Inf: dropped below, as without it
                pts = (pts + other) / 2
            prob = (prob + 1.0 / (1.0 + math.exp(-float(flag.reshape(-1)[0])))) / 2
        if prob < MIN_FLAG:
            return None
        k = roi.side / MESH_SIZE  # the landmarks are in the canvas's continuous coordinates (0 .. MESH_SIZE)
        bx, by, _, _ = roi.box()
        pts[:, 0] = bx + pts[:, 0] * k
        pts[:, 1] = by + pts[:, 1] * k
        pts[:, 2] *= k
        across = float(np.ptp(pts, axis=0).max()) / roi.side
        if not (np.isfinite(pts).all() and across <= MESH_REACH):  # no face's shape: every map drawn from it
            log.debug("face mesh dropped: not finite, or %.3g crop sides across", across)  # is sized by it
            return None
        return pts
