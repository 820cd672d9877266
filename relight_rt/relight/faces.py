"""The face pass: a face stage 1 saw small gets a second stage-1 pass on its head (``head_crops``: where), and a
face the detector finds gets the normals of its mesh blended into the transport (``FacePass``; relight_rt.relight.head,
relight_rt.person.face_mesh)."""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np

from ..engine.errors import RelightError
from ..person.face_mesh import MIN_FACE_NET, FaceMesh, face_transport
from .decomposition import Decomposition
from .head import head_box


def head_crops(decs: list[Decomposition]) -> list[tuple]:
    """Per decomposition whose face stage 1 saw small (relight_rt.relight.head ``head_box``): (its index, it, the head's
    box (y0, y1, x0, x1) in the input frame, the photo inside that box (a read-only view: stage 1 reads it without
    a copy) and the mask there)."""
    todo = []
    for i, dec in enumerate(decs):
        box = head_box(dec.skin, dec.network_mask, dec.geometry)
        if box is not None:
            y0, y1, x0, x1 = box
            todo.append((i, dec, box, dec.image[y0:y1, x0:x1],
                         np.ascontiguousarray(dec.mask[y0:y1, x0:x1])))
    return todo


class FacePass:
    """The face detector and landmarker of a models folder (relight_rt.person.face_mesh), loaded on first use."""

    def __init__(self, models_dir: Path) -> None:
        self.models_dir = models_dir
        self._mesh: FaceMesh | None = None
        self._lock = threading.Lock()

    def mesh(self) -> FaceMesh:
        """The face detector and landmarker of the models folder (relight_rt.person.face_mesh), loaded once."""
        if self._mesh is None:
            with self._lock:
                if self._mesh is None:
                    self._mesh = FaceMesh(self.models_dir, device="cpu")
        return self._mesh

    def find(self, image: np.ndarray, box: tuple[int, int, int, int]) -> tuple[np.ndarray, ...]:
        """The meshes of the faces in ``image`` (H, W, 3) inside ``box`` (y0, y1, x0, x1), none without the face
        models: ((468, 3) float64 x, y, z in input pixels, ...)."""
        mesh = self.mesh()
        return tuple(mesh.faces(image, box)) if mesh.available else ()

    def add_faces(self, dec: Decomposition, transport: np.ndarray, window: tuple[int, int, int, int]) -> np.ndarray:
        """Blend the transport of each of ``dec.face_meshes`` into ``transport`` (the window's, unpremultiplied), in
        place; returns where the faces' skin lies well inside their meshes (``face_transport``; none without a
        mesh)."""
        mesh = self.mesh()
        if not dec.face_meshes:
            return np.zeros(transport.shape[:2], bool)
        if not mesh.available:
            raise RelightError(f"{self.models_dir}: a decomposition with face meshes needs the face models to relight")
        geom = dec.geometry
        k = geom.scale
        (by0, _, bx0, _), (oy, ox) = geom.box, geom.offset
        y0, _, x0, _ = window
        skin = np.zeros(transport.shape[:2], bool)
        for pts in dec.face_meshes:
            net = np.empty_like(pts)  # input pixels -> the window's pixel indices (centres at integers)
            net[:, 0] = (pts[:, 0] - bx0 + ox) / k - 0.5 - x0
            net[:, 1] = (pts[:, 1] - by0 + oy) / k - 0.5 - y0
            net[:, 2] = pts[:, 2] / k
            if np.ptp(net[:, :2], axis=0).max() < MIN_FACE_NET:
                continue
            t_face, weight, face_skin = face_transport(net, mesh.triangles, transport[..., 0])
            transport += weight[..., None] * (t_face - transport)
            skin |= face_skin
        return skin
