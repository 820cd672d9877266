"""benchmarks/matte_fault_kinds.py: what following the selfie graph on one kind of disagreement could win
(selfie_ceiling), on synthetic masks."""

from __future__ import annotations

import numpy as np


def test_the_selfie_ceiling_splits_the_disagreement_by_side_and_by_distance_from_the_outline(load_benchmark):
    fk = load_benchmark("matte_fault_kinds")
    gt = np.zeros((100, 100), bool)
    gt[20:80, 20:80] = True
    ours, selfie = gt.copy(), gt.copy()
    ours[20:80, 10:20] = True  # ours takes a 10-px strip of backdrop the selfie graph leaves (mostly away)
    ours[50:60, 50:60] = False  # ours misses a hole the selfie graph fills (away from the outline)
    selfie[19, 20:80] = True  # the selfie graph takes a 1-px rim ours leaves (in the band), wrongly
    got = fk.selfie_ceiling(ours, selfie, gt)
    assert set(got) == set(fk.SIDES)
    base = 3500 / 4200  # ours: 3500 of the mask's 3600 pixels, union with the 600-px strip 4200
    # the strip's columns 10-17 lie past BAND (2 px) from the outline: 480 px; columns 18-19 in the band: 120 px
    assert np.isclose(got["away: ours adds"], 3500 / 3720 - base)
    assert np.isclose(got["band: ours adds"], 3500 / 4080 - base)
    assert np.isclose(got["away: ours misses"], 3600 / 4200 - base)  # the hole filled
    assert np.isclose(got["band: ours misses"], 3500 / 4260 - base) and got["band: ours misses"] < 0  # a wrong rim
    same = fk.selfie_ceiling(gt, gt, gt)
    assert all(v == 0 for v in same.values())
