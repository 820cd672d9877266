"""relight_rt.relight.factor ``unshaded_albedo``: the share of the photo's own shading that stage 1 put into a
face's albedo (the slope of log albedo on log shading over the face's skin) taken out over the person."""

import numpy as np
import pytest

from relight_rt.relight.unshade import UNSHADE_MIN_SKIN, unshaded_albedo


def _face(share: float, size: int = 40):
    """A side-lit face: shading falling from 1 to 0.1 across it, a true albedo with texture, and stage 1's albedo
    holding ``share`` of the shading (true albedo x (shading / median) ** share)."""
    rng = np.random.default_rng(0)
    shading = np.tile(np.geomspace(1.0, 0.1, size, dtype=np.float32), (size, 1))
    true = (0.5 + 0.05 * rng.standard_normal((size, size))).astype(np.float32)
    level = float(np.median(shading))
    albedo = (true * (shading / level) ** share).astype(np.float32)
    skin = np.zeros((size, size), bool)
    skin[5:35, 5:35] = True
    return albedo, shading, skin, np.ones((size, size), bool), true


@pytest.mark.parametrize("share", [0.2, 0.5])
def test_the_shading_stage1_put_into_the_albedo_is_taken_out(share):
    albedo, shading, skin, inner, true = _face(share)
    out = unshaded_albedo(albedo, shading, skin, inner)
    # the fit's median is over the skin, the made-up one over the whole square: one scale apart at most (within the
    # shading the skin spans)
    ratio = (out / true)[:, 6:34]
    assert ratio.std() / ratio.mean() < 0.02
    slope = np.polyfit(np.log(shading[skin]), np.log(out[skin]), 1)[0]
    assert abs(slope) < 0.02


def test_an_albedo_that_does_not_follow_the_shading_is_kept():
    albedo, shading, skin, inner, _ = _face(0.0)
    albedo = albedo * (shading / np.median(shading)) ** -0.3  # brighter where shaded: not what stage 1 does
    np.testing.assert_array_equal(unshaded_albedo(albedo.astype(np.float32), shading, skin, inner),
                                  albedo.astype(np.float32))  # the slope is kept at >= 0


def test_outside_the_person_and_without_a_face_nothing_changes():
    albedo, shading, skin, inner, _ = _face(0.4)
    inner[:, :10] = False
    out = unshaded_albedo(albedo, shading, skin, inner)
    np.testing.assert_array_equal(out[:, :10], albedo[:, :10])
    assert np.abs(out[:, 10:] - albedo[:, 10:]).max() > 0.05
    few = np.zeros_like(skin)
    few.flat[: UNSHADE_MIN_SKIN - 1] = True
    assert unshaded_albedo(albedo, shading, few, inner) is albedo
    assert albedo.dtype == out.dtype == np.float32


def test_shading_beyond_what_the_skin_spans_gets_the_skins_extreme_gain():
    """Hair turned away in deep shade is not lifted past the darkest skin's correction (a profile's hair came out
    3x brighter)."""
    albedo, shading, skin, inner, _ = _face(0.4)
    shading = shading.copy()
    shading[:, 36:] = 1e-3  # far darker than any skin pixel
    out = unshaded_albedo(albedo, shading, skin, inner)
    gain = out / albedo
    assert gain[:, 36:].max() <= gain[skin].max() * 1.0001
