"""Evaluation: image metrics (masked RMSE, bbox SSIM) and the evaluate command's tables."""

from __future__ import annotations

import json

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from _train_fixtures import make_lights, make_photos, make_samples  # noqa: E402

from export.metrics_img import mask_bbox, masked_rmse, masked_ssim, ssim  # noqa: E402
from relight_rt import RelightError  # noqa: E402


def test_masked_rmse_hand_value():
    pred = np.zeros((2, 2, 3))
    true = np.zeros((2, 2, 3))
    true[0, 0] = 0.3
    true[1, 1] = 9.0  # outside the mask
    mask = np.array([[1.0, 1.0], [1.0, 0.0]])
    assert masked_rmse(pred, true, mask) == pytest.approx(np.sqrt(0.09 / 3))
    assert np.isnan(masked_rmse(pred, true, np.zeros((2, 2))))


@pytest.mark.parametrize("shape", [(16, 16, 3), (20, 31, 1), (24, 24)])
def test_ssim_properties(shape):
    rng = np.random.default_rng(0)
    a = rng.uniform(size=shape)
    b = np.clip(a + rng.normal(0, 0.1, shape), 0, 1)
    c = np.clip(a + rng.normal(0, 0.3, shape), 0, 1)
    assert ssim(a, a) == pytest.approx(1.0)
    assert ssim(a, b) == pytest.approx(ssim(b, a))
    assert ssim(a, c) < ssim(a, b) < 1.0


def test_masked_ssim_uses_the_bounding_box_and_ignores_the_background():
    rng = np.random.default_rng(1)
    a = rng.uniform(size=(32, 32, 3))
    mask = np.zeros((32, 32))
    mask[8:20, 4:30] = 1.0
    assert mask_bbox(mask) == (slice(8, 20), slice(4, 30))
    b = a.copy()
    b[mask == 0] = 0.0  # differs only outside the mask
    assert masked_ssim(a, b, mask) == pytest.approx(1.0)
    assert masked_rmse(a, b, mask) == 0.0


def test_metrics_refuse_bad_input():
    with pytest.raises(RelightError, match="one shape"):
        masked_rmse(np.zeros((4, 4, 3)), np.zeros((4, 5, 3)), np.ones((4, 4)))
    with pytest.raises(RelightError, match="mask"):
        masked_ssim(np.zeros((4, 4, 3)), np.zeros((4, 4, 3)), np.ones((3, 4)))
    with pytest.raises(RelightError, match="empty"):
        masked_ssim(np.zeros((4, 4, 3)), np.zeros((4, 4, 3)), np.zeros((4, 4)))


def test_front_transport_is_the_cosine_lobe_of_a_camera_facing_normal():
    from export.evaluate import FRONT_TRANSPORT

    # DESIGN.md §3 table at (x, y, z) = (1, 0, 0), times A_l = π, 2π/3, π/4
    expected = [np.pi * 0.282095, 0, 0, 2 * np.pi / 3 * 0.488603, 0, 0, np.pi / 4 * -0.315392, 0,
                np.pi / 4 * 0.546274]
    np.testing.assert_allclose(FRONT_TRANSPORT, expected, rtol=2e-6, atol=1e-12)


@pytest.fixture(scope="module")
def checkpoints(tmp_path_factory):
    from export.checkpoint import save_checkpoint
    from export.networks import Stage1Net, Stage2Net

    root = tmp_path_factory.mktemp("eval")
    make_samples(root / "samples", 3, 64, seed=5)
    make_lights(root / "lights", 3)
    make_photos(root / "photos", 2, 3, 64)
    torch.manual_seed(0)
    save_checkpoint(root / "s1.pt", Stage1Net(width=4, resolution=64, norm="instance"))
    save_checkpoint(root / "nosf.pt", Stage1Net(width=4, resolution=64, norm="instance"))
    save_checkpoint(root / "s2.pt", Stage2Net(width=4, resolution=64, norm="instance"))
    return root


def test_evaluate_writes_both_tables(checkpoints, tmp_path):
    from export.__main__ import main

    root = checkpoints
    out = tmp_path / "eval"
    argv = ["evaluate", "--stage1", str(root / "s1.pt"), "--stage2", str(root / "s2.pt"), "--nosf",
            str(root / "nosf.pt"), "--data", str(root / "samples"), "--lights", str(root / "lights"),
            "--photos", str(root / "photos"), "--out", str(out), "--threads", "1"]
    assert main(argv) == 0
    results = json.loads((out / "results.json").read_text())
    syn, photos = results["synthetic"], results["photos"]
    assert set(syn) == {"stage 1", "stage 1 (no SF)", "trivial"}
    assert syn["stage 1"]["n"] == 3
    for key in ("albedo_rmse", "albedo_ssim", "light_rmse", "shading_rmse", "shading_ssim", "recon_rmse",
                "recon_ssim", "transport_rmse"):
        assert np.isfinite(syn["trivial"][key])
    assert set(photos) == {"trivial", "stage 1", "stage 1 + 2", "stage 1 (no SF)", "oracle: true diffuse",
                           "oracle: true diffuse + stage 2", "oracle: stage 1 + true residual"}
    assert photos["stage 1 + 2"]["n_pairs"] == 12  # 2 subjects × 3 × 2 ordered pairs
    assert photos["stage 1"]["n_photos"] == 6
    effect = results["stage2_effect"]
    assert effect["relight_rmse"]["n"] == 12 and effect["relight_rmse"]["subjects"] == 2
    assert effect["recon_rmse"]["n"] == 6
    # the same photos in both rows, so the mean of the differences is the difference of the means
    expected = photos["stage 1 + 2"]["recon_rmse"] - photos["stage 1"]["recon_rmse"]
    assert effect["recon_rmse"]["mean"] == pytest.approx(expected, abs=1e-9)
    # the ceiling: stage 1 plus the photos' true non-diffuse part, on the same pairs
    ceiling = effect["relight_ceiling"]
    assert ceiling["n"] == 12 and ceiling["subjects"] == 2
    expected = photos["oracle: stage 1 + true residual"]["relight_rmse"] - photos["stage 1"]["relight_rmse"]
    assert ceiling["mean"] == pytest.approx(expected, abs=1e-9) and ceiling["mean"] != 0
    text = (out / "results.md").read_text()
    assert "| stage 1 + 2 |" in text and "Table 1" in text and "Table 2" in text and "Stage 2's effect" in text
    assert "a perfect stage 2 (oracle)" in text


def test_paired_change_resamples_subjects_and_counts_improvements():
    from export.evaluate import paired_change

    base = [{"e": 1.0}] * 6
    # subject a: stage 2 lowers the error by 0.1 on all 4 items; subject b: raises it by 0.3 on both
    new = [{"e": 0.9}] * 4 + [{"e": 1.3}] * 2
    groups = ["a"] * 4 + ["b"] * 2
    out = paired_change(base, new, "e", groups, resamples=4000, seed=1)
    assert out["mean"] == pytest.approx((4 * -0.1 + 2 * 0.3) / 6)
    assert out["improved"] == pytest.approx(4 / 6)
    assert (out["n"], out["subjects"]) == (6, 2)
    low, high = out["ci95"]
    # resampling whole subjects: the extremes are "a twice" (-0.1) and "b twice" (+0.3)
    assert low == pytest.approx(-0.1) and high == pytest.approx(0.3)
    same = paired_change(base, base, "e", groups)
    assert same["mean"] == 0 and same["ci95"] == [0, 0] and same["improved"] == 0


def test_trivial_baseline_reconstructs_the_mean_colour(checkpoints):
    from export.evaluate import trivial_decomposition
    from export.shading import render_diffuse

    image = torch.rand(2, 3, 16, 16) * 0.5
    mask = (torch.rand(2, 1, 16, 16) > 0.3).float()
    light = torch.zeros(9, 3)
    light[0] = 1.0
    light[3] = 0.4
    d = trivial_decomposition(image, mask, light)
    recon = render_diffuse(d["albedo"], d["transport"], d["light"], mask)
    mean = (image * mask).sum((2, 3)) / mask.sum((2, 3))
    torch.testing.assert_close(recon, mean[:, :, None, None] * mask, atol=1e-5, rtol=1e-5)


def test_evaluate_needs_some_data(checkpoints, tmp_path, capsys):
    from export.__main__ import main

    assert main(["evaluate", "--stage1", str(checkpoints / "s1.pt"), "--out", str(tmp_path)]) == 2
    assert "--data" in capsys.readouterr().err
    assert main(["evaluate", "--stage1", str(checkpoints / "s2.pt"), "--photos", str(checkpoints / "photos"),
                 "--out", str(tmp_path)]) == 2
    assert "expected a stage1 checkpoint" in capsys.readouterr().err


def test_evaluate_gives_the_same_tables_from_onnx_graphs(checkpoints, tmp_path):
    """The shipped artefacts can be measured directly: .onnx graphs give the checkpoints' numbers."""
    pytest.importorskip("onnxruntime")
    from export.__main__ import main

    root = checkpoints
    for kind in ("stage1", "stage2"):
        short = kind.replace("stage", "s")
        out = tmp_path / f"{kind}.onnx"
        assert main(["onnx", "--checkpoint", str(root / f"{short}.pt"), "--kind", kind, "--out", str(out)]) == 0
    common = ["--data", str(root / "samples"), "--lights", str(root / "lights"), "--photos", str(root / "photos"),
              "--threads", "1"]
    assert main(["evaluate", "--stage1", str(root / "s1.pt"), "--stage2", str(root / "s2.pt"),
                 "--out", str(tmp_path / "pt"), *common]) == 0
    assert main(["evaluate", "--stage1", str(tmp_path / "stage1.onnx"), "--stage2", str(tmp_path / "stage2.onnx"),
                 "--out", str(tmp_path / "onnx"), *common]) == 0
    a = json.loads((tmp_path / "pt" / "results.json").read_text())
    b = json.loads((tmp_path / "onnx" / "results.json").read_text())
    for section in ("synthetic", "photos"):
        assert set(a[section]) == set(b[section])
        for method, row in a[section].items():
            for key, value in row.items():
                assert b[section][method][key] == pytest.approx(value, rel=1e-3, abs=1e-5), (section, method, key)


def test_evaluate_refuses_a_graph_of_the_wrong_kind(checkpoints, tmp_path, capsys):
    pytest.importorskip("onnxruntime")
    from export.__main__ import main

    root = checkpoints
    graph = tmp_path / "s2.onnx"
    assert main(["onnx", "--checkpoint", str(root / "s2.pt"), "--kind", "stage2", "--out", str(graph)]) == 0
    argv = ["evaluate", "--stage1", str(graph), "--photos", str(root / "photos"), "--out", str(tmp_path / "e")]
    assert main(argv) == 2
    assert "stage1" in capsys.readouterr().err


def test_evaluate_compares_stage1_with_a_baseline_pair_by_pair(checkpoints, tmp_path):
    from export.__main__ import main

    root = checkpoints
    out = tmp_path / "eval"
    argv = ["evaluate", "--stage1", str(root / "s1.pt"), "--baseline", str(root / "nosf.pt"), "--data",
            str(root / "samples"), "--lights", str(root / "lights"), "--photos", str(root / "photos"),
            "--out", str(out), "--threads", "1"]
    assert main(argv) == 0
    results = json.loads((out / "results.json").read_text())
    assert "baseline stage 1" in results["synthetic"] and "stage2_effect" not in results
    photos, effect = results["photos"], results["baseline_effect"]
    assert effect["relight_rmse"]["n"] == 12 and effect["relight_rmse"]["subjects"] == 2
    for key in ("recon_rmse", "relight_rmse"):  # the same items in both rows: the change is the difference of means
        expected = photos["stage 1"][key] - photos["baseline stage 1"][key]
        assert effect[key]["mean"] == pytest.approx(expected, abs=1e-9) and expected != 0
    assert "against the baseline stage 1" in (out / "results.md").read_text()
