"""A preset that asks for its own exposure (issue 32: night under "auto" kept the person's brightness, so it read
as a cool grade, not as night): relight_rt.lights.preset_exposure, relight_rt.light.exposure.for_light, and the runtime
and CLI adding it wherever a preset is given by name."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from relight_rt import Relighter, RuntimeConfig, cli, lights
from relight_rt.cli.demo import example_path
from relight_rt.light import exposure
from relight_rt.light.spec import LightSpec


def test_preset_exposure_values():
    assert lights.preset_exposure("night") == -1.0
    assert all(lights.preset_exposure(n) == 0.0 for n in lights.list_presets() if n != "night")
    with pytest.raises(Exception, match="unknown light preset"):
        lights.preset_exposure("dusk")


@pytest.mark.parametrize(("exp", "light", "want"), [
    ("auto", "night", -1.0), (0.5, "night", -0.5), ("+1", "night", 0.0), ("physical", "night", "physical"),
    ("auto", LightSpec.preset("night", rotate=30), -1.0), ("auto", "studio", "auto"), (0.5, "studio", 0.5),
    ("auto", lights.preset("night"), "auto"), ("auto", LightSpec.from_array(lights.preset("night")), "auto"),
])  # fmt: skip
def test_for_light(exp, light, want):
    got = exposure.for_light(exp, light)
    assert got == ("auto" if want == 0.0 else want)


def test_relight_by_name_is_a_stop_darker(tmp_path):
    """relight(photo, "night") is relight(photo, night's array, exposure=-1): half the light, the person darker
    than under "auto"; in a list of lights each gets its own; the CLI's --preset night gives the same picture."""
    rl = Relighter(RuntimeConfig(device="cpu"))
    dec = rl.decompose(example_path())
    night = lights.preset("night")
    by_name = rl.relight(dec, "night")
    np.testing.assert_allclose(by_name, rl.relight(dec, night, exposure=-1), atol=1e-6)
    kept = rl.relight(dec, night)
    person = dec.mask > 0.5
    assert by_name[person].mean() < 0.8 * kept[person].mean()
    many = rl.relight_many(dec, ["night", "studio", night])
    np.testing.assert_allclose(many[0], by_name, atol=1e-6)
    np.testing.assert_allclose(many[1], rl.relight(dec, "studio"), atol=1e-6)
    np.testing.assert_allclose(many[2], kept, atol=1e-6)
    out = tmp_path / "night.png"
    assert cli.main(["relight", str(example_path()), "--preset", "night", "-o", str(out), "--device", "cpu", "-q"]) == 0
    png = cv2.imread(str(out), cv2.IMREAD_UNCHANGED)
    written = cv2.cvtColor(png[..., :3], cv2.COLOR_BGR2RGB).astype(np.float32) / 255
    assert np.abs(written[person] - by_name[person]).mean() < 1.5 / 255
