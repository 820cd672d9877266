"""benchmarks/scene_eval.py's oracles (issue 36, fifth pass): lights that know the view, or the half of the sphere in
front of the camera, perfectly but not what lies behind the camera; checked on synthetic maps whose answer is known."""

import numpy as np
import pytest

from relight_rt import envmap
from relight_rt.image.color import srgb_to_linear
from relight_rt.light import from_background as bgmod


@pytest.fixture(scope="module")
def se(load_benchmark):
    return load_benchmark("scene_eval")


def _map(front: float, back: float, h: int = 32) -> np.ndarray:
    """A grey map: radiance ``front`` in the half in front of the camera (x < 0), ``back`` behind it."""
    ahead = envmap.directions_envmap(h)[..., 0:1] < 0
    return np.where(ahead, front, back).repeat(3, axis=2).astype(np.float32)


def test_front_half_and_a_uniform_behind_make_the_whole_map(se):
    env = _map(0.4, 0.4)
    half, mean = se.front_half(env)
    np.testing.assert_allclose(mean, 0.4, rtol=1e-6)
    whole = se.half_oracle(half, mean, 1.0, 0.0)  # behind: 1 × the half's mean luminance, neutral
    np.testing.assert_allclose(whole, envmap.project_envmap(env), atol=2e-3)


def test_the_half_oracle_cannot_see_behind_the_camera(se):
    # two places alike in front of the camera, one four times brighter behind it: one answer for both
    dim, bright = _map(0.2, 0.2), _map(0.2, 0.8)
    h_dim, h_bright = se.front_half(dim), se.front_half(bright)
    np.testing.assert_allclose(h_dim[0], h_bright[0], atol=1e-9)
    g, _ = se.fit_half_oracle([h_dim, h_bright], [envmap.project_envmap(dim), envmap.project_envmap(bright)])
    light = se.half_oracle(*h_dim, g, 0.0)
    errors = [se.ev_error(light, envmap.project_envmap(e)) for e in (dim, bright)]
    assert errors[0] - errors[1] > 1.0  # the same light, > 1 EV apart in truth: at least one is off


def test_fit_half_oracle_finds_the_gain_that_made_the_truth(se):
    halves = [se.front_half(_map(v, 0.0)) for v in (0.1, 0.3, 0.7)]
    truths = [se.half_oracle(h, m, 2.0, 0.0) for h, m in halves]
    g, _ = se.fit_half_oracle(halves, truths)
    assert g == pytest.approx(2.0)


def test_unclipped_view_reads_what_the_8bit_photo_clipped(se):
    rng = np.random.default_rng(0)
    linear = rng.uniform(0.05, 0.3, (96, 128, 3)).astype(np.float32)
    photo = se.photograph(linear, 1.0)
    parts = bgmod.scene_light(photo, 60.0)
    # nothing clipped: the same front half as the rule's own reading (up to 8-bit rounding)
    same = se.unclipped_view(parts, srgb_to_linear(photo))
    np.testing.assert_allclose(same.view, parts.view + parts.source, rtol=1e-3, atol=1e-5)
    # a lamp of linear value 20: the photo clips it at 1 (× the highlight gain 3), the perfect view has it all
    lamp = linear.copy()
    lamp[30:50, 50:80] = 20.0
    parts = bgmod.scene_light(se.photograph(lamp, 1.0), 60.0)
    seen = se.unclipped_view(parts, lamp)
    assert se.lum(se.side_rgb(seen.view, se.BACK_W)) > 2 * se.lum(se.side_rgb(parts.view + parts.source, se.BACK_W))
    assert not seen.source.any()
    assert seen.level == parts.level  # the statistics stay the photo's


def test_map_tile_shows_the_view_beside_the_map(se):
    tile = se.map_tile(_map(0.1, 0.1, 64), np.zeros((96, 128, 3), np.uint8), 1.0, "x")
    assert tile.shape == (128, 426, 3) and tile.dtype == np.uint8


def test_scene_sets_and_issue_49s_table(se):
    assert se.scene_set("bl-city_y090") == "blender" and se.scene_set("city_y090") == "shared"
    assert se.scene_set(se.scene_of("bl-sunrise_y180")) == "blender"
    front, back = envmap.project_envmap(_map(1.0, 0.1)), envmap.project_envmap(_map(0.1, 1.0))
    maps = ["a_y000", "bl-b_y000"]
    fb = {m: se.front_back(front if m == "a_y000" else back) for m in maps}
    est = {"a_y000": front, "bl-b_y000": front}  # right on a, wrong on bl-b
    rows = [{"B": "a_y000", "ev_est_background": 0.5, "ev_view_background": -0.2, "colour_est": 3.0,
             "colour_view": 2.0, "si_est": 0.1, "si_paste": 0.2},
            {"B": "bl-b_y000", "ev_est_background": -1.5, "ev_view_background": 0.4, "colour_est": 7.0,
             "colour_view": 6.0, "si_est": 0.3, "si_paste": 0.2}]  # fmt: skip
    table = se.must_show(rows, maps, fb, maps, est, est, "cross").splitlines()
    assert table[0].startswith("Issue 49's figures (cross: each scene's numbers fitted on the other scene set)")
    everything, shared, blender = table[4], table[5], table[6]
    assert everything.startswith("| all (2 maps, 2 pairs) | 1.00 / 0.30 | 50 % / 100 % | 50 % / 50 % (2) |")
    assert shared.startswith("| ../shared/hdri (1 maps, 1 pairs) | 0.50 / 0.20 | 100 % / 100 % | 100 % / 100 % (1) |")
    assert blender.endswith("| 7.0 / 6.0 | 0 % |")


def test_fit_backlight_clips_the_truth_so_one_sun_does_not_move_the_line(se):
    """scene24: BACKLIGHT is fitted on the truth clipped to +-BACKLIGHT_CLIP_EV. Four views on a line, called
    right by a line through 0; a fifth view at 0 with a 6-EV truth (a sun the statistics barely see) moves an
    unclipped fit's line past one of them, the clipped fit's not (by hand: raw w = (-1.2, 0.847), clipped (-0.2,
    0.588))."""

    class View:
        def __init__(self, x):
            self.x = x

        def backlight_features(self):
            return np.array([1.0, self.x, 0.0])

    xs, evs = [-2.0, -0.5, 0.5, 2.0, 0.0], [-1.5, -1.2, 1.2, 1.5, -6.0]
    truths = [np.array([[lo], *[[0.0]] * 8]) for lo in evs]  # stand-ins: front_back is monkeypatched below
    se_front_back = se.front_back
    try:
        se.front_back = lambda t: float(t[0, 0])
        clipped = se.fit_backlight([View(x) for x in xs], truths)
        raw = np.linalg.lstsq(np.array([[1.0, x, 0.0] for x in xs]), np.array(evs), rcond=None)[0]
    finally:
        se.front_back = se_front_back
    call = lambda w, x: w[0] + w[1] * x < 0  # noqa: E731
    assert [call(clipped, x) for x in xs] == [True, True, False, False, True]
    assert call(raw, 0.5) is np.True_  # the sun's view pulled the unclipped line past x = 0.5: a wrong call
