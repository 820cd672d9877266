"""Tests of export.dvp (deep video prior fitting) and export.vgg; tiny sizes, torch only."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

torch = pytest.importorskip("torch")

from relight_rt import RelightError  # noqa: E402

N, H, W = 4, 48, 64


def _clip(n: int = N, seed: int = 0) -> dict[str, np.ndarray]:
    """A panning texture, its 'relit' version with per-frame flicker, a turning light."""
    rng = np.random.default_rng(seed)
    big = cv2.GaussianBlur(rng.random((H, W + 2 * n, 3)).astype(np.float32), (0, 0), 2.0)
    big = (big - big.min()) / (big.max() - big.min())
    frames = np.stack([big[:, 2 * t:2 * t + W] for t in range(n)])
    masks = np.zeros((n, H, W), np.float32)
    masks[:, 4:-4, 6:-6] = 1
    lights = np.zeros((n, 9, 3), np.float32)
    lights[:, 0] = 0.8
    lights[:, 1] = 0.3 * np.cos(np.arange(n))[:, None]
    targets = np.clip(frames * rng.uniform(0.8, 1.2, (n, 1, 1, 1)), 0, 1).astype(np.float32)
    return {"frames": frames, "targets": targets, "masks": masks, "lights": lights}


def _u8(rgb: np.ndarray) -> np.ndarray:
    return np.rint(rgb * 255).astype(np.uint8)


def _write_clip(folder: Path, clip: dict) -> None:
    """in/fT.png + in/fT_mask.png, relit/fT.png (BGR on disk), lights.npy (RGB)."""
    for sub in ("in", "relit"):
        (folder / sub).mkdir()
    for t in range(len(clip["frames"])):
        cv2.imwrite(str(folder / "in" / f"f{t}.png"), _u8(clip["frames"][t][..., ::-1]))
        cv2.imwrite(str(folder / "in" / f"f{t}_mask.png"), _u8(clip["masks"][t]))
        cv2.imwrite(str(folder / "relit" / f"f{t}.png"), _u8(clip["targets"][t][..., ::-1]))
    np.save(folder / "lights.npy", clip["lights"])


def test_network_input_layout():
    from export.dvp import network_input

    frames = torch.rand(2, 3, 4, 5)
    masks = (torch.rand(2, 1, 4, 5) > 0.5).float()
    lights = torch.randn(2, 9, 3)
    x = network_input(frames, masks, lights, conditioned=True)
    assert x.shape == (2, 30, 4, 5)
    torch.testing.assert_close(x[:, :3], (2 * frames - 1) * masks)
    for k, c in ((0, 0), (4, 2), (8, 1)):  # channel 3 + 3k + c holds light[k, c] at every pixel
        assert torch.all(x[:, 3 + 3 * k + c] == lights[:, k, c, None, None])
    assert network_input(frames, masks, lights, conditioned=False).shape == (2, 3, 4, 5)


@pytest.mark.parametrize("conditioned", [True, False])
def test_fit_tiny_keeps_best_epoch(conditioned):
    from export.dvp import fit_dvp

    torch.set_num_threads(1)
    model, history = fit_dvp(_clip(), conditioned=conditioned, width=4, max_epochs=3, min_epochs=1, patience=1, lr=1e-3)
    assert model.conditioned is conditioned and not model.training
    scores = [e["score"] for e in history["epochs"]]
    assert history["best_epoch"] == int(np.argmin(scores))
    assert history["best_score"] == pytest.approx(min(scores))
    assert "fallback" in history["loss"]
    assert all(np.isfinite([e["fit_error"], e["flicker"]]).all() for e in history["epochs"])
    assert history["target_flicker"] > 0.01


def test_fit_reduces_fit_error():
    from export.dvp import fit_dvp

    torch.set_num_threads(1)
    _, history = fit_dvp(_clip(), width=4, max_epochs=6, min_epochs=6, patience=10, lr=1e-3)
    fits = [e["fit_error"] for e in history["epochs"]]
    assert fits[-1] < fits[0]


def test_fit_weight_average():
    from export.dvp import fit_dvp

    torch.set_num_threads(1)
    kwargs = dict(width=4, max_epochs=2, min_epochs=2, patience=10, lr=1e-3)
    _, plain = fit_dvp(_clip(), **kwargs)
    # decay 0: the average is the latest weights, so every epoch's prediction is the plain fit's
    _, zero = fit_dvp(_clip(), ema=0.0, **kwargs)
    assert [e["fit_error"] for e in zero["epochs"]] == pytest.approx([e["fit_error"] for e in plain["epochs"]],
                                                                      rel=1e-5)
    # a real average predicts with other weights than the last step's
    model, avg = fit_dvp(_clip(), ema=0.9, **kwargs)
    assert avg["ema"] == 0.9 and not model.training and model.conditioned
    assert avg["epochs"][-1]["fit_error"] != pytest.approx(plain["epochs"][-1]["fit_error"], rel=1e-3)
    with pytest.raises(RelightError, match="ema"):
        fit_dvp(_clip(), ema=1.0, **kwargs)


def test_load_clip(tmp_path):
    from export.dvp import load_clip

    clip = _clip()
    _write_clip(tmp_path, clip)
    got = load_clip(tmp_path / "in", tmp_path / "relit", tmp_path / "lights.npy", size=32)
    assert got["frames"].shape == (N, 24, 32, 3) and got["masks"].shape == (N, 24, 32)
    assert got["lights"].shape == (N, 9, 3)
    one = load_clip(tmp_path / "in", tmp_path / "relit", clip["lights"][0])
    assert one["lights"].shape == (N, 9, 3) and one["frames"].shape == (N, H, W, 3)
    with pytest.raises(RelightError, match=r"\(4, 9, 3\)"):
        load_clip(tmp_path / "in", tmp_path / "relit", np.zeros((3, 9, 3)))
    (tmp_path / "relit" / "f3.png").unlink()
    with pytest.raises(RelightError, match="relit"):
        load_clip(tmp_path / "in", tmp_path / "relit", tmp_path / "lights.npy")


def _torchvision_layout_weights(path: Path) -> Path:
    from export.vgg import VGG19Features

    net = VGG19Features(None)
    state = {f"features.{k}": v for k, v in net.features.state_dict().items()}
    state["classifier.0.weight"] = torch.zeros(2, 2)  # ignored
    torch.save(state, path)
    return path


def test_vgg_loads_torchvision_layout_and_gives_five_maps(tmp_path):
    from export.vgg import PerceptualLoss, VGG19Features

    path = _torchvision_layout_weights(tmp_path / "vgg19.pth")
    net = VGG19Features(path)
    feats = net(torch.rand(1, 3, 32, 32))
    assert [f.shape[1] for f in feats] == [64, 128, 256, 512, 512]
    assert [f.shape[-1] for f in feats] == [32, 16, 8, 4, 2]
    loss = PerceptualLoss(path)
    x = torch.rand(1, 3, 32, 32, requires_grad=True)
    mask = torch.ones(1, 1, 32, 32)
    assert float(loss(x, x.detach(), mask).detach()) == 0.0
    value = loss(x, torch.rand(1, 3, 32, 32), mask)
    value.backward()
    assert value > 0 and x.grad is not None
    assert all(not p.requires_grad for p in loss.parameters())


def test_vgg_bad_weights(tmp_path):
    from export.vgg import VGG19Features

    torch.save({"features.0.weight": torch.zeros(3)}, tmp_path / "bad.pth")
    with pytest.raises(RelightError, match="not VGG19|shape"):
        VGG19Features(tmp_path / "bad.pth")
    (tmp_path / "junk.pth").write_bytes(b"junk")
    with pytest.raises(RelightError, match="cannot read"):
        VGG19Features(tmp_path / "junk.pth")


def test_fit_with_vgg_weights_names_the_loss(tmp_path):
    from export.dvp import fit_dvp

    torch.set_num_threads(1)
    path = _torchvision_layout_weights(tmp_path / "vgg19.pth")
    _, history = fit_dvp(_clip(n=2), width=4, max_epochs=1, vgg_weights=path)
    assert history["loss"].startswith("perceptual")


@pytest.mark.parametrize("unconditioned", [False, True])
def test_fit_dvp_command_exports_contract_graph(tmp_path, unconditioned):
    pytest.importorskip("export.onnx_export")
    from export.__main__ import main
    from relight_rt.video.job import DVPModel

    clip = _clip()
    _write_clip(tmp_path, clip)
    out = tmp_path / "dvp.onnx"
    argv = ["fit-dvp", "--frames", str(tmp_path / "in"), "--relit", str(tmp_path / "relit"), "--lights",
            str(tmp_path / "lights.npy"), "--out", str(out), "--width", "4", "--max-epochs", "3", "--checkpoint",
            str(tmp_path / "dvp.pt")]
    assert main(argv + (["--unconditioned"] if unconditioned else [])) == 0
    log = json.loads(out.with_suffix(".fit.json").read_text())
    assert log["conditioned"] is (not unconditioned)
    dvp = DVPModel(out)
    frames = [clip["frames"][t] for t in range(2)]
    masks = [clip["masks"][t] for t in range(2)]
    a = dvp(frames, masks, [clip["lights"][0]] * 2)
    b = dvp(frames, masks, [clip["lights"][0] * 3] * 2)
    assert a[0].shape == (H, W, 3) and 0 <= a[0].min() and a[0].max() <= 1
    assert np.all(a[0][masks[0] == 0] == 0)
    if unconditioned:
        np.testing.assert_allclose(a[0], b[0], atol=1e-6)  # the light input is ignored
    else:
        assert np.abs(a[0] - b[0]).max() > 1e-4

    # the exported graph reproduces the fitted torch network
    from export.checkpoint import load_checkpoint
    from export.dvp import network_input

    model, _ = load_checkpoint(tmp_path / "dvp.pt")
    model.eval()
    pad = lambda x: np.pad(x, [(0, 0), (0, -H % 64), (0, -W % 64)] + [(0, 0)] * (x.ndim - 3))  # noqa: E731
    fr = torch.from_numpy(pad(np.stack(frames))).permute(0, 3, 1, 2)
    ms = torch.from_numpy(pad(np.stack(masks)))[:, None]
    with torch.no_grad():
        ref = ((model(network_input(fr, ms, torch.from_numpy(clip["lights"][:2] * 0 + clip["lights"][0]),
                                     not unconditioned)) + 1) / 2).clamp(0, 1) * ms
    ref = ref.permute(0, 2, 3, 1)[:, :H, :W].numpy()
    np.testing.assert_allclose(np.stack(a), ref, atol=2e-4)
