"""relight_rt.engine.graph_cache: an optimised graph written once (atomically), loaded later with the same results,
keyed by the graph's bytes, a damaged file replaced, and ``RELIGHT_RT_CACHE=off`` writing nothing."""

import numpy as np
import onnxruntime as ort
import pytest
from _graphs import save, stage1_model

from relight_rt.engine import environment
from relight_rt.engine.graph_cache import graph_digest, graph_key, open_session
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


def graphs(cache):
    """The optimised graphs in the cache folder (not its ``digests/``)."""
    return sorted(p for p in cache.iterdir() if p.is_file())


def run(model):
    feeds = _warmup_feeds(model.session, model.config)
    feeds = {k: np.random.default_rng(1).random(v.shape).astype(np.float32) for k, v in feeds.items()}
    return model.session.run(None, feeds)


def test_written_once_then_loaded_with_the_same_results(graph, cache):
    first = load_model(graph, "stage1", device="cpu", warmup=False)
    files = graphs(cache)
    assert len(files) == 1 and files[0].name.startswith("stage1-") and files[0].suffix == ".onnx"
    stamp = files[0].stat().st_mtime_ns
    second = load_model(graph, "stage1", device="cpu", warmup=False)
    assert graphs(cache) == files and files[0].stat().st_mtime_ns == stamp  # read, not written again
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
    (cached,) = graphs(cache)
    cached.write_bytes(b"not a graph")
    model = load_model(graph, "stage1", device="cpu", warmup=False)
    assert model.config.kind == "stage1" and cached.stat().st_size > 1000  # whole again
    assert not [p for p in cache.rglob("*") if ".tmp" in p.name]  # no temporary file left


def test_the_digest_is_remembered_and_follows_the_file(graph, tmp_path):
    """A cold process reads the graph's digest from a note instead of hashing the file; writing the file (its change
    time moves, even when its size and modification time are put back) makes a new note."""
    import os

    folder = tmp_path / "cache"
    plain = graph_digest(graph)
    assert graph_digest(graph, str(folder)) == plain  # hashed, then noted
    (note,) = (folder / "digests").iterdir()
    note.write_text("0" * 40)  # the note is what is read the second time
    assert graph_digest(graph, str(folder)) == "0" * 40
    st = graph.stat()
    other = tmp_path / "other.onnx"
    save(stage1_model(128), other)
    graph.write_bytes(other.read_bytes()[: st.st_size].ljust(st.st_size, b"\0"))  # another graph, same size
    os.utime(graph, ns=(st.st_atime_ns, st.st_mtime_ns))  # and the same modification time
    assert graph_digest(graph, str(folder)) == graph_digest(graph) != plain
    (new_note,) = set((folder / "digests").iterdir()) - {note}
    new_note.write_text("not a digest")  # a damaged note: the file is hashed again
    assert graph_key(graph, ort.GraphOptimizationLevel.ORT_ENABLE_ALL, CPU, str(folder)) == graph_key(
        graph, ort.GraphOptimizationLevel.ORT_ENABLE_ALL, CPU)


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
