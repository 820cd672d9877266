"""relight-rt bench (relight_rt.cli.bench): the harness runs on the tiny committed graphs and writes JSON + markdown.

Timings are never asserted (they depend on the machine and its load); only structure and plumbing.
"""

import json
import math
import shutil

import numpy as np
import pytest

from relight_rt import RelightError
from relight_rt.cli import bench, main
from relight_rt.engine.config import RuntimeConfig
from relight_rt.relight.relighter import Relighter, diffuse_batch


@pytest.fixture(scope="module")
def tiny_models(tmp_path_factory, test_data_dir):
    """A models folder made of the tiny test graphs (stage 1 at 128, stage 2 any size)."""
    folder = tmp_path_factory.mktemp("models")
    shutil.copy(test_data_dir / "tiny_stage1.onnx", folder / "stage1.onnx")
    shutil.copy(test_data_dir / "tiny_stage2.onnx", folder / "stage2.onnx")
    return folder


FAST = {"batches": [1, 2], "n_lights": 2, "frames": 2, "repeats": 1, "warmup": 0}


@pytest.fixture(scope="module")
def report(tiny_models):
    return bench.run(tiny_models, **FAST)


def test_report_has_every_section_and_batch(report):
    rows = report["rows"]
    got = {(r["section"], r["batch"]) for r in rows}
    for section in ("stage1", "stage2", "sweep"):
        assert {(section, 1), (section, 2)} <= got
    assert {r["section"] for r in rows} == set(bench.SECTIONS)
    assert report["config"]["resolution"] == 128 and report["config"]["precision"] == "fp32"
    for r in rows:
        assert r["min_ms"] <= r["median_ms"] <= r["max_ms"]
        assert r["per_item_ms"] == pytest.approx(r["median_ms"] / r["items"])
        assert r["peak_mb"] > 0 and math.isfinite(r["items_per_s"])
    sweep = [r for r in rows if r["section"] == "sweep"]
    assert all(r["items"] == 2 and r["lights"] == 2 for r in sweep)


def test_report_is_json_and_markdown(report):
    again = json.loads(json.dumps(report))
    assert again["rows"] == report["rows"]
    text = bench.to_markdown(report, "tiny")
    lines = text.splitlines()
    assert lines[0] == "### tiny"
    table = [line for line in lines if line.startswith("|")]
    assert len(table) == 2 + len(report["rows"])  # header, separator, one line per row
    assert "speed-up vs torch" not in text  # no torch rows, no ratio column


def test_markdown_speedup_column_compares_with_torch():
    timing = {"median_ms": 10.0, "min_ms": 9.0, "max_ms": 11.0, "repeats": 3, "peak_mb": 1.0}
    slow = {**timing, "median_ms": 30.0}
    report = {"rows": [bench.row("stage1", "torch", slow), bench.row("stage1", "onnxruntime", timing)]}
    text = bench.to_markdown(report)
    assert "speed-up vs torch" in text
    assert "| 3.00× |" in text


def test_selected_sections_only(tiny_models):
    out = bench.run(tiny_models, sections=["shade", "end_to_end"], **FAST)
    assert {r["section"] for r in out["rows"]} == {"shade", "end_to_end"}
    assert {r["backend"] for r in out["rows"]} == {"numpy", "onnxruntime"}


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [({"sections": ["nope"]}, "unknown"), ({"batches": [0]}, "positive"), ({"n_lights": 0}, "positive")],
)
def test_bad_arguments(tiny_models, kwargs, match):
    with pytest.raises(RelightError, match=match):
        bench.run(tiny_models, **{**FAST, **kwargs})


def test_time_call_counts_calls_and_checks_arguments():
    calls = []
    t = bench.time_call(lambda: calls.append(1), repeats=3, warmup=2)
    assert len(calls) == 5 and t["repeats"] == 3
    with pytest.raises(RelightError, match="repeats"):
        bench.time_call(lambda: None, repeats=0, warmup=0)


def test_cli_writes_json_and_markdown(tiny_models, tmp_path, capsys):
    js, md = tmp_path / "b.json", tmp_path / "b.md"
    argv = ["--models", str(tiny_models), "--sections", "stage1,end_to_end", "--batches", "1", "--repeats", "1",
            "--warmup", "0", "--json", str(js), "--markdown", str(md)]  # fmt: skip
    assert main(["-q", "bench", *argv]) == 0
    data = json.loads(js.read_text())
    assert {r["section"] for r in data["rows"]} == {"stage1", "end_to_end"}
    assert md.read_text() == capsys.readouterr().out
    assert data["system"]["onnxruntime"] and data["system"]["cpu_count"] >= 1


def test_cli_reports_bad_models_folder(tmp_path, capsys):
    assert main(["bench", "--models", str(tmp_path / "missing"), "--repeats", "1"]) == 2
    assert "no relight_rt models found" in capsys.readouterr().err


def test_add_parser_registers_bench_subcommand(tiny_models):
    import argparse

    parser = argparse.ArgumentParser()
    bench.add_parser(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["bench", "--models", str(tiny_models), "--batches", "1,4"])
    assert args.func is bench.cmd_bench and args.batches == [1, 4]


@pytest.mark.parametrize("k", [1, 3])
@pytest.mark.parametrize("size", [(64, 64), (37, 101)])
def test_diffuse_batch_blocks_match_the_formula(k, size):
    rng = np.random.default_rng(k)
    albedo = rng.random((3, *size), dtype=np.float32)
    transport = rng.normal(size=(9, *size)).astype(np.float32)
    lights = rng.normal(size=(k, 9, 3)).astype(np.float32)
    got = diffuse_batch(albedo, transport, lights)
    shading = np.einsum("khw,nkc->nchw", transport.astype(np.float64), lights.astype(np.float64))
    want = np.clip(albedo * np.maximum(shading, 0), 0, 1)
    assert got.shape == (k, 3, *size) and got.dtype == np.float32
    np.testing.assert_allclose(got, want, atol=1e-5)


def test_precision_int8_falls_back_to_fp32_when_absent(tiny_models, caplog):
    r = Relighter(RuntimeConfig(models=tiny_models, device="cpu", precision="int8"))
    assert r.stage1.name.endswith("stage1.onnx")
    assert "no stage1_int8.onnx" in caplog.text


def test_precision_unknown_is_refused(tiny_models):
    with pytest.raises(RelightError, match="precision"):
        Relighter(RuntimeConfig(models=tiny_models, device="cpu", precision="int4"))


# ------------------------------------------------------------------------------ session performance settings


def test_cpu_session_options(monkeypatch):
    import onnxruntime as ort

    from relight_rt.engine.session import cpu_session_options

    monkeypatch.setenv("RELIGHT_RT_THREADS", "3")
    opts = cpu_session_options()
    assert opts.graph_optimization_level == ort.GraphOptimizationLevel.ORT_ENABLE_ALL
    assert opts.execution_mode == ort.ExecutionMode.ORT_SEQUENTIAL
    assert opts.intra_op_num_threads == 3 and opts.enable_mem_pattern and opts.enable_cpu_mem_arena


def test_cuda_and_tensorrt_provider_chain_without_a_gpu(monkeypatch, tmp_path):
    """The provider list asked for when CUDA / TensorRT are offered (nothing runs: no GPU needed)."""
    import onnxruntime as ort

    from relight_rt.engine import session

    offered = ["TensorrtExecutionProvider", "CUDAExecutionProvider", "CPUExecutionProvider"]
    monkeypatch.setattr(ort, "get_available_providers", lambda: offered)
    monkeypatch.delenv("RELIGHT_RT_TENSORRT", raising=False)
    chain = session._providers_for("auto", 1)
    assert [p if isinstance(p, str) else p[0] for p in chain] == ["CUDAExecutionProvider", "CPUExecutionProvider"]
    assert chain[0][1]["device_id"] == "1" and chain[0][1]["cudnn_conv_algo_search"] == "EXHAUSTIVE"
    cache = tmp_path / "trt"
    monkeypatch.setenv("RELIGHT_RT_TENSORRT", str(cache))
    chain = session._providers_for("cuda", 0)
    assert chain[0][0] == "TensorrtExecutionProvider" and chain[1][0] == "CUDAExecutionProvider"
    assert chain[0][1]["trt_engine_cache_path"] == str(cache) and cache.is_dir()
    assert session._providers_for("cpu", 0) == ["CPUExecutionProvider"]
