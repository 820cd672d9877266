"""benchmarks/scene_losses.py (issue 49, scene10): the counterfactual lights it scores the lost pairs with change only
what they say they change, and a lost pair is put down to the right cause; checked on lights whose answer is known."""

import numpy as np
import pytest

from relight_rt import envmap
from relight_rt.light.presets import directional


@pytest.fixture(scope="module")
def sl(load_benchmark):
    return load_benchmark("scene_losses")


def _light(direction, colour=(1.0, 0.8, 0.6), ambient=0.3) -> np.ndarray:
    """(9, 3) a lamp from ``direction`` (subject frame) over a uniform ambient, in ``colour``."""
    lamp = directional(np.asarray(direction, np.float64))[:, 0]
    uniform = envmap.project_envmap(np.ones((32, 64, 3), np.float32))[:, 0]
    return (lamp + ambient * uniform)[:, None] * np.asarray(colour)[None, :]


def test_recolour_takes_the_colour_and_keeps_the_luminance_and_shape(sl):
    warm, cool = _light((0.5, 0.5, 0.7)), _light((-0.6, -0.3, 0.5), colour=(0.5, 0.7, 1.0))
    out = sl.recolour(warm, cool)
    assert sl.se.colour_error(out, cool) == pytest.approx(0.0, abs=1e-4)
    assert sl.se.lum(sl.se.side_rgb(out)) == pytest.approx(sl.se.lum(sl.se.side_rgb(warm)), rel=1e-9)
    assert sl.side(out) == pytest.approx(sl.side(warm), rel=1e-9)  # the shape, per unit front irradiance, kept
    assert sl.se.front_back(out) == pytest.approx(sl.se.front_back(warm), abs=1e-9)


def test_side_reads_the_lamps_side_and_with_side_changes_nothing_else(sl):
    right, left = _light((0.3, 0.9, 0.3)), _light((0.3, -0.9, 0.3))
    assert sl.side(right) > 0.3 and sl.side(left) < -0.3
    assert sl.side(_light((0.8, 0.0, 0.6))) == pytest.approx(0.0, abs=1e-6)
    assert sl.side(_light((0.3, 0.0, 0.9)), 2) > sl.side(_light((0.3, 0.0, -0.9)), 2) + 0.5  # term 2: up-down
    low = sl.with_side(right, 0.1, 2)
    assert sl.side(low, 2) == pytest.approx(0.1, rel=1e-5) and sl.side(low) == pytest.approx(sl.side(right))
    turned = sl.with_side(right, sl.side(left))
    assert sl.side(turned) == pytest.approx(sl.side(left), rel=1e-5)  # y weighs ~1e-7 by quadrature
    # y weighs nothing in the camera-facing or the back irradiance: exposure, colour and front/back unchanged
    np.testing.assert_allclose(sl.se.side_rgb(turned), sl.se.side_rgb(right), rtol=1e-6)
    assert sl.se.front_back(turned) == pytest.approx(sl.se.front_back(right), abs=1e-6)
    # mirrored lamps: the same light in every term but the side's (xy and yz, band 2's left-right, stay the right's)
    np.testing.assert_allclose(np.delete(turned, [4, 5], 0), np.delete(left, [4, 5], 0), atol=1e-5)
    np.testing.assert_allclose(turned[[4, 5]], right[[4, 5]], atol=1e-12)


@pytest.mark.parametrize(
    ("paste", "oracle", "colour_fixed", "shape_fixed", "expected"),
    [
        (0.05, 0.06, 0.01, 0.01, "unwinnable"),
        (0.05, 0.02, 0.04, 0.07, "colour"),
        (0.05, 0.02, 0.07, 0.04, "shape"),
        (0.05, 0.02, 0.04, 0.04, "both"),
        (0.05, 0.02, 0.06, 0.06, "neither"),
    ],
)
def test_cause(sl, paste, oracle, colour_fixed, shape_fixed, expected):
    assert sl.cause(paste, oracle, colour_fixed, shape_fixed) == expected


def test_analyse_counts_the_lost_pairs_by_set_and_side(sl):
    rows = [
        {"subject": "p", "A": "x_y000", "B": "bl-a_y000", "si_paste": 0.05, "si_est": 0.06, "si_oracle": 0.02,
         "colour_est": 8.0, "ev_est_background": 1.5},
        {"subject": "p", "A": "bl-a_y090", "B": "bl-a_y000", "si_paste": 0.05, "si_est": 0.04, "si_oracle": 0.02,
         "colour_est": 3.0, "ev_est_background": -0.5},
        {"subject": "p", "A": "bl-a_y000", "B": "c_y000", "si_paste": 0.05, "si_est": 0.03, "si_oracle": 0.02,
         "colour_est": 2.0, "ev_est_background": 0.2},
    ]  # fmt: skip
    n = len(sl.COUNTERFACTUALS)  # colour fixed, shape fixed, side fixed, side read, side wrong, up fixed, gated
    extra = {0: (0.07, 0.04, 0.04, 0.07, 0.08) + (0.06,) * (n - 5), 1: (0.03,) * n, 2: (0.03,) * n}
    out = sl.analyse(rows, extra, {"bl-a_y000": 0.9, "c_y000": 0.1})
    assert out["all"]["lost"] == 1 and out["all"]["better_than_paste"] == pytest.approx(2 / 3)
    assert out["blender"]["causes"] == {"shape": 1} and out["shared"]["lost"] == 0
    assert out["blender"]["lost_same_place"] == 0 and out["blender"]["pairs_same_place"] == 1
    assert out["blender"]["side fixed_better"] == 1.0 and out["blender"]["side read_better"] == 0.5
    assert out["all"]["by_side"]["high"] == {"maps": 1, "better_than_paste": 0.5}
    assert out["all"]["by_side"]["low"] == {"maps": 1, "better_than_paste": 1.0}
    assert out["blender"]["lost_ev_est_median"] == 1.5 and out["blender"]["won_ev_est_median"] == 0.5
    signs = sl.side_signs({"view": {"bl-a_y000": 0.2, "c_y000": -1.0}}, {"bl-a_y000": 0.9, "c_y000": 0.1})
    assert signs["all"] == {"maps": 1, "view": 1.0}  # c_y000's side is under 0.3: not scored


def test_shading_side_reads_a_view_brighter_to_its_right(sl):
    cols = np.linspace(0.05, 0.8, 128)
    lit_right = np.tile(cols, (96, 1))
    grad, _ = sl.shading_side(lit_right)
    assert grad > 0 and sl.shading_side(lit_right[:, ::-1])[0] == pytest.approx(-grad, rel=1e-4)
    steps = np.where(np.arange(144) % 32 < 16, 0.05, 0.4)[None, :].repeat(96, 0)  # 4 steps up, 4 down
    assert sl.shading_side(steps)[1] == pytest.approx(0.0, abs=0.02)
    assert sl.shading_side(np.full((96, 128), 0.2)) == (0.0, 0.0)  # an even view: no side
