"""relight_rt.relight.strength: stage 1's directional transport bands restored before the relighting factor."""

from __future__ import annotations

import numpy as np
import pytest
from _graphs import OWN_LIGHT, make_models_dir, person, stage1_sides_model, unoccluded_transport

from relight_rt import RelightError, sh
from relight_rt.engine.config import RuntimeConfig
from relight_rt.relight import strength
from relight_rt.relight.relighter import Relighter
from relight_rt.relight.strength import BAND_GAIN, restore_bands


def test_each_degree_is_scaled_by_its_gain_and_the_input_is_kept():
    rng = np.random.default_rng(0)
    t = rng.normal(size=(4, 5, 9)).astype(np.float32)
    keep = t.copy()
    out = restore_bands(t, (2.0, 3.0, 5.0))
    np.testing.assert_allclose(out[..., 0], 2 * t[..., 0], rtol=1e-6)
    np.testing.assert_allclose(out[..., 1:4], 3 * t[..., 1:4], rtol=1e-6)
    np.testing.assert_allclose(out[..., 4:9], 5 * t[..., 4:9], rtol=1e-6)
    np.testing.assert_array_equal(t, keep)
    assert out.dtype == np.float32
    assert BAND_GAIN[0] == 1.0 and BAND_GAIN[1] > 1.0 and BAND_GAIN[2] > 1.0  # band 0 (visibility, exposure) kept


def test_a_transport_without_nine_coefficients_is_one_relight_error():
    with pytest.raises(RelightError, match="9 SH coefficients"):
        restore_bands(np.zeros((4, 4, 4), np.float32))


@pytest.fixture(scope="module")
def sides_relighter(tmp_path_factory):
    folder = make_models_dir(tmp_path_factory.mktemp("sides"), 64, stage2=False, stage1=stage1_sides_model())
    return Relighter(RuntimeConfig(models=folder, device="cpu"))


def _side_factors(relighter, img, mask, light):
    out = relighter.relight(img, light, mask=mask, exposure="physical")
    ratio = (out / np.maximum(img, 1e-6)).mean(axis=2)
    left, right = ratio[40:120, 35:50], ratio[40:120, 60:75]  # the two halves' interiors (person x 30..80)
    return float(np.median(left)), float(np.median(right))


def _lamp_from_right() -> np.ndarray:
    """A white, smooth light coming mostly from the image's right (+y), plus some ambient."""
    n = np.array([0.2, 1.0, 0.1]) / np.linalg.norm([0.2, 1.0, 0.1])
    light = np.repeat(0.15 * unoccluded_transport(n)[:, None] / np.pi, 3, axis=1).astype(np.float32)
    light[0] += 0.1  # relit factors about 0.3 and 0.6: above the ratio's floor, below the highlight shoulder
    return light


def _expected(light, gains):
    """Relit / input on each half: the restored transport's shading under the light over under the own light."""
    out = []
    for normal in ((0, -1, 0), (0, 1, 0)):
        t = restore_bands(unoccluded_transport(normal)[None].astype(np.float32), gains)
        new = max(float(sh.shading(t, light)[0] @ np.array([0.2126, 0.7152, 0.0722])), 0.01)
        own = max(float(sh.shading(t, OWN_LIGHT)[0, 0]), 0.01)
        out.append(new / own)
    return out


def test_the_relit_change_follows_the_restored_transport(sides_relighter, monkeypatch):
    """A white lamp from the image's right, on a person whose left half faces -y and right half +y: each half is
    relit by the restored transport's change of shading (stronger than the network's own transport gives). The
    photo's own unexplained shading kept along its light (``explain_photo``, its own test below) is set aside:
    the random test photo is no shading of the test transport, and it moved the ratio by 2 %."""
    monkeypatch.setattr(strength, "EXPLAIN_SHARE", 0.0)
    img, mask = person(150, 100, seed=2, box=(20, 140, 30, 80))
    light = _lamp_from_right()
    left, right = _side_factors(sides_relighter, img, mask, light)
    exp_left, exp_right = _expected(light, BAND_GAIN)
    plain_left, plain_right = _expected(light, (1.0, 1.0, 1.0))
    assert right / left == pytest.approx(exp_right / exp_left, rel=0.02)
    assert exp_right / exp_left > 1.02 * (plain_right / plain_left)  # the restoration makes the swing larger


def test_own_light_still_gives_the_photo_back(sides_relighter):
    img, mask = person(150, 100, seed=3, box=(20, 140, 30, 80))
    dec = sides_relighter.decompose(img, mask)
    out = sides_relighter.relight(dec, dec.light)
    np.testing.assert_allclose(out, img, atol=1e-4)


def test_without_the_gains_the_change_is_the_networks(sides_relighter, monkeypatch):
    """The gains are what the Relighter uses: set to 1, the change is the unrestored transport's."""
    img, mask = person(150, 100, seed=4, box=(20, 140, 30, 80))
    light = _lamp_from_right()
    monkeypatch.setattr(strength, "BAND_GAIN", (1.0, 1.0, 1.0))
    fresh = Relighter(RuntimeConfig(models=sides_relighter.models_dir, device="cpu"))
    left, right = _side_factors(fresh, img, mask, light)
    exp_left, exp_right = _expected(light, (1.0, 1.0, 1.0))
    assert right / left == pytest.approx(exp_right / exp_left, rel=0.02)


# ------------------------------------------------------------------------------ the photo's own light, refit


def _normals(n, seed):
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(n, 3))
    v[:, 0] = np.abs(v[:, 0]) + 0.3  # facing the camera (+x), as a person's visible surface does
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _scene(seed=0, n=400):
    """Pixels of a diffuse surface: albedo luminance, transport (unoccluded lobes), a true light's photo."""
    rng = np.random.default_rng(seed)
    transport = np.stack([unoccluded_transport(v) for v in _normals(n, seed)])
    albedo = rng.uniform(0.2, 0.8, n)
    lamp = np.array([0.3, -1.0, 0.4]) / np.linalg.norm([0.3, -1.0, 0.4])
    truth = 0.3 * unoccluded_transport(lamp).astype(np.float64) / np.pi
    truth[0] += 0.15
    return albedo, transport, truth, albedo * (transport @ truth)


def test_refit_recovers_the_light_that_explains_the_photo():
    """Stage 1's estimate is a softer light (its directional bands halved): without a prior the refit finds the
    photo's light again; with the default prior it moves most of the way; the photo is explained better."""
    albedo, transport, truth, photo = _scene()
    soft = truth.copy()
    soft[1:] *= 0.5
    estimate = np.repeat(soft[:, None], 3, axis=1).astype(np.float32)
    exact = strength.refit_light(estimate, albedo, transport, photo, prior=0.0)
    np.testing.assert_allclose(exact[:, 1], truth, atol=2e-4)
    fitted = strength.refit_light(estimate, albedo, transport, photo)
    err = lambda light: float(np.abs(albedo * (transport @ light[:, 1]) - photo).mean())  # noqa: E731
    assert err(fitted) < 0.2 * err(estimate)


def test_refit_keeps_a_light_that_already_explains_the_photo_and_its_colour():
    albedo, transport, truth, photo = _scene(seed=1)
    warm = np.array([1.2, 1.0, 0.7])
    light = (truth[:, None] * warm[None, :] / (warm @ np.array([0.2126, 0.7152, 0.0722]))).astype(np.float32)
    np.testing.assert_allclose(strength.refit_light(light, albedo, transport, photo), light, atol=1e-5)
    # a photo twice as bright: the luminance (what the runtime divides by) doubles, the colour stays stage 1's
    out = strength.refit_light(light, albedo, transport, 2 * photo, prior=0.0)
    np.testing.assert_allclose(out @ np.array([0.2126, 0.7152, 0.0722]), 2 * truth, rtol=1e-3, atol=1e-5)
    np.testing.assert_allclose(out[0] / out[0, 1], light[0] / light[0, 1], rtol=1e-4)


def test_refit_with_too_few_pixels_keeps_the_estimate_and_bad_shapes_are_one_error():
    albedo, transport, truth, photo = _scene(n=5)
    light = np.repeat(truth[:, None], 3, axis=1).astype(np.float32) * 0.5
    np.testing.assert_array_equal(strength.refit_light(light, albedo, transport, photo), light)
    with pytest.raises(RelightError, match="refit_light"):
        strength.refit_light(light, albedo[:3], transport, photo)
    with pytest.raises(RelightError, match="light must be"):
        strength.refit_light(light[:4], albedo, transport, photo)
    with pytest.raises(RelightError, match="prior"):
        strength.refit_light(light, albedo, transport, photo, prior=-1.0)


def _face(seed=0, n=6000):
    """Skin pixels of a face (one albedo) lit by a lamp from the front right and a little above, a tenth of them
    darker (eyes, brows); and a stage-1-like estimate of that light that puts the lamp overhead."""
    rng = np.random.default_rng(seed)
    transport = np.stack([unoccluded_transport(v) for v in _normals(n, seed)]).astype(np.float64)
    lamp = np.array([1.0, 0.4, 0.3]) / np.linalg.norm([1.0, 0.4, 0.3])
    truth = 0.4 * unoccluded_transport(lamp).astype(np.float64) / np.pi
    truth[0] += 0.1
    photo = 0.6 * (transport @ truth)
    photo[rng.random(n) < 0.1] *= 0.3
    overhead = 0.4 * unoccluded_transport(np.array([0.3, 0.0, 1.0]) / np.linalg.norm([0.3, 0.0, 1.0])) / np.pi
    overhead[0] = truth[0]
    estimate = np.repeat(overhead[:, None], 3, axis=1).astype(np.float32)
    return transport, photo, truth, estimate


def _band1(light):
    v = np.asarray(light, np.float64)[[3, 1, 2]]
    return v / np.linalg.norm(v)


def test_face_refit_turns_an_overhead_estimate_toward_the_faces_light_and_keeps_the_level():
    """A front-lit face that stage 1 took as lit from overhead: the face's skin (one albedo, its eyes and brows
    left out by the trim) turns the light's degree-1 band most of the way to the lamp; degree 0 and the person's
    mean albedo x shading stay; the colour stays the estimate's."""
    transport, photo, truth, estimate = _face()
    albedo, person = np.full(transport.shape[0], 0.5), transport
    warm = np.array([1.1, 1.0, 0.8]) / (np.array([1.1, 1.0, 0.8]) @ np.array([0.2126, 0.7152, 0.0722]))
    estimate = (estimate[:, 1:2] * warm[None, :]).astype(np.float32)
    out = strength.face_refit(estimate, transport, photo, albedo, person)
    lum = lambda light: np.asarray(light, np.float64) @ np.array([0.2126, 0.7152, 0.0722])  # noqa: E731
    before, after = float(_band1(lum(estimate)) @ _band1(truth)), float(_band1(lum(out)) @ _band1(truth))
    assert before < 0.6 and after > 0.8  # 5,400 kept pixels: 0.73 of the way, less the ridge
    level = lambda light: float((albedo * np.maximum(person @ lum(light), 0)).sum())  # noqa: E731
    assert level(out) == pytest.approx(level(estimate), rel=1e-6)
    np.testing.assert_allclose(out[0] / out[0, 1], estimate[0] / estimate[0, 1], rtol=1e-5)
    # a small face moves the light less (n / (n + FACE_PIXELS) of the way)
    small = strength.face_refit(estimate, transport[:300], photo[:300], albedo, person)
    partway = float(_band1(lum(small)) @ _band1(truth))
    assert before < partway < after


def test_face_refit_keeps_a_light_the_face_already_shows_and_too_small_a_face_says_nothing():
    transport, _, truth, _ = _face(seed=2)
    light = np.repeat(truth[:, None], 3, axis=1).astype(np.float32)
    albedo = np.full(transport.shape[0], 0.5)
    out = strength.face_refit(light, transport, 0.6 * (transport @ truth), albedo, transport)
    np.testing.assert_allclose(out, light, atol=1e-5)
    np.testing.assert_array_equal(strength.face_refit(light, transport[:20], transport[:20, 0], albedo, transport),
                                  light)
    with pytest.raises(RelightError, match="face_refit"):
        strength.face_refit(light, transport, transport[:5, 0], albedo, transport)
    with pytest.raises(RelightError, match="light must be"):
        strength.face_refit(light[:4], transport, transport[:, 0], albedo, transport)


def test_decompose_refits_the_light_and_the_refit_light_gives_the_photo_back(tmp_path_factory):
    """The sides stage 1 reports a frontal light (OWN_LIGHT) for a person whose halves face left and right: it
    does not explain the photo (that light shades the two halves alike, the photo is the albedo). The
    Decomposition's light is refit so that it does; relighting with it gives the photo back."""
    folder = make_models_dir(tmp_path_factory.mktemp("refit"), 64, stage2=False, stage1=stage1_sides_model())
    r = Relighter(RuntimeConfig(models=folder, device="cpu"))
    img, mask = person(150, 100, seed=5, box=(20, 140, 30, 80))
    dec = r.decompose(img, mask)
    assert np.abs(dec.light - OWN_LIGHT).max() > 1e-3
    base = r._factor.restored(dec)
    inner = base["inner"]
    plain = base["albedo"] * (sh.shading(restore_bands(unoccluded_transport((0, 1, 0))[None]), OWN_LIGHT)[0, 0])
    refit = base["albedo"] * sh.shading(base["transport"], dec.white_light)[..., 0]
    photo = base["albedo"]  # this stage 1's albedo is the photo itself
    assert np.abs(refit - photo)[inner].mean() < 0.25 * np.abs(plain - photo)[inner].mean()
    np.testing.assert_allclose(r.relight(dec, dec), img, atol=1e-4)
    np.testing.assert_allclose(r.relight(dec, dec.light), img, atol=1e-4)


def test_video_frames_keep_stage_ones_light(tmp_path_factory):
    folder = make_models_dir(tmp_path_factory.mktemp("frames"), 64, stage2=False, stage1=stage1_sides_model())
    r = Relighter(RuntimeConfig(models=folder, device="cpu"))
    img, mask = person(150, 100, seed=5, box=(20, 140, 30, 80))
    (frame,) = r.decompose_batch([img], [mask], allow_full=True)
    np.testing.assert_allclose(frame.light, OWN_LIGHT, rtol=1e-6)


def test_a_photo_far_brighter_than_its_reconstruction_is_not_blown_out(sides_relighter, monkeypatch):
    """Stage 1's light can leave part of a person in deep shade that the photo shows lit (the cameraman's profile
    face under a light from above and behind); a front light then multiplied it 3-5x, to white. The light the
    model misses, up to half the photo, stays under the new light: the change is at most 1 + twice the change an
    own light that explains the photo gives, and the wrong own light still gives the photo back."""
    from dataclasses import replace

    from relight_rt.relight import factor as factor_module

    img, mask = person(150, 100, seed=5, box=(20, 140, 30, 80))
    dec = sides_relighter.decompose(img, mask)
    n = np.array([0.1, 1.0, 0.0]) / np.linalg.norm([0.1, 1.0, 0.0])  # only from the right: the left half in shade
    shade = np.repeat(0.3 * unoccluded_transport(n)[:, None] / np.pi, 3, axis=1).astype(np.float32)
    shade[0] += 0.01
    wrong = replace(dec, light=shade)
    m = np.array([0.2, -1.0, 0.1]) / np.linalg.norm([0.2, -1.0, 0.1])  # a lamp from the image's left
    left_lamp = np.repeat(0.15 * unoccluded_transport(m)[:, None] / np.pi, 3, axis=1).astype(np.float32)
    left_lamp[0] += 0.1

    def left_factor(d):
        out = sides_relighter.relight(d, left_lamp, exposure="physical")
        return float(np.median((out / np.maximum(img, 1e-6)).mean(axis=2)[40:120, 35:50]))

    honest, floored = left_factor(dec), left_factor(wrong)
    assert floored <= 1 + 2.05 * honest
    np.testing.assert_allclose(sides_relighter.relight(wrong, wrong.light), img, atol=1e-4)
    monkeypatch.setattr(factor_module, "_OWN_FLOOR", np.float32(0.0))
    assert left_factor(replace(dec, light=shade)) > 3 * honest  # without the floor: the blow-out


def test_no_colour_the_light_cannot_give(sides_relighter, monkeypatch):
    """A warm lamp from the front right with a dim blue sky: the half that faces left gets the lamp's ringing in
    red (its shading clamped near 0) and the sky in blue, and the colour of the light there, shading / luminance,
    was a saturated blue (the reference photo's dark scarf under golden-hour). The colour the relit photo takes on
    must stay within what the light gives any unoccluded surface it lights (``look.tint_range``). (Skin the light
    darkens keeps more of its own chroma, ``look.shaded_skin``, a change of the photo's colour, not the light's: held
    off here, where the test model's skin map covers the person.)"""
    from relight_rt import lights
    from relight_rt.relight import factor as factor_module

    monkeypatch.setattr(factor_module, "shaded_skin", lambda factor, *args: factor)

    img, mask = person(150, 100, seed=5, box=(20, 140, 30, 80))
    light = (lights.directional((1.0, 1.0, 0.0), (1.0, 0.7, 0.4), 1.0) + lights.ambient((0.02, 0.03, 0.06))).astype(
        np.float32
    )
    low, high = factor_module.tint_range(light)

    def left_colour():
        out = sides_relighter.relight(img, light, mask=mask, exposure="physical")
        change = (out / np.maximum(img, 1e-6))[40:120, 35:50].reshape(-1, 3)
        lum = change @ np.array([0.2126, 0.7152, 0.0722])
        return np.median(change / np.maximum(lum, 1e-6)[:, None], axis=0)

    tint = left_colour()
    assert (tint >= low - 0.02).all() and (tint <= high + 0.02).all(), (tint, low, high)
    monkeypatch.setattr(factor_module, "tint_range", lambda _: None)
    assert left_colour()[2] > high[2] + 0.5  # without the bound: the blue the light cannot give


def test_explain_photo_moves_along_the_photos_light_only(monkeypatch):
    """explain_photo, unsmoothed: with share 1 the photo's own light gives the shading the photo shows (photo /
    albedo) where the clip allows; a light orthogonal to it sees no change; pixels outside ``where`` and share 0
    are untouched."""
    from relight_rt.relight.strength import EXPLAIN_ALBEDO_MIN, explain_photo

    monkeypatch.setattr(strength, "EXPLAIN_SIGMA", 0.0)

    rng = np.random.default_rng(3)
    t = rng.normal(0.3, 0.2, (6, 5, 9)).astype(np.float32)
    t[..., 0] = 0.9
    light = np.array([1.0, 0.3, 0.2, 0.5, 0.1, 0.0, 0.05, 0.0, 0.1], np.float32)
    albedo = rng.uniform(0.0, 0.8, (6, 5)).astype(np.float32)
    shown = (t @ light) + rng.uniform(-0.4, 0.4, (6, 5)).astype(np.float32)
    photo = shown * np.maximum(albedo, EXPLAIN_ALBEDO_MIN)
    where = np.ones((6, 5), bool)
    where[0] = False
    moved = explain_photo(t, albedo, photo, light, where, share=1.0)
    np.testing.assert_allclose((moved @ light)[1:], shown[1:], atol=1e-5)
    np.testing.assert_array_equal(moved[0], t[0])
    half = explain_photo(t, albedo, photo, light, where, share=0.5)
    np.testing.assert_allclose((half @ light)[1:], ((t @ light + shown) / 2)[1:], atol=1e-5)
    other = rng.normal(size=9).astype(np.float32)
    other -= light * (other @ light) / (light @ light)  # orthogonal to the photo's light
    np.testing.assert_allclose(moved @ other, t @ other, atol=1e-5)
    np.testing.assert_array_equal(explain_photo(t, albedo, photo, light, where, share=0.0), t)
    far = explain_photo(t, albedo, photo * 100, light, where, share=1.0)  # a difference past the clip moves by it
    assert np.all((far @ light - t @ light)[1:] <= 1.0 + 1e-5)
    with pytest.raises(RelightError):
        explain_photo(t[..., :4], albedo, photo, light, where)


def test_explain_photo_moves_a_shadow_by_its_own_share_where_given(monkeypatch):
    """Unsmoothed: ``shadow_share`` (per pixel) moves where the photo shows less shading than the transport (a
    shadow), ``share`` where it shows more; without it both move by ``share``."""
    from relight_rt.relight.strength import explain_photo

    monkeypatch.setattr(strength, "EXPLAIN_SIGMA", 0.0)
    t = np.zeros((2, 2, 9), np.float32)
    t[..., 0] = 1.0
    light = np.zeros(9, np.float32)
    light[0] = 1.0
    albedo = np.full((2, 2), 0.5, np.float32)
    photo = 0.5 * np.array([[0.4, 0.4], [1.6, 1.6]], np.float32)  # shows 0.4 (a shadow), then 1.6 (a surplus) of 1
    where = np.ones((2, 2), bool)
    shadow = np.array([[1.0, 0.5], [1.0, 0.5]], np.float32)  # all of a shadow in the first column, half in the second
    moved = explain_photo(t, albedo, photo, light, where, share=0.5, shadow_share=shadow) @ light
    np.testing.assert_allclose(moved, [[0.4, 0.7], [1.3, 1.3]], atol=1e-6)
    plain = explain_photo(t, albedo, photo, light, where, share=0.5) @ light
    np.testing.assert_allclose(plain, [[0.7, 0.7], [1.3, 1.3]], atol=1e-6)


def test_the_factor_moves_all_of_a_shadow_on_a_face_meshs_skin_only(monkeypatch):
    """``Factor.own`` hands ``explain_photo`` the shadow share ``EXPLAIN_SHADOW_SHARE`` on a face mesh's skin and
    ``EXPLAIN_SHARE`` elsewhere (dark cloth or hair the albedo missed is texture as often as shadow); nothing
    per pixel without a mesh."""
    from relight_rt.relight import factor
    from relight_rt.relight.factor import Factor

    seen = []

    def spy(*args, **kwargs):
        seen.append(kwargs.get("shadow_share"))
        return strength.explain_photo(*args, **kwargs)

    monkeypatch.setattr(factor, "explain_photo", spy)
    inner = np.ones((4, 4), bool)
    skin = np.zeros((4, 4), bool)
    skin[1:3, 1:3] = True
    base = {"window": (0, 4, 0, 4), "alpha": np.ones((4, 4), np.float32), "inner": inner,
            "transport": np.tile(np.float32([1, 0, 0, 0, 0, 0, 0, 0, 0]), (4, 4, 1)),
            "albedo": np.full((4, 4), 0.5, np.float32), "photo": np.full((4, 4), 0.2, np.float32), "face_points": ()}

    class Dec:
        photo = False
        white_light = np.tile(np.float32([[1], [0], [0], [0], [0], [0], [0], [0], [0]]), (1, 3))

    for face_skin in (skin, np.zeros_like(skin)):
        memo: dict = {}
        f = Factor(lambda d, m=memo: m, None, True, lambda d: None)
        monkeypatch.setattr(f, "restored", lambda d, fs=face_skin: {**base, "face_skin": fs})
        f.own(Dec(), with_residual=False)
    np.testing.assert_array_equal(seen[0], np.where(skin, strength.EXPLAIN_SHADOW_SHARE, strength.EXPLAIN_SHARE))
    assert seen[1] is None
    assert strength.EXPLAIN_SHADOW_SHARE == 1.0


def test_explain_photo_keeps_texture_out():
    """Smoothed (the default EXPLAIN_SIGMA): stripes of the photo the albedo missed (one-pixel rows alternately
    brighter and darker than the transport says) move the transport by about their mean, not stripe by stripe,
    while a smooth difference moves it nearly all the way."""
    from relight_rt.relight.strength import explain_photo

    t = np.zeros((40, 40, 9), np.float32)
    t[..., 0] = 1.0
    light = np.zeros(9, np.float32)
    light[0] = 1.0
    albedo = np.full((40, 40), 0.5, np.float32)
    where = np.ones((40, 40), bool)
    stripes = np.where(np.arange(40)[:, None] % 2 == 0, 1.2, 0.8) * np.ones((1, 40), np.float32)
    moved = explain_photo(t, albedo, 0.5 * stripes, light, where, share=1.0)
    assert np.abs(moved[5:35, 5:35] @ light - 1.0).max() < 0.05  # the stripes (+-0.2) averaged out
    smooth = explain_photo(t, albedo, 0.5 * np.full((40, 40), 1.2, np.float32), light, where, share=1.0)
    np.testing.assert_allclose(smooth @ light, 1.2, atol=1e-4)


def test_the_skin_shadow_share_ramps_from_the_share_at_the_skins_edge_to_all_of_it_inside():
    """faces23: explain_photo's shadow share on a face's skin rises inside the skin's edge, not across it in one
    step (a hard switch drew a line where the skin's inset around an eye crosses a cheek's shadow), and stays the
    ordinary share outside the skin (the hair beside a face is not moved)."""
    from relight_rt.relight.strength import EXPLAIN_SHADOW_SHARE, EXPLAIN_SHARE, skin_shadow_share

    assert skin_shadow_share(np.zeros((32, 32), bool), 3.0) is None
    skin = np.zeros((64, 64), bool)
    skin[:, 32:] = True
    share = skin_shadow_share(skin, 3.0)
    row = share[32]
    np.testing.assert_allclose(row[:32], EXPLAIN_SHARE, atol=1e-6)  # outside the skin: the ordinary share
    np.testing.assert_allclose(row[50:], EXPLAIN_SHADOW_SHARE, atol=1e-3)  # deep inside: all of the shadow
    ramp = row[32:42]
    assert EXPLAIN_SHARE < ramp[0] < EXPLAIN_SHADOW_SHARE - 0.1  # a ramp, not a step, at the edge ...
    assert np.all(np.diff(row[32:50]) >= -1e-6)  # ... rising inward
