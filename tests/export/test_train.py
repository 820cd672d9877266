"""Training smoke tests on tiny synthetic spheres (64², width 4): loss goes down, resume, time budget."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from _train_fixtures import make_lights, make_photos, make_samples  # noqa: E402

from export.__main__ import main  # noqa: E402
from export.training import read_jsonl  # noqa: E402
from relight_rt import RelightError  # noqa: E402

TINY = ["--resolution", "64", "--width", "4", "--norm", "instance", "--threads", "1", "--log-every", "1"]


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("train_data")
    make_samples(root / "samples", 8, 64)
    make_lights(root / "lights", 6)
    make_photos(root / "photos", 2, 2, 64)
    return root


def _stage1(data, out, *extra):
    argv = ["train-stage1", "--data", str(data / "samples"), "--lights", str(data / "lights"), "--out", str(out),
            "--val-fraction", "0", *TINY, *extra]
    return main(argv)


def _totals(run):
    return [r["total"] for r in read_jsonl(run / "log.jsonl") if r["event"] == "step"]


def test_stage1_loss_goes_down(data, tmp_path):
    run = tmp_path / "s1"
    assert _stage1(data, run, "--epochs", "3", "--lr", "2e-3") == 0
    totals = _totals(run)  # seeds 0-2 gave last/first ratios 0.41-0.44 at 24 steps
    assert len(totals) == 24
    first, last = np.mean(totals[:6]), np.mean(totals[-6:])
    assert last < 0.75 * first, (first, last)
    ckpt = torch.load(run / "last.pt", weights_only=True)
    assert ckpt["epoch"] == 3 and ckpt["step"] == 0 and ckpt["kind"] == "stage1"
    assert (run / "best.pt").exists()
    epochs = [r for r in read_jsonl(run / "log.jsonl") if r["event"] == "epoch"]
    assert [r["epoch"] for r in epochs] == [0, 1, 2]
    assert set(epochs[0]["train"]) >= {"sf_albedo", "sf_shading", "skin", "render_ATL", "total"}


def test_resume_gives_the_same_weights(data, tmp_path):
    straight, resumed = tmp_path / "a", tmp_path / "b"
    assert _stage1(data, straight, "--epochs", "2") == 0
    assert _stage1(data, resumed, "--epochs", "1") == 0
    assert _stage1(data, resumed, "--epochs", "2", "--resume") == 0
    a = torch.load(straight / "last.pt", weights_only=True)
    b = torch.load(resumed / "last.pt", weights_only=True)
    assert a["epoch"] == b["epoch"] == 2 and a["global_step"] == b["global_step"] == 16
    for key, value in a["state_dict"].items():
        torch.testing.assert_close(b["state_dict"][key], value, rtol=1e-5, atol=1e-6, msg=key)
    # the learning rate continued along the same schedule
    lr_a = [r["lr"] for r in read_jsonl(straight / "log.jsonl") if r["event"] == "step"]
    lr_b = [r["lr"] for r in read_jsonl(resumed / "log.jsonl") if r["event"] == "step"]
    assert lr_a == pytest.approx(lr_b)


def test_max_minutes_stops_mid_epoch_and_resumes(data, tmp_path):
    run = tmp_path / "t"
    assert _stage1(data, run, "--epochs", "3", "--max-minutes", "1e-6") == 0
    end = read_jsonl(run / "log.jsonl")[-1]
    assert end["event"] == "end" and end["stopped"] == "time" and end["steps"] == 1
    ckpt = torch.load(run / "last.pt", weights_only=True)
    assert (ckpt["epoch"], ckpt["step"]) == (0, 1)
    assert _stage1(data, run, "--epochs", "3", "--resume") == 0
    end = read_jsonl(run / "log.jsonl")[-1]
    assert end["stopped"] == "done" and end["global_step"] == 24 and end["epochs_done"] == 3


def test_existing_run_needs_resume(data, tmp_path, capsys):
    run = tmp_path / "r"
    assert _stage1(data, run, "--epochs", "1", "--max-steps", "2") == 0
    assert _stage1(data, run, "--epochs", "1") == 2
    assert "pass --resume" in capsys.readouterr().err


def test_no_sf_run_logs_no_sf_terms(data, tmp_path):
    run = tmp_path / "nosf"
    assert _stage1(data, run, "--epochs", "1", "--max-steps", "2", "--no-sf", "--no-flip") == 0
    step = [r for r in read_jsonl(run / "log.jsonl") if r["event"] == "step"][0]
    assert "sf_albedo" not in step and "render_ATL" in step


def test_band_and_direction_weights_add_their_terms_and_refuse_negative_weights(data, tmp_path, capsys):
    run = tmp_path / "bands"
    assert _stage1(data, run, "--epochs", "1", "--max-steps", "2", "--band-weight", "0.5",
                   "--direction-weight", "0.5") == 0
    step = [r for r in read_jsonl(run / "log.jsonl") if r["event"] == "step"][0]
    assert step["transport_bands"] > 0 and step["transport_direction"] > 0
    assert _stage1(data, tmp_path / "neg", "--epochs", "1", "--band-weight", "-1") == 2
    assert "--band-weight" in capsys.readouterr().err
    assert _stage1(data, tmp_path / "negd", "--epochs", "1", "--direction-weight", "-1") == 2
    assert "--direction-weight" in capsys.readouterr().err


def test_bad_resolution_is_refused(data, tmp_path):
    from export import train_stage1

    parser = argparse.ArgumentParser()
    train_stage1.add_arguments(parser)
    args = parser.parse_args(["--data", str(data / "samples"), "--lights", str(data / "lights"),
                              "--out", str(tmp_path / "x"), "--resolution", "100"])
    with pytest.raises(RelightError, match="multiple of 64"):
        train_stage1.run(train_stage1.config_from_args(args))


def test_stage1_dataset_flip_is_physical(data):
    """An item drawn flipped is the left-right mirror with the k = 1, 4, 5 signs changed (light too)."""
    from export.dataset import read_lights
    from export.losses import FLIP_SIGNS
    from export.torch_data import Stage1Dataset, item_rng

    lights = read_lights(data / "lights")
    ds = Stage1Dataset(data / "samples", lights, 64, seed=3)
    plain = Stage1Dataset(data / "samples", lights, 64, seed=3, flip=False)

    def draws_flip(epoch):
        rng = item_rng(3, epoch, 0)
        rng.integers(len(lights))
        return bool(rng.integers(2))

    epoch = next(e for e in range(50) if draws_flip(e))
    ds.set_epoch(epoch)
    plain.set_epoch(epoch)
    a, b = ds[0], plain[0]
    signs = torch.tensor(FLIP_SIGNS)
    torch.testing.assert_close(a["transport"], b["transport"].flip(-1) * signs[:, None, None], atol=2e-3, rtol=0)
    torch.testing.assert_close(a["light"], b["light"] * signs[:, None])
    torch.testing.assert_close(a["albedo"], b["albedo"].flip(-1))
    assert not torch.equal(a["mask"], b["mask"])  # the sample is not symmetric: the test can fail


def test_stage2_trains_and_caches(data, tmp_path, capsys):
    s1 = tmp_path / "s1"
    assert _stage1(data, s1, "--epochs", "1", "--max-steps", "2") == 0
    run = tmp_path / "s2"
    argv = ["train-stage2", "--photos", str(data / "photos"), "--stage1", str(s1 / "best.pt"), "--out", str(run),
            "--width", "4", "--norm", "instance", "--threads", "1", "--log-every", "1", "--val-fraction", "0"]
    assert main([*argv, "--epochs", "8", "--lr", "2e-3"]) == 0
    with np.load(run / "diffuse_cache.npz", allow_pickle=False) as z:
        assert z["diffuse"].shape == (4, 3, 64, 64) and list(z["names"]) == ["subj0__L0", "subj0__L1", "subj1__L0",
                                                                              "subj1__L1"]
    totals = _totals(run)
    assert np.mean(totals[-6:]) < np.mean(totals[:6])
    assert main([*argv, "--epochs", "9", "--resume"]) == 0  # reuses the cache, continues
    assert read_jsonl(run / "log.jsonl")[-1]["global_step"] == 36
    assert torch.load(run / "best.pt", weights_only=True)["config"]["output_activation"] == "none"
    capsys.readouterr()
    assert main([*argv, "--epochs", "10", "--resume", "--output-activation", "tanh"]) == 2  # weights fit "none"
    assert "trained with output activation 'none'; resuming asks for 'tanh'" in capsys.readouterr().err


def test_export_onnx_at_the_end(data, tmp_path):
    pytest.importorskip("export.onnx_export")
    pytest.importorskip("onnxruntime")
    run = tmp_path / "x"
    assert _stage1(data, run, "--epochs", "1", "--max-steps", "1", "--export-onnx") == 0
    from relight_rt.engine.session import load_model

    model = load_model(run / "stage1.onnx", "stage1", device="cpu")  # the contract's metadata and I/O, checked
    r = model.config.resolution or 64
    out = model.run({"image": np.full((1, 3, r, r), 0.5, np.float32), "mask": np.ones((1, 1, r, r), np.float32)})
    assert out["albedo"].shape == (1, 3, r, r) and out["light"].shape == (1, 9, 3)
    assert all(np.isfinite(v).all() for v in out.values())


def test_args_json_is_written(data, tmp_path):
    run = tmp_path / "j"
    assert _stage1(data, run, "--epochs", "1", "--max-steps", "1") == 0
    args = json.loads((run / "args.json").read_text())
    assert args["command"] == "train-stage1" and args["width"] == 4


@pytest.mark.parametrize("source", ["toy", pytest.param("render", marks=pytest.mark.long)])
def test_quickstart_end_to_end(tmp_path, source):
    """Tiny data, a few training steps, ONNX export, evaluation and a relit image."""
    pytest.importorskip("onnxruntime")
    if source == "render":
        pytest.importorskip("embreex")
    out = tmp_path / "qs"
    argv = ["quickstart", "--out", str(out), "--data-source", source, "--subject", "shapes", "--samples", "3",
            "--photo-subjects", "2", "--photo-lights", "2", "--n-lights", "10", "--resolution", "64", "--width", "4",
            "--dirs", "16", "--stage1-minutes", "0.002", "--stage2-minutes", "0.002", "--stage2-epochs", "2",
            "--threads", "1"]
    assert main(argv) == 0
    for name in ("stage1.onnx", "stage2.onnx", "relit.png", "relit_side_by_side.png", "eval/results.md"):
        assert (out / name).stat().st_size > 0, name
    assert (out / "data" / "SOURCE").read_text().strip() == source
    import cv2

    relit = cv2.imread(str(out / "relit.png"))
    assert relit.shape == (64, 64, 3) and relit.max() > 0


def test_stage2_starts_from_a_zero_residual():
    from export.networks import Stage2Net
    from export.train_stage2 import stage2_step, zero_residual_init

    torch.manual_seed(0)
    model = Stage2Net(width=4, resolution=64, norm="instance")
    diffuse = torch.rand(1, 3, 64, 64)
    mask = torch.ones(1, 1, 64, 64)
    batch = {"diffuse": diffuse, "mask": mask, "photo": diffuse.clone()}
    assert stage2_step(model, batch)["l1"] > 0  # a random last layer adds a residual
    zero_residual_init(model)
    assert stage2_step(model, batch)["l1"] == 0


def test_stage2_relighting_pairs_use_the_other_photos_light(data, tmp_path):
    """An (i, j) item is stage 1's albedo and transport of photo i under photo j's true light, target photo j."""
    from export.torch_data import PhotoDataset
    from export.train_stage2 import Stage2Dataset, relighting_partners

    photos = PhotoDataset(data / "photos", 64)
    assert relighting_partners(photos.names) == [[1], [0], [3], [2]]  # subj0__L0/L1, subj1__L0/L1
    gen = torch.Generator().manual_seed(0)
    cache = {"diffuse": torch.rand(4, 3, 64, 64, generator=gen).numpy().astype(np.float16),
             "albedo": torch.rand(4, 3, 64, 64, generator=gen).numpy().astype(np.float16),
             "transport": torch.randn(4, 9, 64, 64, generator=gen).numpy().astype(np.float16)}
    ds = Stage2Dataset(photos, cache, [(0, 0), (0, 1)], 64, augment=False)
    self_item, pair = ds[0], ds[1]
    mask = photos[0]["mask"] * photos[1]["mask"]
    torch.testing.assert_close(self_item["diffuse"], torch.from_numpy(cache["diffuse"][0].astype(np.float32))
                               * photos[0]["mask"])
    shading = torch.einsum("khw,kc->chw", torch.from_numpy(cache["transport"][0].astype(np.float32)),
                           photos[1]["light"]).clamp_min(0)
    expected = (torch.from_numpy(cache["albedo"][0].astype(np.float32)) * shading).clamp(0, 1) * mask
    torch.testing.assert_close(pair["diffuse"], expected)
    torch.testing.assert_close(pair["photo"], photos[1]["photo"])
    assert not torch.equal(photos[0]["light"], photos[1]["light"])  # the test can fail
    # with cross_light = 1 every reconstruction entry becomes a pair with the sample's other photo
    mixed = Stage2Dataset(photos, cache, [(0, 0)], 64, augment=False, cross_light=1.0)
    torch.testing.assert_close(mixed[0]["diffuse"], pair["diffuse"])
    with pytest.raises(RelightError, match="albedo and transport"):
        Stage2Dataset(photos, {"diffuse": cache["diffuse"]}, [(0, 1)], 64)
    # with true_diffuse = 1 the input is the renderer's own diffuse image of the target photo
    oracle = Stage2Dataset(photos, cache, [(0, 0), (0, 1)], 64, augment=False, true_diffuse=1.0)
    torch.testing.assert_close(oracle[0]["diffuse"], photos[0]["diffuse"] * photos[0]["mask"])
    torch.testing.assert_close(oracle[1]["diffuse"], photos[1]["diffuse"] * mask)
    assert photos[0]["diffuse"].any() and not torch.equal(oracle[0]["diffuse"], self_item["diffuse"])


def test_stage2_trains_on_a_frozen_onnx_stage1_with_relighting_pairs(data, tmp_path):
    pytest.importorskip("onnxruntime")
    s1 = tmp_path / "s1"
    assert _stage1(data, s1, "--epochs", "1", "--max-steps", "2", "--export-onnx") == 0
    run = tmp_path / "s2"
    argv = ["train-stage2", "--photos", str(data / "photos"), "--stage1", str(s1 / "stage1.onnx"), "--out", str(run),
            "--width", "4", "--norm", "instance", "--threads", "1", "--log-every", "1", "--val-fraction", "0.5",
            "--cross-light", "0.5", "--epochs", "8", "--lr", "2e-3"]
    assert main(argv) == 0
    with np.load(run / "diffuse_cache.npz", allow_pickle=False) as z:
        assert z["transport"].shape == (4, 9, 64, 64) and z["albedo"].shape == (4, 3, 64, 64)
    totals = _totals(run)
    assert len(totals) == 16 and np.mean(totals[-4:]) < np.mean(totals[:4])
    epochs = [r for r in read_jsonl(run / "log.jsonl") if r["event"] == "epoch"]
    assert all(np.isfinite(r["val"]) for r in epochs)


def test_stage2_refuses_a_bad_cross_light(data, tmp_path, capsys):
    argv = ["train-stage2", "--photos", str(data / "photos"), "--stage1", str(tmp_path / "none.onnx"), "--out",
            str(tmp_path / "o"), "--cross-light", "1.5"]
    assert main(argv) == 2
    assert "--cross-light" in capsys.readouterr().err


def test_stage2_trains_on_a_folder_of_ones_own_photos(data, tmp_path, capsys):
    """issue 20: ordinary photos, no masks: the automatic matte makes them, bad files are left out."""
    import cv2

    repo = Path(__file__).resolve().parents[2]
    scene = cv2.imread(str(repo / "relight_rt" / "data" / "example_scene.jpg"))
    mine = tmp_path / "mine"
    mine.mkdir()
    for k in range(2):
        cv2.imwrite(str(mine / f"me{k}.jpg"), np.roll(scene, 7 * k, axis=1))
    (mine / "broken.jpg").write_bytes(b"not a jpeg")
    s1 = tmp_path / "s1"
    assert _stage1(data, s1, "--epochs", "1", "--max-steps", "2") == 0
    run = tmp_path / "s2"
    argv = ["train-stage2", "--photos", str(mine), "--stage1", str(s1 / "best.pt"), "--out", str(run),
            "--width", "4", "--norm", "instance", "--threads", "1", "--log-every", "1", "--val-fraction", "0",
            "--epochs", "1"]
    assert main(argv) == 0
    prepared = run / "photos"
    assert sorted(p.name for p in prepared.iterdir()) == ["me0__L0_mask.png", "me0__L0_photo.png",
                                                          "me1__L0_mask.png", "me1__L0_photo.png"]
    truth = cv2.imread(str(repo / "tests" / "data" / "example_scene_truth.png"), cv2.IMREAD_GRAYSCALE) > 127
    matte = cv2.imread(str(prepared / "me0__L0_mask.png"), cv2.IMREAD_GRAYSCALE) > 127
    assert (matte & truth).sum() / (matte | truth).sum() > 0.95  # the automatic matte, not a made-up mask
    assert (run / "best.pt").is_file()
    assert main([*argv, "--cross-light", "0.5"]) == 2  # needs rendered photos' lights
    assert "need rendered photos" in capsys.readouterr().err


def test_stage2_squared_error_loss_is_the_mean_of_squares(data, tmp_path):
    from export.train_stage2 import stage2_step

    model = torch.nn.Module()
    residual = torch.full((1, 3, 8, 8), 0.1)
    model.forward = lambda x: residual  # a fixed residual: the loss is a hand value
    mask = torch.zeros(1, 1, 8, 8)
    mask[..., :4, :] = 1
    batch = {"mask": mask, "diffuse": torch.full((1, 3, 8, 8), 0.5), "photo": torch.full((1, 3, 8, 8), 0.8)}
    assert float(stage2_step(model, batch, "l2")["l2"]) == pytest.approx(0.2**2, rel=1e-5)
    assert float(stage2_step(model, batch)["l1"]) == pytest.approx(0.2, rel=1e-5)
    s1 = tmp_path / "s1"
    assert _stage1(data, s1, "--epochs", "1", "--max-steps", "1") == 0
    run = tmp_path / "s2"
    assert main(["train-stage2", "--photos", str(data / "photos"), "--stage1", str(s1 / "best.pt"), "--out", str(run),
                 "--width", "4", "--norm", "instance", "--threads", "1", "--log-every", "1", "--val-fraction", "0",
                 "--epochs", "1", "--loss", "l2"]) == 0
    steps = [r for r in read_jsonl(run / "log.jsonl") if r["event"] == "step"]
    assert steps and "l2" in steps[0] and "l1" not in steps[0]


def test_stage2_init_starts_from_a_trained_checkpoint(data, tmp_path, capsys, caplog):
    """--init adapts a trained stage 2 to another stage 1: its first step starts from those weights, not from 0."""
    s1 = tmp_path / "s1"
    assert _stage1(data, s1, "--epochs", "1", "--max-steps", "2") == 0
    common = ["--photos", str(data / "photos"), "--stage1", str(s1 / "best.pt"), "--width", "4", "--norm", "instance",
              "--threads", "1", "--log-every", "1", "--val-fraction", "0"]
    assert main(["train-stage2", *common, "--out", str(tmp_path / "a"), "--epochs", "4", "--lr", "2e-3"]) == 0
    trained = torch.load(tmp_path / "a" / "best.pt", weights_only=True)
    capsys.readouterr()
    with caplog.at_level("INFO"):
        assert main(["train-stage2", *common, "--out", str(tmp_path / "b"), "--epochs", "1", "--max-steps", "1",
                     "--lr", "0", "--init", str(tmp_path / "a" / "best.pt")]) == 0
    assert "stage 2 starts from" in caplog.text
    again = torch.load(tmp_path / "b" / "last.pt", weights_only=True)
    for name, value in trained["state_dict"].items():  # lr 0: the loaded weights come through unchanged
        torch.testing.assert_close(again["state_dict"][name], value)
    assert "a/best.pt" in json.loads(again["meta"])["init"]
    assert torch.count_nonzero(trained["state_dict"]["dc5b.weight"]) > 0  # not the zero residual a fresh run has
    assert main(["train-stage2", *common, "--out", str(tmp_path / "c"), "--init", str(tmp_path / "x.onnx")]) == 2
    assert "starts from a .pt checkpoint" in capsys.readouterr().err
