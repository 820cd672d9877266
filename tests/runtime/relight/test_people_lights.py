"""A group photo relit under several lights at once (relight_rt.relight.people ``by_person_lights``): each light's
picture is the one a relight under that light alone gives, bit for bit, while each person's light-independent
work (their own colour's looks, the full-resolution guide) is made once for all the lights."""

from __future__ import annotations

import numpy as np
import pytest

import relight_rt
from relight_rt import RuntimeConfig, lights
from relight_rt.cli.demo import example_path
from relight_rt.image.compositing import Background
from relight_rt.image.io import read_image
from relight_rt.relight import people


@pytest.fixture(scope="module")
def group():
    """The example person over grey and its mirror image beside it, decomposed person by person."""
    rgba = read_image(example_path())
    a = rgba[..., 3:4]
    one = rgba[..., :3] * a + 0.55 * (1 - a)
    image = np.ascontiguousarray(np.hstack([one, one[:, ::-1]]))
    rl = relight_rt.open(RuntimeConfig(device="cpu", matting="all"))
    dec = rl.decompose(image)
    assert len(dec.people) == 2
    return rl, dec


@pytest.mark.parametrize("background", ["original", "transparent", Background.original(grade=True)])
def test_several_lights_give_each_light_alone(group, background):
    rl, dec = group
    sweep = [lights.preset("studio"), lights.directional((0.3, -1.0, 0.2)) + lights.ambient((0.1, 0.1, 0.1)),
             lights.preset("campfire")]
    many = rl.relight_many(dec, sweep, background=background, batch_size=3)
    for k, light in enumerate(sweep):
        np.testing.assert_array_equal(many[k], rl.relight(dec, light, background=background))


def test_lights_at_once_holds_a_bounded_number_of_pictures():
    assert people.lights_at_once((1000, 1000), 3, 4) == 4
    assert people.lights_at_once((5000, 5000), 3, 4) == 1  # a 25-MP group: one picture at a time
    assert people.lights_at_once((10, 10), 4, 1) == 1


def test_a_group_relit_once_lets_each_persons_state_go(group):
    """A photo given as a photo (not a Decomposition) is relit once: each person's memo (texture, shadow fill, own
    light's reconstruction, the guide) is let go after them, not held to the end (16 people on 25 MP: ~0.2 GB), and
    the picture is the same; a Decomposition of the caller's keeps it for the next light."""
    rl, dec = group
    light = lights.preset("neon")
    kept = rl.relight(dec, light)
    assert all(rl._memo(part) for part in dec.people)  # kept for the next call
    assert all("gray" not in rl._memo(one) for part in dec.people for one in (part, part.head) if one is not None)
    parts = list(dec.people)
    rl._memo(parts[0])["marker"] = 1
    once = people.by_person(rl._composer, rl._network.relit, dec, tuple(parts), light, "auto", Background.original(),
                            keep=False)
    np.testing.assert_array_equal(once, kept)
    assert not any(rl._memo(one) for part in parts for one in (part, part.head) if one is not None)
