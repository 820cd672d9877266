"""comfyui/: the node classes as ComfyUI calls them (its node interface and tensor conventions), without ComfyUI.

The nodes' answers must be relight_rt's: the Relight node's image equals ``Relighter.relight`` of the same
photo, light and exposure, and the Light node's light equals what the runtime resolves for the same source.
"""

import math

import numpy as np
import pytest

torch = pytest.importorskip("torch")

import comfyui  # noqa: E402
import relight_rt  # noqa: E402
from comfyui.nodes import LIGHT_SOURCES, RelightLight  # noqa: E402
from relight_rt import LightSpec, RelightError, lights, save_light  # noqa: E402
from relight_rt.image.io import read_image  # noqa: E402

NODES = comfyui.NODE_CLASS_MAPPINGS
COMFY_TYPES = {"IMAGE", "MASK", "STRING", "FLOAT", "INT", "BOOLEAN"}
OWN_TYPES = {"RELIGHT_MODELS", "RELIGHT_DECOMPOSITION", "RELIGHT_LIGHT"}
LIGHT_ARGS = dict(file="", rotation=0.0, lamp_azimuth=45.0, lamp_elevation=30.0, lamp_color="#ffffff",
                  lamp_intensity=1.0, lamp_size=10.0, fov=60.0)


def test_every_node_has_comfyuis_interface():
    assert set(comfyui.NODE_DISPLAY_NAME_MAPPINGS) == set(NODES)
    assert all(name.startswith("RelightRT") for name in NODES)  # one global namespace in ComfyUI
    for name, cls in NODES.items():
        spec = cls.INPUT_TYPES()
        assert set(spec) <= {"required", "optional"} and spec["required"], name
        assert isinstance(cls.RETURN_TYPES, tuple) and len(cls.RETURN_NAMES) == len(cls.RETURN_TYPES), name
        assert set(cls.RETURN_TYPES) <= COMFY_TYPES | OWN_TYPES, name
        assert callable(getattr(cls, cls.FUNCTION)) and cls.CATEGORY == "relight_rt", name
        for group in spec.values():
            for field, (kind, *options) in group.items():
                if isinstance(kind, list):  # a combo: its default must be one of its choices
                    assert options and options[0]["default"] in kind, (name, field)
                else:
                    assert kind in COMFY_TYPES | OWN_TYPES, (name, field)


def test_preset_light_keeps_its_name_and_rotation():
    spec, preview = RelightLight().make("preset", "night", **{**LIGHT_ARGS, "rotation": 30.0})
    assert spec.source == "preset" and spec.value == "night" and spec.rotate == 30.0
    assert tuple(preview.shape) == (1, 128, 128, 3) and preview.dtype == torch.float32
    assert 0.0 <= float(preview.min()) and float(preview.max()) == pytest.approx(1.0)


def test_lamp_comes_from_its_azimuth_and_elevation():
    spec = RelightLight.spec("lamp", "studio", **{**LIGHT_ARGS, "lamp_azimuth": 90.0, "lamp_elevation": 0.0,
                                                   "lamp_color": "1, 0.5, 0.25", "lamp_size": 0.0})
    expected = lights.directional((0.0, 1.0, 0.0), (1.0, 0.5, 0.25), 1.0, 0.0)  # +y: from the image's right
    np.testing.assert_allclose(spec.resolve(dtype=np.float64), expected, atol=1e-12)
    above = RelightLight.spec("lamp", "studio", **{**LIGHT_ARGS, "lamp_elevation": 90.0, "lamp_color": "#ff8000"})
    light = above.resolve(dtype=np.float64)
    assert light[2, 0] > 0 and abs(light[1, 0]) < 1e-9 and abs(light[3, 0]) < 1e-9  # along +z only
    np.testing.assert_allclose(light[:, 1] / light[:, 0], 128 / 255, atol=1e-9)


def test_file_lights(tmp_path, monkeypatch):
    light = lights.preset("golden-hour")
    save_light(tmp_path / "l.npy", light)
    monkeypatch.chdir(tmp_path)  # outside ComfyUI a relative name is taken from the working folder
    spec = RelightLight.spec("sh_file", "studio", **{**LIGHT_ARGS, "file": "l.npy", "rotation": 90.0})
    assert spec.source == "file" and spec.rotate == 90.0
    np.testing.assert_allclose(spec.resolve(), LightSpec.file(tmp_path / "l.npy", rotate=90).resolve())
    with pytest.raises(RelightError, match="not found"):
        RelightLight.spec("hdr_panorama", "studio", **{**LIGHT_ARGS, "file": "missing.hdr"})
    with pytest.raises(RelightError, match="empty field"):
        RelightLight.spec("sh_file", "studio", **LIGHT_ARGS)


@pytest.mark.parametrize(
    ("source", "changes", "match"),
    [
        ("lamp", {"lamp_color": "orange"}, "#RRGGBB"),
        ("lamp", {"lamp_color": "1, -1, 0"}, "#RRGGBB"),
        ("photo", {}, "connect the models"),
        ("sunlight", {}, "expected one of"),
    ],
)
def test_bad_lights_are_refused(source, changes, match):
    with pytest.raises(RelightError, match=match):
        RelightLight.spec(source, "studio", **{**LIGHT_ARGS, **changes})
    assert source in LIGHT_SOURCES or match == "expected one of"


# ------------------------------------------------------------------------------------ with the bundled models


@pytest.fixture(scope="module")
def models():
    (relighter,) = NODES["RelightRTLoadModels"]().load("", "cpu", "fp32", "auto", True)
    return relighter


@pytest.fixture(scope="module")
def photo():
    from pathlib import Path

    import cv2

    path = Path(__file__).resolve().parents[2] / "relight_rt" / "data" / "example_scene.jpg"
    image = read_image(path)
    return cv2.resize(image, (image.shape[1] // 2, image.shape[0] // 2), interpolation=cv2.INTER_AREA)


@pytest.fixture(scope="module")
def decomposed(models, photo):
    batch = torch.from_numpy(np.stack([photo, photo[:, ::-1]]))  # two images: the photo and its mirror image
    return batch, NODES["RelightRTDecompose"]().decompose(models, batch)


def test_decompose_returns_comfyui_batches(decomposed, photo):
    batch, (decs, albedo, shading, mask) = decomposed
    h, w = photo.shape[:2]
    assert len(decs) == 2
    for t, shape in ((albedo, (2, h, w, 3)), (shading, (2, h, w, 3)), (mask, (2, h, w))):
        assert t.dtype == torch.float32 and tuple(t.shape) == shape
        assert 0.0 <= float(t.min()) and float(t.max()) <= 1.0
    assert float(mask.mean()) > 0.05  # the automatic matte found the person
    a, b = mask[0].numpy() > 0.5, mask[1].numpy()[:, ::-1] > 0.5  # the mirrored photo's matte, mirrored back
    assert (a & b).sum() / (a | b).sum() > 0.9


def test_relight_node_is_the_runtimes_relight(models, decomposed):
    _, (decs, *_) = decomposed
    light, _ = RelightLight().make("preset", "night", **LIGHT_ARGS)
    image, mask = NODES["RelightRTRelight"]().relight(models, decs, light, "auto", 0.0)
    assert image.dtype == torch.float32 and tuple(image.shape) == (2, *decs[0].image.shape)
    for i, dec in enumerate(decs):
        np.testing.assert_array_equal(image[i].numpy(), models.relight(dec, "night"))  # night's own exposure too
        np.testing.assert_array_equal(mask[i].numpy(), dec.mask)
    brighter, _ = NODES["RelightRTRelight"]().relight(models, decs[:1], light, "auto", 1.0)
    person = decs[0].mask > 0.5
    assert float(brighter[0].numpy()[person].mean()) > float(image[0].numpy()[person].mean())


def test_decompose_takes_a_given_mask(models, photo):
    h, w = photo.shape[:2]
    mask = np.zeros((h, w), np.float32)
    mask[h // 8 : h - h // 8, w // 3 : 2 * w // 3] = 1.0
    decs, _, _, out = NODES["RelightRTDecompose"]().decompose(models, torch.from_numpy(photo[None]),
                                                             torch.from_numpy(mask))
    np.testing.assert_array_equal(out[0].numpy(), mask)  # a given mask wins over the automatic matte
    with pytest.raises(RelightError, match="64x64"):
        NODES["RelightRTDecompose"]().decompose(models, torch.from_numpy(photo[None]), torch.zeros(64, 64))


def test_light_of_a_photo_is_stage_ones_estimate(models, decomposed, photo):
    _, (decs, *_) = decomposed
    spec = RelightLight.spec("photo", "studio", **{**LIGHT_ARGS, "rotation": 0.0}, models=models,
                             image=torch.from_numpy(photo[None]))
    np.testing.assert_allclose(spec.resolve(), decs[0].white_light, atol=1e-6)


def test_light_of_a_background(photo):
    from relight_rt.light.from_background import light_from_background

    spec = RelightLight.spec("background", "studio", **{**LIGHT_ARGS, "fov": 70.0}, image=torch.from_numpy(photo[None]))
    np.testing.assert_allclose(spec.resolve(), light_from_background(photo, 70.0)[0], atol=1e-6)


def test_relight_over_a_new_background(models, decomposed):
    _, (decs, *_) = decomposed
    light, _ = RelightLight().make("preset", "studio", **LIGHT_ARGS)
    h, w = decs[0].image.shape[:2]
    green = torch.zeros(1, h, w, 3)
    green[..., 1] = 1.0
    image, _ = NODES["RelightRTRelight"]().relight(models, decs, light, "physical", 0.0, green)
    outside = decs[0].mask == 0
    assert outside.any()
    np.testing.assert_array_equal(image[0].numpy()[outside], np.array([0.0, 1.0, 0.0], np.float32)[None].repeat(
        outside.sum(), 0))
    assert not math.isnan(float(image.mean()))


def test_composite_node_is_the_runtimes_composite(models, photo):
    import cv2

    backdrop = np.ascontiguousarray(cv2.resize(photo, (320, 240), interpolation=cv2.INTER_AREA)[::-1, ::-1])
    node = NODES["RelightRTComposite"]()
    (image,) = node.composite(models, torch.from_numpy(photo[None]), torch.from_numpy(backdrop[None]), 0.0, 60.0,
                              True, 0.8, 0.5, 0.95)
    assert image.dtype == torch.float32 and tuple(image.shape) == (1, 240, 320, 3)
    expected = relight_rt.scene.composite(models, photo, backdrop, light=None, position=(0.5, 0.95), height=0.8,
                                          shadow=True)
    np.testing.assert_array_equal(image[0].numpy(), expected)
    with pytest.raises(RelightError, match="both"):
        node.composite(models, torch.from_numpy(photo[None]), torch.from_numpy(backdrop[None]), 0.0, 60.0, True,
                       0.0, 0.5, -1.0)


def test_a_changed_light_file_runs_the_node_again(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    save_light(tmp_path / "l.npy", lights.preset("studio"))
    before = RelightLight.IS_CHANGED(source="sh_file", file="l.npy", preset="studio", rotation=0.0)
    import os

    os.utime(tmp_path / "l.npy", ns=(1, 1))
    assert RelightLight.IS_CHANGED(source="sh_file", file="l.npy", preset="studio", rotation=0.0) != before
    assert RelightLight.IS_CHANGED(source="preset", file="", preset="night") == ""


class _FakeComfy:
    """comfy.utils.ProgressBar and comfy.model_management's interrupt check, as the nodes use them in ComfyUI."""

    def __init__(self, interrupt_after: int | None = None):
        self.updates, self.checks, self.total, self.interrupt_after = 0, 0, None, interrupt_after
        fake = self

        class ProgressBar:
            def __init__(self, total):
                fake.total = total

            def update(self, value):
                fake.updates += value

        def throw_exception_if_processing_interrupted():
            fake.checks += 1
            if fake.interrupt_after is not None and fake.checks > fake.interrupt_after:
                raise InterruptedError("interrupted")

        import types

        self.utils = types.SimpleNamespace(ProgressBar=ProgressBar)
        self.management = types.SimpleNamespace(
            throw_exception_if_processing_interrupted=throw_exception_if_processing_interrupted)
        self.package = types.SimpleNamespace(utils=self.utils, model_management=self.management)

    def install(self, monkeypatch):
        import sys

        monkeypatch.setitem(sys.modules, "comfy", self.package)
        monkeypatch.setitem(sys.modules, "comfy.utils", self.utils)
        monkeypatch.setitem(sys.modules, "comfy.model_management", self.management)


def test_progress_and_interrupt_inside_comfyui(models, decomposed, monkeypatch):
    _, (decs, *_) = decomposed
    light, _ = RelightLight().make("preset", "studio", **LIGHT_ARGS)
    fake = _FakeComfy()
    fake.install(monkeypatch)
    NODES["RelightRTRelight"]().relight(models, decs, light, "auto", 0.0)
    assert fake.total == 2 and fake.updates == 2 and fake.checks == 2  # one step per image of the batch
    stop = _FakeComfy(interrupt_after=1)
    stop.install(monkeypatch)
    with pytest.raises(InterruptedError):
        NODES["RelightRTRelight"]().relight(models, decs, light, "auto", 0.0)
    assert stop.updates == 1  # the second image was not relit


def test_passes_node_encodes_the_passes_for_comfyui(models, decomposed):
    from relight_rt.apps.render_passes import compute_passes

    _, (decs, *_) = decomposed
    light, _ = RelightLight().make("preset", "rim", **LIGHT_ARGS)
    normal, albedo, shading, residual, alpha = NODES["RelightRTPasses"]().passes(models, decs, light, "auto", 0.0)
    h, w = decs[0].image.shape[:2]
    for image in (normal, albedo, shading, residual):
        assert image.dtype == torch.float32 and tuple(image.shape) == (2, h, w, 3)
        assert 0.0 <= float(image.min()) and float(image.max()) <= 1.0
    layers = compute_passes(models, decs[1], "rim").layers
    np.testing.assert_allclose(normal[1].numpy(), 0.5 + 0.5 * layers["normal"], atol=1e-6)
    np.testing.assert_allclose(residual[1].numpy(), np.clip(0.5 + layers["residual"], 0, 1), atol=1e-6)
    np.testing.assert_array_equal(alpha[1].numpy(), layers["alpha"])
    outside = layers["alpha"] == 0
    np.testing.assert_allclose(normal[1].numpy()[outside], 0.5)  # grey off the person
