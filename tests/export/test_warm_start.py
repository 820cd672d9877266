"""Fine-tuning from shipped weights: an ONNX graph's folded norms unfold into a network that computes the
same, and re-measured norm statistics keep it so in eval mode and on the calibration batch in training mode."""

from __future__ import annotations

import copy

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("onnxruntime")

from _train_fixtures import make_lights, make_samples  # noqa: E402

from export.__main__ import main  # noqa: E402
from export.networks import Stage1Net  # noqa: E402
from export.onnx_export import export_onnx  # noqa: E402
from export.warm_start import calibrate_norms, load_init  # noqa: E402
from relight_rt import RelightError  # noqa: E402


def _trained_graph(tmp_path, width=4, seed=1):
    """A batch-norm stage-1 network with non-trivial norm statistics, exported to ONNX."""
    torch.manual_seed(seed)
    net = Stage1Net(width=width, resolution=64, norm="batch")
    net.train()
    with torch.no_grad():  # move the running statistics and affine parameters away from their defaults
        for m in net.modules():
            if isinstance(m, torch.nn.BatchNorm2d):
                m.weight.uniform_(0.5, 1.5)
                m.bias.uniform_(-0.2, 0.2)
        for _ in range(3):
            net(torch.rand(4, 3, 64, 64) * 2 - 1)
    path = tmp_path / "s1.onnx"
    export_onnx(net, path, source="test")
    net.eval()
    return net, path


def test_an_onnx_graph_unfolds_into_the_same_network(tmp_path):
    original, path = _trained_graph(tmp_path)
    fresh = Stage1Net(width=4, resolution=64, norm="batch")
    assert "unfolded" in load_init(fresh, path)
    fresh.eval()
    x = torch.rand(2, 3, 64, 64) * 2 - 1
    with torch.no_grad():
        for a, b in zip(original(x), fresh(x), strict=True):
            assert torch.allclose(a, b, atol=1e-4, rtol=1e-4)


def test_calibration_keeps_eval_mode_and_makes_training_mode_agree(tmp_path):
    _, path = _trained_graph(tmp_path)
    net = Stage1Net(width=4, resolution=64, norm="batch")
    load_init(net, path)
    x = torch.rand(4, 3, 64, 64) * 2 - 1
    net.eval()
    with torch.no_grad():
        before = net(x)
        probe = copy.deepcopy(net).train()  # a training-mode pass moves running statistics: use a copy
        uncalibrated = probe(x)[3]  # the light head has no dropout: compare it in training mode
    assert calibrate_norms(net, [x]) > 0
    net.eval()
    with torch.no_grad():
        after = net(x)
        net.train()
        light_train = net(x)[3]
    for a, b in zip(before, after, strict=True):
        assert torch.allclose(a, b, atol=1e-4, rtol=1e-3)
    err = float((light_train - before[3]).abs().max())
    assert err < 1e-3 * float(before[3].abs().max()) + 1e-5
    assert float((uncalibrated - before[3]).abs().max()) > 10 * err  # without calibration it did differ


def test_a_graph_of_another_width_is_refused(tmp_path):
    _, path = _trained_graph(tmp_path, width=4)
    with pytest.raises(RelightError, match="another width or resolution"):
        load_init(Stage1Net(width=8, resolution=64, norm="batch"), path)
    with pytest.raises(RelightError, match="no such file"):
        load_init(Stage1Net(width=4, resolution=64, norm="batch"), tmp_path / "missing.onnx")


def test_train_stage1_init_starts_from_the_graph(tmp_path):
    _, path = _trained_graph(tmp_path)
    make_samples(tmp_path / "samples", 8, 64)
    make_lights(tmp_path / "lights", 6)
    out = tmp_path / "run"
    argv = ["train-stage1", "--data", str(tmp_path / "samples"), "--lights", str(tmp_path / "lights"),
            "--out", str(out), "--resolution", "64", "--width", "4", "--norm", "batch", "--batch-size", "4",
            "--threads", "1", "--val-fraction", "0", "--epochs", "1", "--max-steps", "1", "--lr", "1e-9",
            "--lr-min", "1e-9", "--init", str(path)]
    assert main(argv) == 0
    ckpt = torch.load(out / "last.pt", weights_only=True)
    net = Stage1Net(width=4, resolution=64, norm="batch")
    load_init(net, path)
    state = ckpt["state_dict"]
    for name, module in net.named_modules():
        if isinstance(module, torch.nn.Conv2d):  # one step at lr 1e-9 leaves them where the graph put them
            assert np.allclose(state[f"{name}.weight"].numpy(), module.weight.detach().numpy(), atol=1e-6), name
    assert "unfolded" in ckpt["meta"]
