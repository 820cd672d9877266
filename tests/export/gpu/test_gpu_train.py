"""``gpu-bank`` and ``gpu-train`` rehearsed on the CPU with tiny settings: the GPU run's code path, end to end."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from export.__main__ import main  # noqa: E402
from export.checkpoint import load_checkpoint  # noqa: E402
from export.frozen import OnnxStage  # noqa: E402
from export.toy_data import make_lights  # noqa: E402
from export.training import read_jsonl  # noqa: E402

TINY = ["--resolution", "64", "--width", "4", "--batch-size", "2", "--pool", "4", "--fresh-per-step", "1",
        "--render-share", "1", "--dirs", "8", "--shadow-size", "32", "--log-every", "1", "--device", "cpu",
        "--val-people", "0"]
HOLD_ONE = ["--val-people", "1", "--val-samples", "2", "--val-every", "1e-9"]  # shapes_300001 held out, every step


@pytest.fixture(scope="module")
def bank_dir(tmp_path_factory):
    root = tmp_path_factory.mktemp("gpu")
    make_lights(root / "lights", 4)
    argv = ["gpu-bank", "--out", str(root / "bank"), "--lights", str(root / "lights"), "--n", "2",
            "--subject", "shapes", "--texture-size", "16"]
    assert main(argv) == 0
    return root / "bank"


def test_the_bank_holds_two_people_and_the_lights(bank_dir):
    index = json.loads((bank_dir / "bank.json").read_text())
    assert index["subjects"] == ["shapes_300000", "shapes_300001"]
    assert np.load(bank_dir / "lights.npy").shape == (4, 9, 3)


def test_two_steps_end_with_a_contract_graph_a_checkpoint_and_a_log(bank_dir, tmp_path):
    out = tmp_path / "run"
    assert main(["gpu-train", "--bank", str(bank_dir), "--out", str(out), "--init", "none", "--max-steps", "2",
                 *TINY]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["stopped"] == "steps" and summary["steps"] == 2 and summary["error"] is None
    assert summary["samples_rendered"] == 2 + 2  # a batch to start with, then one per step
    assert set(summary["render_s_per_sample_by_framing"]) <= {"full", "knees-up", "waist-up", "head-shoulders",
                                                               "face"}
    stage = OnnxStage(out / "stage1.onnx", "stage1")
    assert stage.resolution == 64
    # the bank's lights can be swapped (gpu-bank --lights-only): the summary and the graph name the ones trained on
    import hashlib

    import onnxruntime as ort

    digest = hashlib.sha256(np.load(bank_dir / "lights.npy").tobytes()).hexdigest()[:12]
    meta = ort.InferenceSession(str(out / "stage1.onnx"), providers=["CPUExecutionProvider"]).get_modelmeta()
    assert summary["lights"] == f"4 lights, sha256 {digest}"
    assert summary["lights"] in meta.custom_metadata_map["relight_rt.source"]
    model, ckpt = load_checkpoint(out / "last.pt")
    assert ckpt["step"] == 2 and model.config["width"] == 4
    events = [r["event"] for r in read_jsonl(out / "log.jsonl")]
    assert events[0] == "start" and events.count("step") == 2 and events[-1] == "end"


def tiny_graph(path):
    """A width-4, 64-px stage-1 ONNX graph at ``path`` with its norms away from their defaults, as in a trained graph
    (the exporter folds them)."""
    from export.networks import Stage1Net
    from export.onnx_export import export_onnx

    torch.manual_seed(0)
    net = Stage1Net(width=4, resolution=64, norm="batch")
    with torch.no_grad():
        for m in net.modules():
            if isinstance(m, torch.nn.BatchNorm2d):
                m.weight.uniform_(0.5, 1.5)
                m.bias.uniform_(-0.2, 0.2)
    export_onnx(net.eval(), path, source="test")
    return path


def test_it_starts_from_an_onnx_graph(bank_dir, tmp_path):
    init = tiny_graph(tmp_path / "init.onnx")
    out = tmp_path / "run"
    assert main(["gpu-train", "--bank", str(bank_dir), "--out", str(out), "--init", str(init), "--max-steps", "1",
                 *TINY]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert "init.onnx (ONNX, norm layers unfolded" in summary["init"]


def test_an_anchored_run_logs_its_term_and_says_so_in_the_graph(bank_dir, tmp_path):
    import onnx

    init = tiny_graph(tmp_path / "init.onnx")
    runs = {}
    for weight in ("0", "2"):
        out = tmp_path / f"run{weight}"
        assert main(["gpu-train", "--bank", str(bank_dir), "--out", str(out), "--init", str(init), "--max-steps", "2",
                     *TINY, "--albedo-anchor", weight]) == 0
        steps = [r for r in read_jsonl(out / "log.jsonl") if r["event"] == "step"]
        source = {p.key: p.value for p in onnx.load(str(out / "stage1.onnx")).metadata_props}["relight_rt.source"]
        runs[weight] = steps, source
    plain, anchored = runs["0"], runs["2"]
    assert len(anchored[0]) == 2 and all("albedo_anchor" not in r for r in plain[0])
    # in training mode (dropout, batch statistics) the albedo differs from the frozen start's from the first step
    assert all(r["albedo_anchor"] > 0 for r in anchored[0])
    assert anchored[1].endswith(", albedo anchored to it (weight 2)") and "albedo anchored" not in plain[1]


def test_rendering_keeps_to_its_share_of_the_time(bank_dir, tmp_path):
    out = tmp_path / "run"
    # rendering the first batch takes far more than 1% of what two tiny steps take: no fresh samples after it
    assert main(["gpu-train", "--bank", str(bank_dir), "--out", str(out), "--init", "none", "--max-steps", "2",
                 *TINY, "--render-share", "0.01"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["steps"] == 2 and summary["samples_rendered"] == 2


def test_the_deadline_stops_it_and_it_still_exports(bank_dir, tmp_path):
    out = tmp_path / "run"
    # the deadline minus the export reserve has passed before the first step: no training, still a graph
    assert main(["gpu-train", "--bank", str(bank_dir), "--out", str(out), "--init", "none", "--deadline", "2",
                 "--export-reserve", "1.99", *TINY]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["stopped"] == "deadline" and summary["steps"] == 0
    assert (out / "stage1.onnx").is_file() and (out / "last.pt").is_file()


def test_flipped_batches_shade_as_the_mirror_image():
    from export.gpu.train import _Pool
    from export.torch_data import render_input

    rng = torch.Generator().manual_seed(0)
    pool = _Pool(2, 8, torch.device("cpu"))
    sample = {"albedo": torch.rand(3, 8, 8, generator=rng), "mask": (torch.rand(1, 8, 8, generator=rng) > 0.3).float(),
              "skin": torch.rand(1, 8, 8, generator=rng), "transport": torch.randn(9, 8, 8, generator=rng)}
    pool.add(sample)
    light = torch.randn(1, 9, 3, generator=rng)
    plain = pool.batch(torch.tensor([0]), light, torch.tensor([False]))
    flipped = pool.batch(torch.tensor([0]), light, torch.tensor([True]))
    assert torch.allclose(render_input(flipped), render_input(plain).flip(-1), atol=1e-6)


@pytest.mark.parametrize("argv, message", [
    (["--bank", "nowhere"], "bank.json"),  # (and no run folder is left: the bank is read before it is made)
    (["--resolution", "96"], "multiple of 64"),
    (["--init", "missing.onnx"], "no such file"),
    # issue 50, round 4 fuzz (benchmarks/fuzz_round5.py): these trained, ran out of memory or diverged (exit 1)
    (["--dirs", "100000000"], "--dirs"),
    (["--shadow-size", "100000"], "--shadow-size"),
    (["--resolution", "1984", "--dirs", "4096"], "GiB"),
    (["--pool", "100000", "--resolution", "1024"], "--pool"),
    (["--lr", "inf"], "--lr"),
    (["--max-yaw", "nan"], "--max-yaw"),
    (["--checkpoint-every", "nan"], "--checkpoint-every"),
    (["--framings", "nope"], "--framings"),
    (["--val-people", "2"], "--val-people 2: the bank has 2 people"),  # nobody left to train on
    (["--val-samples", "0"], "--val-samples"),
    (["--val-every", "nan"], "--val-every"),
    (["--band-weight", "-1"], "--band-weight"),
    (["--albedo-anchor", "-1"], "--albedo-anchor"),
    (["--albedo-anchor", "nan"], "--albedo-anchor"),
    (["--init", "none", "--albedo-anchor", "1"], "needs a warm start"),  # nothing to anchor to
])
def test_bad_settings_get_one_line(bank_dir, tmp_path, capsys, argv, message):
    args = ["gpu-train", "--bank", str(bank_dir), "--out", str(tmp_path / "run"), *TINY, *argv]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1
    assert not (tmp_path / "run").exists()  # refused before the run folder is made


@pytest.mark.parametrize("where, message", [("file", "a file"), ("bank", "bank folder"), ("init", "--init")])
def test_a_bad_out_or_init_is_one_error_before_anything_is_written(bank_dir, tmp_path, capsys, where, message):
    """issue 50 round 4 fuzz: --out naming a file was a FileExistsError traceback, a bad --init a failed run (exit 1)
    after the pool was rendered, and --out = the bank wrote the run into it."""
    (tmp_path / "file").write_text("keep")
    (tmp_path / "garbage.onnx").write_bytes(b"not a graph")
    out = {"file": tmp_path / "file", "bank": bank_dir, "init": tmp_path / "run"}[where]
    init = ["--init", str(tmp_path / "garbage.onnx")] if where == "init" else []
    before = sorted(p.name for p in bank_dir.iterdir())
    assert main(["gpu-train", "--bank", str(bank_dir), "--out", str(out), *TINY, *init]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1
    assert (tmp_path / "file").read_text() == "keep" and not (tmp_path / "run").exists()
    assert sorted(p.name for p in bank_dir.iterdir()) == before


def test_gpu_check_never_writes_over_the_bank(bank_dir, capsys):
    """issue 50 round 4 fuzz: gpu-check --out BANK/bank.json replaced the bank's index with its figures."""
    pytest.importorskip("embreex")
    index = (bank_dir / "bank.json").read_bytes()
    argv = ["gpu-check", "--bank", str(bank_dir), "--n", "1", "--resolution", "32", "--dirs", "8",
            "--shadow-size", "16", "--reference-dirs", "8", "--embree-dirs", "8", "--out", str(bank_dir / "bank.json")]
    assert main(argv) == 2
    assert "refusing to overwrite" in capsys.readouterr().err
    assert (bank_dir / "bank.json").read_bytes() == index
    assert main([*argv[:-2], "--reference-dirs", "0"]) == 2
    assert "--reference-dirs" in capsys.readouterr().err


def test_gpu_bank_swaps_the_lights_of_a_built_bank_without_building_anyone(bank_dir, tmp_path, capsys):
    """--lights-only: the people stay byte for byte, lights.npy becomes the new folder's lights."""
    from export import dataset

    swapped = tmp_path / "bank"
    shutil.copytree(bank_dir, swapped)
    make_lights(tmp_path / "new", 6)
    argv = ["gpu-bank", "--out", str(swapped), "--lights", str(tmp_path / "new"), "--lights-only"]
    assert main(argv) == 0
    np.testing.assert_array_equal(np.load(swapped / "lights.npy"), dataset.read_lights(tmp_path / "new"))
    for person in ("shapes_300000.npz", "shapes_300001.npz"):
        assert (swapped / person).read_bytes() == (bank_dir / person).read_bytes()
    index = json.loads((swapped / "bank.json").read_text())
    assert index["subjects"] == ["shapes_300000", "shapes_300001"] and index["lights"] == "lights.npy"
    # a folder without a bank is refused in one line, and nothing is written there
    (tmp_path / "empty").mkdir()
    assert main([*argv[:2], str(tmp_path / "empty"), *argv[3:]]) == 2
    assert "bank.json" in capsys.readouterr().err and not any((tmp_path / "empty").iterdir())


@pytest.mark.parametrize("argv, message", [
    (["--seed", "-1"], "--seed"),  # a ValueError traceback from numpy's seeding
    (["--out", "FILE"], "a file"),  # a FileExistsError traceback
    (["--out", "LIGHTS"], "--lights folder"),  # the bank was written into the light folder
    (["--texture-size", "100000"], "--texture-size"),  # more than the reader takes back
])
def test_gpu_bank_refuses_bad_settings_in_one_line(tmp_path, capsys, argv, message):
    """issue 50 round 4 fuzz (benchmarks/fuzz_round5.py)."""
    make_lights(tmp_path / "lights", 2)
    (tmp_path / "file").write_text("keep")
    argv = [{"FILE": str(tmp_path / "file"), "LIGHTS": str(tmp_path / "lights")}.get(a, a) for a in argv]
    before = sorted(p.name for p in (tmp_path / "lights").iterdir())
    base = ["gpu-bank", "--out", str(tmp_path / "bank"), "--lights", str(tmp_path / "lights"), "--n", "1",
            "--subject", "shapes", "--texture-size", "16"]
    assert main([*base, *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1
    assert not (tmp_path / "bank").exists() and (tmp_path / "file").read_text() == "keep"
    assert sorted(p.name for p in (tmp_path / "lights").iterdir()) == before


def test_it_needs_nothing_the_gpu_machine_lacks(bank_dir, tmp_path):
    """The device has torch, numpy, onnx, onnxruntime and OpenCV, not anny, embree, trimesh or warp."""
    import subprocess
    import sys

    code = (
        "import sys\n"
        "class Block:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name.split('.')[0] in {'anny', 'embreex', 'trimesh', 'warp'}:\n"
        "            raise ImportError(f'{name} is not on the GPU machine')\n"
        "sys.meta_path.insert(0, Block())\n"
        "from export.__main__ import main\n"
        "sys.exit(main(sys.argv[1:]))\n"
    )
    out = tmp_path / "run"
    argv = ["gpu-train", "--bank", str(bank_dir), "--out", str(out), "--init", "none", "--max-steps", "1", *TINY,
            *HOLD_ONE]
    done = subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert json.loads((out / "summary.json").read_text())["steps"] == 1


def test_held_out_people_are_never_trained_on_and_their_loss_is_logged(bank_dir, tmp_path):
    out = tmp_path / "run"
    assert main(["gpu-train", "--bank", str(bank_dir), "--out", str(out), "--init", "none", "--max-steps", "2",
                 *TINY, *HOLD_ONE]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["trained_people"] == 1 and summary["subjects"] == 2
    val = summary["val"]
    assert val["people"] == ["shapes_300001"] and val["samples"] == 2
    assert val["checks"] == 3 and val["last_step"] == 2  # before the first step, then after each of the two
    records = read_jsonl(out / "log.jsonl")
    assert records[0]["val_people"] == ["shapes_300001"]
    vals = [r for r in records if r["event"] == "val"]
    assert len(vals) == 3 and all(np.isfinite([r["val_loss"] for r in vals]))
    relit = [r["val_relit_rmse"] for r in vals]
    assert all(0 < x < 1 for x in relit) and val["metric"] == "relit_rmse"
    assert val["best"] == min(relit) and summary["exported"] == f"best (step {val['best_step']})"
    assert (out / "best.pt").is_file()


@pytest.mark.parametrize("metric, winner", [("relit_rmse", 2), ("loss", 1)])
def test_the_weights_of_the_lowest_held_out_figure_are_exported(bank_dir, tmp_path, monkeypatch, metric, winner):
    """Training that only overfits must not ship: the graph is the one of the best validation, not the last."""
    from export.gpu import validate

    # before step 1, after steps 1, 2 and 3: the loss is lowest after step 1, the relit RMSE after step 2
    scripted = iter([{"loss": 1.0, "relit_rmse": 0.3}, {"loss": 0.5, "relit_rmse": 0.4},
                     {"loss": 2.0, "relit_rmse": 0.1}, {"loss": 3.0, "relit_rmse": 0.5}])
    monkeypatch.setattr(validate.HeldOut, "measure", lambda self, *a, **k: next(scripted))
    out = tmp_path / "run"
    assert main(["gpu-train", "--bank", str(bank_dir), "--out", str(out), "--init", "none", "--max-steps", "3",
                 "--lr", "0.05", *TINY, *HOLD_ONE, "--val-metric", metric]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["exported"] == f"best (step {winner})" and summary["val"]["best_step"] == winner
    assert summary["val"]["first"] == {"loss": 1.0, "relit_rmse": 0.3}[metric]
    assert summary["val"]["last"] == {"loss": 3.0, "relit_rmse": 0.5}[metric]
    best, best_ckpt = load_checkpoint(out / "best.pt")
    last, last_ckpt = load_checkpoint(out / "last.pt")
    assert best_ckpt["step"] == winner and last_ckpt["step"] == 3
    # the graph's metadata names what its weights had seen: the best check's steps and samples, not the run's
    source = _source(out / "stage1.onnx")
    assert source.startswith(f"relight_rt gpu-train: {winner} steps on ")
    seen = int(source.split(" steps on ")[1].split()[0])
    assert seen == 2 + winner  # TINY: a pool of 2, then one fresh sample a step (as test_two_steps counts)
    image = torch.rand(1, 3, 64, 64, generator=torch.Generator().manual_seed(0))
    mask = torch.ones(1, 1, 64, 64)
    got = OnnxStage(out / "stage1.onnx", "stage1").run({"image": image, "mask": mask})["transport"]
    with torch.no_grad():
        want = [m.eval()((2 * image - 1) * mask)[0] for m in (best, last)]
    assert torch.allclose(got, want[0], atol=1e-4)
    assert not torch.allclose(got, want[1], atol=1e-3)



def test_a_step_0_best_is_named_as_untrained(bank_dir, tmp_path, monkeypatch):
    """Training that never beats the start exports the start, and its metadata says it saw nothing of the run."""
    from export.gpu import validate

    scripted = iter([0.1, 0.2, 0.3, 0.4])
    monkeypatch.setattr(validate.HeldOut, "measure", lambda self, *a, **k: {"loss": 1.0, "relit_rmse": next(scripted)})
    out = tmp_path / "run"
    assert main(["gpu-train", "--bank", str(bank_dir), "--out", str(out), "--init", "none", "--max-steps", "3",
                 *TINY, *HOLD_ONE]) == 0
    assert json.loads((out / "summary.json").read_text())["exported"] == "best (step 0)"
    assert _source(out / "stage1.onnx").startswith("relight_rt gpu-train: 0 steps on 0 samples rendered")

def test_split_people_holds_out_the_last_ones():
    from export.gpu.validate import split_people

    assert split_people(["a", "b", "c", "d"], 2) == (["a", "b"], ["c", "d"])
    assert split_people(["a"], 0) == (["a"], [])


@pytest.mark.parametrize("extra, logged", [
    ([], {"transport_bands", "transport_direction"}),  # the shipped stage 1's recipe by default
    (["--band-weight", "0", "--direction-weight", "0"], set()),  # the paper's objective, as the first lend ran
])
def test_the_band_and_direction_terms_are_trained_by_default(bank_dir, tmp_path, extra, logged):
    out = tmp_path / "run"
    assert main(["gpu-train", "--bank", str(bank_dir), "--out", str(out), "--init", "none", "--max-steps", "1",
                 *TINY, *extra]) == 0
    step = next(r for r in read_jsonl(out / "log.jsonl") if r["event"] == "step")
    assert {"transport_bands", "transport_direction"} & set(step) == logged
    assert all(step[k] > 0 for k in logged)


def test_the_relit_rmse_is_zero_for_the_truth_and_grows_with_a_wrong_albedo(bank_dir):
    from export.gpu import bank
    from export.gpu.render import DeviceSubject, RenderSettings
    from export.gpu.validate import HeldOut
    from export.losses import Stage1Loss

    data = bank.read_subject(bank_dir / "shapes_300001.npz", bank.read_template(bank_dir))
    subject = DeviceSubject.from_data(data, torch.device("cpu"))
    lights = torch.as_tensor(np.load(bank_dir / "lights.npy"))
    held = HeldOut([subject], lights, RenderSettings(resolution=32, dirs=8, shadow_size=16), ["full", "face"], 2,
                   45.0, 0)

    class Truth(torch.nn.Module):  # answers every batch with the held-out samples' own truth, albedo scaled
        def __init__(self, scale):
            super().__init__()
            self.scale = scale

        def forward(self, x):
            d = held.data[: len(x)].float()
            return d[:, 5:], d[:, :3] * self.scale, d[:, 4:5], held.lights[: len(x)]

    exact = held.measure(Truth(1.0), Stage1Loss(sf_scale=0.2), 2, amp=False)
    dim = held.measure(Truth(0.5), Stage1Loss(sf_scale=0.2), 2, amp=False)
    assert exact["relit_rmse"] == pytest.approx(0.0, abs=1e-6)
    assert dim["relit_rmse"] > 0.01 and dim["loss"] > exact["loss"]


@pytest.mark.parametrize("where", ["measure", "samples", "later", "keeping"])
def test_a_failing_held_out_check_turns_the_checks_off_and_training_goes_on(bank_dir, tmp_path, monkeypatch, where):
    """The checks never ran on the device before a lend: one that fails there must not cost the run's training, nor
    its export: at step 0, after a best was kept (the step-0 weights, the shipped stage 1 on the device, must not be
    what comes back), or in keeping the last check's best (after the training loop)."""
    from export.gpu import validate

    calls = []

    def broken(*args, **kwargs):
        raise RuntimeError("CUDA-only trouble")

    def measure_once(self, *args, **kwargs):  # step 0 is measured, every later check fails
        calls.append(1)
        if len(calls) > 1:
            broken()
        return {"loss": 1.0, "relit_rmse": 0.1}

    offer = validate.Best.offer

    def offer_once(self, *args, **kwargs):  # the first best is kept, keeping a later one fails
        if self.step is not None:
            broken()
        return offer(self, *args, **kwargs)

    if where == "measure":
        monkeypatch.setattr(validate.HeldOut, "measure", broken)
    elif where == "samples":
        monkeypatch.setattr(validate.HeldOut, "__init__", broken)
    elif where == "later":
        monkeypatch.setattr(validate.HeldOut, "measure", measure_once)
    else:
        monkeypatch.setattr(validate.HeldOut, "measure", lambda self, *a, **k: {"loss": 1.0, "relit_rmse": 0.1})
        monkeypatch.setattr(validate.Best, "offer", offer_once)
    out = tmp_path / "run"
    argv = ["gpu-train", "--bank", str(bank_dir), "--out", str(out), "--init", "none", "--max-steps", "3", *TINY,
            *HOLD_ONE]
    if where == "keeping":
        argv += ["--val-every", "1000"]  # no check inside the loop: only step 0's and the last one's
    assert main(argv) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["steps"] == 3 and summary["error"] is None and summary["stopped"] == "steps"
    assert "CUDA-only trouble" in summary["val_error"]
    assert summary["exported"].startswith("last")
    assert (out / "stage1.onnx").is_file()
    assert _source(out / "stage1.onnx").startswith(f"relight_rt gpu-train: 3 steps on {summary['samples_rendered']} ")


def _source(graph):
    """The ``relight_rt.source`` metadata of an ONNX graph."""
    import onnx

    return {p.key: p.value for p in onnx.load(str(graph)).metadata_props}["relight_rt.source"]


CALL = Path(__file__).resolve().parents[3] / "scripts" / "gpu_call.sh"


def test_the_device_call_fits_the_run_tool_and_is_the_one_documented():
    call = CALL.read_text()
    assert len(call) <= 2000 and call.count("\n") == 1 and call.endswith("\n")  # run's command: 2,000 characters
    assert call.strip() in (CALL.parents[1] / "docs" / "GPU.md").read_text()


@pytest.mark.skipif(not all(shutil.which(t) for t in ("bash", "timeout", "sed")), reason="needs bash and coreutils")
def test_the_device_call_trains_twice_at_once_and_leaves_eight_files_at_most(bank_dir, tmp_path):
    """The call of docs/GPU.md as it is, its settings shrunk through $X as the rehearsal there does: two runs,
    anchored with weights 2 and 5, each with its graph, and last.pt dropped where a graph exists (the device sends
    back 8 files)."""
    from export.networks import Stage1Net
    from export.onnx_export import export_onnx

    torch.manual_seed(0)
    net = Stage1Net(width=4, resolution=64, norm="batch")
    with torch.no_grad():  # norms away from their defaults, as in a trained graph (the exporter folds them)
        for m in net.modules():
            if isinstance(m, torch.nn.BatchNorm2d):
                m.weight.uniform_(0.5, 1.5)
                m.bias.uniform_(-0.2, 0.2)
    init = tmp_path / "init.onnx"
    export_onnx(net.eval(), init, source="test")
    out = tmp_path / "out"
    out.mkdir()
    root = CALL.parents[1]
    env = {**os.environ, "OUT": str(out), "T": "1", "PYTHONPATH": str(root),
           "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}",
           "X": " ".join(["--bank", str(bank_dir), "--init", str(init), "--max-steps", "2", *TINY])}
    done = subprocess.run(["bash", str(CALL)], cwd=root, env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    files = sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file())
    runs = ("anchor2", "anchor5")
    assert files == [f"{run}/{name}" for run in runs for name in ("log.jsonl", "stage1.onnx", "summary.json")]
    summaries = {run: json.loads((out / run / "summary.json").read_text()) for run in runs}
    assert all(s["error"] is None and s["steps"] == 2 for s in summaries.values())
    assert [(s["config"]["albedo_anchor"], s["config"]["seed"]) for s in summaries.values()] == [("2.0", "0"),
                                                                                                ("5.0", "1")]
    assert "anchor2: " in done.stdout and "anchor5: " in done.stdout  # each run's lines named
