"""relight_rt.lightfile: SH light files (.npy, .json; BGR only when asked), atomic writes (DESIGN.md §6)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from _sh_samples import random_light

from relight_rt import RelightError, lightfile, sh

# ----------------------------------------------------------------------------------------- light files


@pytest.mark.parametrize("ext", [".npy", ".json"])
@pytest.mark.parametrize("bgr", [False, True])
def test_save_load_round_trip(tmp_path, ext, bgr):
    light = random_light()
    path = tmp_path / f"light{ext}"
    lightfile.save_light(path, light, bgr=bgr)
    np.testing.assert_array_equal(lightfile.load_light(path, bgr=bgr), light)
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # no temporary file left behind
    stored = np.load(path) if ext == ".npy" else np.array(json.loads(path.read_text())["sh"])
    np.testing.assert_array_equal(stored, light[:, ::-1] if bgr else light)


def test_load_light_bgr_swaps_columns(tmp_path):
    light = random_light()
    path = tmp_path / "l.npy"
    np.save(path, light)
    np.testing.assert_array_equal(lightfile.load_light(path, bgr=True), light[:, ::-1])
    np.testing.assert_array_equal(lightfile.load_light(path), light)


def test_load_light_json_order(tmp_path):
    light = random_light()
    path = tmp_path / "l.json"
    path.write_text(json.dumps({"sh": light[:, ::-1].tolist(), "order": "bgr"}))
    np.testing.assert_allclose(lightfile.load_light(path), light)
    path.write_text(json.dumps({"sh": light.tolist()}))
    np.testing.assert_allclose(lightfile.load_light(path), light)  # "order" defaults to rgb
    path.write_text(json.dumps({"sh": light.tolist(), "order": "rgb"}))
    with pytest.raises(RelightError, match="bgr=True but"):
        lightfile.load_light(path, bgr=True)


def test_load_light_layouts(tmp_path):
    light = random_light()
    flat = tmp_path / "flat.npy"
    np.save(flat, light.reshape(27))  # index 3k + c
    transposed = tmp_path / "t.npy"
    np.save(transposed, light.T)
    np.testing.assert_array_equal(lightfile.load_light(flat, layout="27-kc"), light)
    np.testing.assert_array_equal(lightfile.load_light(transposed, layout="3x9"), light)
    for path in (flat, transposed):
        with pytest.raises(RelightError, match="say how to read it"):
            lightfile.load_light(path)
    with pytest.raises(RelightError, match="expects shape"):
        lightfile.load_light(flat, layout="3x9")
    with pytest.raises(RelightError, match="layout"):
        lightfile.load_light(flat, layout="27-ck")


def test_load_light_bad_files(tmp_path):
    with pytest.raises(RelightError, match="missing.npy: light file not found"):
        lightfile.load_light(tmp_path / "missing.npy")
    with pytest.raises(RelightError, match="unsupported"):
        lightfile.load_light(tmp_path / "light.txt")
    cases = {
        "shape.npy": lambda p: np.save(p, np.zeros((9, 4))),
        "nan.npy": lambda p: np.save(p, np.full((9, 3), np.nan)),
        "corrupt.npy": lambda p: p.write_bytes(b"garbage"),
        "pickle.npy": lambda p: np.save(p, np.array([{"a": 1}], dtype=object), allow_pickle=True),
        "text.npy": lambda p: np.save(p, np.full((9, 3), "a")),
        "corrupt.json": lambda p: p.write_text("{not json"),
        "list.json": lambda p: p.write_text("[1, 2, 3]"),
        "ragged.json": lambda p: p.write_text(json.dumps({"sh": [[1, 2, 3], [1]]})),
        "order.json": lambda p: p.write_text(json.dumps({"sh": np.zeros((9, 3)).tolist(), "order": "xyz"})),
        "inf.json": lambda p: p.write_text(json.dumps({"sh": [[1e999, 0, 0]] * 9})),
        # fuzz9: an OverflowError from numpy, and strings / true read as numbers
        "bigint.json": lambda p: p.write_text('{"sh": [[' + "9" * 400 + ", 0, 0]" + ", [0, 0, 0]" * 8 + "]}"),
        "strings.json": lambda p: p.write_text(json.dumps({"sh": [["0.5", "0.5", "0.5"]] * 9})),
        "bools.json": lambda p: p.write_text(json.dumps({"sh": [[True, 0.5, 0.5]] * 9})),
    }
    for name, write in cases.items():
        path = tmp_path / name
        write(path)
        with pytest.raises(RelightError, match=name.replace(".", r"\.")):
            lightfile.load_light(path)


def test_save_light_rejects_bad_input(tmp_path):
    with pytest.raises(RelightError, match="NaN"):
        lightfile.save_light(tmp_path / "l.npy", np.full((9, 3), np.nan))
    with pytest.raises(RelightError, match="unsupported"):
        lightfile.save_light(tmp_path / "l.txt", random_light())
    with pytest.raises(RelightError, match="does not exist"):
        lightfile.save_light(tmp_path / "nope" / "l.npy", random_light())
    assert list(tmp_path.iterdir()) == []


def test_reference_lights_load_bgr(reference_dir):
    files = sorted((reference_dir / "lights").glob("*.npy"))
    assert len(files) == 10
    for path in files:
        raw = np.load(path, allow_pickle=False)
        light = lightfile.load_light(path, bgr=True)
        np.testing.assert_array_equal(light, raw[:, ::-1])
        # Scale of the reference's lights (measured): DC 0.2-1.5 per channel, sphere peak 0.9-2.5.
        assert 0.4 <= light[0].max() <= 1.5
        assert 0.5 <= sh.render_sphere(light, 32).max() <= 3.0
