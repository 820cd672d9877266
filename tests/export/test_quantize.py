"""export.quantize: int8 QDQ copy of a contract graph behind a PSNR gate (tiny committed graphs, no torch)."""

import numpy as np
import onnxruntime as ort
import pytest

pytest.importorskip("onnx")
pytest.importorskip("onnxruntime.quantization")

from export.quantize import psnr, quantize  # noqa: E402
from relight_rt import RelightError  # noqa: E402
from relight_rt.cli.bench import network_inputs  # noqa: E402


def feeds(n, seed=0):
    return [network_inputs("stage2", 1, 64, seed=seed + i) for i in range(n)]


def test_quantize_writes_a_contract_graph_with_int8_convs(test_data_dir, tmp_path):
    out = tmp_path / "stage2_int8.onnx"
    summary = quantize(test_data_dir / "tiny_stage2.onnx", out, feeds(3), feeds(2, seed=10), min_psnr=20)
    assert out.is_file() and summary["kind"] == "stage2" and summary["quantized_convs"] > 0
    assert set(summary["psnr"]) == {"residual", "relit"} and min(summary["psnr"].values()) >= 20
    session = ort.InferenceSession(str(out), providers=["CPUExecutionProvider"])
    meta = session.get_modelmeta().custom_metadata_map
    assert meta["relight_rt.kind"] == "stage2" and "int8" in meta["relight_rt.source"]
    assert [i.name for i in session.get_inputs()] == ["diffuse", "mask"]
    assert list(tmp_path.iterdir()) == [out]  # no temporary left behind


def test_gate_refuses_and_writes_nothing(test_data_dir, tmp_path):
    out = tmp_path / "stage2_int8.onnx"
    with pytest.raises(RelightError, match="under 1000 dB; nothing written"):
        quantize(test_data_dir / "tiny_stage2.onnx", out, feeds(2), feeds(1, seed=10), min_psnr=1000)
    assert list(tmp_path.iterdir()) == []


def test_feeds_must_match_the_graph(test_data_dir, tmp_path):
    wrong = [network_inputs("stage1", 1, 64)]
    with pytest.raises(RelightError, match=r"calibration\[0\]: expected inputs \['diffuse', 'mask'\]"):
        quantize(test_data_dir / "tiny_stage2.onnx", tmp_path / "x.onnx", wrong, feeds(1))
    with pytest.raises(RelightError, match="held_out: expected at least one input"):
        quantize(test_data_dir / "tiny_stage2.onnx", tmp_path / "x.onnx", feeds(1), [])


def test_psnr_values():
    a = np.array([0.0, 1.0, 0.5], np.float32)
    assert psnr(a, a) == np.inf
    assert psnr(a, a + 0.1) == pytest.approx(20.0)  # peak 1, mse 0.01
    assert psnr(a, np.array([0, np.nan, 0], np.float32)) == -np.inf


def test_stage1_light_stays_exactly_fp32(test_data_dir, tmp_path):
    """KEEP_FP32 leaves every conv that the light depends on in fp32, and no quantised tensor reaches it."""
    cal = [network_inputs("stage1", 1, 128, seed=i) for i in range(2)]
    held = [network_inputs("stage1", 1, 128, seed=10)]
    summary = quantize(test_data_dir / "tiny_stage1.onnx", tmp_path / "s1.onnx", cal, held, min_psnr=20)
    assert summary["psnr"]["light"] == np.inf
    assert summary["quantized_convs"] > 0 and summary["fp32_convs"] > 0
