"""relight_rt.video.job.ClipLights: a clip's light as given, turned into its LightSpec and schedule."""

import numpy as np
import pytest

from relight_rt import LightSpec, RelightError
from relight_rt.light import presets
from relight_rt.video.job import ClipLights


def test_a_bare_array_is_a_light_like_its_spec():
    """A (9, 3) array (Ray's relight_videos clips, API callers) reads as LightSpec.of reads it: it raised
    AttributeError in ClipLights.paths before (fuzz9)."""
    light = presets.preset("studio")
    bare, spec = ClipLights(spec=light), ClipLights(spec=LightSpec.from_array(light))
    assert bare.paths == () and isinstance(bare.spec, LightSpec)
    np.testing.assert_array_equal(bare.schedule(10)(3, 25.0), spec.schedule(10)(3, 25.0))


def test_a_preset_name_and_a_file_are_read_by_the_one_rule(tmp_path):
    path = tmp_path / "key.npy"
    np.save(path, presets.preset("night"))
    assert (ClipLights(spec="studio").spec.source, ClipLights(spec="studio").spec.value) == ("preset", "studio")
    assert ClipLights(spec=str(path)).paths == (str(path),)


@pytest.mark.parametrize("bad", [np.zeros((9, 4)), "no-such-preset", np.full((9, 3), np.nan)])
def test_a_bad_light_is_one_relight_error(bad):
    with pytest.raises(RelightError, match="light"):
        ClipLights(spec=bad)
