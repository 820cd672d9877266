"""User meshes (.obj + .mtl + texture) as Subjects, and the preview image."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("trimesh")
cv2 = pytest.importorskip("cv2")

from export.render.objmesh import load_obj  # noqa: E402
from export.render.preview import preview_subject, render_preview, sample_texture  # noqa: E402
from relight_rt import RelightError  # noqa: E402

_OBJ = """mtllib quad.mtl
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
usemtl cloth
f 1/1 2/2 3/3
f 1/1 3/3 4/4
"""


def _write_quad(folder: Path, texture: bool = True) -> Path:
    (folder / "quad.obj").write_text(_OBJ)
    if texture:
        (folder / "quad.mtl").write_text("newmtl cloth\nKd 1 1 1\nmap_Kd tex.png\n")
        img = np.zeros((8, 8, 3), np.uint8)
        img[:4] = (0, 0, 255)  # top half red (BGR on disk) = v in (0.5, 1]
        img[4:] = (255, 0, 0)  # bottom half blue
        cv2.imwrite(str(folder / "tex.png"), img)
    else:
        (folder / "quad.mtl").write_text("newmtl cloth\nKd 0.2 0.4 0.6\n")
    return folder / "quad.obj"


def test_load_textured_obj(tmp_path):
    subject = load_obj(_write_quad(tmp_path), up="z")
    assert subject.name == "quad" and len(subject.parts) == 1
    part = subject.parts[0]
    np.testing.assert_allclose(part.vertices, [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    assert part.faces.dtype == np.int32 and part.faces.shape == (2, 3)
    assert part.uv.shape == (2, 3, 2) and part.uv.dtype == np.float32
    assert part.albedo.shape == (8, 8, 3) and part.albedo.dtype == np.float32
    # RGB in memory, row 0 of the texture is v = 1
    np.testing.assert_allclose(sample_texture(part.albedo, np.array([[0.5, 0.9], [0.5, 0.1]])), [[1, 0, 0], [0, 0, 1]])
    assert part.skin == 0.0 and part.subsurface == 0.0


def test_y_up_scans_are_turned_into_the_subject_frame(tmp_path):
    part = load_obj(_write_quad(tmp_path), up="y").parts[0]
    # (x, y, z)_scan -> (z, x, y): the scan's +y (up) becomes +z, its facing +z becomes +x (the camera),
    # and its +x (the viewer's right in the usual y-up, look-along-−z view) becomes +y (the image's right)
    np.testing.assert_allclose(part.vertices[2], [0, 1, 1])


def test_skin_label_texture(tmp_path):
    path = _write_quad(tmp_path)
    label = np.zeros((16, 16), np.uint8)
    label[:, :8] = 255  # left half is skin
    cv2.imwrite(str(tmp_path / "skin.png"), label)
    part = load_obj(path, tmp_path / "skin.png", up="z").parts[0]
    assert part.skin.shape == (16, 16) and part.subsurface == 1.0
    np.testing.assert_allclose(sample_texture(part.skin, np.array([[0.2, 0.5], [0.8, 0.5]])), [1.0, 0.0])


def test_untextured_material_gives_its_colour(tmp_path):
    part = load_obj(_write_quad(tmp_path, texture=False), up="z").parts[0]
    np.testing.assert_allclose(part.albedo, [0.2, 0.4, 0.6], atol=0.01)


@pytest.mark.parametrize(
    ("make", "kwargs", "match"),
    [
        (lambda d: d / "missing.obj", {}, "does not exist"),
        (lambda d: _write_quad(d), {"up": "x"}, "expected up='y' or 'z'"),
        (lambda d: (d / "empty.obj").write_text("v 0 0 0\n") and d / "empty.obj", {}, "has no triangles"),
    ],
)
def test_bad_input(tmp_path, make, kwargs, match):
    with pytest.raises(RelightError, match=match):
        load_obj(make(tmp_path), **kwargs)


def test_missing_skin_texture_raises(tmp_path):
    with pytest.raises(RelightError, match="cannot read texture"):
        load_obj(_write_quad(tmp_path), tmp_path / "nope.png")


def test_preview_shows_the_texture(tmp_path):
    subject = load_obj(_write_quad(tmp_path), up="z")
    part = subject.parts[0]
    part.vertices = part.vertices[:, [2, 0, 1]].copy()  # the x-y quad into the y-z plane, facing the camera (+x)
    img = render_preview(subject, 32, "albedo")
    assert img.shape == (32, 32, 3)
    assert img[8, 16, 0] > 0.9 and img[8, 16, 2] < 0.1  # top: red
    assert img[24, 16, 2] > 0.9 and img[24, 16, 0] < 0.1  # bottom: blue
    out = preview_subject(subject, tmp_path / "p.png", size=32)
    assert cv2.imread(str(out)).shape == (32, 96, 3)


def test_centimetre_scans_are_scaled_to_metres(tmp_path):
    obj = _OBJ.replace("v 1 1 0", "v 170 170 0").replace("v 0 1 0", "v 0 170 0").replace("v 1 0 0", "v 170 0 0")
    (tmp_path / "big.obj").write_text(obj.replace("mtllib quad.mtl\n", ""))
    part = load_obj(tmp_path / "big.obj", up="y").parts[0]
    assert abs(float(part.vertices[:, 2].max()) - 1.7) < 1e-5  # 170 cm tall, y up -> 1.7 m along +z
    part = load_obj(tmp_path / "big.obj", up="y", scale=1.0).parts[0]
    assert float(part.vertices[:, 2].max()) == 170.0
    with pytest.raises(RelightError, match="positive scale"):
        load_obj(tmp_path / "big.obj", scale=-1.0)
