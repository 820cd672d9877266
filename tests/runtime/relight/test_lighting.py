"""relight_rt.relight.lighting: a Decomposition relit under one light or K, the stages ordered: the light resolved and
exposed (a preset's own exposure asked for), stage 2 run in batches, the composite over the backdrop, a group handed to
relight_rt.relight.people. The stages are stand-ins that record what they are handed and answer values that say where
they came from (no ONNX); one test runs the Relighter on the hand-made graphs of tests/_graphs.py. What a relit picture
looks like is test_relighter.py's; that relight_many agrees with relight at any batch size is there too.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
import pytest
from _graphs import models_dir, person

from relight_rt import LightSpec, Relighter, RelightError, RuntimeConfig, lights
from relight_rt.image.compositing import Background
from relight_rt.light import exposure as _exposure
from relight_rt.relight import lighting as lighting_module
from relight_rt.relight.light_args import resolve_light
from relight_rt.relight.lighting import Lighting

__all__ = ["models_dir"]  # fixture

H, W = 6, 5
RIM, NIGHT = lights.preset("rim"), lights.preset("night")


def gain(exposure) -> float:
    """The stand-in meter's gain: 1 for "auto" and "physical", 2**EV for an EV offset (a value that shows which)."""
    mode = _exposure.parse_exposure(exposure)
    return 1.0 if isinstance(mode, str) else 2.0**mode


@dataclass(frozen=True)
class Layers:
    """What the stand-in composer's ``with_layers`` answers (a dataclass, as RelightResult is)."""

    image: np.ndarray
    lit: np.ndarray
    outputs: object


class Stages:
    """Stand-ins for Network, Factor (its meter) and Composer; ``log`` holds every call in order."""

    def __init__(self) -> None:
        self.log = []
        self.meter = SimpleNamespace(expose=self.expose)
        self.memo, self.factor = None, None

    def expose(self, dec, lights_, exposure):
        self.log.append(("expose", np.array(lights_), exposure))
        return (np.array(lights_, np.float32) * gain(exposure)).astype(np.float32)

    def relit(self, dec, lits, batch_size, want_layers):
        self.log.append(("relit", np.array(lits), batch_size, want_layers))
        for k in range(len(lits)):
            yield {"light": k, "layers": want_layers}

    def compose(self, dec, lit, outputs, backdrop, clean, grade):
        self.log.append(("compose", lit, outputs, backdrop, clean, grade))
        return np.full((H, W, 3), lit[0, 0], np.float32)  # the picture says which light it was composed under

    def with_layers(self, dec, lit, outputs, backdrop, clean, grade):
        self.log.append(("with_layers", lit, outputs, backdrop, clean, grade))
        return Layers(np.full((H, W, 3), lit[0, 0], np.float32), lit, outputs)

    def calls(self, name: str) -> list:
        return [c[1:] for c in self.log if c[0] == name]


def photo(people=()):
    image = np.linspace(0, 1, H * W * 3, dtype=np.float32).reshape(H, W, 3)
    return SimpleNamespace(image=image, people=people, geometry=SimpleNamespace(frame=(H, W)))


def make(detail: bool = True) -> tuple[Lighting, Stages]:
    stages = Stages()
    return Lighting(stages, SimpleNamespace(meter=stages.meter), stages, detail), stages


def resolver(seen: list):
    def resolve(value):
        seen.append(value)
        return resolve_light(value, None)

    return resolve


# ------------------------------------------------------------------------------------------------ one


@pytest.mark.parametrize("detail", [True, False])
def test_one_light_exposed_run_and_composed(detail):
    light, stages = make(detail)
    dec, seen = photo(), []
    got = light.one(dec, RIM, 1.0, "original", resolver(seen), layers=False, keep=False)
    ((lits, exposure),) = stages.calls("expose")
    np.testing.assert_array_equal(lits, RIM.astype(np.float32))
    assert exposure == 1.0
    ((stacked, batch, want_layers),) = stages.calls("relit")
    np.testing.assert_allclose(stacked, 2 * RIM[None], rtol=1e-6)  # the exposed light, one at a time
    assert (batch, want_layers) == (1, detail)  # stage 2's layers only for the detail transfer
    ((lit, outputs, backdrop, clean, grade),) = stages.calls("compose")
    np.testing.assert_allclose(lit, 2 * RIM, rtol=1e-6)
    assert outputs == {"light": 0, "layers": detail} and backdrop is dec.image and (clean, grade) == (False, False)
    np.testing.assert_array_equal(got, np.full((H, W, 3), np.float32(2 * RIM[0, 0])))
    assert [c[0] for c in stages.log] == ["expose", "relit", "compose"] and len(seen) == 1


@pytest.mark.parametrize(("background", "clean", "grade"), [
    ("black", True, False), ("transparent", True, False), (Background.original(grade=True), False, True)])
def test_one_over_a_backdrop(background, clean, grade):
    light, stages = make()
    dec = photo()
    light.one(dec, RIM, "auto", background, resolver([]), layers=False, keep=False)
    ((_, _, backdrop, got_clean, got_grade),) = stages.calls("compose")
    assert (got_clean, got_grade) == (clean, grade)
    if background == "black":
        np.testing.assert_array_equal(backdrop, np.zeros((H, W, 3)))
    elif background == "transparent":
        assert backdrop is None
    else:
        assert backdrop is dec.image


@pytest.mark.parametrize(("given", "exposure", "want"), [
    ("night", "auto", -1.0), ("night", 0.5, -0.5), ("night", "physical", "physical"),
    (LightSpec.preset("night", rotate=90), "auto", -1.0), (NIGHT, "auto", "auto"), ("rim", "-1", -1.0)])
def test_one_preset_asks_for_its_own_exposure(given, exposure, want):
    """A preset's exposure (night: a stop darker under "auto") reaches the meter; the name is read once (``resolve``
    is handed the LightSpec it became), an array of the same numbers is no preset."""
    light, stages = make()
    seen = []
    light.one(photo(), given, exposure, "original", resolver(seen), layers=False, keep=False)
    ((lits, got),) = stages.calls("expose")
    assert got == want
    assert not isinstance(seen[0], str)
    np.testing.assert_allclose(lits, resolve_light(given, None), rtol=1e-6)


def test_one_with_layers():
    light, stages = make(detail=False)
    dec = photo()
    res = light.one(dec, RIM, -1, "black", resolver([]), layers=True, keep=False)
    assert isinstance(res, Layers) and not stages.calls("compose")
    ((_, _, want_layers),) = stages.calls("relit")
    assert want_layers  # the layers are stage 2's, detail or not
    np.testing.assert_allclose(res.lit, 0.5 * RIM, rtol=1e-6)
    ((_, outputs, backdrop, clean, grade),) = stages.calls("with_layers")
    assert outputs is res.outputs and (clean, grade) == (True, False) and not backdrop.any()


def test_one_refuses_a_bad_light_or_exposure():
    light, _ = make()
    for given, exposure, match in ((np.ones((9, 4)), "auto", r"\(9, 3\)"), ("dusk", "auto", "unknown light preset"),
                                   (RIM, "bright", "exposure: expected"), ("night", 99, "±20")):
        with pytest.raises(RelightError, match=match):
            light.one(photo(), given, exposure, "original", resolver([]), layers=False, keep=False)


# ------------------------------------------------------------------------------------------------ each


def test_each_exposes_a_shared_exposure_once_and_yields_in_order():
    light, stages = make()
    stack = np.stack([RIM, 0.5 * RIM, 0.25 * RIM]).astype(np.float32)
    out = list(light.each(photo(), stack, [0.0] * 3, "original", batch_size=2, keep=False))
    ((lits, exposure),) = stages.calls("expose")  # one call for the whole stack
    np.testing.assert_array_equal(lits, stack)
    assert exposure == 0.0
    ((_, batch, want_layers),) = stages.calls("relit")
    assert (batch, want_layers) == (2, True)
    assert [c[1]["light"] for c in stages.calls("compose")] == [0, 1, 2]
    np.testing.assert_allclose([o[0, 0, 0] for o in out], stack[:, 0, 0], rtol=1e-6)


def test_each_is_one_per_light():
    """Lights with different exposures are exposed one by one; each picture is ``one``'s under that light."""
    light, stages = make()
    stack = np.stack([NIGHT, RIM, RIM]).astype(np.float32)
    exposures = [-1.0, "auto", 1.0]
    out = list(light.each(photo(), stack, exposures, "black", batch_size=4, keep=False))
    assert [c[1] for c in stages.calls("expose")] == exposures
    assert [c[0].shape for c in stages.calls("expose")] == [(1, 9, 3)] * 3
    assert len(out) == 3 and len(stages.calls("relit")) == 1
    for picture, lit, exposure in zip(out, stack, exposures, strict=True):
        alone, _ = make()
        np.testing.assert_array_equal(picture, alone.one(photo(), lit, exposure, "black", resolver([]), False, False))


# ------------------------------------------------------------------------------------------------ a group


def test_a_group_is_relit_person_by_person(monkeypatch):
    calls = []

    def by_person(composer, relit, dec, parts, light, exposure, bg, keep):
        calls.append(("by_person", parts, light, exposure, bg.kind, keep))
        return np.full((H, W, 3), 0.25, np.float32)

    monkeypatch.setattr(lighting_module.per_person, "by_person", by_person)
    light, stages = make()
    group = photo(people=("a", "b"))
    out = light.one(group, "night", "auto", "original", resolver([]), layers=False, keep=True)
    ((_, parts, lit, exposure, kind, keep),) = calls
    assert (parts, exposure, kind, keep) == (("a", "b"), -1.0, "original", True)
    np.testing.assert_allclose(lit, NIGHT, rtol=1e-6)  # resolved, not exposed: each person meters their own
    assert not stages.calls("compose") and (out == 0.25).all()
    res = light.one(group, RIM, "auto", "original", resolver([]), layers=True, keep=False)
    assert isinstance(res, Layers) and (res.image == 0.25).all()  # the group's picture with the group's layers
    np.testing.assert_allclose(res.lit, RIM, rtol=1e-6)
    assert calls[-1][-1] is False


@pytest.mark.parametrize(("keep", "want"), [(False, [True, True, False]), (True, [True, True, True])])
def test_a_group_takes_lights_in_steps_keeping_its_state_until_the_last(monkeypatch, keep, want):
    steps = []

    def by_person_lights(composer, relit, dec, parts, lights_, exposures, bg, keep):
        steps.append((len(lights_), list(exposures), keep))
        return [np.full((H, W, bg.channels), lit[0, 0], np.float32) for lit in lights_]

    monkeypatch.setattr(lighting_module.per_person, "lights_at_once", lambda frame, channels, most: 2)
    monkeypatch.setattr(lighting_module.per_person, "by_person_lights", by_person_lights)
    light, _ = make()
    stack = np.arange(5, dtype=np.float32)[:, None, None] * np.ones((5, 9, 3), np.float32)
    out = list(light.each(photo(people=("a", "b")), stack, list(range(5)), "transparent", 4, keep=keep))
    assert [s[0] for s in steps] == [2, 2, 1] and [s[1] for s in steps] == [[0, 1], [2, 3], [4]]
    assert [s[2] for s in steps] == want  # a group decomposed for this call lets go after its last lights
    assert [o[0, 0, 0] for o in out] == [0, 1, 2, 3, 4] and out[0].shape == (H, W, 4)


# ------------------------------------------------------------------------------------------------ real graphs


def test_a_full_turn_relights_as_the_light_itself(models_dir):
    """On the analytic graphs: a light turned 360 degrees (or -90 then +90) gives the picture of the light itself."""
    rl = Relighter(RuntimeConfig(models=models_dir, device="cpu"))
    img, mask = person(60, 40, box=(10, 50, 10, 30))
    dec = rl.decompose(img, mask)
    want = rl.relight(dec, "rim")
    for turned in (LightSpec.preset("rim", rotate=360), LightSpec.preset("rim", rotate=-90).rotated(90)):
        np.testing.assert_allclose(rl.relight(dec, turned), want, atol=1e-6)
    quarter = rl.relight(dec, LightSpec.preset("rim", rotate=90))
    assert np.abs(quarter - want).max() > 0.01  # a quarter turn is not
    np.testing.assert_allclose(rl.relight(dec, RIM), want, atol=1e-6)  # the preset's array: the same light
