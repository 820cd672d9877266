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


def test_shading_cues_read_a_silhouette_under_a_bright_sky(fb):
    lum = np.full((96, 128), 0.2)
    lum[:40] = 2.0  # a bright sky over the horizon
    lum[40:58] = 0.02  # the dark faces of things toward the camera
    cues = fb.shading_cues(lum)
    assert cues["edge_polarity"] == pytest.approx(0.0, abs=1e-6)  # one step down at 40, one up at 58
    assert cues["vertical_dark"] > 3
    assert cues["lower_dark"] > 0 and cues["ground_gradient"] < 0  # the dark band reaches below the horizon
    lit = np.full((96, 128), 0.2)
    lit[:40] = 2.0
    assert fb.shading_cues(lit)["edge_polarity"] == 1.0  # only brighter above
    even = fb.shading_cues(np.full((96, 128), 0.3))
    assert set(even) == {"lower_contrast", "lower_over_upper", "lower_dark", "ground_gradient", "vertical_dark",
                         "edge_polarity"}  # fmt: skip
    assert all(v == pytest.approx(0.0, abs=1e-5) for v in even.values())  # an even view: no cue (float32 blur)


def test_opposed_order_counts_the_opposite_views_a_cue_orders(fb):
    rows = {
        "a_y000": ({"score": -0.5}, -2.0), "a_y180": ({"score": -0.1}, 2.0),  # ordered right, both called back
        "b_y090": ({"score": 0.3}, -1.5), "b_y270": ({"score": 0.1}, 1.5),  # ordered wrong
        "c_y000": ({"score": 0.0}, -0.5), "c_y180": ({"score": 1.0}, 0.5),  # not clear: not counted
    }  # fmt: skip
    assert fb.opposed_order(rows) == (1, ["a_y000", "b_y090"])


def test_best_line_is_the_in_sample_ceiling(fb):
    rows = {f"m{i}": ({"top_bottom": float(i), "colour_share": 0.0}, -1.5 if i < 3 else 1.5) for i in range(6)}
    assert fb.best_line(rows) == 1.0  # separable: a threshold on top_bottom
    rows["m5"] = ({"top_bottom": 0.0, "colour_share": 0.0}, 1.5)  # the same point as m0, the other answer
    assert fb.best_line(rows) == pytest.approx(5 / 6)


def test_both_either_and_the_vote(fb):
    """scene24's combinations of two rules: back-lit where both say / where either says; the vote takes their call
    where they agree and a third rule's where they do not."""
    yes, no = (lambda train: lambda f: True), (lambda train: lambda f: False)
    f = {}
    assert fb.both(yes, yes)([])(f) and not fb.both(yes, no)([])(f)
    assert fb.either(yes, no)([])(f) and not fb.either(no, no)([])(f)
    assert fb.vote(yes, yes, no)([])(f) and not fb.vote(no, no, yes)([])(f)
    assert fb.vote(yes, no, yes)([])(f) and not fb.vote(yes, no, no)([])(f)


def test_lstsq_rule_clip_keeps_a_sun_from_moving_the_line(fb):
    train = [({"x": x}, t) for x, t in ((-2.0, -1.5), (-0.5, -1.2), (0.5, 1.2), (2.0, 1.5), (0.0, -6.0))]
    assert fb.lstsq_rule(["x"], clip=1.0)(train)({"x": 0.5}) is False  # front-lit, as its truth
    assert fb.lstsq_rule(["x"])(train)({"x": 0.5}) is True  # the unclipped fit calls it back-lit
    assert fb.lstsq_rule(["x"], clear_only=True)(train)({"x": 0.5}) is True  # clear-only keeps the sun
