"""benchmarks/people_masks_eval.py's outline_offset: where a mask's outline cuts the photo's own (blurred) edge."""

from __future__ import annotations

import cv2
import numpy as np


def disc_photo(radius: float = 40.0, blur: float = 1.2, size: int = 160):
    """A red disc on a blue backdrop, its edge blurred as a lens and JPEG blur it; the disc's true outline is the
    circle ``radius`` (the edge's half mix)."""
    yy, xx = np.mgrid[:size, :size].astype(np.float32)
    r = np.hypot(yy - size / 2 + 0.5, xx - size / 2 + 0.5)
    sharp = np.clip(radius + 0.5 - r, 0.0, 1.0)  # area coverage, about
    alpha = cv2.GaussianBlur(sharp, (0, 0), blur)
    rgb = alpha[..., None] * np.float32([0.8, 0.2, 0.1]) + (1 - alpha[..., None]) * np.float32([0.1, 0.3, 0.8])
    return rgb.astype(np.float32), r


def test_an_outline_through_the_edges_half_mix_is_at_zero_and_a_generous_one_is_not(load_benchmark):
    pme = load_benchmark("people_masks_eval")
    rgb, r = disc_photo()
    on = pme.outline_offset(rgb, r < 40.0)
    wide = pme.outline_offset(rgb, r < 41.0)
    tight = pme.outline_offset(rgb, r < 39.0)
    assert abs(on) < 0.3  # measured 0.02 (41 px: +0.89, 39 px: -0.81)
    assert 0.6 < wide - on < 1.4 and 0.6 < on - tight < 1.4  # one pixel more or less of the edge's backdrop side
    grey = np.full_like(rgb, 0.5)  # no edge to measure against
    assert np.isnan(pme.outline_offset(grey, r < 40.0))
