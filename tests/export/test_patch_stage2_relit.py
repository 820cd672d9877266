"""export/patch_stage2_relit.py and the shipped stage-2 graphs: relit = clip(diffuse + r, 0, 1) * mask, r the
network's raw output, added before masking as the reference does (issue 34, DESIGN.md §5)."""

from __future__ import annotations

import numpy as np
import onnxruntime as ort
import pytest

from relight_rt.engine.session import bundled_models_dir

onnx = pytest.importorskip("onnx")


def sample_inputs(seed: int, size: int = 128) -> dict[str, np.ndarray]:
    """A random diffuse image and a soft elliptic mask with exact zeros and ones (as export.onnx_export's)."""
    rng = np.random.default_rng(seed)
    yy, xx = np.meshgrid(np.linspace(-1, 1, size), np.linspace(-1, 1, size), indexing="ij")
    mask = np.clip((1 - (xx / 0.7) ** 2 - (yy / 0.9) ** 2) * 8, 0, 1).astype(np.float32)[None, None]
    return {"diffuse": rng.random((1, 3, size, size), dtype=np.float32), "mask": mask}


def _session(path):
    return ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])


def _old_relit_rule(model):
    """``model`` with relit = clip(diffuse + residual, 0, 1) * mask (residual masked first): the graphs of
    before issue 34."""
    import copy

    old = copy.deepcopy(model)
    raw = next(n for n in old.graph.node if "residual" in n.output).input[0]
    add = next(n for n in old.graph.node if n.op_type == "Add" and "diffuse" in n.input and raw in n.input)
    add.input[list(add.input).index(raw)] = "residual"
    return old


@pytest.mark.parametrize("which", ["bundled", "tiny"])
def test_shipped_stage2_graphs_add_the_raw_residual(which, test_data_dir):
    """issue 34: relit = clip(diffuse + r, 0, 1) * mask with r unmasked (the reference's rule); the shipped
    graphs masked r first. residual / mask gives r back where mask > 0, so the rule is checked at soft edges."""
    path = bundled_models_dir() / "stage2.onnx" if which == "bundled" else test_data_dir / "tiny_stage2.onnx"
    inputs = sample_inputs(seed=3)
    residual, relit = _session(path).run(None, inputs)
    mask = inputs["mask"]
    soft = (mask > 0) & (mask < 1)
    assert soft.mean() > 0.05
    r = np.divide(residual, mask, out=np.zeros_like(residual), where=np.broadcast_to(mask > 0, residual.shape))
    np.testing.assert_allclose(relit, np.clip(inputs["diffuse"] + r, 0, 1) * mask, atol=1e-5)


def test_patch_script_rewires_an_old_graph_and_changes_relit_only_at_soft_edges(test_data_dir, tmp_path, capsys):
    from export.patch_stage2_relit import check, main, patch_model

    new = onnx.load(str(test_data_dir / "tiny_stage2.onnx"))
    old = _old_relit_rule(new)
    onnx.save(old, str(tmp_path / "old.onnx"))
    assert main([str(tmp_path / "old.onnx"), "--out", str(tmp_path / "new.onnx")]) == 0
    out = capsys.readouterr().out
    assert "relit max |diff| where mask is 0 or 1: 0" in out and "wrote" in out
    patched = onnx.load(str(tmp_path / "new.onnx"))
    assert list(patched.graph.node) == list(new.graph.node)  # what the fixed exporter makes (make_test_models)
    assert list(patched.metadata_props) == list(new.metadata_props)
    figures = check(old, patched)
    assert figures["relit max |diff| at soft edges"] > 1e-3  # the patch changes something, there only
    assert patch_model(patched)[1] is False  # a patched graph is left as it is
    assert main([str(tmp_path / "new.onnx")]) == 0 and "already" in capsys.readouterr().out
