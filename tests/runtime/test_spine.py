"""The runtime's one spine (issue 25): RuntimeConfig, the kinds registry, typed lights and backgrounds,
the mask resolver, plain-data decompositions and decompose_batch."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from _graphs import OWN_LIGHT, models_dir, person  # noqa: F401

import relight_rt
from relight_rt import (
    Background,
    Decomposition,
    LightSpec,
    Relighter,
    RelightError,
    RuntimeConfig,
    envmap,
    lightfile,
    lights,
    sh,
)
from relight_rt.engine.contract import KINDS, KindSpec, ModelConfig, TensorSpec, config_from_metadata, register_kind
from relight_rt.image.compositing import parse_background
from relight_rt.light.spec import parse_light
from relight_rt.person.masks import resolve_mask
from relight_rt.relight.decomposition import intrinsic_layers


@pytest.fixture(scope="module")
def relighter(models_dir):  # noqa: F811
    return Relighter(RuntimeConfig(models=models_dir, device="cpu"))


# ------------------------------------------------------------------------------ RuntimeConfig


def test_runtime_config_pickles_and_is_checked(tmp_path):
    cfg = RuntimeConfig(models=tmp_path, device="cpu", precision="int8", preprocess="reference", detail=False)
    back = pickle.loads(pickle.dumps(cfg))
    assert back == cfg and back.models == str(tmp_path)
    assert cfg.replace(device="auto").device == "auto" and cfg.device == "cpu"
    for bad, match in ((dict(device="tpu"), "device"), (dict(precision="fp8"), "precision"),
                       (dict(preprocess="nearest"), "preprocess"), (dict(matting="maybe"), "matting"),
                       (dict(device_id=-1), "device_id"), (dict(detail="yes"), "detail")):
        with pytest.raises(RelightError, match=match):
            RuntimeConfig(**bad)


def test_open_uses_every_field(models_dir):  # noqa: F811
    cfg = RuntimeConfig(models=str(models_dir), device="cpu", preprocess="reference", detail=False, matting="off")
    r = relight_rt.open(cfg)
    assert r.config == cfg
    assert (r.preprocess, r.detail, r.matter) == ("reference", False, None)
    assert relight_rt.open(cfg.replace(matting="auto")).matter is not None  # the bundled matte, handed in
    with pytest.raises(RelightError, match="RuntimeConfig"):
        relight_rt.open({"device": "cpu"})


# ------------------------------------------------------------------------------ Decomposition: plain data


def test_decomposition_pickles_and_relights_the_same(relighter):
    img, mask = person(seed=11)
    dec = relighter.decompose(img, mask)
    back = pickle.loads(pickle.dumps(dec))
    assert isinstance(back, Decomposition) and back is not dec
    for name in ("albedo_chw", "transport_chw", "skin", "light", "network_mask", "network_image", "mask", "image"):
        np.testing.assert_array_equal(getattr(back, name), getattr(dec, name))
        assert not getattr(back, name).flags.writeable, name
    assert back.geometry == dec.geometry
    light = lights.preset("window-left")
    np.testing.assert_array_equal(relighter.relight(back, light), relighter.relight(dec, light))
    assert not hasattr(dec, "_cache")


def test_decompose_batch_equals_decompose_one_by_one(relighter):
    pairs = [person(seed=s) for s in (1, 2)]
    batch = relighter.decompose_batch([p[0] for p in pairs], [p[1] for p in pairs])
    for (img, mask), dec in zip(pairs, batch, strict=True):
        one = relighter.decompose(img, mask)
        np.testing.assert_allclose(dec.albedo_chw, one.albedo_chw, atol=1e-6)
        np.testing.assert_allclose(dec.light, one.light, atol=1e-6)
    with pytest.raises(RelightError, match="one per image"):
        relighter.decompose_batch([pairs[0][0]], [])


# ------------------------------------------------------------------------------ masks


def test_mask_resolver_order():
    img = np.full((20, 30, 4), 0.5, np.float32)
    img[..., 3] = 0
    img[5:15, 10:20, 3] = 1  # the alpha's person
    given = np.zeros((20, 30), np.float32)
    given[2:8, 2:8] = 1

    class Matte:
        calls = 0

        def __call__(self, rgb, name="image"):
            Matte.calls += 1
            assert rgb.shape == (20, 30, 3)
            out = np.zeros(rgb.shape[:2], np.float32)
            out[10:20, 0:5] = 1
            return out

    matte = Matte()
    np.testing.assert_array_equal(resolve_mask(img, given, matter=matte), given)  # a given mask wins
    np.testing.assert_array_equal(resolve_mask(img, None, matter=matte), img[..., 3])  # then alpha
    assert Matte.calls == 0
    auto = resolve_mask(img[..., :3], None, matter=matte)  # then the matte
    assert auto[15, 2] == 1 and auto[0, 0] == 0 and Matte.calls == 1
    forced = resolve_mask(img, "auto", matter=matte)  # "auto" wins over alpha
    np.testing.assert_array_equal(forced, auto)
    with pytest.raises(RelightError, match="--mask FILE in the CLI, mask= in the API"):
        resolve_mask(img[..., :3], None)
    with pytest.raises(RelightError, match="no automatic matting model"):
        resolve_mask(img, "auto")
    with pytest.raises(RelightError, match="automatic matte returned"):
        resolve_mask(img[..., :3], None, matter=lambda rgb, name: np.zeros((3, 3), np.float32))


def test_an_alpha_opaque_everywhere_is_no_mask():
    """An RGBA photo whose alpha has no transparent pixel (as editors and screenshots save them) was refused
    with "mask covers the whole image"; it says nothing of the person, so the automatic matte decides."""
    rgba = np.ones((20, 10, 4), np.float32)
    rgba[..., :3] = 0.4
    matte = np.zeros((20, 10), np.float32)
    matte[5:15, 3:7] = 1
    np.testing.assert_array_equal(resolve_mask(rgba, None, matter=lambda rgb, name: matte.copy()), matte)
    with pytest.raises(RelightError, match="opaque everywhere"):
        resolve_mask(rgba, None)
    rgba[0, 0, 3] = 0.0  # one transparent pixel: the alpha is the mask, as before
    np.testing.assert_array_equal(resolve_mask(rgba, None, matter=lambda rgb, name: matte.copy()), rgba[..., 3])


def test_soft_mask_values_survive_and_video_masks_may_be_empty():
    img = np.zeros((10, 10, 3), np.float32)
    soft = np.linspace(0, 1, 100, dtype=np.float32).reshape(10, 10)
    np.testing.assert_allclose(resolve_mask(img, soft), soft)  # soft stays soft (no threshold)
    with pytest.raises(RelightError, match="empty"):
        resolve_mask(img, np.zeros((10, 10), np.float32))
    assert not resolve_mask(img, np.zeros((10, 10), np.float32), allow_empty=True).any()


# ------------------------------------------------------------------------------ lights


def test_light_spec_sources_and_rotation(tmp_path):
    studio = lights.preset("studio")
    np.testing.assert_allclose(LightSpec.preset("studio").resolve(), studio, atol=1e-6)
    turned = LightSpec.preset("studio", rotate=90).resolve()
    np.testing.assert_allclose(turned, sh.rotate_z(studio, np.pi / 2), atol=1e-6)
    assert LightSpec.preset("studio").rotated(30).rotated(60).rotate == 90
    lightfile.save_light(tmp_path / "l.npy", studio)
    bgr = LightSpec.file(tmp_path / "l.npy", bgr=True).resolve()
    np.testing.assert_allclose(bgr, studio[:, ::-1], atol=1e-6)  # columns swapped
    assert LightSpec.file(tmp_path / "l.npy").paths == (str(tmp_path / "l.npy"),)
    with pytest.raises(RelightError, match="stage-1 model"):
        LightSpec.photo(tmp_path / "p.png").resolve()
    with pytest.raises(RelightError, match="bgr"):
        LightSpec.preset("studio", rotate=0).__class__("preset", "studio", bgr=True)
    with pytest.raises(RelightError, match="finite"):
        LightSpec.preset("studio", rotate=float("nan"))


def test_one_string_rule_for_photos_and_video(tmp_path, relighter):
    import cv2

    from relight_rt.video import job as video

    env = np.clip(envmap.envmap_from_light(lights.preset("rim"), 16), 0, 1)
    cv2.imwrite(str(tmp_path / "sky.png"), (env[..., ::-1] * 255).astype(np.uint8))  # 2:1, an env map
    img, mask = person(seed=5)
    cv2.imwrite(str(tmp_path / "someone.png"), (img[..., ::-1] * 255).astype(np.uint8))
    cv2.imwrite(str(tmp_path / "someone_mask.png"), (mask * 255).astype(np.uint8))
    assert parse_light(tmp_path / "sky.png").source == "envmap"
    assert parse_light(tmp_path / "someone.png").source == "photo"
    assert parse_light("studio").source == "preset"
    # the two entry points agree on the same string
    np.testing.assert_allclose(relighter.resolve_light(str(tmp_path / "sky.png")),
                               video.resolve_light(str(tmp_path / "sky.png")), atol=1e-6)
    np.testing.assert_allclose(relighter.resolve_light(str(tmp_path / "someone.png")),
                               video.resolve_light(str(tmp_path / "someone.png"), relighter), atol=1e-6)
    with pytest.raises(RelightError, match="not found"):
        parse_light("missing.npy")


@pytest.mark.parametrize("text", ["../etc/passwd", "/etc/hosts", "light.npy", "sky.hdr", "a/b", "C:\\x.npy",
                                  "no-such-preset", ""])
def test_server_facing_parser_refuses_paths(text, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    lightfile.save_light(tmp_path / "light.npy", lights.preset("studio"))  # even an existing file is refused
    with pytest.raises(RelightError):
        parse_light(text, allow_paths=False)
    assert parse_light("studio", allow_paths=False).source == "preset"
    with pytest.raises(RelightError, match="file path"):
        parse_background(Background.from_image(str(tmp_path / "light.npy")), allow_paths=False)
    with pytest.raises(RelightError):
        parse_background(str(tmp_path / "light.npy"), allow_paths=False)


# ------------------------------------------------------------------------------ backgrounds


def test_background_kinds_and_fits(relighter):
    img, mask = person(seed=6)
    dec = relighter.decompose(img, mask)
    light = lights.preset("front")
    black = relighter.relight(dec, light, background="black")
    assert not black[mask == 0].any()
    teal = relighter.relight(dec, light, background="#008080")
    np.testing.assert_allclose(teal[mask == 0], np.broadcast_to([0, 128 / 255, 128 / 255], teal[mask == 0].shape),
                               atol=1e-6)
    orig = relighter.relight(dec, light)
    inside = mask == 1
    np.testing.assert_array_equal(black[inside], orig[inside])  # the person does not depend on the background
    wide = np.zeros((10, 40, 3), np.float32)
    wide[:, 20:] = 1
    contain = relighter.relight(dec, light, background=Background.from_image(wide, "contain"))
    assert not contain[0, 50].any() and contain[75, 99].max() == 1  # letterboxed top, image at mid-right
    with pytest.raises(RelightError, match="fit"):
        Background("image", image=wide, fit="tile")
    with pytest.raises(RelightError, match="colour"):
        Background.solid((2, 0, 0))


# ------------------------------------------------------------------------------ kinds, declared once


def test_a_new_kind_is_one_registration(tmp_path):
    onnx = pytest.importorskip("onnx")
    from onnx import TensorProto, helper

    from relight_rt.engine.session import load_model

    spec = register_kind(KindSpec("test_matte", inputs=(TensorSpec("image", 4, 3),),
                                  outputs=(TensorSpec("alpha", 4, 1),), fixed_size=True,
                                  filename="test_matte.onnx", metadata=()))
    try:
        cfg = ModelConfig(kind="test_matte", resolution=32, norm="", source="tests")
        meta = cfg.metadata()
        assert "relight_rt.norm" not in meta and "relight_rt.sh_degree" not in meta  # not carried when meaningless
        assert config_from_metadata(meta).kind == "test_matte"
        graph = helper.make_graph(
            [helper.make_node("ReduceMean", ["image"], ["alpha"], axes=[1], keepdims=1)], "m",
            [helper.make_tensor_value_info("image", TensorProto.FLOAT, ["N", 3, 32, 32])],
            [helper.make_tensor_value_info("alpha", TensorProto.FLOAT, ["N", 1, 32, 32])])
        model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
        model.ir_version = 8
        for k, v in meta.items():
            model.metadata_props.add(key=k, value=v)
        onnx.save(model, str(tmp_path / spec.filename))
        m = load_model(tmp_path / spec.filename, "test_matte", device="cpu", warmup=True)  # validation + warm-up
        out = m.run({"image": np.ones((1, 3, 32, 32), np.float32)})["alpha"]
        assert out.shape == (1, 1, 32, 32) and np.allclose(out, 1)
        with pytest.raises(RelightError, match="already registered"):
            register_kind(KindSpec("test_matte", inputs=(), outputs=(), fixed_size=True, filename="x.onnx"))
    finally:
        KINDS.pop("test_matte", None)


# ------------------------------------------------------------------------------ full-resolution layers (issue 22)


def test_layers_have_the_photos_size_and_detail(relighter):
    import cv2

    h, w = 300, 200  # larger than the network's 64 px square: the detail has to come from the photo
    rng = np.random.default_rng(3)
    img = (0.3 + 0.5 * rng.random((h, w, 3))).astype(np.float32)  # per-pixel texture
    mask = np.zeros((h, w), np.float32)
    mask[40:260, 50:150] = 1
    dec = relighter.decompose(img, mask)
    layers = intrinsic_layers(dec)
    assert layers["albedo"].shape == (h, w, 3) and layers["skin"].shape == (h, w)
    inside = cv2.erode(mask, np.ones((9, 9), np.uint8)) > 0
    # the photo is explained: albedo x shading gives it back where nothing clips
    recon = layers["albedo"] * layers["shading"]
    np.testing.assert_allclose(recon[inside], img[inside], atol=2e-3)
    # and the albedo carries the photo's pixel-level texture, which the 64 px network albedo cannot
    up = dec.to_input(np.ascontiguousarray(dec.albedo))
    lap = lambda a: np.abs(cv2.Laplacian(a, cv2.CV_32F))[inside].mean()  # noqa: E731
    assert lap(layers["albedo"]) > 3 * lap(up)
    assert not layers["albedo"][mask == 0].any() and not layers["shading"][mask == 0].any()
