"""export.average (``python -m export average``): the weighted mean of checkpoints of one network."""

from __future__ import annotations

import json

import pytest

torch = pytest.importorskip("torch")

from export.__main__ import main as export_main  # noqa: E402
from export.checkpoint import load_checkpoint, save_checkpoint  # noqa: E402
from export.networks import Stage1Net, Stage2Net  # noqa: E402


def _saved(path, seed, width=2, norm="batch", cls=Stage1Net):
    torch.manual_seed(seed)
    net = cls(width=width, resolution=128, norm=norm)
    with torch.no_grad():  # running statistics and step counts that differ between the two
        for buf in net.buffers():
            buf.add_(seed + 1) if buf.is_floating_point() else buf.fill_(10 * (seed + 1))
    return save_checkpoint(path, net, epoch=seed), net.state_dict()


def test_the_weighted_mean_of_every_float_tensor_and_the_last_step_counts(tmp_path):
    a, sa = _saved(tmp_path / "a.pt", 0)
    b, sb = _saved(tmp_path / "b.pt", 1)
    out = tmp_path / "soup.pt"
    assert export_main(["average", str(a), str(b), "--weights", "1", "3", "--out", str(out)]) == 0
    model, ckpt = load_checkpoint(out)
    got = model.state_dict()
    ints = 0
    for k, v in got.items():
        if v.is_floating_point():
            torch.testing.assert_close(v, 0.25 * sa[k] + 0.75 * sb[k])
        else:
            ints += 1
            assert torch.equal(v, sb[k])
    assert ints > 0
    assert json.loads(ckpt["meta"])["weights"] == [0.25, 0.75] and "optimizer" not in ckpt


def test_checkpoints_of_different_networks_or_bad_weights_are_one_error(tmp_path, capsys):
    a, _ = _saved(tmp_path / "a.pt", 0)
    wide, _ = _saved(tmp_path / "wide.pt", 1, width=4)
    other, _ = _saved(tmp_path / "s2.pt", 1, cls=Stage2Net)
    out = tmp_path / "soup.pt"
    for argv, says in (
        ([a, wide], "not the stage1"),
        ([a, other], "a stage2"),
        ([a], "two or more"),
        ([a, a, "--weights", "1"], "one per checkpoint"),
        ([a, a, "--weights", "1", "-1"], "non-negative"),
    ):
        assert export_main(["average", *map(str, argv), "--out", str(out)]) == 2
        assert says in capsys.readouterr().err
    assert not out.exists()
    before = a.read_bytes()
    assert export_main(["average", str(a), str(wide), "--out", str(a)]) == 2  # never over an input
    assert "one of the checkpoints averaged" in capsys.readouterr().err and a.read_bytes() == before
