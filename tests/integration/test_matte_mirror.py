"""benchmarks/matte_mirror.py: the mirror gap of a matte (matte(mirror(photo)) mirrored back against matte(photo))."""

from __future__ import annotations

import numpy as np


def photo() -> np.ndarray:
    """A bright block off-centre to the left on a dark (H, W, 3) backdrop: differs from its mirror image."""
    rgb = np.full((40, 60, 3), 0.1, np.float32)
    rgb[5:35, 4:24] = 0.9
    return rgb


def test_a_matte_that_mirrors_with_the_photo_has_no_gap(load_benchmark):
    mm = load_benchmark("matte_mirror")
    row = mm.mirror_gap(lambda rgb: (rgb.mean(axis=2) > 0.5).astype(np.float32), photo())
    assert row == {"p99": 0.0, "max": 0.0, "iou": 1.0}


def test_a_matte_fixed_to_one_side_of_the_frame_has_the_whole_person_as_its_gap(load_benchmark):
    mm = load_benchmark("matte_mirror")

    def left(rgb):
        alpha = np.zeros(rgb.shape[:2], np.float32)
        alpha[5:35, 4:24] = 1.0  # where the person is on the photo as it comes, whatever it is shown
        return alpha

    row = mm.mirror_gap(left, photo())
    assert row["iou"] == 0.0 and row["max"] == 255.0 and row["p99"] == 255.0
    half = mm.mirror_gap(lambda rgb: left(rgb) * 0.5 + 0.5 * (rgb.mean(axis=2) > 0.5), photo())
    assert 0.0 < half["iou"] < 1.0 and half["max"] == 127.5  # (0.5 in 8-bit levels)


def test_nobody_on_either_side_is_no_gap(load_benchmark):
    mm = load_benchmark("matte_mirror")
    assert mm.mirror_gap(lambda rgb: np.zeros(rgb.shape[:2], np.float32), photo()) == {
        "p99": 0.0,
        "max": 0.0,
        "iou": 1.0,
    }


def test_repeat_below_one_is_refused(load_benchmark):
    import pytest

    mm = load_benchmark("matte_mirror")
    with pytest.raises(SystemExit):
        mm.main(["--repeat", "0"])
