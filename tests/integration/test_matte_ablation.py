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


def test_mirrored_runs_the_ablation_on_mirrored_images_without_the_baseline_check(
    load_benchmark, monkeypatch, tmp_path
):
    import cv2

    ab = load_benchmark("matte_ablation")
    photo = np.zeros((8, 12, 3), np.uint8)
    photo[:, :4] = 255
    cv2.imwrite(str(tmp_path / "x.png"), photo)
    seen = []

    def ablate(rules, save, check):
        seen.append((rules, check, ab.PME.read_rgb(tmp_path / "x.png")))
        return 0

    monkeypatch.setattr(ab, "ablate", ablate)
    assert ab.main(["--mirrored", "--rules", "turned"]) == 0
    assert ab.main(["--rules", "turned"]) == 0
    (rules, check, mirrored), (_, check_asis, asis) = seen
    assert rules == ["turned"] and not check and check_asis
    assert mirrored[:, -4:].min() == 1.0 and mirrored[:, :-4].max() == 0.0
    np.testing.assert_array_equal(asis, mirrored[:, ::-1])  # and the readers are put back after the run
