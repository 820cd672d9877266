"""relight_rt.light.from_background: light from one background photo (direction, band 0, bad inputs) and the view
helper."""

import math

import cv2
import numpy as np
import pytest

from relight_rt import RelightError, envmap, sh
from relight_rt.image.color import REC709
from relight_rt.light import from_background as bgmod
from relight_rt.light.from_background import envmap_view, light_from_background, parse_key_light, scene_light

FRONT, BACK = np.array([[1.0, 0, 0]]), np.array([[-1.0, 0, 0]])  # normals facing the camera / away from it


def lum(rgb):
    return float(np.asarray(rgb).reshape(-1, 3)[0] @ np.array([0.2126, 0.7152, 0.0722]))


def test_bright_right_side_gives_light_from_plus_y():
    img = np.full((100, 150, 3), 40, np.uint8)
    img[:, 100:] = 230  # the photo's right third is bright
    light, env = light_from_background(img)
    assert light.shape == (9, 3) and light.dtype == np.float32
    assert env.shape == (64, 128, 3) and env.dtype == np.float32 and env.min() >= 0
    raw = scene_light(img).light(shape_weight=1.0, front_back_power=1.0)  # the rule before step 6
    assert np.all(raw[1] > 0.5 * raw[0])  # strong +y (image right) component
    assert np.all(light[1] > 0.1 * light[0])  # kept, weaker, after the shape is drawn toward the usual one
    flipped, _ = light_from_background(img[:, ::-1].copy())
    np.testing.assert_allclose(flipped[1], -light[1], rtol=1e-4, atol=1e-6)  # unmirrored: flip → −y


def test_bright_top_gives_light_from_above():
    img = np.full((120, 160, 3), 30, np.uint8)
    img[:40] = 220
    light, _ = light_from_background(img)
    assert np.all(light[2] > 0.3 * light[0])


def test_uniform_grey_fills_the_front_with_the_photo_and_the_back_with_the_ambient():
    grey = np.full((80, 120, 3), 128, np.uint8)
    v = ((128 / 255 + 0.055) / 1.055) ** 2.4  # sRGB → linear
    parts = scene_light(grey)
    assert parts.level == pytest.approx(v, rel=1e-5)
    d = envmap.directions_envmap(64)
    front = d[..., 0] < 0
    np.testing.assert_allclose(parts.view_env[front], v, rtol=1e-5)  # what lies behind the person: the photo
    assert np.abs(parts.view_env[~front]).max() == 0 and np.abs(parts.source).max() == 0  # nothing clipped
    # scale: a surface facing away from the camera sees the photo's level (the project's units: uniform v shades v)
    assert lum(sh.irradiance(parts.view, BACK)) == pytest.approx(v, rel=0.1)
    # the half behind the camera: a uniform radiance AMBIENT_GAIN × the median, neutral (saturation 0)
    light, env = light_from_background(grey)
    ambient = bgmod.AMBIENT_GAIN * v
    np.testing.assert_allclose(env[~front & (d[..., 1] < -0.99)], ambient, rtol=0.02)  # away from the key (+y side)
    without_key = parts.light(key_front=0.0, key_back=0.0)
    assert lum(sh.irradiance(without_key, FRONT)) == pytest.approx(ambient, rel=0.1)
    assert lum(sh.irradiance(light, FRONT)) > lum(sh.irradiance(without_key, FRONT))  # plus the key


def test_front_and_back_are_told_apart():
    """The rule before mirrored the photo behind the camera, so every scene was as bright in front of the person
    as behind it. A contrasty view with a bright top (a sun in frame, the near side of things in shadow) is now
    back-lit; a dim, even view (the light behind the camera) is front-lit."""
    backlit = np.full((120, 160, 3), 12, np.uint8)
    backlit[:40] = 200
    backlit[10:20, 70:90] = 255  # the sun
    dim = np.full((120, 160, 3), 70, np.uint8)
    dim[60:] = 90
    for photo, back_lit in ((backlit, True), (dim, False)):
        light, _ = light_from_background(photo)
        front, back = lum(sh.irradiance(light, FRONT)), lum(sh.irradiance(light, BACK))
        assert (back > front) if back_lit else (front > back)
        assert scene_light(photo).key()[1] is back_lit


def _patches(saturation: float) -> np.ndarray:
    """A view of 8 x 6 patches, a bright top row (a white sky) over patches of several levels, each in a random hue
    of the given saturation."""
    rng = np.random.default_rng(3)
    levels = rng.uniform(0.05, 0.3, (6, 8))
    levels[0] = 0.8
    hues = rng.uniform(0, 1, (6, 8, 1))
    tint = 1 + saturation * np.concatenate([np.cos(2 * np.pi * (hues + k / 3)) for k in range(3)], axis=2)
    tint[0] = 1  # the sky white
    rgb = levels[..., None] * tint / (tint @ np.asarray(REC709))[..., None]
    lin = np.clip(np.kron(rgb, np.ones((20, 20, 1))), 0, 0.9)
    return ((np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * lin ** (1 / 2.4) - 0.055)) * 255 + 0.5).astype(np.uint8)


def test_the_colour_share_is_read_but_does_not_make_the_call():
    """The colour share (scene5's front/back statistic) is still read: low where what varies is light (nearly grey
    patches under a bright top), high where it is the surfaces' colour, GREY_SHARE for a black-and-white view. Since
    scene24 step 4's call rests on top/bottom and the luminance spread alone (the colour share's fitted weight did
    not hold across map sets: docs/RESULTS.md), so the two views, alike in luminance, get the same call, and that
    call follows the score on those two statistics."""
    grey, colourful = scene_light(_patches(0.05)), scene_light(_patches(0.8))
    assert colourful.top_bottom == pytest.approx(grey.top_bottom, abs=0.1)
    assert colourful.contrast == pytest.approx(grey.contrast, abs=0.1)
    assert grey.colour_share < 0.2 < 1 < colourful.colour_share
    assert scene_light(_patches(0.0)).colour_share == bgmod.GREY_SHARE
    for parts in (grey, colourful):
        np.testing.assert_allclose(parts.backlight_features(), [1.0, parts.top_bottom, parts.contrast])
        a, b, c = bgmod.BACKLIGHT
        assert parts.key()[1] is (a + b * parts.top_bottom + c * parts.contrast < 0)
    assert grey.key()[1] is colourful.key()[1]


def test_the_colour_share_does_not_change_with_white_balance_or_exposure():
    """A camera's white balance and exposure are gains per channel in linear light: they shift log2 R/G and B/G
    without spreading them, and move log2 luminance little (luminance weighs the channels), so the share stays
    within a few per cent."""
    lin = np.clip(np.kron(np.random.default_rng(4).uniform(0.02, 0.5, (6, 8, 3)), np.ones((20, 20, 1))), 0, 1)
    shares = []
    for gain in ((1.0, 1.0, 1.0), (0.7, 1.0, 1.4), (1.5, 1.2, 0.8), (0.5, 0.5, 0.5)):
        v = np.clip(lin * np.asarray(gain), 0, 0.95)
        photo = ((np.where(v <= 0.0031308, 12.92 * v, 1.055 * v ** (1 / 2.4) - 0.055)) * 255 + 0.5).astype(np.uint8)
        shares.append(scene_light(photo).colour_share)
    assert max(shares) - min(shares) < 0.1 * shares[0]
    assert bgmod.colour_share(np.ones((16, 16, 3), np.float32), np.ones((16, 16), np.float32), 0.0) == 0.0


def test_an_even_view_is_front_lit_whatever_the_score(monkeypatch):
    """No source and no shade in frame (log2 luminance spread < 0.1): nothing says back-lit."""
    monkeypatch.setattr(bgmod, "BACKLIGHT", (-1.0, 0.0, 0.0))
    assert scene_light(np.full((96, 128, 3), 120, np.uint8)).key()[1] is False
    ramp = np.repeat(np.linspace(90, 150, 96).astype(np.uint8)[:, None, None], 128, axis=1).repeat(3, axis=2)
    assert scene_light(ramp).key()[1] is True


def test_the_key_light_can_be_steered():
    img = np.full((90, 120, 3), 80, np.uint8)
    right, _ = light_from_background(img, key_light=(90, 20))
    left, _ = light_from_background(img, key_light="-90, 20")
    np.testing.assert_allclose(left[1], -right[1], rtol=1e-4, atol=1e-6)  # mirror images
    assert np.all(right[1] > 0)
    front, _ = light_from_background(img, key_light=(0, 30))
    behind, _ = light_from_background(img, key_light=(180, 30))
    assert lum(sh.irradiance(front, FRONT)) > lum(sh.irradiance(behind, FRONT))
    assert lum(sh.irradiance(behind, BACK)) > lum(sh.irradiance(front, BACK))
    assert bgmod.key_direction(90, 0) == pytest.approx([0, 1, 0], abs=1e-12)  # from the image's right: +y


@pytest.mark.parametrize("value", ["45", "a,b", "0,91", "nan,10", (1, 2, 3)])
def test_bad_key_lights(value):
    with pytest.raises(RelightError, match="key light"):
        parse_key_light(value)


def test_clipped_highlights_are_boosted():
    img = np.full((100, 100, 3), 100, np.uint8)
    img[10:30, 40:60] = 255
    boosted, _ = light_from_background(img)
    img[10:30, 40:60] = 249  # just below the clip level: counted as is
    plain, _ = light_from_background(img)
    extra = boosted - plain  # the boost alone: brighter, and from above
    assert np.all(extra[0] > 0) and np.all(extra[2] > 0.5 * extra[0])


def test_grayscale_and_16_bit_backgrounds_are_colour(tmp_path):
    """issue 34: black-and-white and 16-bit photos were refused as backgrounds."""
    rng = np.random.default_rng(0)
    gray = rng.integers(0, 256, (90, 120), dtype=np.uint8)
    colour, _ = light_from_background(np.repeat(gray[..., None], 3, axis=2))
    for src in (gray, gray[..., None]):
        np.testing.assert_allclose(light_from_background(src)[0], colour, rtol=1e-6, atol=1e-7)
    cv2.imwrite(str(tmp_path / "g.png"), gray)
    np.testing.assert_allclose(light_from_background(tmp_path / "g.png")[0], colour, rtol=1e-6, atol=1e-7)
    cv2.imwrite(str(tmp_path / "g16.png"), gray.astype(np.uint16) * 257)
    np.testing.assert_allclose(light_from_background(tmp_path / "g16.png")[0], colour, rtol=1e-4, atol=1e-6)


def test_float_and_file_inputs_agree(tmp_path):
    rng = np.random.default_rng(0)
    img = rng.integers(0, 256, (90, 120, 3), dtype=np.uint8)
    cv2.imwrite(str(tmp_path / "bg.png"), img[..., ::-1])
    a, _ = light_from_background(img)
    b, _ = light_from_background(tmp_path / "bg.png")
    c, _ = light_from_background(img.astype(np.float32) / 255)
    np.testing.assert_allclose(a, b)
    np.testing.assert_allclose(a, c, rtol=1e-4, atol=1e-6)


@pytest.mark.parametrize(
    "image, fov, match",
    [
        (np.zeros((63, 200, 3), np.uint8), 60, "at least 64"),
        (np.zeros((100, 100, 2), np.uint8), 60, r"\(H, W, 3\)"),
        (np.zeros((100, 100, 4), np.uint8), 60, "RGBA"),
        (np.zeros((100, 100, 3), np.uint8), 10, "field of view"),
        (np.zeros((100, 100, 3), np.uint8), 170, "field of view"),
        (np.zeros((100, 100, 3), np.uint8), "wide", "field of view"),
        (np.full((100, 100, 3), 2.0, np.float32), 60, r"\[0, 1\]"),
        ("missing.png", 60, "cannot read|cannot decode"),
    ],
)
def test_bad_inputs(image, fov, match):
    with pytest.raises(RelightError, match=match):
        light_from_background(image, fov)


def test_view_of_a_map_and_back():
    """A view of a map with one bright patch straight ahead-right: envmap_view puts it right of centre and the
    light estimated from the view comes from there (+y, −x side mirrored, so only y and z signs are checked)."""
    h = 64
    d = envmap.directions_envmap(h)
    target = np.array([-math.cos(0.3), math.sin(0.3), 0.1])
    patch = (d @ (target / np.linalg.norm(target)) > 0.97)[..., None]
    env = np.repeat(np.where(patch, 5.0, 0.2), 3, axis=2).astype(np.float32)
    view = envmap_view(env, (96, 128), 60.0)
    cols = np.flatnonzero(view.max(axis=(0, 2)) > 1)
    assert cols.min() > 64  # right half of the view
    photo = (np.clip(view / 5.0, 0, 1) ** (1 / 2.2) * 255).astype(np.uint8)
    light, _ = light_from_background(photo)
    assert np.all(light[1] > 0) and np.all(light[2] > 0)
    with pytest.raises(RelightError, match="equirectangular"):
        envmap_view(np.zeros((4, 4, 3)), (8, 8))


def test_step_6_keeps_the_front_exposure_and_colour_and_the_front_back_call():
    """The shape is drawn toward the usual light's (module docstring, step 6); what the person's camera-facing
    side gets (exposure, colour) and which side is brighter stay the rule's; a key the user gives skips it."""
    rng = np.random.default_rng(5)
    img = np.repeat(np.clip(rng.normal(90, 25, (96, 128, 1)), 0, 255).astype(np.uint8), 3, axis=2)  # grey shade
    img[:30] = (240, 200, 150)  # a warm, bright top: back-lit
    parts = scene_light(img)
    light, raw = parts.light(), parts.light(shape_weight=1.0, front_back_power=1.0)
    np.testing.assert_allclose(bgmod.FRONT_WEIGHTS @ light, bgmod.FRONT_WEIGHTS @ raw, rtol=1e-6)
    ratio = lambda lt: float(bgmod.BACK_WEIGHTS @ lt @ REC709) / float(bgmod.FRONT_WEIGHTS @ lt @ REC709)  # noqa: E731
    assert ratio(raw) > 1  # back-lit
    assert ratio(light) == pytest.approx(ratio(raw) ** bgmod.FRONT_BACK_POWER, rel=1e-6)
    assert not np.allclose(light, raw)
    # all the weight on the prior: the luminance shape is the prior's but for its x (front/back) coefficient
    prior_only = parts.light(shape_weight=0.0) @ REC709
    prior = np.asarray(bgmod.SHAPE_PRIOR)
    keep = [0, 1, 2, 4, 5, 6, 7, 8]
    np.testing.assert_allclose(prior_only[keep] / prior_only[0], prior[keep] / prior[0], rtol=1e-6, atol=1e-9)
    # a key the user gives is added whole: two given keys differ by exactly their lobes
    raw_k = lambda k: parts.light(k, shape_weight=1.0, front_back_power=1.0)  # noqa: E731
    np.testing.assert_allclose(parts.light((30, 40)) - parts.light((-60, 10)), raw_k((30, 40)) - raw_k((-60, 10)),
                               atol=1e-9)  # fmt: skip
    assert not np.allclose(parts.light((30, 40)), raw_k((30, 40)))  # the rest is shaped
    black, _ = light_from_background(np.zeros((80, 80, 3), np.uint8))
    assert np.isfinite(black).all() and np.abs(black).max() < 1e-6


def test_step_6_puts_the_front_back_ratio_on_the_side_of_the_call(monkeypatch):
    """The raw light (the view, the ambient, the key) can be brighter in front while step 4 calls the view back-lit
    (a weak back key, a bright view lighting the front): step 6 then gives the light the same back/front ratio the
    other way round, so the light says what the rule read; the front's exposure and colour stay the raw light's."""
    img = np.repeat(np.linspace(90, 150, 96).astype(np.uint8)[:, None, None], 128, axis=1).repeat(3, axis=2)
    parts = scene_light(img)  # not even (an even view is front-lit whatever the score)
    monkeypatch.setattr(bgmod, "BACKLIGHT", (-1.0, 0.0, 0.0))  # every view read as back-lit ...
    monkeypatch.setattr(bgmod, "KEY_BACK", 0.0)  # ... with no back key: the raw light is brighter in front
    ratio = lambda lt: float(bgmod.BACK_WEIGHTS @ lt @ REC709) / float(bgmod.FRONT_WEIGHTS @ lt @ REC709)  # noqa: E731
    raw, light = parts.light(shape_weight=1.0, front_back_power=1.0), parts.light()
    assert ratio(raw) < 1
    assert ratio(light) == pytest.approx(ratio(raw) ** -bgmod.FRONT_BACK_POWER, rel=1e-6)
    np.testing.assert_allclose(bgmod.FRONT_WEIGHTS @ light, bgmod.FRONT_WEIGHTS @ raw, rtol=1e-6)
    monkeypatch.setattr(bgmod, "BACKLIGHT", (1.0, 0.0, 0.0))  # read as front-lit: the raw light's side, damped
    raw, light = parts.light(shape_weight=1.0, front_back_power=1.0), parts.light()
    assert ratio(light) == pytest.approx(ratio(raw) ** bgmod.FRONT_BACK_POWER, rel=1e-6) and ratio(light) < 1


def test_the_ambient_colour_is_the_places_not_a_lamps():
    """The colour of the light behind the camera comes from the photo's ordinary surfaces (the median), so a
    small saturated lamp or sign in frame does not tint it (the mean colour did)."""
    img = np.full((100, 100, 3), 120, np.uint8)
    img[:12, :40] = (255, 40, 0)  # a red sign, 5 % of the photo
    colour = scene_light(img).ambient_colour(saturation=1.0)
    np.testing.assert_allclose(colour, 1.0, rtol=1e-4)


def test_the_brightest_part_and_the_back_key_from_it():
    """A sun up and to the right in frame: ``bright`` points at it (the photo's geometry), and the "source" back key
    comes from that side and behind the person (azimuth beyond 90° on the +y side), at the sun's elevation."""
    img = np.full((90, 160, 3), 40, np.uint8)
    img[:30] = 120  # a brighter sky: the default score reads a back-lit view
    img[10:16, 120:128] = 255  # the sun: columns 120-128 of 160, rows 10-16 of 90
    parts = scene_light(img, 60.0)
    tan_h = math.tan(math.radians(30))
    psi = math.degrees(math.atan((124 / 160 * 2 - 1) * tan_h))
    el = math.degrees(math.atan2((1 - 13 / 90 * 2) * tan_h * 90 / 160, math.hypot(1, math.tan(math.radians(psi)))))
    assert parts.bright[0] == pytest.approx(psi, abs=1.5) and parts.bright[1] == pytest.approx(el, abs=1.5)
    (az, elev), back = parts.key(backlight=(-1.0, 0.0, 0.0), back_key="source")
    assert back and az == pytest.approx(180 - psi, abs=1.5) and elev == pytest.approx(el, abs=1.5)
    mirrored = scene_light(img[:, ::-1], 60.0)
    (az_m, _), _ = mirrored.key(backlight=(-1.0, 0.0, 0.0), back_key="source")
    assert az_m == pytest.approx(-az, abs=1.5)  # the sun on the left: the key from the left
