"""benchmarks/scene_frontback.py's sky cue (issue 49): a clear-sky model fitted with the sun free tells a sun ahead of
the camera from one behind it, on skies made by the same model (the benchmark then measures it on real maps)."""

import math

import numpy as np
import pytest


@pytest.fixture(scope="module")
def fb(load_benchmark):
    return load_benchmark("scene_frontback")


def _sky(fb, azimuth: float, elevation: float, h: int = 96, w: int = 128) -> np.ndarray:
    """(h, w) log2 luminance of a clear Perez sky seen by the benchmark's level 60° camera (looking along −x; sun
    azimuth 0 behind the camera, 180 ahead), its top half; the bottom half a flat ground."""
    a, b, c, d, e = fb._PEREZ
    tan_h = math.tan(math.radians(30))
    ys, xs = np.mgrid[:h, :w]
    ray = np.stack([-np.ones((h, w)), ((xs + 0.5) / w * 2 - 1) * tan_h, (1 - (ys + 0.5) / h * 2) * tan_h * h / w], -1)
    ray /= np.linalg.norm(ray, axis=-1, keepdims=True)
    az, el = math.radians(azimuth), math.radians(elevation)
    cos_g = np.clip(ray @ [math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)], -1, 1)
    sky = (1 + a * np.exp(b / np.maximum(ray[..., 2], 0.02))) * (1 + c * np.exp(d * np.arccos(cos_g)) + e * cos_g**2)
    return np.where(ys < h // 2, np.log2(sky), -3.0)


@pytest.mark.parametrize("elevation", [10.0, 25.0, 45.0])
def test_a_sun_ahead_is_told_from_one_behind(fb, elevation):
    mask = np.zeros((96, 128), bool)
    mask[:48] = True
    ahead = fb.perez_ahead(_sky(fb, 170.0, elevation), mask)
    behind = fb.perez_ahead(_sky(fb, 10.0, elevation), mask)
    assert ahead > 0.5 and behind < -0.5
    assert fb.perez_ahead(_sky(fb, 170.0, elevation), np.zeros_like(mask)) == 0.0  # no sky: no answer
