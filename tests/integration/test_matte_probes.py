"""benchmarks/matte_probes.py's replayed rules on synthetic masks: what each takes out or in, and what it leaves."""

from __future__ import annotations

import numpy as np


def scene():
    """A 100x100 matte: a body (rows 20-80, columns 30-60) with a blob beside it (rows 40-50, columns 60-70) that
    neither graph sees; the selfie graph sees the body and an arm joined to it (rows 30-35, columns 10-30) and a
    patch far away (rows 85-95, columns 80-95); the pose graph sees all of what the selfie graph sees."""
    pred = np.zeros((100, 100), bool)
    pred[20:80, 30:60] = True
    pred[40:50, 60:70] = True
    selfie = np.zeros((100, 100))
    selfie[20:80, 30:60] = 0.99
    selfie[30:35, 10:30] = 0.99
    selfie[85:95, 80:95] = 0.99
    return pred, selfie, selfie.copy()


def test_drop_takes_out_what_both_graphs_doubt_and_keeps_the_body(load_benchmark):
    mp = load_benchmark("matte_probes")
    pred, selfie, pose = scene()
    out = mp.dropped(pred, selfie, pose, 0.05, 0.05, 0.002)
    assert not out[40:50, 60:70].any() and out[20:80, 30:60].all()
    assert mp.dropped(pred, selfie, pose, 0.05, 0.05, 0.002, gate=0.99) is pred  # the gate: the whole photo disagrees
    assert mp.dropped(pred, selfie, pose, 0.05, 0.05, 0.2).sum() == pred.sum()  # a part under MIN x the matte stays


def test_add_takes_in_a_seen_part_joined_to_the_matte_and_not_one_apart(load_benchmark):
    mp = load_benchmark("matte_probes")
    pred, selfie, pose = scene()
    out = mp.added(pred, selfie, pose, 0.9, 0.5, 0.5)
    assert out[30:35, 10:30].all() and not out[85:95, 80:95].any()
    assert not mp.added(pred, selfie, pose, 0.9, 0.5, 0.01)[30:35, 10:30].any()  # larger than MAX x the matte
