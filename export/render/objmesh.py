"""User meshes: a textured Wavefront .obj (+ .mtl + texture image) as a Subject.

For scans (commercial or self-made). The mesh is used in its own coordinates except for an optional
axis convention: scans usually have +y up and face +z (glTF/OBJ habit), which ``up="y"`` maps to the
subject frame of DESIGN.md §3 (the person faces +x, the camera; +z up). Skin labels come from an
optional grey-level texture in the same UV layout (white = skin); without one the skin label is 0.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from export.render.scene import Part, Subject
from relight_rt.engine.errors import RelightError

log = logging.getLogger(__name__)

#: Scan axes -> subject frame. "y": y up, facing +z  ->  (x, y, z)_subject = (z, x, y).  "z": unchanged.
_AXES = {
    "y": np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),
    "z": np.eye(3),
}


def _read_image(path: Path, grey: bool) -> np.ndarray:
    import cv2

    img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE if grey else cv2.IMREAD_COLOR)
    if img is None:
        raise RelightError(f"cannot read texture {path}: expected a readable image file")
    img = img.astype(np.float32) / 255.0
    return img if grey else np.ascontiguousarray(img[..., ::-1])


def _unit_scale(height: float) -> float:
    """Metres per file unit, guessed from the mesh's height: scans come in m, cm or mm."""
    if height > 300.0:
        return 0.001
    if height > 10.0:
        return 0.01
    return 1.0


def load_obj(path: str | Path, skin_path: str | Path | None = None, *, up: str = "y",
             name: str | None = None, scale: float | None = None) -> Subject:
    """Load a textured .obj (its .mtl's ``map_Kd`` texture, or its ``Kd`` colour) as a Subject.

    Args:
        path: the .obj file.
        skin_path: optional skin-label image in the mesh's UV layout (white = skin, black = not), any size.
        up: the scan's up axis, "y" (faces +z, the common OBJ habit) or "z" (already the subject frame).
        name: the Subject's name (default: the file stem).
        scale: metres per file unit; None guesses from the height (over 10 units: cm, over 300: mm).

    Returns:
        Subject with one Part per material/texture ("mesh" when there is one), albedo in [0, 1] RGB,
        uv per face corner (v up), roughness 0.6, specular 0.04, subsurface = skin label's mean > 0.

    Raises:
        RelightError: a missing or unreadable file, a mesh without faces, or a bad ``up``.
    """
    try:
        import trimesh
    except ImportError as exc:  # pragma: no cover
        raise RelightError("loading meshes needs the 'render' extra: pip install 'relight-rt[render]'") from exc
    path = Path(path)
    if up not in _AXES:
        raise RelightError(f"expected up='y' or 'z', got {up!r}")
    if not path.is_file():
        raise RelightError(f"mesh file {path} does not exist")
    try:
        loaded = trimesh.load(str(path), process=False, maintain_order=True)
    except Exception as exc:  # trimesh raises many kinds
        raise RelightError(f"cannot read mesh {path}: {exc}") from exc
    meshes = list(loaded.geometry.values()) if isinstance(loaded, trimesh.Scene) else [loaded]
    meshes = [m for m in meshes if isinstance(m, trimesh.Trimesh) and len(m.faces)]
    if not meshes:
        raise RelightError(f"mesh {path} has no triangles")
    skin_tex = _read_image(Path(skin_path), grey=True) if skin_path is not None else None
    axes = _AXES[up]
    if scale is None:
        heights = np.concatenate([np.asarray(m.vertices) @ axes.T for m in meshes])[:, 2]
        scale = _unit_scale(float(heights.max() - heights.min()))
    if not (np.isfinite(scale) and scale > 0):
        raise RelightError(f"expected a positive scale in metres per unit, got {scale}")
    parts = []
    for i, mesh in enumerate(meshes):
        verts = (np.asarray(mesh.vertices, dtype=np.float64) @ axes.T * scale).astype(np.float32)
        faces = np.asarray(mesh.faces, dtype=np.int32)
        visual = mesh.visual
        uv_v = getattr(visual, "uv", None)
        albedo: np.ndarray = np.full(3, 0.7, dtype=np.float32)
        if uv_v is not None and len(uv_v) == len(verts):
            uv = np.asarray(uv_v, dtype=np.float32)[faces]
        else:
            uv = np.zeros((len(faces), 3, 2), dtype=np.float32)
        material = getattr(visual, "material", None)
        image = getattr(material, "image", None) if material is not None else None
        if image is not None and uv_v is not None:
            arr = np.asarray(image.convert("RGB"), dtype=np.float32) / 255.0
            albedo = arr
        elif material is not None:
            kd = getattr(material, "diffuse", None)
            if kd is None:
                kd = getattr(material, "main_color", None)
            if kd is not None:
                albedo = (np.asarray(kd, dtype=np.float32)[:3] / 255.0).astype(np.float32)
        uv = np.mod(uv, 1.0, where=(uv < 0) | (uv > 1), out=uv.copy())
        skin = skin_tex if skin_tex is not None else 0.0
        parts.append(Part(
            name="mesh" if len(meshes) == 1 else f"mesh_{i}",
            vertices=verts,
            faces=faces,
            uv=uv.astype(np.float32),
            albedo=albedo.astype(np.float32),
            skin=skin,
            roughness=0.6,
            specular=0.04,
            subsurface=1.0 if skin_tex is not None and float(skin_tex.mean()) > 0 else 0.0,
        ))
    log.info("loaded %s: %d part(s), %d triangles", path, len(parts), sum(len(p.faces) for p in parts))
    return Subject(parts, name or path.stem)
