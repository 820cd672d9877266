"""Ray casting against a subject with Embree (embreex): primary hits and batched occlusion queries.

All parts of a :class:`~export.render.scene.Subject` go into one Embree scene. Embree scenes
cannot be pickled: build one :class:`Tracer` per process.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from relight_rt.engine.errors import RelightError

from .scene import Subject

log = logging.getLogger(__name__)


def _embree():
    try:
        from embreex import mesh_construction, rtcore_scene
    except ImportError as exc:  # pragma: no cover - depends on the installed extras
        raise ImportError(
            "ray casting needs embreex (and trimesh): pip install -e '.[render]'"
        ) from exc
    return rtcore_scene, mesh_construction


@dataclass
class Hits:
    """Where rays hit the subject. Arrays have one row per ray; rows without a hit hold zeros.

    Attributes:
        hit: (N,) bool.
        face: (N,) int64 index into the tracer's concatenated faces, −1 without a hit.
        part: (N,) int64 index of the subject's part, −1 without a hit.
        bary: (N, 3) float32 barycentric weights of the face's three corners.
        position: (N, 3) float32 hit point, subject frame, metres.
        normal: (N, 3) float32 unit shading normal (interpolated vertex normals), turned to face the ray's origin.
        geo_normal: (N, 3) float32 unit face normal, turned to the same side as ``normal``.
    """

    hit: np.ndarray
    face: np.ndarray
    part: np.ndarray
    bary: np.ndarray
    position: np.ndarray
    normal: np.ndarray
    geo_normal: np.ndarray


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(n, 1e-20)


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted smooth normals (V, 3) float32; vertices at the same position share one normal,
    so texture seams (duplicated vertices) do not show as creases."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    face_n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])  # length = 2 * area
    _, weld = np.unique(np.round(v, 7), axis=0, return_inverse=True)
    weld = weld.reshape(-1)
    acc = np.zeros((weld.max() + 1, 3))
    for corner in range(3):
        np.add.at(acc, weld[f[:, corner]], face_n)
    return _unit(acc[weld]).astype(np.float32)


class Tracer:
    """An Embree scene of every part of a subject.

    Attributes:
        vertices: (V, 3) float32, every part's vertices concatenated.
        faces: (F, 3) int64 into ``vertices``.
        face_part: (F,) int64 part index of each face.
        face_start: (P + 1,) first face of each part (and the total).
        normals: (V, 3) float32 smooth vertex normals.
        face_normals: (F, 3) float32 unit face normals (counter-clockwise = outside).
        scale: length of the bounding box diagonal, metres.
    """

    def __init__(self, subject: Subject) -> None:
        if not subject.parts:
            raise RelightError(f"subject {subject.name!r}: expected at least one part, got none")
        verts, faces, normals, face_part, face_start = [], [], [], [], [0]
        offset = 0
        for i, part in enumerate(subject.parts):
            v = np.asarray(part.vertices, dtype=np.float32)
            f = np.asarray(part.faces, dtype=np.int64)
            if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
                raise RelightError(
                    f"part {part.name!r}: expected (V, 3) vertices and (F, 3) faces, got {v.shape} and {f.shape}"
                )
            if f.min() < 0 or f.max() >= len(v):
                raise RelightError(f"part {part.name!r}: face indices outside 0..{len(v) - 1}")
            verts.append(v)
            faces.append(f + offset)
            normals.append(vertex_normals(v, f))
            face_part.append(np.full(len(f), i, np.int64))
            face_start.append(face_start[-1] + len(f))
            offset += len(v)
        self.vertices = np.concatenate(verts)
        self.faces = np.concatenate(faces)
        self.normals = np.concatenate(normals)
        self.face_part = np.concatenate(face_part)
        self.face_start = np.asarray(face_start, np.int64)
        tri = self.vertices[self.faces].astype(np.float64)
        self.face_normals = _unit(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])).astype(np.float32)
        lo, hi = self.vertices.min(axis=0), self.vertices.max(axis=0)
        self.scale = float(np.linalg.norm(hi - lo))
        rtcore_scene, mesh_construction = _embree()
        self._scene = rtcore_scene.EmbreeScene()
        mesh_construction.TriangleMesh(self._scene, self.vertices, self.faces.astype(np.int32))
        log.debug("tracer: %d parts, %d triangles", len(subject.parts), len(self.faces))

    def intersect(self, origins: np.ndarray, directions: np.ndarray) -> Hits:
        """First hits of rays (origins, directions: (N, 3), directions unit length)."""
        o = np.ascontiguousarray(origins, dtype=np.float32)
        d = np.ascontiguousarray(directions, dtype=np.float32)
        res = self._scene.run(o, d, output=1)
        face = res["primID"].astype(np.int64)
        hit = face >= 0
        n = len(face)
        bary = np.zeros((n, 3), np.float32)
        u, v = res["u"][hit], res["v"][hit]
        bary[hit] = np.stack([1.0 - u - v, u, v], axis=1)
        fh = face[hit]
        corners = self.faces[fh]
        position = np.zeros((n, 3), np.float32)
        position[hit] = np.einsum("nc,ncd->nd", bary[hit], self.vertices[corners])
        normal = np.zeros((n, 3), np.float32)
        geo = np.zeros((n, 3), np.float32)
        ns = _unit(np.einsum("nc,ncd->nd", bary[hit], self.normals[corners]))
        ng = self.face_normals[fh]
        # two-sided: both normals face the side the ray came from (open garment shells show their inside)
        ng = np.where((np.einsum("nd,nd->n", ng, d[hit]) > 0)[:, None], -ng, ng)
        ns = np.where((np.einsum("nd,nd->n", ns, ng) < 0)[:, None], -ns, ns)
        normal[hit], geo[hit] = ns, ng
        part = np.full(n, -1, np.int64)
        part[hit] = self.face_part[fh]
        return Hits(hit=hit, face=face, part=part, bary=bary, position=position, normal=normal, geo_normal=geo)

    def occluded(self, origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """(N,) bool: whether each ray (origins, directions (N, 3)) hits anything (unbounded length)."""
        o = np.ascontiguousarray(origins, dtype=np.float32)
        d = np.ascontiguousarray(directions, dtype=np.float32)
        return self._scene.run(o, d, query="OCCLUDED") >= 0
