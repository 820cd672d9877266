"""The ship rule of benchmarks/stage1_verdict.py on hand-made figures (no graph is run)."""

from __future__ import annotations

import pytest

SHIPPED = {"heldout": {"face": 0.078, "head-shoulders": 0.097, "waist-up": 0.116, "knees-up": 0.111, "full": 0.118},
           "yale": {"relight": {"corr": 0.873, "contrast": 0.759, "relerr": 0.513},
                    "delight": {"corr": 0.922, "contrast": 0.887, "relerr": 0.397}}}


def _graph(heldout=None, **yale):
    """The shipped figures with some changed: heldout {framing: rmse}, yale task_key=value (relight_corr=...)."""
    out = {"heldout": {**SHIPPED["heldout"], **(heldout or {})},
           "yale": {t: dict(v) for t, v in SHIPPED["yale"].items()}}
    for key, value in yale.items():
        task, _, name = key.partition("_")
        out["yale"][task][name] = value
    return out


@pytest.fixture(scope="module")
def sv(load_benchmark):
    return load_benchmark("stage1_verdict")


BETTER3 = {"face": 0.070, "waist-up": 0.110, "full": 0.110}


def test_better_on_three_and_yale_kept_ships(sv):
    ships, reasons = sv.verdict(SHIPPED, _graph(BETTER3))
    assert ships and reasons == []


def test_the_shipped_graph_against_itself_does_not_ship(sv):
    ships, reasons = sv.verdict(SHIPPED, _graph())
    assert not ships and reasons == ["held-out RMSE better on 0 framings (< 3)"]


def test_better_on_two_only_does_not_ship(sv):
    ships, reasons = sv.verdict(SHIPPED, _graph({"face": 0.070, "full": 0.110}))
    assert not ships and reasons == ["held-out RMSE better on 2 framings (< 3)"]


def test_worse_on_one_framing_does_not_ship(sv):
    ships, reasons = sv.verdict(SHIPPED, _graph({**BETTER3, "knees-up": 0.1111}))
    assert not ships and reasons == ["held-out RMSE worse on knees-up"]


@pytest.mark.parametrize(("key", "value", "ships"), [
    ("relight_corr", 0.873 - 0.0029, True), ("relight_corr", 0.873 - 0.0031, False),
    ("delight_corr", 0.922 - 0.0031, False), ("relight_relerr", 0.513 + 0.0029, True),
    ("relight_relerr", 0.513 + 0.0031, False), ("delight_relerr", 0.397 + 0.0031, False),
    ("relight_contrast", 0.60, True),  # contrast is reported, never gating
])
def test_yale_slack(sv, key, value, ships):
    assert sv.verdict(SHIPPED, _graph(BETTER3, **{key: value}))[0] is ships


def test_a_missing_framing_fails(sv):
    graph = _graph(BETTER3 | {"knees-up": 0.100})
    del graph["heldout"]["full"]
    ships, reasons = sv.verdict(SHIPPED, graph)
    assert not ships and reasons[0] == "held-out framings not measured: full"


def test_best_is_the_lowest_mean_rmse_among_those_that_pass(sv):
    figures = {"a": _graph(BETTER3), "b": _graph({f: v - 0.001 for f, v in BETTER3.items()}),
               "c": _graph({f: 0.05 for f in SHIPPED["heldout"]})}
    assert sv.best_of(figures, ["a", "b"]) == "b"
    assert sv.best_of(figures, []) is None


def test_names_from_the_run_folders(sv):
    from pathlib import Path

    paths = [Path("o/anchor2/stage1.onnx"), Path("o/anchor5/stage1.onnx"), Path("p/anchor5/stage1.onnx"),
             Path("x/soup.onnx")]
    assert sv._names(paths) == ["anchor2", "anchor5", "anchor5_3", "soup"]


def test_a_re_export_of_the_same_weights_ties(sv):
    """A step-0 export reads ~1e-8 off the shipped graph's RMSE: neither worse nor better."""
    ships, reasons = sv.verdict(SHIPPED, _graph({f: v + 1e-8 * (-1) ** i for i, (f, v)
                                                 in enumerate(SHIPPED["heldout"].items())}))
    assert not ships and reasons == ["held-out RMSE better on 0 framings (< 3)"]
    assert sv.verdict(SHIPPED, _graph({**BETTER3, "knees-up": 0.111 + 4e-5}))[0]
    assert not sv.verdict(SHIPPED, _graph({**BETTER3, "knees-up": 0.111 + 6e-5}))[0]
