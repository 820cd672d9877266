"""The compact bank (export.gpu.bank): subjects round-trip, template parts are stored as face masks."""

from __future__ import annotations

import json

import numpy as np
import pytest

from export.gpu import bank
from export.render.scene import Part, Subject
from export.render.shapes import plane, sphere
from relight_rt import RelightError


def _grid(n: int):
    """A template: an n×n grid of vertices, two triangles per cell, per-corner UVs unique per face."""
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1), indexing="ij")
    a = (i * n + j).ravel()
    faces = np.concatenate([np.stack([a, a + n, a + 1], 1), np.stack([a + 1, a + n, a + n + 1], 1)])
    y, z = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n), indexing="ij")
    uv_v = np.stack([y.ravel(), z.ravel()], 1).astype(np.float32)
    verts = np.stack([np.zeros(n * n), y.ravel(), z.ravel()], 1).astype(np.float32)
    return verts, faces.astype(np.int64), uv_v[faces]


def test_a_mesh_subject_round_trips(tmp_path):
    skin = np.random.default_rng(0).uniform(0, 1, (32, 32)).astype(np.float32)
    albedo = np.random.default_rng(1).uniform(0, 1, (32, 32, 3)).astype(np.float32)
    parts = [sphere((0, 0, 1.0), 0.3, (0.2, 0.5, 0.8), rows=8, name="ball", skin=0.0),
             Part("card", *(lambda p: (p.vertices, p.faces, p.uv))(plane(0.5, cells=2, x=0.4)), albedo, skin)]
    subject = Subject(parts, "two")
    path = bank.write_subject(tmp_path, subject, texture_size=64)
    got = bank.read_subject(path, None)
    assert got.name == "two" and [p.name for p in got.parts] == ["ball", "card"]
    span = np.ptp(np.concatenate([p.vertices for p in parts]), axis=0).max()
    for want, have in zip(parts, got.parts, strict=True):
        assert np.abs(have.vertices - want.vertices).max() <= span / 65535
        assert np.array_equal(have.faces, want.faces) and np.array_equal(have.uv, want.uv)
    ball, card = got.parts
    assert ball.skin == 0.0 and card.skin == -1.0
    assert np.allclose(got.textures[ball.texture][0, 0, :3], (0.2, 0.5, 0.8), atol=1 / 255)
    tex = got.textures[card.texture]
    assert np.abs(tex[..., :3] - albedo).max() <= 0.5 / 255 + 1e-6
    assert np.abs(tex[..., 3] - skin).max() <= 0.5 / 255 + 1e-6
    back = bank.to_subject(got)
    assert back.parts[1].skin.shape == (32, 32) and back.parts[0].skin == 0.0


def test_textures_are_shrunk_to_the_texture_size(tmp_path):
    part = plane(1.0, cells=1)
    part = Part("p", part.vertices, part.faces, part.uv, np.full((128, 64, 3), 0.25, np.float32), 1.0)
    got = bank.read_subject(bank.write_subject(tmp_path, Subject([part], "s"), texture_size=32), None)
    assert got.textures[0].shape == (32, 16, 4)


def test_template_parts_are_stored_as_masks_and_come_back_exactly(tmp_path):
    verts, faces, uv = _grid(30)
    bank.write_template(tmp_path, faces, uv)
    index = bank._TemplateIndex(faces, uv)
    albedo = np.full((16, 16, 3), 0.5, np.float32)
    skin = np.ones((16, 16), np.float32)
    sel = np.zeros(len(faces), bool)
    sel[::3] = True
    body = verts + np.float32(0.01)
    used = np.unique(faces[~sel])
    remap = np.full(len(verts), -1)
    remap[used] = np.arange(len(used))
    shell = (body + [0.05, 0, 0])[used]
    parts = [Part("body", body, faces[sel], uv[sel], albedo, skin),
             Part("body_covered", body, faces[~sel], uv[~sel], albedo, skin),
             Part("shirt", shell.astype(np.float32), remap[faces[~sel]], uv[~sel], albedo, 0.0)]
    path = bank.write_subject(tmp_path, Subject(parts, "templated"), template=index)
    with np.load(path) as z:
        meta = json.loads(str(z["meta"]))
        assert [p["mode"] for p in meta["parts"]] == ["full", "full", "subset"]
        assert "p1_vertices" not in z.files  # shares the body's vertices
    got = bank.read_subject(path, bank.read_template(tmp_path))
    for want, have in zip(parts, got.parts, strict=True):
        assert np.array_equal(have.faces, want.faces) and np.array_equal(have.uv, want.uv)
        assert np.abs(have.vertices - want.vertices).max() < 1e-4
    with pytest.raises(RelightError, match="template.npz"):
        bank.read_subject(path, None)


def test_a_folder_without_a_bank_is_refused(tmp_path):
    with pytest.raises(RelightError, match="bank.json"):
        bank.read_index(tmp_path)
    (tmp_path / "bank.json").write_text(json.dumps({"format": "other", "subjects": ["a"]}))
    with pytest.raises(RelightError, match="format"):
        bank.read_index(tmp_path)
    (tmp_path / "x.npz").write_bytes(b"not an npz")
    with pytest.raises(RelightError, match="not readable"):
        bank.read_subject(tmp_path / "x.npz", None)


# issue 50, round 4 fuzz (benchmarks/fuzz_round5.py): a damaged or hostile bank ends in one RelightError


def _ball_bank(root):
    bank.write_subject(root, Subject([sphere((0, 0, 1.0), 0.3, (0.2, 0.5, 0.8), rows=6, name="ball", skin=0.0)],
                                     "ball"), texture_size=16)
    np.save(root / "lights.npy", np.zeros((2, 9, 3), np.float32))
    return bank.write_index(root)


def _rewrite(path, name, data):
    import zipfile

    with zipfile.ZipFile(path) as z:
        members = {n: z.read(n) for n in z.namelist()}
    members[name] = data
    with zipfile.ZipFile(path, "w") as z:
        for n, d in members.items():
            z.writestr(n, d)


def _npy_declaring(shape, dtype="<u2"):
    import io

    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": dtype, "fortran_order": False, "shape": shape})
    return buf.getvalue() + bytes(16)


@pytest.mark.parametrize("edit, message", [
    ({"subjects": ["../elsewhere/ball"]}, "no paths"),
    ({"subjects": ["/dev/zero"]}, "no paths"),
    ({"lights": "/dev/zero"}, "no paths"),
    ({"subjects": "ball"}, "subjects"),
])
def test_the_index_names_only_files_inside_the_bank(tmp_path, edit, message):
    index = _ball_bank(tmp_path)
    (tmp_path / "bank.json").write_text(json.dumps({**index, **edit}))
    with pytest.raises(RelightError, match=message):
        bank.read_index(tmp_path)
    (tmp_path / "bank.json").write_text("[1, 2]")
    with pytest.raises(RelightError, match="not a JSON object"):
        bank.read_index(tmp_path)


def test_a_damaged_subject_is_refused_before_its_memory_is_spent(tmp_path):
    _ball_bank(tmp_path)
    path = tmp_path / "ball.npz"
    good = path.read_bytes()
    _rewrite(path, "p0_vertices.npy", _npy_declaring((2_000_000_000, 3)))  # 12 GB declared, 16 bytes stored
    with pytest.raises(RelightError, match="MiB"):
        bank.read_subject(path, None)
    path.write_bytes(good)
    png = np.frombuffer(b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR" + (30000).to_bytes(4, "big") * 2 + bytes(20), np.uint8)
    buf = __import__("io").BytesIO()
    np.save(buf, png)
    _rewrite(path, "tex0.npy", buf.getvalue())  # a 30000² texture declared
    with pytest.raises(RelightError, match="texture 0"):
        bank.read_subject(path, None)
    path.write_bytes(good)
    _rewrite(path, "p0_faces.npy", _npy_declaring((0, 3), "<i4")[:-16])
    with pytest.raises(RelightError, match="indexes outside"):
        bank.read_subject(path, None)
    path.write_bytes(good[: len(good) // 2])
    with pytest.raises(RelightError, match="not readable"):
        bank.read_subject(path, None)


def test_lights_declaring_more_than_they_hold_are_refused(tmp_path):
    index = _ball_bank(tmp_path)
    (tmp_path / "lights.npy").write_bytes(_npy_declaring((100_000_000, 9, 3), "<f4"))
    with pytest.raises(RelightError, match="bank lights"):
        bank.read_lights(tmp_path, index)
