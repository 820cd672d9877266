"""relight_rt.relight.graphs: which file of a kind runs in a precision, and stage 1 and 2 loaded, warmed up as the
config says and checked against each other. The loader is a stand-in that records what it was asked (no ONNX), but
for one smoke test on the hand-made graphs of tests/_graphs.py; test_relighter.py and cli/test_bench.py check the same
through a Relighter (a mismatched stage 2, int8's fall-back).
"""

from __future__ import annotations

import logging
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from _graphs import make_models_dir

from relight_rt import RelightError, RuntimeConfig
from relight_rt.relight import graphs
from relight_rt.relight.graphs import graph_file, load_stages

LOGGER = "relight_rt.relight.graphs"


def touch(folder: Path, *names: str) -> Path:
    for name in names:
        (folder / name).write_bytes(b"")
    return folder


# ------------------------------------------------------------------------------------------------ graph_file


@pytest.mark.parametrize(("kind", "precision", "present", "want"), [
    ("stage1", "fp32", (), "stage1.onnx"),  # fp32 is the kind's own name, there or not
    ("stage1", "fp16", ("stage1.onnx", "stage1_fp16.onnx"), "stage1_fp16.onnx"),
    ("stage2", "int8", ("stage2_int8.onnx",), "stage2_int8.onnx"),
    ("stage2", "int8", (), "stage2_int8.onnx"),  # neither: the one asked for, so that its absence is named
    ("dvp", "fp16", ("dvp.onnx", "dvp_int8.onnx"), "dvp.onnx"),  # fp32 rather than another precision
])
def test_graph_file_picks_the_precision_else_fp32(tmp_path, caplog, kind, precision, present, want):
    touch(tmp_path, *present)
    with caplog.at_level(logging.WARNING, logger=LOGGER):
        assert graph_file(tmp_path, kind, precision) == tmp_path / want
    fell_back = want == f"{kind}.onnx" and precision != "fp32"
    assert (f"no {kind}_{precision}.onnx, running {kind} in fp32" in caplog.text) == fell_back


def test_graph_file_refuses_an_unknown_kind(tmp_path):
    with pytest.raises(RelightError, match=r"model kind 'stage3' is unknown; known kinds: \[.*'stage1'"):
        graph_file(tmp_path, "stage3", "fp32")


# ------------------------------------------------------------------------------------------------ load_stages


class Loader:
    """A stand-in for relight_rt.engine.session.load_model: models of the given resolutions, on CUDA or not, that
    count their warm-ups; ``calls`` holds (file name, kind, warmup, session arguments)."""

    def __init__(self, on_cuda: bool = False, resolutions=None) -> None:
        self.on_cuda, self.resolutions = on_cuda, resolutions or {"stage1": 64, "stage2": 0}
        self.calls, self.models = [], {}

    def __call__(self, path, kind, *, warmup, **session_args):
        self.calls.append((Path(path).name, kind, warmup, session_args))
        model = SimpleNamespace(config=SimpleNamespace(resolution=self.resolutions[kind]), on_cuda=self.on_cuda,
                                warm_ups=0)
        model.warm_up = lambda: setattr(model, "warm_ups", model.warm_ups + 1)
        self.models[kind] = model
        return model


ARGS = {"device": "cpu", "device_id": 0, "providers": None}


@pytest.mark.parametrize(("warmup", "on_cuda", "warm"), [
    (None, False, False), (None, True, True), (True, False, True), (False, True, False)])
def test_load_stages_warms_up_as_the_config_says(tmp_path, monkeypatch, warmup, on_cuda, warm):
    """Stage 1 is loaded cold and warmed once when ``config.warmup`` says so (None: on CUDA); stage 2 is asked for
    the same."""
    loader = Loader(on_cuda)
    monkeypatch.setattr(graphs, "load_model", loader)
    touch(tmp_path, "stage1.onnx", "stage2.onnx")
    stage1, stage2 = load_stages(tmp_path, RuntimeConfig(models=tmp_path, warmup=warmup), ARGS)
    assert (stage1, stage2) == (loader.models["stage1"], loader.models["stage2"])
    assert loader.calls == [("stage1.onnx", "stage1", False, ARGS), ("stage2.onnx", "stage2", warm, ARGS)]
    assert stage1.warm_ups == int(warm) and stage2.warm_ups == 0  # stage 2's is load_model's to do


def test_load_stages_in_a_precision(tmp_path, monkeypatch, caplog):
    loader = Loader()
    monkeypatch.setattr(graphs, "load_model", loader)
    touch(tmp_path, "stage1.onnx", "stage1_int8.onnx", "stage2.onnx")
    with caplog.at_level(logging.WARNING, logger=LOGGER):
        load_stages(tmp_path, RuntimeConfig(models=tmp_path, precision="int8"), ARGS)
    assert [c[0] for c in loader.calls] == ["stage1_int8.onnx", "stage2.onnx"]
    assert "no stage2_int8.onnx, running stage2 in fp32" in caplog.text


def test_without_stage2_results_are_diffuse_only(tmp_path, monkeypatch, caplog):
    loader = Loader()
    monkeypatch.setattr(graphs, "load_model", loader)
    touch(tmp_path, "stage1.onnx")
    with caplog.at_level(logging.WARNING, logger=LOGGER):
        stage1, stage2 = load_stages(tmp_path, RuntimeConfig(models=tmp_path), ARGS)
    assert stage2 is None and stage1 is loader.models["stage1"] and len(loader.calls) == 1
    assert "has no stage2.onnx: results are diffuse-only" in caplog.text


@pytest.mark.parametrize("res2", [0, 64])
def test_stage2_at_stage1s_resolution_or_any(tmp_path, monkeypatch, res2):
    monkeypatch.setattr(graphs, "load_model", Loader(resolutions={"stage1": 64, "stage2": res2}))
    touch(tmp_path, "stage1.onnx", "stage2.onnx")
    assert load_stages(tmp_path, RuntimeConfig(models=tmp_path), ARGS)[1].config.resolution == res2


@pytest.mark.parametrize("res2", [32, 128])
def test_stage2_at_another_resolution_is_refused(tmp_path, monkeypatch, res2):
    monkeypatch.setattr(graphs, "load_model", Loader(resolutions={"stage1": 64, "stage2": res2}))
    touch(tmp_path, "stage1.onnx", "stage2.onnx")
    with pytest.raises(RelightError, match=rf"stage2.onnx: resolution {res2} does not match stage 1's 64 \(or 0"):
        load_stages(tmp_path, RuntimeConfig(models=tmp_path), ARGS)


def test_load_stages_on_the_hand_made_graphs(tmp_path):
    """Smoke: the analytic stage 1 (R = 64) and the toy stage 2 (any size) load and run on the CPU."""
    folder = make_models_dir(tmp_path / "models", 64)
    stage1, stage2 = load_stages(folder, RuntimeConfig(models=folder, device="cpu"), {"device": "cpu"})
    assert (stage1.config.kind, stage1.config.resolution, stage1.on_cuda) == ("stage1", 64, False)
    assert (stage2.config.kind, stage2.config.resolution) == ("stage2", 0)
    diffuse = np.full((1, 3, 8, 8), 0.5, np.float32)
    out = stage2.run({"diffuse": diffuse, "mask": np.ones((1, 1, 8, 8), np.float32)})
    np.testing.assert_allclose(out["relit"], diffuse)  # the toy's r = gain x (diffuse - 0.5) is 0 here
    for precision in ("fp32", "fp16"):  # no graphs at all: the file asked for is named
        name = "stage1.onnx" if precision == "fp32" else f"stage1_{precision}.onnx"
        with pytest.raises(RelightError, match=f"model file .*{name} not found"):
            load_stages(tmp_path, RuntimeConfig(models=tmp_path, precision=precision), {"device": "cpu"})
