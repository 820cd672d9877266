"""relight_rt.scene.composite, Relighter.composite and the CLI commands `composite` and `lights from-background`."""

import cv2
import numpy as np
import pytest
from _graphs import diffuse_models_dir, models_dir, person

from relight_rt import Relighter, RelightError, cli
from relight_rt.color import linear_to_srgb, srgb_to_linear
from relight_rt.scene import composite, parse_position

__all__ = ["diffuse_models_dir", "models_dir"]  # fixtures


@pytest.fixture(scope="module")
def diffuse(diffuse_models_dir):
    return Relighter(diffuse_models_dir, device="cpu", detail=False)


def flat_person(h=150, w=100, colour=(150, 110, 90)):
    img = np.zeros((h, w, 3), np.uint8)
    img[:] = colour
    mask = np.zeros((h, w), np.float32)
    mask[20:140, 30:70] = 1.0
    mask[20:140, 30:35] = 0.5  # a soft band on the left
    return img, mask


def test_output_has_the_background_size(diffuse):
    img, mask = flat_person()
    bg = np.full((120, 260, 3), 90, np.uint8)
    out = composite(diffuse, img, bg, mask=mask)
    assert out.shape == (120, 260, 3) and out.dtype == np.float32 and 0 <= out.min() and out.max() <= 1
    far = out[:, 200:]  # away from the person: the background, unchanged
    np.testing.assert_allclose(far, 90 / 255, atol=1e-5)
    out2 = diffuse.composite(img, bg, mask=mask, position=(0.8, 1.0), height=0.5, shadow=True)
    assert out2.shape == (120, 260, 3)


def test_alpha_blending_is_proportional_in_linear_light(diffuse):
    """Same-size background, default placement: the person lands on its own pixels, scale 1. A uniform grey
    background of linear value g lights the analytic person (albedo = linear photo, camera-facing normals) with
    shading g, so inside the person the linear result is a·P + (1 − a)·g for matte a, with P the relit colour:
    c·g where a = 1, and c·g in the soft band too (issue 33: over a new backdrop the band's colour is the
    decontaminated foreground, c here, times the relighting's gain from the opaque pixels nearby; before, the
    analytic stage 1's masking scaled it by a once more)."""
    img, mask = flat_person()
    bg = np.full((150, 100, 3), 128, np.uint8)
    g = float(srgb_to_linear(np.uint8(128)))
    c = srgb_to_linear(np.array([150, 110, 90], np.uint8))
    out = composite(diffuse, img, bg, mask=mask)
    lin = srgb_to_linear(out)
    for a, sl in ((1.0, np.s_[40:120, 45:65]), (0.5, np.s_[40:120, 31:34])):
        want = a * (c * g) + (1 - a) * g
        np.testing.assert_allclose(lin[sl].reshape(-1, 3).mean(0), want, rtol=0.03)
    np.testing.assert_allclose(out[:10], linear_to_srgb(np.full((10, 100, 3), g, np.float32)), atol=1e-5)
    # EV +1 doubles the person's light; "physical" with the background's light is the same as auto
    brighter = srgb_to_linear(composite(diffuse, img, bg, mask=mask, exposure=1.0))
    np.testing.assert_allclose(brighter[40:120, 45:65].mean((0, 1)), 2 * c * g, rtol=0.03)
    np.testing.assert_allclose(composite(diffuse, img, bg, mask=mask, exposure="physical"), out, atol=1e-6)


def test_shadow_darkens_the_ground_under_the_feet(diffuse):
    img, mask = flat_person()
    bg = np.full((150, 100, 3), 160, np.uint8)
    plain = composite(diffuse, img, bg, mask=mask, position=(0.5, 0.9))
    shaded = composite(diffuse, img, bg, mask=mask, position=(0.5, 0.9), shadow=True)
    below = np.s_[136:140, 30:70]  # just under the feet (the person ends at row 135)
    assert shaded[below].mean() < plain[below].mean() - 0.02
    np.testing.assert_allclose(shaded[:40], plain[:40])  # far above: untouched


def test_a_given_light_is_white_balanced_and_exposed_to_the_background(diffuse):
    img, mask = flat_person(colour=(128, 128, 128))
    warm_bg = np.zeros((150, 100, 3), np.uint8)
    warm_bg[:] = (200, 140, 90)
    out = composite(diffuse, img, warm_bg, mask=mask, light="front")  # a white preset
    own = composite(diffuse, img, warm_bg, mask=mask)
    person_px = np.s_[40:120, 45:65]
    ratio = out[person_px].mean((0, 1)) / own[person_px].mean((0, 1))
    np.testing.assert_allclose(ratio, ratio.mean(), rtol=0.05)  # same colour balance as the background's light
    neutral = composite(diffuse, img, warm_bg, mask=mask, light="front", white_balance=False)[person_px].mean((0, 1))
    assert neutral[0] / neutral[2] < out[person_px].mean((0, 1))[0] / out[person_px].mean((0, 1))[2]


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"position": (1.2, 0.5)}, "position"),
        ({"position": "0.5"}, "position"),
        ({"position": (0.5, -0.1)}, "position"),
        ({"height": 0.0}, "height"),
        ({"height": 1.5}, "height"),
        ({"fov": 175}, "field of view"),
        ({"exposure": "bright"}, "exposure"),
    ],
)
def test_bad_arguments(diffuse, kwargs, match):
    img, mask = flat_person()
    with pytest.raises(RelightError, match=match):
        composite(diffuse, img, np.full((100, 100, 3), 90, np.uint8), mask=mask, **kwargs)


def test_bad_backgrounds_and_too_large_person(diffuse):
    img, mask = flat_person()
    for bg, match in (
        (np.zeros((50, 100, 3), np.uint8), "at least 64"),
        (np.zeros((100, 100), np.uint8), "grayscale"),
        (np.zeros((100, 100, 4), np.uint8), "RGBA"),
    ):
        with pytest.raises(RelightError, match=match):
            composite(diffuse, img, bg, mask=mask)
    wide = np.zeros((150, 100), np.float32)
    wide[60:80, 2:98] = 1  # 96 px wide, 20 high
    with pytest.raises(RelightError, match="larger than the background"):
        composite(diffuse, img, np.full((100, 100, 3), 90, np.uint8), mask=wide, height=0.5)


def test_parse_position():
    assert parse_position("0.25, 1") == (0.25, 1.0)
    with pytest.raises(RelightError, match="position"):
        parse_position("nan,0.5")


# ------------------------------------------------------------------------------------------------ CLI


@pytest.fixture
def work(tmp_path, models_dir, monkeypatch):
    monkeypatch.setenv("RELIGHT_RT_MODELS", str(models_dir))
    monkeypatch.chdir(tmp_path)
    img, mask = person(150, 100, seed=1)
    cv2.imwrite("p.png", (img[..., ::-1] * 255).round().astype(np.uint8))
    cv2.imwrite("p_mask.png", (mask * 255).astype(np.uint8))
    bg = np.zeros((96, 160, 3), np.uint8)
    bg[:] = (60, 90, 140)
    bg[:, 110:] = 240  # bright on the right
    cv2.imwrite("bg.png", bg[..., ::-1])
    return tmp_path


def run(argv, capsys):
    code = cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_cli_composite(work, capsys):
    code, _, err = run(["composite", "p.png", "--background", "bg.png", "-o", "out.png", "--shadow"], capsys)
    assert code == 0, err
    assert cv2.imread("out.png").shape == (96, 160, 3)
    argv = ["composite", "p.png", "--background", "bg.png", "-o", "o2.jpg", "--preset", "studio"]
    code, _, err = run([*argv, "--position", "0.3,0.9", "--height", "0.6", "--exposure", "-1", "--fov", "80"], capsys)
    assert code == 0, err
    assert cv2.imread("o2.jpg").shape == (96, 160, 3)


@pytest.mark.parametrize(
    "extra, match",
    [
        (["--position", "2,0.5"], "position"),
        (["--fov", "5"], "field of view"),
        (["--height", "3"], "height"),
        (["--exposure", "loud"], "exposure"),
        (["--light", "none.npy"], "none.npy"),
    ],
)
def test_cli_composite_errors(work, capsys, extra, match):
    code, _, err = run(["composite", "p.png", "--background", "bg.png", "-o", "out.png", *extra], capsys)
    assert code == 2 and err.startswith("relight-rt: error:") and len(err.strip().splitlines()) == 1, err
    assert __import__("re").search(match, err)
    assert not (work / "out.png").exists()


def test_cli_composite_never_overwrites_an_input(work, capsys):
    before = (work / "bg.png").read_bytes()
    code, _, err = run(["composite", "p.png", "--background", "bg.png", "-o", "bg.png"], capsys)
    assert code == 2 and "bg.png" in err
    assert (work / "bg.png").read_bytes() == before


def test_cli_lights_from_background(work, capsys):
    code, _, err = run(["lights", "from-background", "bg.png", "-o", "l.npy", "--preview", "sheet.png"], capsys)
    assert code == 0, err
    light = np.load("l.npy", allow_pickle=False)
    assert light.shape == (9, 3) and np.all(light[1] > 0)  # bright on the right: light from +y
    sheet = cv2.imread("sheet.png")
    assert sheet.shape[0] == 256 and sheet.shape[1] > 3 * 256
    code, _, err = run(["lights", "from-background", "bg.png", "-o", "l.json", "--fov", "90"], capsys)
    assert code == 0, err
    code, _, err = run(["lights", "from-background", "bg.png", "-o", "l2.npy", "--fov", "180"], capsys)
    assert code == 2 and "field of view" in err and not (work / "l2.npy").exists()
    code, _, err = run(["lights", "from-background", "p_mask.png", "-o", "l3.npy"], capsys)
    assert code == 2 and "grayscale" in err


def test_the_automatic_matte_sees_the_photo_not_its_linear_copy(diffuse_models_dir):
    img, mask = flat_person()
    seen = []

    def matter(rgb, name="image"):
        seen.append(float(rgb.mean()))
        return mask

    r = Relighter(diffuse_models_dir, device="cpu", detail=False)
    r._matter, r._matter_loaded = matter, True  # the automatic matte, replaced by one that records its input
    bg = np.full((120, 260, 3), 90, np.uint8)
    with_matte = r.composite(img, bg)
    assert seen and seen[0] == pytest.approx(img.mean() / 255, abs=1e-6)  # sRGB values, as in every other command
    np.testing.assert_array_equal(with_matte, r.composite(img, bg, mask=mask))  # the same as that mask given
