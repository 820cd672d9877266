"""Tests for export.networks and export.checkpoint: reference layout, shapes, norms, checkpoints."""

from __future__ import annotations

import json

import pytest

torch = pytest.importorskip("torch")

from export.checkpoint import check_state_dict, load_checkpoint, save_checkpoint  # noqa: E402
from export.networks import DVPNet, Stage1Net, Stage2Net, build_network, light_head_depth  # noqa: E402
from relight_rt import RelightError  # noqa: E402

torch.set_num_threads(1)


@pytest.fixture(scope="module")
def layout(reference_dir):
    return json.loads((reference_dir / "checkpoint_layout.json").read_text())


@pytest.mark.parametrize("kind", ["stage1", "stage2", "dvp"])
def test_reference_layout_keys_and_shapes(layout, kind):
    with torch.device("meta"):
        net = build_network(kind, {"width": 64, "resolution": 1024, "norm": "instance"})
    got = {k: list(v.shape) for k, v in net.state_dict().items()}
    assert got == layout[kind]
    assert list(got) == list(layout[kind])  # same order too, so the checkpoints look alike


@pytest.mark.parametrize(("resolution", "depth"), [(64, 0), (128, 1), (192, 1), (256, 2), (512, 3), (1024, 4)])
def test_light_head_depth(resolution, depth):
    assert light_head_depth(resolution) == depth
    net = Stage1Net(width=2, resolution=resolution)
    names = {k.split(".")[0] for k in net.state_dict() if k.startswith("c") and k.split(".")[0].endswith("l")}
    assert names == {f"c{i}l" for i in range(max(depth, 1))}


@pytest.mark.parametrize("norm", ["batch", "instance"])
@pytest.mark.parametrize("resolution", [64, 128, 256])
def test_stage1_shapes(norm, resolution):
    net = Stage1Net(width=4, resolution=resolution, norm=norm).eval()
    x = torch.rand(2, 3, resolution, resolution) * 2 - 1
    with torch.no_grad():
        transport, albedo, skin, light = net(x)
    assert transport.shape == (2, 9, resolution, resolution)
    assert albedo.shape == (2, 3, resolution, resolution) and skin.shape == (2, 1, resolution, resolution)
    assert light.shape == (2, 9, 3)
    assert 0 <= albedo.min() and albedo.max() <= 1 and 0 <= skin.min() and skin.max() <= 1


@pytest.mark.parametrize(("h", "w"), [(64, 64), (128, 192)])
def test_stage2_and_dvp_any_size(h, w):
    s2 = Stage2Net(width=4, resolution=128, norm="instance").eval()
    dvp = DVPNet(width=4, resolution=128, norm="instance").eval()
    with torch.no_grad():
        r = s2(torch.randn(1, 3, h, w))
        d = dvp(torch.randn(1, 30, h, w))
    assert r.shape == d.shape == (1, 3, h, w)


@pytest.mark.parametrize("cls", [Stage2Net, DVPNet])
def test_stage2_and_dvp_output_activation(cls):
    """No activation by default (the reference returns decoder b's last conv, upsampled); tanh only on request."""
    torch.manual_seed(0)
    plain = cls(width=4, resolution=128, norm="instance").eval()
    bounded = cls(width=4, resolution=128, norm="instance", output_activation="tanh").eval()
    bounded.load_state_dict(plain.state_dict())
    with torch.no_grad():
        plain.dc5b.weight.mul_(30)  # make the raw output large, so that a hidden tanh could not go unnoticed
        bounded.dc5b.weight.mul_(30)
        x = torch.randn(1, plain.c0.in_channels, 128, 128)
        raw = plain(x)
        decoded = plain._decode(plain.rb(plain._encode(x)[5]), plain._encode(x), "b")
        squashed = bounded(x)
    assert raw.abs().max() > 1.5
    assert torch.equal(raw, decoded)
    torch.testing.assert_close(squashed, torch.tanh(raw))
    assert plain.config["output_activation"] == "none" and bounded.config["output_activation"] == "tanh"
    with pytest.raises(RelightError, match="output_activation"):
        cls(width=4, resolution=128, output_activation="sigmoid")


def test_light_channel_order():
    """Output channel 3k + c of the last light conv is light[k, c]."""
    net = Stage1Net(width=2, resolution=128).eval()
    with torch.no_grad():
        net.c0l.weight.zero_()
        net.c0l.bias.copy_(torch.arange(27.0))
        light = net(torch.zeros(1, 3, 128, 128))[3]
    assert torch.equal(light[0], torch.arange(27.0).reshape(9, 3))


def test_instance_norm_is_per_sample_and_matches_train_mode_batch_of_one(monkeypatch):
    torch.manual_seed(0)
    inst = Stage1Net(width=4, resolution=128, norm="instance").eval()
    ref = Stage1Net(width=4, resolution=128, norm="batch")
    ref.load_state_dict(inst.state_dict())
    x = torch.randn(2, 3, 128, 128)
    with torch.no_grad():
        both = inst(x)
        singles = [inst(x[i : i + 1]) for i in range(2)]
        # the reference: BatchNorm in training mode on a batch of one, dropout off
        monkeypatch.setattr(torch.nn.functional, "dropout", lambda h, *args, **kwargs: h)
        ref_out = ref.train()(x[:1])
    for b, s0, s1, r in zip(both, singles[0], singles[1], ref_out, strict=True):
        torch.testing.assert_close(b[:1], s0, rtol=1e-5, atol=1e-5)
        torch.testing.assert_close(b[1:], s1, rtol=1e-5, atol=1e-5)
        torch.testing.assert_close(s0, r, rtol=1e-4, atol=1e-5)


def test_dropout_only_in_training():
    net = Stage2Net(width=4, resolution=128, norm="instance")
    x = torch.randn(1, 3, 128, 128)
    net.eval()
    with torch.no_grad():
        a, b = net(x), net(x)
    assert torch.equal(a, b)
    net.train()
    with torch.no_grad():
        c, d = net(x), net(x)
    assert not torch.equal(c, d)


def test_instance_norm_leaves_running_stats():
    net = Stage2Net(width=4, resolution=128, norm="instance").train()
    before = {k: v.clone() for k, v in net.state_dict().items() if "running" in k}
    net(torch.randn(2, 3, 128, 128))
    after = net.state_dict()
    assert all(torch.equal(v, after[k]) for k, v in before.items())


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"width": 0}, "width"),
        ({"resolution": 100}, "resolution"),
        ({"resolution": 0}, "resolution"),
        ({"norm": "group"}, "norm"),
    ],
)
def test_bad_constructor_args(kwargs, match):
    with pytest.raises(RelightError, match=match):
        Stage1Net(**kwargs)


def test_bad_inputs():
    net = Stage1Net(width=2, resolution=128).eval()
    with pytest.raises(RelightError, match=r"expected \(N, 3, 128, 128\)"):
        net(torch.zeros(1, 3, 64, 64))
    with pytest.raises(RelightError, match=r"expected \(N, 3, H, W\)"):
        net(torch.zeros(1, 4, 128, 128))
    with pytest.raises(RelightError, match="multiples of 64"):
        Stage2Net(width=2, resolution=128)(torch.zeros(1, 3, 64, 96))
    with pytest.raises(RelightError, match="unknown; known kinds"):
        build_network("stage3", {})


def test_config_and_kind():
    assert Stage1Net(4, 128, "batch").config == {"width": 4, "resolution": 128, "norm": "batch"}
    assert Stage2Net(4, 128, "batch").config == {"width": 4, "resolution": 128, "norm": "batch",
                                                 "output_activation": "none"}
    assert DVPNet(4, 128, "instance", conditioned=False).config["conditioned"] is False
    assert DVPNet(4, 128).c0.in_channels == 30 and DVPNet(4, 128, conditioned=False).c0.in_channels == 3
    assert [c.kind for c in (Stage1Net, Stage2Net, DVPNet)] == ["stage1", "stage2", "dvp"]


@pytest.mark.parametrize("cls", [Stage1Net, Stage2Net, DVPNet])
def test_checkpoint_round_trip(tmp_path, cls):
    net = cls(width=2, resolution=128, norm="instance")
    path = save_checkpoint(tmp_path / "sub" / "net.pt", net, epoch=3, losses=[0.5, 0.25])
    model, ckpt = load_checkpoint(path)
    assert type(model) is cls and model.config == net.config
    assert ckpt["epoch"] == 3 and ckpt["losses"] == [0.5, 0.25]
    for k, v in net.state_dict().items():
        assert torch.equal(v, model.state_dict()[k])
    assert [p.name for p in path.parent.iterdir()] == ["net.pt"]  # no temporary left


def test_checkpoint_refusals(tmp_path):
    net = Stage2Net(width=2, resolution=128)
    with pytest.raises(RelightError, match="reserved"):
        save_checkpoint(tmp_path / "a.pt", net, config={})
    with pytest.raises(RelightError, match="not found"):
        load_checkpoint(tmp_path / "missing.pt")
    torch.save({"format": "other"}, tmp_path / "b.pt")
    with pytest.raises(RelightError, match="relight_rt.ckpt/1"):
        load_checkpoint(tmp_path / "b.pt")
    torch.save({"x": _Pickled()}, tmp_path / "c.pt")
    with pytest.raises(RelightError, match="refused"):
        load_checkpoint(tmp_path / "c.pt")
    path = save_checkpoint(tmp_path / "d.pt", net)
    ckpt = torch.load(path, weights_only=True)
    ckpt["state_dict"]["c0.weight"] = torch.zeros(1)
    del ckpt["state_dict"]["c0.bias"]
    ckpt["state_dict"]["bogus"] = torch.zeros(1)
    torch.save(ckpt, path)
    match = r"missing keys: c0.bias.*unexpected keys: bogus.*mis-shaped: c0.weight \[1\]"
    with pytest.raises(RelightError, match=match):
        load_checkpoint(path)


@pytest.mark.parametrize("cls", [Stage2Net, DVPNet])
def test_checkpoint_from_before_output_activation_loads_as_tanh(tmp_path, cls):
    """Stage-2 / DVP checkpoints written before the option existed were all trained with tanh."""
    net = cls(width=2, resolution=128, norm="instance", output_activation="tanh")
    path = save_checkpoint(tmp_path / "old.pt", net)
    ckpt = torch.load(path, weights_only=True)
    del ckpt["config"]["output_activation"]
    torch.save(ckpt, path)
    model, _ = load_checkpoint(path)
    assert model.output_activation == "tanh"
    fresh = save_checkpoint(tmp_path / "new.pt", cls(width=2, resolution=128, norm="instance"))
    assert load_checkpoint(fresh)[0].output_activation == "none"


def test_check_state_dict_not_a_mapping():
    with pytest.raises(RelightError, match="expected a state_dict"):
        check_state_dict(Stage2Net(2, 128), [1, 2], "x")


class _Pickled:
    """An arbitrary class: torch.load(weights_only=True) must refuse it."""
