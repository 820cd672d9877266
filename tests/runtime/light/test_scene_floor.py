"""relight_rt.light.scene_floor: the photo's light from every side kept under a new light over the kept background."""

from __future__ import annotations

import numpy as np
import pytest

from relight_rt import RelightError
from relight_rt.light import presets, scene_floor


def test_the_floor_of_a_uniform_light_is_all_of_it_of_a_lamp_none_of_a_sky_its_downward_share():
    assert scene_floor.floor(presets.ambient(0.3)) == pytest.approx(1.0)
    assert scene_floor.floor(presets.directional((0, 1, 0))) == 0.0  # degree-2 ringing below 0: clipped to none
    # presets.sky: a surface facing down gets (zenith + 5 ground) / 6, the mean over the sphere (zenith + ground) / 2
    assert scene_floor.floor(presets.sky((1, 1, 1), (0, 0, 0))) == pytest.approx(1 / 3, abs=2e-3)
    assert scene_floor.floor(np.zeros((9, 3))) == 0.0


@pytest.mark.parametrize("shape", [(9, 3), (4, 9, 3)])
def test_a_light_below_the_floor_is_raised_to_it_at_the_same_mean_and_one_above_left_as_it_is(shape):
    lamp = presets.preset("campfire").astype(np.float32)
    lights = np.broadcast_to(lamp, shape).copy()
    before = lights.copy()
    out = scene_floor.with_scene_floor(lights, 0.5)
    np.testing.assert_array_equal(lights, before)  # not modified in place
    assert out.shape == shape and out.dtype == np.float32
    for one in out.reshape(-1, 9, 3):
        assert scene_floor.floor(one) == pytest.approx(0.5, abs=1e-4)
        # the mean irradiance over the sphere (degree 0's luminance) is the light's own
        assert float(one[0] @ [0.2126, 0.7152, 0.0722]) == pytest.approx(float(lamp[0] @ [0.2126, 0.7152, 0.0722]),
                                                                          rel=1e-5)
    # the photo's own light has its own floor: left exactly as it is (it gives the photo back)
    own = presets.preset("overcast").astype(np.float32)
    np.testing.assert_array_equal(scene_floor.with_scene_floor(own, scene_floor.floor(own)), own)
    np.testing.assert_array_equal(scene_floor.with_scene_floor(lamp, 0.0), lamp)


def test_a_floor_outside_zero_to_one_is_refused():
    with pytest.raises(RelightError, match="own_floor"):
        scene_floor.with_scene_floor(presets.preset("rim"), 1.5)
    with pytest.raises(RelightError, match="own_floor"):
        scene_floor.with_scene_floor(presets.preset("rim"), float("nan"))
    with pytest.raises(RelightError, match="9, 3"):
        scene_floor.floor(np.zeros(5))
