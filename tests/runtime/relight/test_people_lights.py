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


def test_the_people_here_are_lit_apart(group):
    """The two people's own lights differ (the mirror's comes from the other side): what the tests below need."""
    rl, dec = group
    own = [p.white_light for p in dec.people]
    assert own[0][1, 0] * own[1][1, 0] < 0  # their y (image right) coefficients have opposite signs ...
    assert min(abs(own[0][1, 0]), abs(own[1][1, 0])) > 0.3 * dec.white_light[0, 0]  # ... and are not small


@pytest.mark.parametrize("background", ["original", Background.original(grade=True)])
def test_the_groups_own_light_gives_the_photo_back(group, background):
    """relight(group, the group's own light): each person under their own (140 levels off when the group's light
    reached both as it is, each divided by their own)."""
    rl, dec = group
    out = np.asarray(rl.relight(dec, dec, background=background))
    assert 255 * np.abs(out - dec.image).max() < 0.5


def test_a_light_reaches_a_person_with_their_deviation(group):
    rl, dec = group
    g = dec.white_light
    for part in dec.people:
        own = part.white_light
        np.testing.assert_allclose(people.reaching(g, part, dec), own, atol=1e-6)  # the group's light: their own
        np.testing.assert_allclose(people.reaching(2 * g, part, dec), 2 * own, atol=1e-6)  # twice as strong
        lamp = lights.directional((0.3, -1.0, 0.2), (1.0, 0.5, 0.25))  # a coloured light: the deviation in its colour
        dc = lamp[0] / g[0, 0]
        np.testing.assert_allclose(people.reaching(lamp, part, dec), lamp + dc * (own - g), atol=1e-6)
        batch = np.stack([g, lamp])  # (K, 9, 3) as (9, 3) one by one
        np.testing.assert_allclose(people.reaching(batch, part, dec),
                                   np.stack([people.reaching(v, part, dec) for v in batch]), atol=1e-6)
        dark = np.zeros((9, 3), np.float32)
        dark[1] = 0.5  # no degree 0: no strength to scale the deviation by, the light as it is
        np.testing.assert_array_equal(people.reaching(dark, part, dec), dark)
        dark[0] = -0.2  # a negative degree 0: no deviation either
        np.testing.assert_array_equal(people.reaching(dark, part, dec), dark)


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
