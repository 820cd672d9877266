"""relight_rt.exposure and its wiring into Relighter.relight / relight_many / iter_relight and `relight --exposure`."""

import numpy as np
import pytest
from _graphs import OWN_LIGHT, diffuse_models_dir, models_dir, person

from relight_rt import Relighter, RelightError, RuntimeConfig, lights
from relight_rt.exposure import REC709, exposure_scale, mean_luminance, parse_exposure

__all__ = ["diffuse_models_dir", "models_dir"]  # fixtures


@pytest.fixture(scope="module")
def diffuse(diffuse_models_dir):
    return Relighter(RuntimeConfig(models=diffuse_models_dir, device="cpu", detail=False))


def lum_inside(img, mask):
    return float((img[mask > 0.5] @ REC709).mean())


@pytest.mark.parametrize(
    "value, want", [("auto", "auto"), ("PHYSICAL", "physical"), ("+1", 1.0), ("-0.5", -0.5), (2, 2.0), (0.25, 0.25)]
)
def test_parse_exposure(value, want):
    assert parse_exposure(value) == want


@pytest.mark.parametrize("value", ["bright", "", "nan", "inf", 21, -40.0, True, None, [1]])
def test_parse_exposure_rejects(value):
    with pytest.raises(RelightError, match="exposure"):
        parse_exposure(value)


def test_scale_is_exact_and_homogeneous():
    rng = np.random.default_rng(0)
    albedo = rng.random((16, 16, 3)).astype(np.float32)
    transport = rng.normal(size=(16, 16, 9)).astype(np.float32)
    mask = (rng.random((16, 16)) > 0.3).astype(np.float32)
    light = lights.preset("studio")
    s = exposure_scale(albedo, transport, mask, light, 0.3, "auto")
    assert mean_luminance(albedo, transport, mask, s * light) == pytest.approx(0.3, rel=1e-5)
    assert exposure_scale(albedo, transport, mask, light, 0.3, 1.0) == pytest.approx(2 * s, rel=1e-6)
    assert exposure_scale(albedo, transport, mask, light, 0.3, "physical") == 1.0
    assert exposure_scale(albedo, transport, mask, 0 * light, 0.3, "auto") == 1.0  # nothing to scale
    with pytest.raises(RelightError, match="target"):
        exposure_scale(albedo, transport, mask, light, -1.0)


def test_auto_keeps_the_mean_luminance(diffuse):
    """Diffuse-only, no detail transfer: the result inside the mask is the network's diffuse image, so its mean
    luminance is the input's under any light (as long as nothing clips); EV +1 doubles it; physical does not."""
    img, mask = person(seed=3)
    img = 0.5 * img  # headroom: nothing clips at EV +1
    dec = diffuse.decompose(img, mask)
    before = lum_inside(img, mask)
    for light in (0.3 * OWN_LIGHT, 2.0 * OWN_LIGHT, lights.preset("front")):
        out = diffuse.relight(dec, light)
        assert lum_inside(out, mask) == pytest.approx(before, rel=0.02)
        brighter = diffuse.relight(dec, light, exposure=1.0)
        assert lum_inside(brighter, mask) == pytest.approx(2 * before, rel=0.02)
    phys = diffuse.relight(dec, 0.3 * OWN_LIGHT, exposure="physical")
    assert lum_inside(phys, mask) == pytest.approx(0.3 * before, rel=0.02)


def test_relight_many_and_iter_relight_expose_each_light(diffuse):
    img, mask = person(seed=4)
    dec = diffuse.decompose(0.5 * img, mask)
    lits = np.stack([0.2 * OWN_LIGHT, 1.5 * OWN_LIGHT])
    many = diffuse.relight_many(dec, lits)
    np.testing.assert_allclose(many[0], many[1], atol=1e-5)  # same direction and colour: same picture
    np.testing.assert_allclose(many[0], diffuse.relight(dec, lits[0]), atol=1e-6)
    phys = list(diffuse.iter_relight(dec, lits, exposure="physical"))
    assert lum_inside(phys[1], mask) > 5 * lum_inside(phys[0], mask)
    with pytest.raises(RelightError, match="exposure"):
        diffuse.relight(dec, lits[0], exposure="loud")


def test_cli_relight_exposure(tmp_path, models_dir, monkeypatch, capsys):
    import cv2

    from relight_rt import cli

    monkeypatch.setenv("RELIGHT_RT_MODELS", str(models_dir))
    monkeypatch.chdir(tmp_path)
    img, mask = person(seed=5)
    cv2.imwrite("p.png", (img[..., ::-1] * 127).round().astype(np.uint8))
    cv2.imwrite("p_mask.png", (mask * 255).astype(np.uint8))
    np.save("half.npy", 0.5 * OWN_LIGHT.astype(np.float64))
    outs = {}
    for exp in ("auto", "physical", "+1"):
        assert cli.main(["relight", "p.png", "--light", "half.npy", "--exposure", exp, "-o", f"{exp}.png"]) == 0
        outs[exp] = cv2.imread(f"{exp}.png").astype(float)[mask > 0.5].mean()
    src = cv2.imread("p.png").astype(float)[mask > 0.5].mean()
    assert abs(outs["auto"] - src) < 0.05 * src
    assert outs["physical"] < 0.7 * src and outs["+1"] > 1.6 * src
    assert cli.main(["relight", "p.png", "--light", "half.npy", "--exposure", "bright", "-o", "x.png"]) == 2
    assert "relight-rt: error: exposure" in capsys.readouterr().err


def test_video_engine_takes_the_same_exposure(diffuse):
    from relight_rt import video

    img, mask = person(seed=6)
    img = 0.5 * img
    engine = video.RelighterEngine(diffuse, exposure="physical")
    layers = engine.decompose([img], [mask])[0]
    dim = engine.render(layers, layers.albedo, layers.transport, None, 0.3 * OWN_LIGHT, "original")
    auto = video.RelighterEngine(diffuse).render(layers, layers.albedo, layers.transport, None, 0.3 * OWN_LIGHT,
                                                 "original")  # fmt: skip
    assert lum_inside(dim, mask) == pytest.approx(0.3 * lum_inside(auto, mask), rel=0.03)
    with pytest.raises(RelightError, match="exposure"):
        video.RelighterEngine(diffuse, exposure="bright")


def test_parse_exposure_refuses_a_huge_integer():
    """A JSON request can carry an integer of 400 digits: float() overflows; one RelightError, not a crash."""
    with pytest.raises(RelightError, match="exposure: expected an EV offset"):
        parse_exposure(7 * 10**400)
    with pytest.raises(RelightError, match="exposure: expected an EV offset"):
        parse_exposure(10**5000)  # more digits than int → str allows
