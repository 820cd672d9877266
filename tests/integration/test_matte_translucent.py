"""benchmarks/matte_translucent.py's translucent_share: how much of a mask's interior a matte leaves neither 0 nor 1."""

from __future__ import annotations

import numpy as np


def test_only_a_soft_interior_counts_not_a_soft_edge_nor_a_missed_part(load_benchmark):
    mt = load_benchmark("matte_translucent")
    yy, xx = np.mgrid[:200, :200] + 0.5
    r = np.hypot(yy - 100, xx - 100)
    mask = r < 60
    sharp = mask.astype(np.float32)
    assert mt.translucent_share(sharp, mask) == 0.0
    soft_edge = np.clip((60 - r) / 5, 0, 1).astype(np.float32)  # soft over 5 px at the outline (2 bands: 6 px)
    assert mt.translucent_share(soft_edge, mask) == 0.0
    assert mt.translucent_share(np.where(mask, 0.73, 0.0).astype(np.float32), mask) == 1.0  # see-through inside
    assert mt.translucent_share(np.zeros_like(sharp), mask) == 0.0  # missed: an IoU fault, not a translucent one
    half = np.where(mask & (xx < 100), 0.6, sharp).astype(np.float32)
    assert 0.45 < mt.translucent_share(half, mask) < 0.55
    assert mt.translucent_share(sharp, r < 3) == 0.0  # no interior
