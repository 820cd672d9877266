"""relight_rt.relight.light_args: a light argument resolved to the (9, 3) float32 SH light, a list of them, and each
one's exposure. No models: a photo's light comes from a stand-in for ``Relighter.decompose`` that records what it was
asked; test_relighter_api.py checks the same rule through a Relighter on the analytic graphs.
"""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from relight_rt import LightSpec, RelightError, lightfile, lights
from relight_rt.image.color import REC709
from relight_rt.image.crop import CropGeometry
from relight_rt.light import sh
from relight_rt.relight.decomposition import Decomposition
from relight_rt.relight.light_args import float32_light, lights_with_exposures, resolve_light, resolve_lights

RIM = lights.preset("rim")  # (9, 3) float64, the preset the forms below all name


class Decompose:
    """A stand-in for ``Relighter.decompose``: records (photo, mask) and answers a fixed light."""

    def __init__(self, light: np.ndarray) -> None:
        self.light, self.calls = light, []

    def __call__(self, photo, mask):
        self.calls.append((photo, mask))
        return SimpleNamespace(white_light=self.light)


def decomposition(light) -> Decomposition:
    """A small real Decomposition whose estimated light is ``light`` (only its light is read here)."""
    r = 8
    mask = np.ones((r, r), np.float32)
    zeros = lambda *shape: np.zeros(shape, np.float32)  # noqa: E731
    return Decomposition(zeros(3, r, r), zeros(r, r), zeros(9, r, r), light, mask, zeros(r, r, 3), mask,
                         zeros(r, r, 3), CropGeometry.from_mask(mask, r))


# ------------------------------------------------------------------------------------------------ float32_light


def test_float32_light_is_a_checked_float32_copy():
    given = RIM.tolist()
    got = float32_light(given, "key")
    assert got.shape == (9, 3) and got.dtype == np.float32
    np.testing.assert_array_equal(got, RIM.astype(np.float32))
    got[0, 0] = 7
    assert given == RIM.tolist()  # a new array; the argument is as it was


@pytest.mark.parametrize(("value", "match"), [(np.ones((9, 4)), r"key: expected .*\(9, 3\)"),
                                              (np.full((9, 3), np.nan), "key: .*NaN"),
                                              (np.full((9, 3), 2e30), "key: SH light coefficient 2e\\+30 is too large"),
                                              ("rim", "key: expected")])
def test_float32_light_refuses(value, match):
    with pytest.raises(RelightError, match=match):
        float32_light(value, "key")


# ------------------------------------------------------------------------------------------------ resolve_light


def test_every_accepted_form_of_one_light_gives_the_same_array(tmp_path):
    np.save(tmp_path / "rim.npy", RIM)
    lightfile.save_light(tmp_path / "rim.json", RIM)
    decompose = Decompose(np.zeros((9, 3), np.float32))
    forms = [RIM, RIM.astype(np.float32), RIM.tolist(), tuple(map(tuple, RIM)), "rim", LightSpec.preset("rim"),
             LightSpec.from_array(RIM), LightSpec.from_numbers(RIM.ravel().tolist()), tmp_path / "rim.npy",
             str(tmp_path / "rim.json"), LightSpec.file(tmp_path / "rim.npy"), LightSpec.preset("rim", rotate=360),
             LightSpec.from_array(sh.rotate_z(RIM, math.pi / 2), rotate=-90)]
    want = RIM.astype(np.float32)
    for form in forms:
        got = resolve_light(form, decompose)
        assert got.shape == (9, 3) and got.dtype == np.float32, form
        np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-7, err_msg=repr(form))
    assert decompose.calls == []  # no form but a photo asks for stage 1


def test_float64_keeps_every_bit_of_the_light():
    light = RIM + 1e-9  # below float32's resolution
    got = resolve_light(light, Decompose(RIM), dtype=np.float64)
    assert got.dtype == np.float64
    np.testing.assert_array_equal(got, light)
    assert not np.array_equal(resolve_light(light, Decompose(RIM)), light)  # float32 rounds it


def test_a_photos_light_is_its_estimate_with_its_mask(tmp_path):
    """A photo's light is what ``decompose`` estimates of it, with the mask named, else NAME_mask.png beside it,
    else None (its alpha or a matte); taken as given (the stand-in's light is already white)."""
    import cv2

    own = np.repeat(np.linspace(0.1, 0.9, 9)[:, None], 3, axis=1).astype(np.float32)
    for name in ("a.png", "b.jpg", "b_mask.png", "c.png", "m.png"):
        cv2.imwrite(str(tmp_path / name), np.full((60, 100, 3), 90, np.uint8))  # not 2:1: a photo, not a map
    decompose = Decompose(own)
    np.testing.assert_array_equal(resolve_light(tmp_path / "a.png", decompose), own)
    resolve_light(str(tmp_path / "b.jpg"), decompose)
    resolve_light(LightSpec.photo(tmp_path / "c.png", mask=tmp_path / "m.png"), decompose)
    assert decompose.calls == [(tmp_path / "a.png", None), (tmp_path / "b.jpg", tmp_path / "b_mask.png"),
                               (tmp_path / "c.png", str(tmp_path / "m.png"))]
    turned = resolve_light(LightSpec.photo(tmp_path / "a.png", rotate=90), decompose)
    np.testing.assert_allclose(turned, sh.rotate_z(own, math.pi / 2), atol=1e-6)


def test_a_decomposition_is_its_light_taken_as_white():
    light = np.array([[1.0, 0.5, 0.25]] * 9, np.float32) * np.linspace(1, 0.2, 9)[:, None]
    dec = decomposition(light)
    want = np.repeat((light.astype(np.float64) @ REC709.astype(np.float64))[:, None], 3, axis=1)
    for dtype in (np.float32, np.float64):
        got = resolve_light(dec, Decompose(RIM), dtype=dtype)
        assert got.dtype == dtype
        np.testing.assert_allclose(got, want, rtol=1e-6)


@pytest.mark.parametrize("light", [RIM, "rim"])
def test_resolve_light_refuses_a_dtype_it_does_not_run_in(light):
    with pytest.raises(RelightError, match="dtype: expected float32 or float64"):
        resolve_light(light, Decompose(RIM), dtype=np.int32)
    with pytest.raises(RelightError, match="dtype: expected float32 or float64"):
        resolve_light(decomposition(RIM), Decompose(RIM), dtype=np.float16)
    with pytest.raises(RelightError, match="dtype: expected float32 or float64"):  # TypeError in numpy (fuzz9)
        resolve_light(light, Decompose(RIM), dtype="nonsense")


def test_a_path_object_whose_fspath_is_no_text_is_refused():
    """fuzz9: os.fspath raised TypeError for an object whose __fspath__ returns an int."""

    class Odd:
        def __fspath__(self):
            return 3

    with pytest.raises(RelightError, match="expected a preset name or a file"):
        resolve_light(Odd(), Decompose(RIM))


@pytest.mark.parametrize(("light", "match"), [
    ("dusk", "unknown light preset 'dusk'; known presets: studio"), ("missing/rim.npy", "not found"),
    (np.ones((9, 4)), r"\(9, 3\)"),
    ([[1, 2, 3]] * 8, r"\(9, 3\)"), (np.full((9, 3), 4e38), "too large"), (np.full((9, 3), np.inf), "NaN or Inf")])
def test_resolve_light_refuses(light, match):
    with pytest.raises(RelightError, match=match):
        resolve_light(light, Decompose(RIM))
    with pytest.raises(RelightError, match=match):
        resolve_light(light, Decompose(RIM), dtype=np.float64)


# ------------------------------------------------------------------------------------------------ lists


def spy_resolve(seen: list):
    def resolve(value):
        seen.append(value)
        return resolve_light(value, Decompose(RIM))

    return resolve


def test_resolve_lights_stacks_each_resolved_light():
    stack = np.stack([RIM, 2 * RIM, 0.5 * RIM])
    for given in (stack, list(stack), tuple(stack)):
        seen = []
        got = resolve_lights(given, spy_resolve(seen))
        assert got.shape == (3, 9, 3) and got.dtype == np.float32 and len(seen) == 3
        np.testing.assert_array_equal(got, stack.astype(np.float32))
    seen = []
    resolve_lights(["rim", RIM], spy_resolve(seen))
    assert seen[0] == "rim"  # each as given, in order


@pytest.mark.parametrize(("lights_", "match"), [
    (RIM, r"lights: expected \(K, 9, 3\) SH lights, got \(9, 3\) float64"),
    (np.ones((2, 9, 4)), r"lights: expected \(K, 9, 3\) SH lights, got \(2, 9, 4\)"),
    ("rim", r"lights: expected a \(K, 9, 3\) array or a list of lights, got str"),
    ({"a": RIM}, "got dict"), ([], "at least one light, got none"), (np.zeros((0, 9, 3)), "at least one light"),
    ([RIM, "dusk"], "unknown light preset")])
def test_resolve_lights_refuses(lights_, match):
    with pytest.raises(RelightError, match=match):
        resolve_lights(lights_, spy_resolve([]))


def test_each_light_gets_its_own_exposure(tmp_path):
    """A preset that asks for its own exposure (night: a stop darker) gets it in a list; arrays and files do not; a
    string is read once, the LightSpec it becomes is what ``resolve`` is handed."""
    np.save(tmp_path / "n.npy", lights.preset("night"))
    names = ["night", "studio", lights.preset("night"), tmp_path / "n.npy"]
    for exposure, want in (("auto", [-1.0, "auto", "auto", "auto"]), (0.5, [-0.5, 0.5, 0.5, 0.5]),
                           ("+1", [0.0, 1.0, 1.0, 1.0]), ("physical", ["physical"] * 4)):
        seen = []
        resolved, exposures = lights_with_exposures(names, exposure, spy_resolve(seen))
        assert exposures == [e if e != 0.0 else "auto" for e in want], exposure
        np.testing.assert_allclose(resolved[0], lights.preset("night").astype(np.float32))
        assert [type(v) for v in seen] == [LightSpec, LightSpec, np.ndarray, LightSpec]
        assert seen[3].source == "file" and Path(seen[3].value) == tmp_path / "n.npy"
    _, exposures = lights_with_exposures(("night", "rim"), "auto", spy_resolve([]))
    assert exposures == [-1.0, "auto"]


def test_an_array_of_lights_shares_one_exposure():
    stack = np.stack([lights.preset("night"), RIM])
    resolved, exposures = lights_with_exposures(stack, "-0.5", spy_resolve([]))
    assert exposures == [-0.5, -0.5]
    np.testing.assert_array_equal(resolved, stack.astype(np.float32))
    assert lights_with_exposures(stack, "Physical ", spy_resolve([]))[1] == ["physical"] * 2


@pytest.mark.parametrize("lights_", [["rim"], np.stack([RIM])])
def test_lights_with_exposures_refuses_a_bad_exposure(lights_):
    for wrong, match in (("bright", "exposure: expected 'auto', 'physical' or an EV number"), (21, "±20"),
                         (True, "got bool")):
        with pytest.raises(RelightError, match=match):
            lights_with_exposures(lights_, wrong, spy_resolve([]))
