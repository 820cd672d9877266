"""benchmarks/stage1_mix.py: one stage-1 graph's albedo and skin with another's transport and light."""

import numpy as np
import pytest

torch = pytest.importorskip("torch")


def _graph(path, seed):
    from export.networks import Stage1Net
    from export.onnx_export import export_onnx

    torch.manual_seed(seed)
    net = Stage1Net(width=4, resolution=64, norm="batch")
    with torch.no_grad():  # norms away from their defaults: two graphs whose outputs differ everywhere
        for m in net.modules():
            if isinstance(m, torch.nn.BatchNorm2d):
                m.weight.uniform_(0.5, 1.5)
                m.bias.uniform_(-0.2, 0.2)
    export_onnx(net.eval(), path, source=f"test {seed}")
    return path


def _run(path, feed):
    import onnxruntime as ort

    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    return dict(zip([o.name for o in session.get_outputs()], session.run(None, feed), strict=True))


def test_the_mix_takes_albedo_and_skin_from_one_graph_and_transport_and_light_from_the_other(load_benchmark,
                                                                                            tmp_path):
    import onnx

    sm = load_benchmark("stage1_mix")
    a, t = _graph(tmp_path / "a.onnx", 0), _graph(tmp_path / "t.onnx", 1)
    out = tmp_path / "mix" / "stage1.onnx"
    assert sm.main(["--albedo", str(a), "--transport", str(t), "--out", str(out)]) == 0
    rng = np.random.default_rng(0)
    mask = np.zeros((1, 1, 64, 64), np.float32)
    mask[..., 8:56, 16:48] = 1
    feed = {"image": rng.random((1, 3, 64, 64), dtype=np.float32), "mask": mask}
    got, from_a, from_t = _run(out, feed), _run(a, feed), _run(t, feed)
    assert set(got) == {"albedo", "skin", "transport", "light"}
    for name in ("albedo", "skin", "transport", "light"):
        assert not np.allclose(from_a[name], from_t[name])  # the two graphs tell apart on every output
        np.testing.assert_array_equal(got[name], (from_a if name in ("albedo", "skin") else from_t)[name])
    source = {p.key: p.value for p in onnx.load(str(out)).metadata_props}["relight_rt.source"]
    assert source.startswith("test 0") and "mixed" in source


def test_graphs_that_are_not_both_stage_1_are_refused(load_benchmark, tmp_path, capsys):
    sm = load_benchmark("stage1_mix")
    a = _graph(tmp_path / "a.onnx", 0)
    with pytest.raises(SystemExit):
        sm.main(["--albedo", str(a), "--transport", str(tmp_path / "none.onnx"), "--out", str(tmp_path / "m.onnx")])
    assert "no such file" in capsys.readouterr().err
    import onnx

    model = onnx.load(str(a))
    model.graph.output.pop()  # three outputs: not a stage-1 graph
    with pytest.raises(ValueError, match="same inputs and outputs"):
        sm.mix(onnx.load(str(a)), model)
