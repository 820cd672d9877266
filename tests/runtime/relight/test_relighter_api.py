"""The Relighter's constructor (one RuntimeConfig, kept once), its narrow relight API and resolve_light, the one
place where a light is resolved; the old forms (keyword constructor, relight_layers, to_photo) are gone."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from _graphs import OWN_LIGHT, models_dir, person

import relight_rt
from relight_rt import LightSpec, Relighter, RelightError, RelightResult, RuntimeConfig, lightfile, lights, sh
from relight_rt.video import job as video

__all__ = ["models_dir"]  # fixture


@pytest.fixture(scope="module")
def relighter(models_dir):
    return Relighter(RuntimeConfig(models=str(models_dir), device="cpu"))


def test_config_constructor_keeps_settings_once_and_does_not_warn(models_dir):
    config = RuntimeConfig(models=str(models_dir), device="cpu", detail=False, preprocess="reference")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        r = Relighter(config)
    assert r.config is config
    assert (r.detail, r.preprocess, r.precision) == (False, "reference", "fp32")  # read from the config
    with pytest.raises(AttributeError):
        r.detail = True  # no second copy to drift from the config
    assert relight_rt.open(config).config is config


def test_constructor_takes_a_runtime_config_only(models_dir):
    """The old keyword constructor (``Relighter(models, device=...)``) went, as its warning said it would."""
    for wrong in (42, str(models_dir)):
        with pytest.raises(RelightError, match="expected a RuntimeConfig"):
            Relighter(wrong)
    with pytest.raises(TypeError):
        Relighter(RuntimeConfig(models=str(models_dir), device="cpu"), device="cpu")


def test_layers_by_a_flag(relighter):
    img, mask = person(60, 40, box=(10, 50, 10, 30))
    dec = relighter.decompose(img, mask)  # decompose once, relight many
    light = lights.preset("rim")
    plain = relighter.relight(dec, light)
    res = relighter.layers(dec, light)
    assert isinstance(res, RelightResult) and set(res.layers) >= {"albedo", "shading", "diffuse", "mask"}
    np.testing.assert_array_equal(res.image, plain)
    assert not hasattr(relighter, "relight_layers") and not hasattr(relighter, "to_photo")  # the old verbs went


def test_resolve_light_every_source_and_dtype(relighter, tmp_path):
    rim = lights.preset("rim")
    turned = relighter.resolve_light(LightSpec.from_array(rim, rotate=90))  # an array's rotation is applied
    np.testing.assert_allclose(turned, sh.rotate_z(rim, math.pi / 2), atol=1e-6)
    assert turned.dtype == np.float32
    lightfile.save_light(tmp_path / "l.json", rim)
    wide = relighter.resolve_light(tmp_path / "l.json", dtype=np.float64)
    assert wide.dtype == np.float64
    np.testing.assert_allclose(wide, rim, atol=1e-12)
    np.testing.assert_array_equal(relighter.resolve_light("rim"), rim.astype(np.float32))
    with pytest.raises(RelightError, match="dtype"):
        relighter.resolve_light(rim, dtype=np.int32)


def test_video_resolves_a_photos_light_through_the_relighter(relighter, tmp_path):
    import cv2

    img, mask = person(60, 40, box=(10, 50, 10, 30))
    cv2.imwrite(str(tmp_path / "p.png"), (img[..., ::-1] * 255).astype(np.uint8))
    cv2.imwrite(str(tmp_path / "p_mask.png"), (mask * 255).astype(np.uint8))
    got = video.resolve_light(tmp_path / "p.png", relighter)
    assert got.dtype == np.float64
    np.testing.assert_allclose(got, relighter.resolve_light(tmp_path / "p.png"), atol=1e-6)
    np.testing.assert_allclose(got, OWN_LIGHT, atol=1e-5)
    with pytest.raises(RelightError, match="stage-1 model"):
        video.resolve_light(tmp_path / "p.png")  # no relighter: a photo's light cannot be had


def test_the_test_run_refuses_old_names_outside_a_warning_check():
    """pyproject's filterwarnings: a relight_rt DeprecationWarning reached by a test is an error, so the project's own
    code and tests cannot slip back to an old name (today none is left: sh's moved names went with issue 47)."""
    with pytest.raises(DeprecationWarning, match="relight_rt.light.sh.old_name"):
        warnings.warn("relight_rt.light.sh.old_name moved", DeprecationWarning, stacklevel=1)
    assert not hasattr(sh, "load_light") and not hasattr(sh, "load_envmap")
