"""The default models shipped inside the package (models/README.md is their card).

They must load with no model folder given, satisfy the contract, stay within the 25 MB budget, and
relight a rendered person (the bundled example, seen under another light by the renderer: a
ground-truth relit photo in tests/data) with a lower error than trivial baselines.
"""

import numpy as np
import pytest

from relight_rt import Relighter, RuntimeConfig, load_light
from relight_rt.cli.demo import example_path
from relight_rt.engine.session import bundled_models_dir, find_models, load_model
from relight_rt.image.io import read_image
from relight_rt.light.sh import basis, cosine_lobe

BUDGET_BYTES = 25 * 1000 * 1000


@pytest.fixture(scope="module")
def relighter():
    return Relighter(RuntimeConfig(models=bundled_models_dir(), device="cpu"))


def test_bundled_models_are_found_without_a_folder(monkeypatch):
    monkeypatch.delenv("RELIGHT_RT_MODELS", raising=False)
    assert find_models() == bundled_models_dir()


def test_bundled_models_satisfy_the_contract_and_budget():
    folder = bundled_models_dir()
    stage1 = load_model(folder / "stage1.onnx", "stage1", device="cpu")
    stage2 = load_model(folder / "stage2.onnx", "stage2", device="cpu")
    assert stage1.config.resolution in (128, 256, 512) and stage1.config.color == "RGB"
    assert stage2.config.resolution in (0, stage1.config.resolution)
    # the relighting graphs; with the matting graphs everything stays within 40 MB
    # (tests/runtime/person/matting/test_matting.py)
    total = sum(p.stat().st_size for p in folder.glob("stage*.onnx"))
    assert total <= BUDGET_BYTES, f"bundled relighting models take {total / 1e6:.1f} MB, budget 25 MB"


def test_bundled_models_relight_better_than_trivial(relighter, test_data_dir):
    src = read_image(example_path(), "example")  # photo under light L0 (RGBA, alpha = mask)
    target = read_image(test_data_dir / "example_L1.png", "example_L1")  # the same person under L1
    l0 = load_light(test_data_dir / "example_L0_light.json")
    l1 = load_light(test_data_dir / "example_L1_light.json")
    inside = src[..., 3] > 0.5

    def rmse(image):
        return float(np.sqrt(np.mean((image[inside] - target[..., :3][inside]) ** 2)))

    black = np.zeros(src.shape[:2] + (3,), np.float32)
    relit = relighter.relight(src, l1, background=black, exposure="physical")  # the true light's own intensity
    assert relit.shape == src.shape[:2] + (3,)
    # Baselines: the photo left as it is, and a flat person (mean colour) whose brightness follows
    # the true old -> new irradiance ratio of a camera-facing normal (it even knows the true old light).
    front = cosine_lobe() * basis(np.array([1.0, 0.0, 0.0]))
    ratio = np.maximum(front @ l1, 1e-3) / np.maximum(front @ l0, 1e-3)
    flat = np.broadcast_to(src[..., :3][inside].mean(0) * ratio, src[..., :3].shape)
    ours, unchanged, trivial = rmse(relit), rmse(src[..., :3]), rmse(flat)
    # Measured with the shipped 256² models: ours 0.115, unchanged 0.151, trivial 0.167.
    assert ours < 0.85 * unchanged, (ours, unchanged)
    assert ours < 0.85 * trivial, (ours, trivial)


def test_bundled_light_estimate_is_informative(relighter, test_data_dir):
    l0 = load_light(test_data_dir / "example_L0_light.json")
    l1 = load_light(test_data_dir / "example_L1_light.json")
    dec = relighter.decompose(example_path())
    err_true = np.sqrt(np.mean((dec.light - l0) ** 2))
    err_other = np.sqrt(np.mean((dec.light - l1) ** 2))
    assert err_true < err_other, (err_true, err_other)  # it recognises the light the photo was taken in


def test_bundled_stage2_records_its_output_activation():
    """The bundled stage 2 has no output activation, as the reference's (the one before it ended in a tanh, a
    training option): its metadata says so, and the graph has no Tanh."""
    path = bundled_models_dir() / "stage2.onnx"
    meta = load_model(path, "stage2", device="cpu").session.get_modelmeta().custom_metadata_map
    assert meta.get("relight_rt.output_activation") == "none"
    onnx = pytest.importorskip("onnx")
    ops = [n.op_type for n in onnx.load(str(path)).graph.node]
    assert ops.count("Tanh") == 0
