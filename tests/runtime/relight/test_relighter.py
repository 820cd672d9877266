"""relight_rt.relight.relighter: decompose / relight / relight_many on hand-made analytic graphs (no torch).

The analytic stage 1 (tests/_graphs.py) gives albedo = input ⊙ mask and a transport whose shading under
the photo's own light is exactly 1, so relighting with that light must give the input back, and a light
k times as bright gives k x the input inside the mask.
"""

import logging

import cv2
import numpy as np
import pytest
from _graphs import LOBE, OWN_LIGHT, diffuse_models_dir, make_models_dir, models_dir, person, save, stage2_model

pytest.importorskip("hypothesis", reason='property tests; pip install "relight-rt[test]"')
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from hypothesis.extra import numpy as hnp  # noqa: E402

import relight_rt
from relight_rt import RelightError, lights, sh  # noqa: E402
from relight_rt.engine.config import RuntimeConfig  # noqa: E402
from relight_rt.image.compositing import Background  # noqa: E402
from relight_rt.relight.relighter import Decomposition, Relighter, RelightResult, diffuse_batch  # noqa: E402

__all__ = ["models_dir", "diffuse_models_dir"]  # fixtures


@pytest.fixture(scope="module")
def relighter(models_dir):
    return relight_rt.open(RuntimeConfig(models=models_dir, device="cpu"))


@pytest.fixture(scope="module")
def plain(models_dir):
    return Relighter(RuntimeConfig(models=models_dir, device="cpu", detail=False))


def inside(mask):
    return mask > 0.5


def test_decompose_returns_network_and_input_frames(relighter):
    img, mask = person()
    dec = relighter.decompose(img, mask)
    assert isinstance(dec, Decomposition)
    assert dec.albedo.shape == (64, 64, 3) and dec.transport.shape == (64, 64, 9) and dec.skin.shape == (64, 64)
    assert dec.light.shape == (9, 3) and dec.mask.shape == (150, 100) and dec.image.shape == (150, 100, 3)
    np.testing.assert_allclose(dec.light, OWN_LIGHT, rtol=1e-6)
    np.testing.assert_allclose(dec.shading()[dec.network_mask == 1], 1.0, atol=1e-5)
    assert not dec.albedo.flags.writeable
    core = np.zeros_like(mask, bool)
    core[26:134, 36:74] = True  # away from the outline, which the 64-px mask blurs
    np.testing.assert_allclose(dec.to_input(dec.network_mask)[core], 1.0, atol=1e-5)


def test_own_light_gives_the_input_back(relighter):
    img, mask = person()
    keep = img.copy(), mask.copy()
    out = relighter.relight(img, relighter.decompose(img, mask), mask=mask)
    assert out.shape == img.shape and out.dtype == np.float32
    np.testing.assert_allclose(out, img, atol=1e-5)
    np.testing.assert_array_equal(img, keep[0])  # arguments never modified
    np.testing.assert_array_equal(mask, keep[1])


def test_full_resolution_detail_beats_plain_upsampling(relighter, plain):
    """A person 2x larger than the network square (crop side 128, R = 64), fine texture: relit with its own
    estimated light, detail transfer returns the input (RMSE < 1e-4) while upsampling the network's
    64 x 64 output loses the texture (RMSE > 0.1 on uniform noise in [0.2, 0.8])."""
    # rows 16-133: crop 128 x 110 → side 128 = 2R (the symmetric crop, crop.SYMMETRIC_CROP, keeps the 5 px margin
    # after the mask too; the reference's crop needed rows 16-134: the premise, not the property, mirror33)
    img, mask = person(150, 140, seed=5, box=(16, 134, 20, 120))
    dec = relighter.decompose(img, mask)
    assert dec.geometry.side == 128 and dec.geometry.scale == 2.0
    m = inside(mask)
    err_detail = np.sqrt(np.mean((relighter.relight(dec, dec.light) - img)[m] ** 2))
    err_plain = np.sqrt(np.mean((plain.relight(dec, dec.light) - img)[m] ** 2))
    assert err_detail < 1e-4
    assert err_plain > 0.1
    assert err_plain > 1000 * err_detail


@pytest.mark.parametrize("k", [0.5, 0.8, 1.2])
def test_detail_transfer_follows_another_light(relighter, plain, k):
    """Stage 2 here adds 0.1 (d - 0.5), d = k·input: the true result is clip(1.1 d - 0.05). The ratio is
    taken from 64-px images (and is not exactly a ratio where stage 2 adds light), so it is close, not exact;
    plain upsampling loses the texture: at least 5x worse on average. Compared where the result stays below
    the highlight shoulder's lowest knee (0.8): above it the runtime rolls off instead of clipping."""
    img, mask = person(150, 140, seed=6, box=(16, 135, 20, 120))
    dec = relighter.decompose(img, mask)
    m = inside(mask)
    m_all = m.copy()
    m &= (np.clip(1.1 * np.clip(k * img, 0, 1) - 0.05, 0, 1) < 0.8).all(axis=2)
    assert m.sum() > 0.3 * m_all.sum()
    d = np.clip(k * img, 0, 1)
    expect = np.clip(d + 0.1 * (d - 0.5), 0, 1)
    out = relighter.relight(dec, k * dec.light, exposure="physical")  # tests the absolute intensity
    err = np.abs(out - expect)[m].mean()
    err_plain = np.abs(plain.relight(dec, k * dec.light, exposure="physical") - expect)[m].mean()
    assert err < 0.02 and err_plain > 5 * err, (err, err_plain)
    np.testing.assert_array_equal(out[~m_all], img[~m_all])  # background untouched outside the mask


def test_background_untouched_outside_the_mask(relighter):
    img, mask = person(seed=2)
    out = relighter.relight(img, 0.3 * OWN_LIGHT, mask=mask, exposure="physical")
    np.testing.assert_array_equal(out[mask == 0], img[mask == 0])
    assert np.abs(out[inside(mask)] - img[inside(mask)]).mean() > 0.1


def test_transparent_and_image_backgrounds(relighter):
    img, mask = person(seed=3)
    rgba = relighter.relight(img, OWN_LIGHT, mask=mask, background="transparent")
    assert rgba.shape == (150, 100, 4)
    np.testing.assert_array_equal(rgba[..., 3], mask)
    assert not rgba[mask == 0, :3].any()
    bg = np.full((150, 100, 3), 0.25, np.float32)
    out = relighter.relight(img, OWN_LIGHT, mask=mask, background=bg)
    np.testing.assert_array_equal(out[mask == 0], bg[mask == 0])
    np.testing.assert_allclose(out[inside(mask)], img[inside(mask)], atol=1e-5)
    with pytest.raises(RelightError, match="background: is 10x10"):  # "exact": sizes must match
        relighter.relight(img, OWN_LIGHT, mask=mask, background=Background.from_image(np.zeros((10, 10, 3)), "exact"))
    small = np.zeros((10, 10, 3), np.float32)
    small[:, 5:] = 1.0  # left half black, right half white: "cover" keeps the halves, scaled to the photo
    out = relighter.relight(img, OWN_LIGHT, mask=mask, background=small)
    assert out.shape == (150, 100, 3)
    assert out[0, 10].max() == 0 and out[0, 90].min() == 1
    with pytest.raises(RelightError, match="background: expected"):
        relighter.relight(img, OWN_LIGHT, mask=mask, background=3)


def soft_person_over_blue(h=150, w=100):
    """A person of flat colour F with a 10-px soft edge over pure blue: photo = alpha F + (1 - alpha) blue."""
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    inside_dist = np.minimum.reduce([yy - 20, 140 - yy, xx - 30, 70 - xx])
    alpha = np.clip(inside_dist / 10 + 0.5, 0, 1).astype(np.float32)
    f = np.array([0.8, 0.5, 0.3], np.float32)
    photo = alpha[..., None] * f + (1 - alpha[..., None]) * np.array([0.0, 0.0, 1.0], np.float32)
    return photo.astype(np.float32), alpha, f


def test_a_new_backdrop_carries_none_of_the_old_one(relighter):
    """Issue 33: over a new backdrop the soft edge kept the photo's old background (a blue fringe here)."""
    photo, alpha, f = soft_person_over_blue()
    green = np.zeros_like(photo)
    green[..., 1] = 1.0
    out = relighter.relight(photo, OWN_LIGHT, mask=alpha, background="green")
    truth = alpha[..., None] * f + (1 - alpha[..., None]) * green
    naive = alpha[..., None] * photo + (1 - alpha[..., None]) * green  # the photo's own edge colour
    soft = (alpha > 0.1) & (alpha < 0.9)
    assert np.abs(naive - truth)[soft].mean() > 0.1
    assert np.abs(out - truth)[soft].mean() < 0.3 * np.abs(naive - truth)[soft].mean()
    rgba = relighter.relight(photo, OWN_LIGHT, mask=alpha, background="transparent")
    assert np.abs(rgba[soft][:, 2] - f[2]).mean() < 0.3 * np.abs(photo[soft][:, 2] - f[2]).mean()
    same = relighter.relight(photo, OWN_LIGHT, mask=alpha)  # over its own background nothing is taken out
    np.testing.assert_allclose(same[soft], photo[soft], atol=0.05)


def test_a_video_frame_relights_only_the_person_share_of_its_thin_edge(relighter):
    """A video frame's anti-aliased edge mixes the person and the backdrop: only the person's share is relit.

    Before, the frame's own pixels were relit as they were, so the backdrop's share of every edge pixel took the
    new light (a line of the new light's colour along the outline, the clip of frames 1-8 under golden-hour).
    """
    h, w = 150, 100
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    inside_dist = np.minimum.reduce([yy - 20, 140 - yy, xx - 30.3, 70.6 - xx])
    alpha = np.clip(inside_dist / 1.5 + 0.5, 0, 1).astype(np.float32)  # a 1.5-px edge
    f = np.array([0.4, 0.25, 0.15], np.float32)
    backdrop = np.array([0.6, 0.7, 0.9], np.float32)
    frame = (alpha[..., None] * f + (1 - alpha[..., None]) * backdrop).astype(np.float32)
    (dec,) = relighter.decompose_batch([frame], [alpha], allow_full=True)
    out = relighter.relight(dec, 2 * OWN_LIGHT, exposure="physical")
    truth = alpha[..., None] * 2 * f + (1 - alpha[..., None]) * backdrop
    soft = (alpha > 0.1) & (alpha < 0.9)
    assert soft.sum() > 100
    naive = frame * (1 + alpha[..., None])  # the frame's own pixels relit: alpha 2 I + (1 - alpha) I
    assert np.abs(naive - truth)[soft].mean() > 0.03
    assert np.abs(out - truth)[soft].mean() < 0.25 * np.abs(naive - truth)[soft].mean()
    np.testing.assert_allclose(relighter.relight(dec, OWN_LIGHT, exposure="physical"), frame, atol=2e-3)


def test_layers(relighter):
    img, mask = person(seed=4)
    res = relighter.layers(img, 2 * OWN_LIGHT, mask=mask, exposure="physical")
    assert isinstance(res, RelightResult) and not res.diffuse_only
    for name in ("albedo", "shading", "diffuse", "residual", "relit"):
        assert res.layers[name].shape == (150, 100, 3) and res.layers[name].dtype == np.float32
    core = np.zeros((150, 100), bool)
    core[30:130, 40:70] = True
    np.testing.assert_allclose(res.layers["shading"][core], 2.0, atol=1e-4)
    assert abs(res.layers["albedo"][core].mean() - img[core].mean()) < 0.01  # 64-px albedo, upsampled
    np.testing.assert_allclose(res.light, 2 * OWN_LIGHT)


def test_diffuse_only_without_stage2(diffuse_models_dir, caplog):
    with caplog.at_level(logging.WARNING, logger="relight_rt.relight.graphs"):
        r = Relighter(RuntimeConfig(models=diffuse_models_dir, device="cpu"))
    assert r.diffuse_only and "diffuse-only" in caplog.text
    img, mask = person(seed=7)
    res = r.layers(img, 0.5 * OWN_LIGHT, mask=mask, exposure="physical")
    assert res.diffuse_only and not res.layers["residual"].any()
    m = inside(mask)
    np.testing.assert_allclose(res.image[m], 0.5 * img[m], atol=0.03)  # ratio (0.5 c + eps) / (c + eps)
    np.testing.assert_allclose(res.layers["diffuse"][30:130, 40:70].mean(), 0.5 * img[30:130, 40:70].mean(), atol=0.01)
    assert r.dvp is None


def test_relight_many_matches_relight_in_any_batch_size(relighter):
    img, mask = person(seed=8)
    dec = relighter.decompose(img, mask)
    lights = np.stack([OWN_LIGHT * k for k in (0.5, 0.9, 1.3, 1.7, 0.2)])
    one = np.stack([relighter.relight(dec, lit, exposure="physical") for lit in lights])
    for bs in (1, 2, 5, 8):
        many = relighter.relight_many(dec, lights, batch_size=bs, exposure="physical")
        np.testing.assert_allclose(many, one, atol=1e-6)
    rgba = relighter.relight_many(img, list(lights[:2]), mask=mask, background="transparent")
    assert rgba.shape == (2, 150, 100, 4)
    assert sum(1 for _ in relighter.iter_relight(dec, lights[:3])) == 3
    with pytest.raises(RelightError, match="batch_size"):
        relighter.relight_many(dec, lights, batch_size=0)
    with pytest.raises(RelightError, match=r"\(K, 9, 3\)"):
        relighter.relight_many(dec, np.zeros((2, 9, 4)))
    with pytest.raises(RelightError, match="at least one"):
        relighter.relight_many(dec, [])
    with pytest.raises(RelightError, match="NaN"):
        relighter.relight_many(dec, np.full((2, 9, 3), np.nan))


def test_diffuse_batch_is_sh_shading():
    rng = np.random.default_rng(9)
    albedo = rng.random((3, 8, 8)).astype(np.float32)
    transport = rng.normal(size=(9, 8, 8)).astype(np.float32)
    lights = rng.normal(size=(3, 9, 3))
    got = diffuse_batch(albedo, transport, lights)
    for k in range(3):
        want = np.clip(albedo.transpose(1, 2, 0) * sh.shading(transport.transpose(1, 2, 0), lights[k]), 0, 1)
        np.testing.assert_allclose(got[k].transpose(1, 2, 0), want, atol=1e-5)


def test_light_forms(relighter, tmp_path):
    img, mask = person(seed=10)
    dec = relighter.decompose(img, mask)
    want = relighter.relight(dec, 0.7 * OWN_LIGHT)
    np.save(tmp_path / "l.npy", 0.7 * OWN_LIGHT.astype(np.float64))
    np.testing.assert_allclose(relighter.relight(dec, tmp_path / "l.npy"), want, atol=1e-6)
    np.testing.assert_allclose(relighter.relight(dec, (0.7 * OWN_LIGHT).tolist()), want, atol=1e-6)
    # light transfer from another photo (its light is OWN_LIGHT: the analytic graph's fixed estimate)
    cv2.imwrite(str(tmp_path / "other.jpg"), (img[..., ::-1] * 255).astype(np.uint8))
    cv2.imwrite(str(tmp_path / "other_mask.png"), (mask * 255).astype(np.uint8))
    np.testing.assert_allclose(relighter.resolve_light(tmp_path / "other.jpg"), OWN_LIGHT, rtol=1e-6)
    np.testing.assert_allclose(relighter.resolve_light(dec), OWN_LIGHT, rtol=1e-6)
    # a constant environment of radiance 1 → L00 = sqrt(4π) in every colour
    cv2.imwrite(str(tmp_path / "env.hdr"), np.ones((16, 32, 3), np.float32))
    np.testing.assert_allclose(relighter.resolve_light(tmp_path / "env.hdr")[0], np.sqrt(4 * np.pi), rtol=1e-2)
    np.testing.assert_allclose(relighter.resolve_light("studio"), lights.preset("studio"), rtol=1e-6)


@pytest.mark.parametrize(
    ("light", "match"),
    [
        (np.zeros((9, 4)), r"\(9, 3\)"),
        (np.full((9, 3), np.nan), "NaN"),
        (np.full((9, 3), np.inf), "Inf"),
        ("no/such/light.npy", "not found"),
        ("definitely-not-a-preset", "definitely-not-a-preset.*studio"),
    ],
)
def test_bad_lights(relighter, light, match):
    img, mask = person(seed=11)
    with pytest.raises(RelightError, match=match):
        relighter.relight(img, light, mask=mask)


@pytest.mark.parametrize(
    ("image", "mask", "match"),
    [
        (np.zeros((20, 20, 3), np.float32), np.zeros((20, 21)), "image is 20x20"),
        (np.zeros((20, 20, 3), np.float32), np.zeros((20, 20)), "empty"),
        (np.zeros((20, 20, 3), np.float32), np.ones((20, 20)), "whole image"),
        (np.zeros((20, 20, 2), np.uint8), np.ones((20, 20)), r"\(H, W, 3\)"),
        (np.full((20, 20, 3), np.nan, np.float32), np.ones((20, 20)), "NaN"),
        (np.zeros((20, 20, 3), np.float32), None, "no person found in image"),  # the automatic matte looked
        ("missing.png", None, "cannot read"),
    ],
)
def test_bad_inputs(relighter, image, mask, match):
    with pytest.raises(RelightError, match=match):
        relighter.decompose(image, mask)
    with pytest.raises(RelightError, match=match):
        relighter.relight(image, OWN_LIGHT, mask=mask)


def test_rgba_alpha_is_the_mask(relighter):
    img, mask = person(seed=12)
    rgba = np.concatenate([img, mask[..., None]], axis=2)
    np.testing.assert_allclose(relighter.relight(rgba, OWN_LIGHT), relighter.relight(img, OWN_LIGHT, mask=mask))
    with pytest.raises(RelightError, match="alpha channel is opaque everywhere, so it is no mask"):
        # an opaque alpha is no mask: the automatic matte decides, and finds nobody in this drawing
        relighter.relight(np.concatenate([img, np.ones_like(mask)[..., None]], axis=2), OWN_LIGHT)
    with pytest.raises(RelightError, match="already has its mask"):
        relighter.relight(relighter.decompose(img, mask), OWN_LIGHT, mask=mask)


def test_missing_models_and_mismatched_stage2(tmp_path, monkeypatch):
    monkeypatch.delenv("RELIGHT_RT_MODELS", raising=False)
    with pytest.raises(RelightError, match="looked in"):
        Relighter(RuntimeConfig(models=tmp_path / "none", device="cpu"))
    folder = make_models_dir(tmp_path / "m", 64, stage2=False)
    save(stage2_model(128), folder / "stage2.onnx")
    with pytest.raises(RelightError, match="resolution 128 does not match stage 1's 64"):
        Relighter(RuntimeConfig(models=folder, device="cpu"))
    folder = make_models_dir(tmp_path / "n", 64, stage2=False)
    with pytest.raises(RelightError, match="preprocess"):
        Relighter(RuntimeConfig(models=folder, device="cpu", preprocess="nearest"))


def test_reference_photo_end_to_end(relighter, reference_dir):
    """The reference's real photo (1950 x 1302, person ~8%): output has its size, background untouched."""
    photo, mask_path = reference_dir / "photo" / "sample.jpg", reference_dir / "photo" / "sample_mask.png"
    out = relighter.relight(photo, 1.2 * OWN_LIGHT, mask=mask_path, exposure="physical")
    img = cv2.cvtColor(cv2.imread(str(photo)), cv2.COLOR_BGR2RGB).astype(np.float32) / 255
    mask = cv2.imread(str(mask_path), cv2.IMREAD_GRAYSCALE)  # the reference reads its masks this way
    assert out.shape == img.shape
    np.testing.assert_allclose(out[mask == 0], img[mask == 0], atol=1e-6)
    assert np.abs(out - img)[mask == 255].mean() > 0.02


def _elements(dtype):
    return st.floats(0, 1, width=32) if np.dtype(dtype).kind == "f" else None  # else the dtype's full range


@st.composite
def photo_and_mask(draw):
    """Mostly well-formed inputs (so that the success path is exercised), with every kind of defect mixed in."""
    h, w = draw(st.integers(1, 48)), draw(st.integers(1, 48))
    channels = draw(st.sampled_from([3, 3, 3, 3, 4, 1, 2]))
    dtype = draw(st.sampled_from([np.uint8, np.uint8, np.float32, np.float64, np.uint16, np.int16, np.bool_]))
    shape = (h, w, channels) if draw(st.booleans()) or channels != 1 else (h, w)
    image = draw(hnp.arrays(dtype, shape, elements=_elements(dtype)))
    defect = draw(st.sampled_from([None] * 6 + [np.nan, np.inf, -0.5, 1.5]))
    if defect is not None and image.dtype.kind == "f":
        image.flat[draw(st.integers(0, image.size - 1))] = defect
    kind = draw(st.sampled_from(["box", "box", "random", "none", "wrong-size"]))
    if kind == "none":
        return image, None
    mh, mw = (h, w) if kind != "wrong-size" else (h + 1, w)
    if kind == "box":
        mask = np.zeros((mh, mw), np.float32)
        y0, x0 = draw(st.integers(0, mh - 1)), draw(st.integers(0, mw - 1))
        mask[y0 : y0 + draw(st.integers(1, mh)), x0 : x0 + draw(st.integers(1, mw))] = 1
    else:
        mdtype = draw(st.sampled_from([np.float32, np.uint8, np.bool_]))
        mask = draw(hnp.arrays(mdtype, (mh, mw), elements=_elements(mdtype)))
    return image, mask


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    inputs=photo_and_mask(),
    light=st.one_of(
        st.just(OWN_LIGHT),
        hnp.arrays(np.float64, st.sampled_from([(9, 3), (3, 9), (9,)]), elements=st.floats(-1e3, 1e3)),
        st.just(np.full((9, 3), np.nan)),
        st.builds(lambda v: np.full((9, 3), v), st.sampled_from([1e30, 4e38, 5e-324, -0.0, 1e300])),
    ),
    background=st.sampled_from(["original", "transparent"]),
)
def test_property_only_correct_results_or_relight_error(relighter, inputs, light, background):
    image, mask = inputs
    try:
        out = relighter.relight(image, light, mask=mask, background=background)
    except RelightError:
        return
    channels = 4 if background == "transparent" else 3
    assert out.dtype == np.float32 and out.shape == image.shape[:2] + (channels,)
    assert np.isfinite(out).all() and out.min() >= 0 and out.max() <= 1


EXTREMES = [0.0, -0.0, 1e30, -1e30, 1.0000001e30, 3.4e38, 4e38, -4e38, 1e300, 5e-324, 1e-45, 1.1754942e-38,
            2.2250738585072014e-308, np.nan, np.inf, -np.inf]  # fmt: skip


def _light_values():
    """Light coefficients: ordinary, extreme (overflowing float32, subnormal, signed zero) and non-finite."""
    return st.one_of(st.floats(-2.0, 2.0), st.sampled_from(EXTREMES), st.floats(allow_nan=True, allow_infinity=True))


@st.composite
def extreme_light(draw):
    """A (9, 3) light: a sane light with the coefficients of a random bit pattern set to one drawn value
    (ordinary, extreme or non-finite), in a drawn dtype, as an array or a nested list. Drawn from a few
    scalars rather than 27 elements, so that 1,000 examples take seconds."""
    value = draw(_light_values())
    bits = draw(st.integers(0, (1 << 27) - 1))
    scale = draw(st.floats(-2.0, 2.0))
    dtype = draw(st.sampled_from([np.float64, np.float64, np.float32, np.float16, np.int64]))
    chosen = ((bits >> np.arange(27)) & 1).astype(bool).reshape(9, 3)
    base = np.where(chosen, value, scale * OWN_LIGHT.astype(np.float64))
    with np.errstate(all="ignore"):
        light = base.astype(dtype) if dtype != np.int64 else np.nan_to_num(base).clip(-1e18, 1e18).astype(dtype)
    return light if draw(st.booleans()) else light.tolist()


@pytest.fixture(scope="module")
def small_decomposition(relighter):
    img, mask = person(40, 30, seed=21, box=(5, 35, 8, 22))
    return relighter.decompose(img, mask)


@pytest.mark.long
@settings(max_examples=1000, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(light=extreme_light())
def test_property_extreme_lights(relighter, small_decomposition, light):
    """Issue 18: every light is either refused with RelightError or gives finite pixels in [0, 1], and ``relight``
    and ``relight_many`` agree on which (a light valid in float64 but not in float32 was accepted by one only)."""
    dec = small_decomposition
    try:
        out = relighter.relight(dec, light)
    except RelightError as exc:
        with pytest.raises(RelightError):
            relighter.relight_many(dec, [light])
        assert "NaN or Inf" in str(exc) or "too large" in str(exc) or "overflows" in str(exc) or "(9, 3)" in str(exc)
        return
    assert out.shape == (40, 30, 3) and out.dtype == np.float32
    assert np.isfinite(out).all() and out.min() >= 0 and out.max() <= 1
    np.testing.assert_allclose(relighter.relight_many(dec, [light])[0], out, atol=1e-6)


@pytest.mark.parametrize("value", [1e30, -0.0, 5e-324, 1e-45])
def test_extreme_but_valid_lights_give_finite_images(relighter, small_decomposition, value):
    out = relighter.relight(small_decomposition, np.full((9, 3), value))
    assert np.isfinite(out).all() and 0 <= out.min() and out.max() <= 1


@pytest.mark.parametrize("value", [4e38, -4e38, 1e300, 1.0000001e30])
def test_lights_too_large_for_float32_are_refused(relighter, small_decomposition, value):
    for call in (relighter.relight, lambda d, v: relighter.relight_many(d, [v])):
        with pytest.raises(RelightError, match="too large"):
            call(small_decomposition, np.full((9, 3), value))


def test_lobe_matches_sh_module():
    """The analytic graph's transport is sh's cosine lobe times the basis at +x (sanity of the fixture)."""
    np.testing.assert_allclose(LOBE, sh.cosine_lobe() * sh.basis(np.array([1.0, 0, 0])), rtol=1e-6)


@pytest.fixture(scope="module")
def tiny_models(test_data_dir, tmp_path_factory):
    """The export helper's tiny random-weight graphs (tests/data), under the names a models folder uses."""
    import shutil

    if not (test_data_dir / "tiny_stage1.onnx").is_file():
        pytest.skip("tests/data/tiny_*.onnx not present")
    folder = tmp_path_factory.mktemp("tiny")
    for kind in ("stage1", "stage2", "dvp"):
        shutil.copy(test_data_dir / f"tiny_{kind}.onnx", folder / f"{kind}.onnx")
    return folder


def test_exported_tiny_models_run_end_to_end(tiny_models):
    r = Relighter(RuntimeConfig(models=tiny_models, device="cpu"))
    assert r.resolution == 128 and not r.diffuse_only and r.dvp is not None
    img, mask = person(300, 200, seed=13, box=(20, 280, 50, 150))
    dec = r.decompose(img, mask)
    assert dec.transport.shape == (128, 128, 9) and np.isfinite(dec.light).all()
    outs = r.relight_many(dec, np.stack([lights.preset(n) for n in ("studio", "rim", "neon")]), batch_size=2)
    assert outs.shape == (3, 300, 200, 3) and np.isfinite(outs).all() and 0 <= outs.min() and outs.max() <= 1
    np.testing.assert_array_equal(outs[:, mask == 0], np.broadcast_to(img[mask == 0], (3,) + img[mask == 0].shape))
    np.testing.assert_allclose(outs[1], r.relight(dec, lights.preset("rim")), atol=1e-5)  # batch items independent
    np.testing.assert_allclose(r.relight(dec, dec), img, atol=1e-5)  # own light through detail transfer


def test_shade_graph_is_the_numpy_formula():
    """The hand-encoded ONNX shading graph used on CUDA (relight_rt.engine.device_chain) equals diffuse_batch (run on
    CPU)."""
    import onnx
    import onnxruntime as ort

    from relight_rt.engine.device_chain import shade_graph

    onnx.checker.check_model(onnx.load_from_string(shade_graph()), full_check=True)
    session = ort.InferenceSession(shade_graph(), providers=["CPUExecutionProvider"])
    rng = np.random.default_rng(14)
    albedo = rng.random((3, 16, 12)).astype(np.float32)
    transport = rng.normal(size=(9, 16, 12)).astype(np.float32)
    lits = rng.normal(size=(5, 9, 3)).astype(np.float32)
    got = session.run(None, {"albedo": albedo[None], "transport": transport[None], "light": lits})[0]
    np.testing.assert_allclose(got, diffuse_batch(albedo, transport, lits), atol=1e-6)


@pytest.mark.parametrize("with_stage2", [True, False])
def test_io_binding_chain_matches_numpy_path(tiny_models, diffuse_models_dir, with_stage2):
    """The CUDA chain's IO-binding logic, run with device "cpu" (no GPU here): same results as numpy."""
    from relight_rt.engine.device_chain import DeviceChain

    folder = tiny_models if with_stage2 else diffuse_models_dir
    ref = Relighter(RuntimeConfig(models=folder, device="cpu"))
    chained = Relighter(RuntimeConfig(models=folder, device="cpu"))
    chained._network.chain = DeviceChain(chained.stage1, chained.stage2, device="cpu")
    img, mask = person(200, 150, seed=15, box=(10, 190, 40, 110))
    dec_a, dec_b = ref.decompose(img, mask), chained.decompose(img, mask)
    np.testing.assert_allclose(dec_b.transport, dec_a.transport, atol=1e-6)
    lits = np.stack([lights.preset(n) for n in ("studio", "rim", "neon")])
    want = ref.relight_many(dec_a, lits)
    np.testing.assert_allclose(chained.relight_many(dec_b, lits, batch_size=2), want, atol=1e-5)
    la, lb = ref.layers(dec_a, lits[0]), chained.layers(dec_a, lits[0])
    for name in la.layers:
        np.testing.assert_allclose(lb.layers[name], la.layers[name], atol=1e-5)


def test_io_binding_chain_relights_a_person_seen_upright_as_numpy_does(models_dir):
    """A person stage 1 saw turned upright (relight_rt.relight.upright) keeps no device copies of stage 1's outputs
    (they are the turned picture's): the CUDA chain's logic, run with device "cpu", uploads the turned-back ones and
    relights as numpy does. Both Relighters are told the person lies (the analytic graphs find no face)."""
    from relight_rt.engine.device_chain import DeviceChain

    ref = Relighter(RuntimeConfig(models=models_dir, device="cpu"))
    chained = Relighter(RuntimeConfig(models=models_dir, device="cpu"))
    chained._network.chain = DeviceChain(chained.stage1, chained.stage2, device="cpu")
    img, mask = person(120, 200, seed=17, box=(40, 90, 15, 185))  # lying across the picture
    for r in (ref, chained):
        r._network.upright.quarters = lambda *args: 1
    dec_a, dec_b = ref.decompose(img, mask), chained.decompose(img, mask)
    assert dec_a.upright == dec_b.upright == 1
    np.testing.assert_allclose(dec_b.albedo_chw, dec_a.albedo_chw, atol=1e-6)
    lits = np.stack([lights.preset(n) for n in ("studio", "rim", "neon")])
    np.testing.assert_allclose(chained.relight_many(dec_b, lits, batch_size=2), ref.relight_many(dec_a, lits),
                               atol=1e-5)


@pytest.mark.gpu
def test_cuda_matches_cpu(tiny_models):
    import onnxruntime as ort

    if "CUDAExecutionProvider" not in ort.get_available_providers():
        pytest.skip("needs onnxruntime-gpu and a CUDA device")
    gpu = Relighter(RuntimeConfig(models=tiny_models, device="cuda"))
    cpu = Relighter(RuntimeConfig(models=tiny_models, device="cpu"))
    assert gpu._chain is not None and gpu.stage1.on_cuda
    img, mask = person(300, 200, seed=16, box=(20, 280, 50, 150))
    lits = np.stack([lights.preset(n) for n in ("studio", "rim")])
    want = cpu.relight_many(img, lits, mask=mask)
    np.testing.assert_allclose(gpu.relight_many(img, lits, mask=mask), want, atol=2e-3)


def test_detail_helpers():
    from relight_rt.relight.detail import extend_outward, unpremultiply, window

    m = np.zeros((20, 20), np.float32)
    m[5:10, 6:12] = 1
    assert window(m, margin=2) == (3, 12, 4, 14)
    assert window(np.zeros((4, 4)), margin=2) == (0, 4, 0, 4)
    premult = np.full((20, 20, 3), 0.4, np.float32) * m[..., None]
    np.testing.assert_allclose(unpremultiply(premult, m)[m == 1], 0.4)
    assert not unpremultiply(premult, m)[m == 0].any()
    filled = extend_outward(np.full((20, 20, 1), 3.0, np.float32), m == 1)
    np.testing.assert_allclose(filled[4:11, 5:13], 3.0, rtol=1e-5)  # next to the person: its values
    assert filled[19, 0, 0] == 1.0  # far away: neutral


def test_no_mask_without_matting_says_how_to_give_one(models_dir):
    r = Relighter(RuntimeConfig(models=models_dir, device="cpu", matting="off"))
    assert r.matter is None
    with pytest.raises(RelightError, match="no mask given.*--mask FILE in the CLI, mask= in the API"):
        r.decompose(np.zeros((20, 20, 3), np.float32))


def test_highlight_shoulder_keeps_hue_and_gradation_and_the_photo():
    """Colours made brighter than 1 roll off smoothly, all channels scaled together; what is no brighter than the
    photo's own peak (knee >= 0.8) is untouched."""
    from relight_rt.light.exposure import knee
    from relight_rt.relight.look import shoulder

    photo = np.array([[[0.5, 0.3, 0.2], [0.5, 0.3, 0.2], [0.5, 0.3, 0.2], [0.95, 0.6, 0.4]]], np.float32)
    colour = np.array([[[0.6, 0.36, 0.24], [1.2, 0.72, 0.48], [1.6, 0.96, 0.64], [0.95, 0.6, 0.4]]], np.float32)
    out = shoulder(colour.copy(), knee(photo))
    np.testing.assert_array_equal(out[0, 0], colour[0, 0])  # below the knee
    np.testing.assert_array_equal(out[0, 3], colour[0, 3])  # the photo's own bright pixel, unchanged
    assert out.max() < 1 and out[0, 1, 0] < out[0, 2, 0]  # in range, and brighter stays brighter
    for px in (1, 2):  # hue: channel ratios kept
        np.testing.assert_allclose(out[0, px] / out[0, px, 0], colour[0, px] / colour[0, px, 0], rtol=1e-5)


def test_a_light_that_brightens_near_black_cloth_does_not_turn_its_faint_cast_teal():
    """issue 48: a black jacket whose pixels agree on a faint cyan cast (Lab C* ~6 at L* ~8), brightened 2-4x by a
    warm light, went teal (a* < -8) on real photos. It is pulled toward grey at its luminance as far as the gain
    brightens it (fully from 2x), so it takes the light's colour; the luminance is the plain product's (under a
    white gain; near it under a coloured one); a saturated dark cloth, the deep shade of blue jeans and shaded dark
    skin keep their colour, and a darkening gain changes nothing."""
    import cv2

    from relight_rt.relight.look import steady_chroma as _steady_chroma

    rec709 = np.array([0.2126, 0.7152, 0.0722], np.float32)
    jacket = np.broadcast_to(np.array([0.04, 0.10, 0.12], np.float32), (15, 15, 3)).copy()
    warm = np.broadcast_to(np.array([3.7, 2.5, 1.6], np.float32), (15, 15, 3)).copy()  # campfire's gain, measured
    lab = lambda c: cv2.cvtColor(np.clip(c, 0, 1).astype(np.float32), cv2.COLOR_RGB2Lab)[7, 7]  # noqa: E731
    assert lab(jacket * warm)[1] < -8  # the plain product: teal
    out = _steady_chroma(jacket, warm)
    assert lab(out)[1] > -3
    np.testing.assert_allclose(out[7, 7] @ rec709, (jacket * warm)[7, 7] @ rec709, rtol=0.1)  # grey x warm: 5 %
    white3 = np.full((15, 15, 3), 3.0, np.float32)
    grey = _steady_chroma(jacket, white3)[7, 7]
    np.testing.assert_allclose(grey @ rec709, 3 * jacket[7, 7] @ rec709, rtol=1e-4)  # a white gain: the luminance
    assert float(np.ptp(grey)) < 0.5 * float(np.ptp(3 * jacket[7, 7]))  # ... with the cast not tripled
    dim = np.full((15, 15, 3), 0.7, np.float32)
    np.testing.assert_allclose(_steady_chroma(jacket, dim), jacket * dim, rtol=1e-6)
    navy = np.broadcast_to(np.array([0.05, 0.08, 0.35], np.float32), (15, 15, 3)).copy()  # a saturated dark blue
    np.testing.assert_allclose(_steady_chroma(navy, warm), navy * warm, rtol=1e-4)
    # the deep shade of blue jeans (the bundled example's, a* 0) and shaded dark skin (warm) keep their colour
    for shade in ((6, 9, 14), (40, 28, 22)):
        cloth = np.broadcast_to(np.array(shade, np.float32) / 255, (15, 15, 3)).copy()
        np.testing.assert_allclose(_steady_chroma(cloth, white3), cloth * 3, rtol=1e-4)


def test_a_faint_green_cast_on_grey_cloth_counts_by_its_direction():
    """issue 48 (faces10): grey cloth at levels (22, 24, 22) has a* -1.3 only because its chroma is tiny (C* 1.6):
    the a* gate let it through, and a side lamp that brightened it 4-5x made it a* -5 to -10 on real photos. Its cast
    points to green (-a* / C* 0.8), so it is pulled toward grey as the a* gate's casts are; blue jeans' deep shade
    (a* 0, its cast blue) keeps its colour."""
    import cv2

    from relight_rt.relight.look import steady_chroma

    lab = lambda c: cv2.cvtColor(np.clip(c, 0, 1).astype(np.float32), cv2.COLOR_RGB2Lab)[7, 7]  # noqa: E731
    cloth = np.broadcast_to(np.array([22, 24, 22], np.float32) / 255, (15, 15, 3)).copy()
    gain = np.full((15, 15, 3), 4.7, np.float32)
    assert lab(cloth * gain)[1] < -5  # the plain product: the cast amplified
    assert abs(float(lab(steady_chroma(cloth, gain))[1])) < 1
    jeans = np.broadcast_to(np.array([6, 9, 14], np.float32) / 255, (15, 15, 3)).copy()
    np.testing.assert_allclose(steady_chroma(jeans, gain), jeans * gain, rtol=1e-4)


def test_a_strong_gain_does_not_turn_a_dark_pixels_compression_colour_into_a_fringe():
    """Dark pixels beside a lit jaw carry JPEG's colour errors ((0.13, 0.04, 0.0) on the reference photo); brightened
    5x they became a red fringe. Such a pixel is pulled toward its dark neighbours' colour; a dark cloth whose
    pixels agree keeps its colour, as do bright pixels, pixels not brightened, and the new light's own colour."""
    from relight_rt.relight.look import steady_chroma

    rec709 = np.array([0.2126, 0.7152, 0.0722], np.float32)
    hair = np.full((15, 15, 3), 0.06, np.float32)  # dark, neutral
    hair[7, 7] = (0.13, 0.04, 0.0)  # the compression's red
    white5 = np.full((15, 15, 3), 5.0, np.float32)
    out = steady_chroma(hair, white5)
    spread = lambda c: float(c.max() - c.min())  # noqa: E731
    assert spread(out[7, 7]) < 0.5 * spread(hair[7, 7] * 5)  # the fringe damped
    np.testing.assert_allclose(out[7, 7] @ rec709, (hair[7, 7] * 5) @ rec709, rtol=1e-4)  # at the same luminance
    cloth = np.broadcast_to(np.array([0.15, 0.03, 0.02], np.float32), (15, 15, 3)).copy()  # dark red, all agree
    np.testing.assert_allclose(steady_chroma(cloth, white5), cloth * 5, rtol=1e-4)
    skin = np.full((15, 15, 3), (0.8, 0.5, 0.4), np.float32)
    np.testing.assert_allclose(steady_chroma(skin, white5), skin * 5, rtol=1e-6)  # bright: its colour is signal
    dim = np.full((15, 15, 3), 0.8, np.float32)
    np.testing.assert_allclose(steady_chroma(hair, dim), hair * dim, rtol=1e-6)  # not brightened: untouched
    warm = np.broadcast_to(np.array([6.0, 4.0, 2.0], np.float32), (15, 15, 3))  # a warm light on the grey hair
    np.testing.assert_allclose(steady_chroma(hair, warm)[0, 0], hair[0, 0] * warm[0, 0], rtol=1e-4)
