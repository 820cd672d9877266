"""benchmarks/matte_identical.py: a difference is told apart from none, and two runs of one tree agree to the bit
(the comparison that says a house-keeping change changed no matte)."""

from __future__ import annotations

import numpy as np


def test_difference_tells_apart_none_a_matte_missing_and_a_change(load_benchmark):
    mi = load_benchmark("matte_identical")
    a = np.zeros((4, 5), np.float32)
    b = a.copy()
    b[2, 3] = 0.25
    empty = np.zeros(0, np.float32)
    assert mi.difference(a, a.copy()) == 0.0
    assert mi.difference(a, b) == 0.25
    assert mi.difference(empty, empty) == "none"
    assert mi.difference(a, empty) == "DIFFERS" and mi.difference(empty, a) == "DIFFERS"
    assert mi.difference(a, np.zeros((5, 4), np.float32)) == "DIFFERS"


def test_the_tree_against_itself_gives_the_same_mattes(load_benchmark, monkeypatch, capsys):
    mi = load_benchmark("matte_identical")
    example = str(mi.REPO / "relight_rt" / "data" / "example.png")
    monkeypatch.setattr(mi, "chosen", lambda *a: [("example", example, False), ("mirrored", example, True)])
    assert mi.main([str(mi.REPO)]) == 0
    out = capsys.readouterr().out
    assert "4 mattes, largest difference 0, 0 differing" in out
