"""relight_rt.apps.render_passes and relight_rt.image.exr: compositor passes, read back by a second reader (OpenEXR's
own module).

Golden identities: albedo x shading + residual = beauty (the module's definition, checked through the files); the
beauty pass is ``Relighter.relight(..., background="transparent")`` premultiplied; the normal map of an unoccluded
transport (T_k = A_l Y_k(n), DESIGN.md §3) is n itself.
"""

import json
import math
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

import relight_rt
from relight_rt import RelightError, sh
from relight_rt.apps.render_passes import PASSES, compute_passes, transport_normals, write_passes
from relight_rt.image.exr import encode_exr

REPO = Path(__file__).resolve().parents[3]
OpenEXR = pytest.importorskip("OpenEXR")  # the second reader (the dev extra installs it)


def read_exr(path) -> dict:
    with OpenEXR.File(str(path), separate_channels=True) as f:
        return {name: np.array(ch.pixels) for name, ch in f.channels().items()}


# ------------------------------------------------------------------------------------------------ the writer


@pytest.mark.parametrize("shape", [(1, 1), (16, 3), (17, 5), (40, 33)])  # 16 rows per chunk: whole and partial
def test_exr_round_trip_through_openexr(tmp_path, shape):
    rng = np.random.default_rng(0)
    channels = {"R": rng.random(shape), "G": np.full(shape, -3.5), "B": rng.normal(size=shape) * 1e4,
                "A": np.ones(shape), "normal.X": np.linspace(-1, 1, math.prod(shape)).reshape(shape)}
    (tmp_path / "a.exr").write_bytes(encode_exr(channels))
    back = read_exr(tmp_path / "a.exr")
    assert set(back) == set(channels)
    for name, values in channels.items():
        assert back[name].dtype == np.float32
        np.testing.assert_array_equal(back[name], values.astype(np.float32))
    with OpenEXR.File(str(tmp_path / "a.exr")) as f:
        assert f.header()["compression"] == OpenEXR.ZIP_COMPRESSION


def test_exr_compresses_smooth_data():
    smooth = np.tile(np.linspace(0, 1, 256, dtype=np.float32), (64, 1))
    assert len(encode_exr({"Y": smooth})) < smooth.nbytes / 2


@pytest.mark.parametrize(
    ("channels", "match"),
    [
        ({}, "at least one"),
        ({"R": np.zeros((2, 2)), "G": np.zeros((2, 3))}, "one size"),
        ({"R": np.zeros((0, 2))}, "one size"),
        ({"R": np.zeros((2, 2, 3))}, "one size"),
        ({"R": np.full((2, 2), np.nan)}, "NaN or Inf"),
        ({"": np.zeros((2, 2))}, "channel name"),
    ],
)
def test_exr_refuses(channels, match):
    with pytest.raises(RelightError, match=match):
        encode_exr(channels)


# ------------------------------------------------------------------------------------------------ normals


class _Unoccluded:
    """What ``transport_normals`` reads of a Decomposition, for a surface with known normals and no occlusion."""

    def __init__(self, normals: np.ndarray, mask: np.ndarray):
        lobe = sh.cosine_lobe()
        self.transport = (sh.basis(normals.reshape(-1, 3)) * lobe).reshape(*normals.shape[:2], 9).astype(np.float32)
        self.transport *= mask[..., None]  # masked, as stage 1's is
        self.mask = mask

    def to_input(self, layer):
        return np.array(layer, np.float32)


def test_normals_of_an_unoccluded_transport_are_the_normals():
    rng = np.random.default_rng(1)
    n = rng.normal(size=(6, 7, 3))
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    mask = np.ones((6, 7), np.float32)
    mask[0, 0], mask[1, 1] = 0.0, 0.3  # off the person, and a soft edge (the mask cancels)
    out = transport_normals(_Unoccluded(n, mask))
    camera = n[..., [1, 2, 0]]  # R = +y (image right), G = +z (up), B = +x (toward the camera)
    inside = mask > 0
    np.testing.assert_allclose(out[inside], camera[inside], atol=1e-5)
    assert np.all(out[0, 0] == 0)


# ------------------------------------------------------------------------------------------------ passes


@pytest.fixture(scope="module")
def relighter():
    return relight_rt.open()


@pytest.fixture(scope="module")
def scene(relighter):
    photo = cv2.imread(str(REPO / "relight_rt" / "data" / "example_scene.jpg"))[..., ::-1]
    photo = cv2.resize(photo, (photo.shape[1] // 2, photo.shape[0] // 2), interpolation=cv2.INTER_AREA)
    dec = relighter.decompose(np.ascontiguousarray(photo))
    return dec, compute_passes(relighter, dec, "night")


def test_passes_add_up(relighter, scene):
    dec, passes = scene
    layers = passes.layers
    assert set(layers) == set(PASSES)
    h, w = dec.image.shape[:2]
    for name, values in layers.items():
        assert values.dtype == np.float32 and values.shape[:2] == (h, w), name
    alpha = layers["alpha"][..., None]
    np.testing.assert_allclose(layers["albedo"] * layers["shading"] + layers["residual"], layers["beauty"][..., :3],
                               atol=1e-6)
    np.testing.assert_allclose(layers["beauty"][..., :3], layers["foreground"] * alpha, atol=1e-7)
    np.testing.assert_array_equal(layers["diffuse"], layers["albedo"] * layers["shading"])
    relit = relighter.relight(dec, "night", background="transparent")  # night's own exposure included
    np.testing.assert_allclose(layers["beauty"][..., :3], relit[..., :3] * relit[..., 3:], atol=1e-7)
    np.testing.assert_array_equal(layers["alpha"], relit[..., 3])
    inside = layers["alpha"] > 0.5
    # the diffuse term explains most of the person: the residual is a correction
    assert np.abs(layers["residual"][inside]).mean() < 0.5 * layers["diffuse"][inside].mean()
    # the photo's own light through its own shading gives the photo back (where the shading is trusted)
    trusted = inside & (layers["shading_photo"].min(axis=-1) > 0.2)
    photo = dec.image[trusted]
    assert np.abs(layers["albedo"][trusted] / layers["alpha"][trusted][:, None] * layers["shading_photo"][trusted]
                  - photo).mean() < 0.01
    np.testing.assert_allclose(passes.light, relighter.layers(dec, "night").light, rtol=1e-6)


def test_normal_map_faces_the_camera(scene):
    dec, passes = scene
    normal, alpha = passes.layers["normal"], passes.layers["alpha"]
    inside = alpha > 0.5
    np.testing.assert_allclose(np.linalg.norm(normal[inside], axis=-1), 1.0, atol=1e-5)
    assert np.all(normal[alpha == 0] == 0)
    ys, xs = np.nonzero(inside)
    centre = xs.mean()
    assert normal[inside][:, 2].mean() > 0.5  # toward the camera
    left, right = xs < centre - 10, xs > centre + 10
    # the body's sides turn away to their own side
    assert normal[ys[left], xs[left], 0].mean() < 0 < normal[ys[right], xs[right], 0].mean()


@pytest.mark.parametrize("fmt", ["exr", "png16"])
def test_files_recompose_with_a_second_reader(tmp_path, scene, fmt):
    _, passes = scene
    written = write_passes(tmp_path / "out", passes, fmt)
    suffix = ".exr" if fmt == "exr" else ".png"
    assert sorted(p.name for p in written) == sorted([n + suffix for n in PASSES] + ["light.json", "light_photo.json",
                                                                                       "passes.json"])
    doc = json.loads((tmp_path / "out" / "passes.json").read_text())
    assert doc["format"] == fmt and set(doc["passes"]) == set(PASSES)
    np.testing.assert_allclose(json.loads((tmp_path / "out" / "light.json").read_text())["sh"], passes.light, rtol=1e-6)
    run = subprocess.run([sys.executable, str(REPO / "scripts" / "recompose_passes.py"), str(tmp_path / "out")],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stdout + run.stderr
    error = float(run.stdout.rsplit("=", 1)[1])
    assert error <= (1e-6 if fmt == "exr" else 1e-3)
    if fmt == "exr":  # every pass as written, through OpenEXR
        for name in PASSES:
            back = read_exr(tmp_path / "out" / f"{name}.exr")
            values = passes.layers[name]
            stacked = back["Y"] if values.ndim == 2 else np.stack([back[c] for c in "RGBA"[: values.shape[2]]], -1)
            np.testing.assert_array_equal(stacked, values)
    else:  # 16-bit, through OpenCV, with the offset and scale of passes.json
        entry = doc["passes"]["residual"]
        raw = cv2.imread(str(tmp_path / "out" / "residual.png"), cv2.IMREAD_UNCHANGED)
        assert raw.dtype == np.uint16
        back = raw[..., ::-1] / 65535 * entry["scale"] + entry["offset"]
        np.testing.assert_allclose(back, passes.layers["residual"], atol=entry["scale"] / 65535)


def test_writes_all_or_none(tmp_path, scene):
    _, passes = scene
    out = tmp_path / "out"
    out.mkdir()
    (out / "alpha.exr").write_bytes(b"an input")
    with pytest.raises(RelightError, match="refusing to overwrite"):
        write_passes(out, passes, "exr", protect=[out / "alpha.exr"])
    assert [p.name for p in out.iterdir()] == ["alpha.exr"]
    with pytest.raises(RelightError, match="format"):
        write_passes(out, passes, "tiff")
    (tmp_path / "file").write_bytes(b"")
    with pytest.raises(RelightError, match="not a folder"):
        write_passes(tmp_path / "file", passes, "exr")


@pytest.mark.parametrize("bad", [np.nan, np.inf])
@pytest.mark.parametrize("name", ["residual", "albedo"])
def test_png16_refuses_nan_as_exr_does(tmp_path, bad, name):
    """Round 6: a NaN or Inf in the residual was a ValueError out of math.ceil, in the albedo a silent 0."""
    from relight_rt.apps.render_passes import PASSES, Passes, write_passes

    layers = {n: np.zeros((4, 4, 4 if n in ("beauty", "foreground") else 3), np.float32) for n in PASSES}
    layers["alpha"] = np.zeros((4, 4), np.float32)
    layers[name][1, 1] = bad
    passes = Passes(layers, np.zeros((9, 3), np.float32), np.zeros((9, 3), np.float32))
    for fmt, match in (("png16", f"png16: the {name} pass holds NaN or Inf"), ("exr", "holds NaN or Inf")):
        with pytest.raises(RelightError, match=match):
            write_passes(tmp_path / fmt, passes, fmt)
        assert not (tmp_path / fmt).exists()  # refused before any file or folder
