"""relight_rt.engine.graph_cache: an optimised graph written once (atomically), loaded later with the same results,
keyed by the graph's bytes, a damaged file replaced, and ``RELIGHT_RT_CACHE=off`` writing nothing."""

import numpy as np
import onnxruntime as ort
import pytest
from _graphs import save, stage1_model

from relight_rt.engine import environment
from relight_rt.engine.graph_cache import graph_key, open_session
from relight_rt.engine.session import _warmup_feeds, cpu_session_options, load_model

CPU = ["CPUExecutionProvider"]


@pytest.fixture
def graph(tmp_path):
    path = tmp_path / "stage1.onnx"
    save(stage1_model(64), path)
    return path


@pytest.fixture
def cache(tmp_path, monkeypatch):
    folder = tmp_path / "cache"
    monkeypatch.setenv("RELIGHT_RT_CACHE", str(folder))
    return folder


def run(model):
    feeds = _warmup_feeds(model.session, model.config)
    feeds = {k: np.random.default_rng(1).random(v.shape).astype(np.float32) for k, v in feeds.items()}
    return model.session.run(None, feeds)


def test_written_once_then_loaded_with_the_same_results(graph, cache):
    first = load_model(graph, "stage1", device="cpu", warmup=False)
    files = sorted(cache.iterdir())
    assert len(files) == 1 and files[0].name.startswith("stage1-") and files[0].suffix == ".onnx"
    stamp = files[0].stat().st_mtime_ns
    second = load_model(graph, "stage1", device="cpu", warmup=False)
    assert sorted(cache.iterdir()) == files and files[0].stat().st_mtime_ns == stamp  # read, not written again
    assert second.config == first.config  # the metadata travels with the optimised graph
    for a, b in zip(run(first), run(second), strict=True):
        np.testing.assert_array_equal(a, b)
    opts = cpu_session_options()
    open_session(graph, opts, CPU)
    assert opts.graph_optimization_level == ort.GraphOptimizationLevel.ORT_ENABLE_ALL  # the caller's options kept
    assert opts.optimized_model_filepath == ""


def test_key_follows_the_graph_and_onnxruntime(graph, tmp_path):
    level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
    key = graph_key(graph, level, CPU)
    assert key == graph_key(graph, level, CPU)
    other = tmp_path / "other.onnx"
    save(stage1_model(128), other)
    assert graph_key(other, level, CPU) != key
    assert graph_key(graph, ort.GraphOptimizationLevel.ORT_ENABLE_BASIC, CPU) != key


def test_a_damaged_file_is_optimised_again(graph, cache):
    load_model(graph, "stage1", device="cpu", warmup=False)
    (cached,) = cache.iterdir()
    cached.write_bytes(b"not a graph")
    model = load_model(graph, "stage1", device="cpu", warmup=False)
    assert model.config.kind == "stage1" and cached.stat().st_size > 1000  # whole again
    assert not [p for p in cache.iterdir() if p.name.endswith(".tmp")]  # no temporary file left


def test_off_writes_nothing(graph, tmp_path, monkeypatch):
    monkeypatch.setenv("RELIGHT_RT_CACHE", "off")
    assert environment.graph_cache() is None
    load_model(graph, "stage1", device="cpu", warmup=False)
    assert [p.name for p in tmp_path.iterdir()] == ["stage1.onnx"]
    monkeypatch.delenv("RELIGHT_RT_CACHE")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert environment.graph_cache() == str(tmp_path / "xdg" / "relight_rt" / "graphs")


def test_an_unwritable_folder_falls_back(graph, tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    monkeypatch.setenv("RELIGHT_RT_CACHE", str(blocker / "sub"))  # under a file: cannot be made
    assert load_model(graph, "stage1", device="cpu", warmup=False).config.kind == "stage1"
