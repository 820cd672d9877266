"""Quick looks at a Subject: an orthographic albedo × Lambert image from the camera (+x), by ray casting.

For eyeballing bodies and garments only; the real renderer is export.render's ray caster.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from export.render.scene import Part, Subject

log = logging.getLogger(__name__)


def sample_texture(tex: np.ndarray | float, uv: np.ndarray) -> np.ndarray:
    """Nearest-texel lookup of a texture at UV coordinates.

    Args:
        tex: (Ht, Wt, C) or (Ht, Wt) texture (row 0 is v = 1), a (C,) colour or a scalar.
        uv: (..., 2) coordinates in [0, 1], v up.

    Returns:
        (..., C) or (...) float32 values.
    """
    arr = np.asarray(tex, dtype=np.float32)
    if arr.ndim <= 1:
        return np.broadcast_to(arr, (*uv.shape[:-1], *arr.shape)).astype(np.float32)
    h, w = arr.shape[:2]
    col = np.clip((uv[..., 0] * w).astype(np.int64), 0, w - 1)
    row = np.clip(((1.0 - uv[..., 1]) * h).astype(np.int64), 0, h - 1)
    return arr[row, col]


def _merged(subject: Subject) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    verts, faces, owner = [], [], []
    offset = 0
    for i, part in enumerate(subject.parts):
        verts.append(part.vertices)
        faces.append(part.faces + offset)
        owner.append(np.full(len(part.faces), i))
        offset += len(part.vertices)
    return np.concatenate(verts), np.concatenate(faces), np.concatenate(owner)


def render_preview(subject: Subject, size: int = 384, channel: str = "shaded") -> np.ndarray:
    """(size, size, 3) float32 RGB in [0, 1]: the subject seen from +x, orthographic, fitted with a margin.

    Args:
        subject: what to draw.
        size: image side in pixels.
        channel: "shaded" (albedo × (0.25 + 0.75 · Lambert from the upper front-left)), "albedo" or "skin"
            (grey levels, on a light blue background).
    """
    import trimesh

    verts, faces, owner = _merged(subject)
    mesh = trimesh.Trimesh(verts, faces, process=False)
    lo, hi = subject.bounds()
    centre = (lo + hi) / 2
    half = 0.55 * max(hi[1] - lo[1], hi[2] - lo[2])
    ys = centre[1] + half * (2 * (np.arange(size) + 0.5) / size - 1)
    zs = centre[2] - half * (2 * (np.arange(size) + 0.5) / size - 1)
    gy, gz = np.meshgrid(ys, zs)
    origins = np.stack([np.full(gy.size, hi[0] + 1.0), gy.ravel(), gz.ravel()], axis=1)
    dirs = np.tile([-1.0, 0.0, 0.0], (gy.size, 1))
    tri, ray, loc = mesh.ray.intersects_id(origins, dirs, multiple_hits=False, return_locations=True)
    image = np.empty((gy.size, 3), dtype=np.float32)
    image[:] = (0.55, 0.75, 1.0) if channel == "skin" else (1.0, 1.0, 1.0)  # skin: 1 white, 0 black
    if len(tri) == 0:
        return image.reshape(size, size, 3)
    corners = verts[faces[tri]]
    bary = trimesh.triangles.points_to_barycentric(corners, loc)
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    light = np.array([0.6, -0.4, 0.7]) / np.linalg.norm([0.6, -0.4, 0.7])
    lambert = np.abs(normals @ light) * (normals @ np.array([1.0, 0, 0]) >= -0.2)
    # per part lookups
    offsets = np.cumsum([0] + [len(p.faces) for p in subject.parts])
    colours = np.zeros((len(tri), 3), dtype=np.float32)
    for i, part in enumerate(subject.parts):
        sel = owner[tri] == i
        if not sel.any():
            continue
        uv = np.einsum("nk,nkc->nc", bary[sel], part.uv[tri[sel] - offsets[i]])
        if channel == "skin":
            colours[sel] = sample_texture(part.skin, uv)[:, None]
        else:
            colours[sel] = sample_texture(part.albedo, uv)
    if channel == "shaded":
        colours = colours * (0.25 + 0.75 * lambert[:, None])
    image[ray] = colours
    return np.clip(image.reshape(size, size, 3), 0.0, 1.0)


def preview_subject(subject: Subject, path: str | Path, size: int = 384) -> Path:
    """Save a contact strip (shaded, albedo, skin label) of ``subject`` as a PNG and return its path."""
    import cv2

    strip = np.concatenate([render_preview(subject, size, c) for c in ("shaded", "albedo", "skin")], axis=1)
    path = Path(path)
    cv2.imwrite(str(path), (strip[..., ::-1] * 255 + 0.5).astype(np.uint8))
    log.info("wrote %s", path)
    return path


def body_part(name: str, vertices: np.ndarray, faces: np.ndarray, uv: np.ndarray, colour) -> Part:
    """A flat-coloured Part, for previews and tests."""
    return Part(name, vertices.astype(np.float32), faces.astype(np.int32), uv.astype(np.float32),
                np.asarray(colour, dtype=np.float32))
