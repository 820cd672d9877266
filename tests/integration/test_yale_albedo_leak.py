"""benchmarks/yale_albedo_leak.py ``leak``: how much of a photo's light an albedo keeps, on synthetic faces whose
answer is known (no Yale data needed)."""

import numpy as np


def _photos(ya, size=64):
    """A face lit from the front (even) and from one side (a sweep from bright to nearly black), with skin texture."""
    rng = np.random.default_rng(0)
    skin = 0.6 * np.exp(0.1 * rng.standard_normal((size, size)))
    sweep = np.clip(np.linspace(1.0, 0.02, size), 0, 1)[None, :].repeat(size, 0)
    return (skin * 0.8).astype(np.float32), (skin * 0.8 * sweep).astype(np.float32), ya.ellipse((size, size)) > 0


def test_an_albedo_that_keeps_no_light_scores_zero_and_one_that_keeps_all_scores_the_photos_change(load_benchmark):
    ya = load_benchmark("yale_albedo_leak")
    front, side, face = _photos(ya)
    none = ya.leak(front / 0.8, front / 0.8, side, front, face)  # the same albedo under both lamps
    assert all(abs(v) < 1e-9 for v in none.values())
    everything = ya.leak(side, front, side, front, face)  # the albedo is the photo: all the light kept
    assert abs(everything["slope"] - 1) < 1e-6
    assert everything["dark"] < -1.0 < everything["lit"] < 0  # the dark side kept as dark albedo (-1.31)
    assert everything["broad"] > 5 * everything["fine"]  # a sweep: the kept light is broad
    half = ya.leak(np.sqrt(side * front), front, side, front, face)  # half of it, in log
    assert abs(half["slope"] - 0.5) < 0.01 and abs(half["dark"] - everything["dark"] / 2) < 0.02


def test_fine_detail_kept_shows_as_fine_not_broad(load_benchmark):
    ya = load_benchmark("yale_albedo_leak")
    front, side, face = _photos(ya)
    speckle = np.exp(0.3 * np.random.default_rng(1).standard_normal(front.shape)).astype(np.float32)
    f = ya.leak(front * speckle, front, side, front, face)
    assert f["fine"] > 3 * f["broad"]
