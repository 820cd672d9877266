"""benchmarks/matte_ablation.py's machinery: each rule's switch names a real function or constant and puts it back,
and the graphs' memo answers an input seen before without running the graph again."""

from __future__ import annotations

import numpy as np
import pytest

from relight_rt.engine.session import Model


def test_every_rule_switches_a_real_attribute_off_and_back(load_benchmark):
    ab = load_benchmark("matte_ablation")
    assert len(ab.RULES) >= 20
    for rule, (_, patches) in ab.RULES.items():
        before = [getattr(obj, attr) for obj, attr, _ in patches]  # AttributeError: a rule renamed or removed
        with ab.switched_off(rule):
            assert all(getattr(obj, attr) is off for obj, attr, off in patches), rule
        assert all(getattr(obj, attr) is b for (obj, attr, _), b in zip(patches, before, strict=True)), rule


def test_a_switch_is_put_back_when_the_run_fails(load_benchmark):
    ab = load_benchmark("matte_ablation")
    obj, attr, _ = ab.RULES["turned"][1][0]
    before = getattr(obj, attr)
    with pytest.raises(RuntimeError), ab.switched_off("turned"):
        raise RuntimeError("a failing run")
    assert getattr(obj, attr) is before


def test_the_memo_runs_a_graph_once_per_input_and_hands_out_copies(load_benchmark, monkeypatch):
    ab = load_benchmark("matte_ablation")
    calls = []

    def run(self, feeds):
        calls.append(self.name)
        return {"out": feeds["image"].sum(axis=1, keepdims=True) * 2.0}

    monkeypatch.setattr(Model, "run", run)  # memoise_graphs wraps this one; monkeypatch restores the real run
    monkeypatch.setattr(ab, "_MEMO", {})
    ab.memoise_graphs()
    model, other = Model(None, None, "a"), Model(None, None, "b")
    image = np.arange(12, dtype=np.float32).reshape(1, 3, 2, 2)
    first = model.run({"image": image})
    first["out"][:] = -1.0  # a caller writing into its answer changes no later answer
    again = model.run({"image": image.copy()})
    np.testing.assert_array_equal(again["out"], image.sum(axis=1, keepdims=True) * 2.0)
    assert calls == ["a"]
    other.run({"image": image})  # another graph, the same input: its own run
    model.run({"image": image + 1.0})  # another input: run
    assert calls == ["a", "b", "a"]
