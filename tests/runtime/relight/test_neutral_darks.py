"""relight.look ``neutral_darks`` / ``keep_neutral``: a near-neutral dark of the photo brightened by a white light
keeps the photo's chroma; a real colour and a coloured light's tint are left alone."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from _graphs import OWN_LIGHT, diffuse_models_dir

import relight_rt
from relight_rt.engine.config import RuntimeConfig
from relight_rt.image.color import REC709
from relight_rt.relight.look import keep_neutral, neutral_darks

__all__ = ["diffuse_models_dir"]  # fixture


def patch(rgb, size: int = 24, width: int | None = None) -> np.ndarray:
    """(size, width or size, 3) of one colour."""
    return np.broadcast_to(np.asarray(rgb, np.float32), (size, width or size, 3)).copy()


def lab(rgb: np.ndarray) -> np.ndarray:
    """Mean CIE Lab (L*, a*, b*) of an image's centre."""
    h, w = rgb.shape[:2]
    return cv2.cvtColor(np.clip(rgb, 0, 1).astype(np.float32), cv2.COLOR_RGB2Lab)[h // 4 : -h // 4, w // 4 : -w // 4] \
        .reshape(-1, 3).mean(0)


def chroma(rgb: np.ndarray) -> float:
    _, a, b = lab(rgb)
    return float(np.hypot(a, b))


def gain_of(colour, brightness: float, size: int = 24) -> np.ndarray:
    """A gain of the colour ``colour`` (made luminance 1) that brightens by ``brightness``."""
    c = np.asarray(colour, np.float32)
    return patch(brightness * c / float(c @ REC709), size)


# dark hair photographed under a bluish shade light: L* ~14, C* ~5, the tint a faint blue
BLUE_GREY = (0.075, 0.085, 0.11)


def test_a_near_grey_dark_brightened_by_a_white_light_keeps_the_photos_chroma():
    image = patch(BLUE_GREY)
    before = chroma(image)
    assert before < 6
    gain = gain_of((1, 1, 1), 4.0)
    plain = image * gain
    assert chroma(plain) > before + 6  # the fault: the faint cast grows with the lightness (blue-grey hair)
    out = keep_neutral(plain, gain, neutral_darks(image))
    assert lab(out)[0] == pytest.approx(lab(plain)[0], abs=1.0)  # the brightness is the light's
    assert chroma(out) < before + 1.5
    # the photo's hue direction stays
    _, a0, b0 = lab(image)
    _, a1, b1 = lab(out)
    turn = np.degrees(abs(np.angle(np.exp(1j * (np.arctan2(b1, a1) - np.arctan2(b0, a0))))))
    assert turn < 10


def test_a_real_colour_is_left_alone():
    teal = patch((0.02, 0.22, 0.22))  # a teal shirt: C* ~ 25 at L* ~ 25
    gain = gain_of((1, 1, 1), 3.0)
    assert neutral_darks(teal) is None
    np.testing.assert_array_equal(keep_neutral(teal * gain, gain, neutral_darks(teal)), teal * gain)


def test_bright_or_dimmed_pixels_and_the_photos_own_light_are_untouched():
    grey = patch(BLUE_GREY)
    dark = neutral_darks(grey)
    for k in (0.5, 1.0, 1.05):  # dimmed, the photo's own light, barely brighter
        gain = gain_of((1, 1, 1), k)
        np.testing.assert_allclose(keep_neutral(grey * gain, gain, dark), grey * gain, rtol=1e-6)
    light = patch((0.6, 0.62, 0.7))  # a pale, light grey: not dark (L* > 45)
    assert neutral_darks(light) is None


def test_a_coloured_light_still_tints_as_its_colour_says():
    image = patch(BLUE_GREY)
    dark = neutral_darks(image)
    warm = (1.0, 0.55, 0.2)  # campfire-like
    gain_w, gain_c = gain_of((1, 1, 1), 4.0), gain_of(warm, 4.0)
    white = keep_neutral(image * gain_w, gain_w, dark)
    coloured = keep_neutral(image * gain_c, gain_c, dark)
    # what the light's colour alone does to the white light's answer
    tint = gain_c / (gain_c @ REC709)[..., None]
    np.testing.assert_allclose(coloured, white * tint, rtol=1e-4, atol=1e-6)
    _, a, b = lab(coloured)
    assert b > 20 and a > 0  # orange, as the light


@pytest.mark.parametrize("colour", [(0.0, 1.0, 1.0), (1.0, 0.0, 0.0), (1.0, 1.0, 0.0)])
def test_a_light_without_one_channel_is_left_to_give_its_own_colour(colour):
    """A pure cyan (red, yellow) lamp gives a dark none of one channel: the rule leaves the pixel as the light gives
    it (before, the missing channel's tint fell back to 1 and a cyan-lit grey dark got a red of 0.2)."""
    image = patch(BLUE_GREY)
    gain = patch(8 * np.asarray(colour, np.float32))
    plain = image * gain
    np.testing.assert_array_equal(keep_neutral(plain, gain, neutral_darks(image)), plain)


def test_a_partly_dark_image_changes_only_its_near_neutral_darks():
    image = np.concatenate([patch(BLUE_GREY), patch((0.02, 0.22, 0.22)), patch((0.7, 0.5, 0.4))], axis=1)
    gain = np.concatenate([gain_of((1, 1, 1), 3.0, 24)] * 3, axis=1)
    out = keep_neutral(image * gain, gain, neutral_darks(image))
    # the teal and the skin beyond the weight's smoothing (a reduced pixel's sigma: up to ~12 px past the grey)
    np.testing.assert_array_equal(out[:, 40:], (image * gain)[:, 40:])
    assert chroma(out[:, :24]) < chroma(image[:, :24]) + 1.5
    assert keep_neutral(image, gain, None) is image  # nothing near-neutral: the colour as it came


def test_shaded_dark_skin_and_a_dark_colours_shaded_folds_keep_their_colour():
    """Warm darks (shaded dark skin, brown hair) read as their material when brightened, and a dark fold of a
    coloured cloth is that cloth (its hue reaches a real colour nearby): neither is made more neutral."""
    skin = patch((0.16, 0.10, 0.07))  # shaded dark skin: L* ~13, C* ~9, hue ~45 degrees
    _, a, b = lab(skin)
    assert np.hypot(a, b) < 12 and a > 0 and b > 0
    gain = gain_of((1, 1, 1), 3.0)
    assert neutral_darks(skin) is None
    # blue jeans: a deep fold (C* ~3, 8 px wide) between the lit front's strips (C* ~32)
    lit, fold = patch((0.05, 0.08, 0.25), 16, 48), patch((0.03, 0.035, 0.06), 16, 8)
    jeans = np.concatenate([lit, fold, lit], axis=1)
    _, a, b = lab(fold)
    assert np.hypot(a, b) < 8
    gain = np.broadcast_to(gain_of((1, 1, 1), 3.0, 1)[0, 0], jeans.shape).copy()
    np.testing.assert_allclose(keep_neutral(jeans * gain, gain, neutral_darks(jeans)), jeans * gain, rtol=1e-6)
    # the same fold with no blue beside it is a near-neutral dark: it keeps its own chroma
    grey = patch((0.3, 0.3, 0.3), 16, 48)
    alone = np.concatenate([grey, fold, grey], axis=1)
    assert not np.allclose(keep_neutral(alone * gain, gain, neutral_darks(alone)), alone * gain, rtol=1e-3)


def test_through_the_relighter_a_near_grey_stays_grey_a_teal_shirt_teal_and_the_own_light_gives_the_photo_back(
        diffuse_models_dir):
    """End to end on the analytic graphs (tests/_graphs.py: the photo's own light gives shading 1, a light k times as
    bright k x the photo): a person half near-grey dark under a bluish photo light, half a dark teal shirt."""
    r = relight_rt.open(RuntimeConfig(models=diffuse_models_dir, device="cpu"))
    image = np.zeros((120, 96, 3), np.float32)
    image[:, :48], image[:, 48:] = BLUE_GREY, (0.02, 0.22, 0.22)
    mask = np.zeros((120, 96), np.float32)
    mask[8:112, 8:88] = 1
    dec = r.decompose(image, mask)
    grey, teal = (slice(30, 90), slice(16, 36)), (slice(30, 90), slice(62, 80))
    # the photo's own light: the photo back, every pixel
    np.testing.assert_allclose(r.relight(dec, OWN_LIGHT, exposure="physical"), image, atol=1e-5)
    # a white light 3x as bright: the grey as grey as the photo (3x the photo would be visibly blue), teal 3x
    out = r.relight(dec, 3 * OWN_LIGHT, exposure="physical")
    assert chroma(3 * image[grey]) > chroma(image[grey]) + 6
    assert chroma(out[grey]) < chroma(image[grey]) + 1.5
    assert lab(out[grey])[0] == pytest.approx(lab(3 * image[grey])[0], abs=1.0)
    np.testing.assert_allclose(out[teal], 3 * image[teal], atol=1e-5)
    # a campfire-coloured light as bright: grey hair turns orange, as the light says
    warm = np.asarray((1.0, 0.55, 0.2), np.float32)
    _, a, b = lab(r.relight(dec, 3 * OWN_LIGHT * (warm / float(warm @ REC709)), exposure="physical")[grey])
    assert b > 20 and a > 0


def test_a_window_of_the_photo_reads_the_photos_reduction_grid():
    """A group's person (a window of the photo at ``origin``, of any size) finds the weights the photo finds there:
    the reduction averages the photo's own blocks of ``_NEUTRAL_STEP`` pixels, whatever the window's size (an
    INTER_AREA resize to a size that is not a whole number of blocks spreads them, and moved the weight by up to 0.6
    on real photos). Compared away from the window's edges, which see less of the neighbourhood."""
    rng = np.random.default_rng(3)
    tiles = rng.choice(np.asarray([BLUE_GREY, (0.02, 0.22, 0.22), (0.05, 0.05, 0.07), (0.2, 0.2, 0.22),
                                   (0.16, 0.10, 0.07)], np.float32), size=(9, 13))
    image = cv2.resize(tiles, (13 * 23, 9 * 23), interpolation=cv2.INTER_LINEAR)  # 207 x 299: no whole blocks
    image = np.clip(image + rng.normal(0, 0.004, image.shape).astype(np.float32), 0, 1)

    def weights(img, origin=(0, 0)):
        found = neutral_darks(img, origin)
        out = np.zeros(img.shape[0] * img.shape[1], np.float32)
        out[found.index[0] // 3] = found.weight
        return out.reshape(img.shape[:2])

    whole = weights(image)
    assert (whole > 0.9).mean() > 0.1 and (whole < 0.1).mean() > 0.1
    m = 90  # past the hue's blur, the material's reach and the weight's smoothing, in photo pixels
    for y0, x0, y1, x1 in ((5, 9, 205, 296), (6, 3, 203, 298), (1, 2, 207, 299)):
        part = weights(image[y0:y1, x0:x1], (y0, x0))
        np.testing.assert_allclose(part[m - y0 : y1 - y0 - m, m - x0 : x1 - x0 - m], whole[m:y1 - m, m:x1 - m],
                                   atol=1e-5)


def test_a_backdrop_of_the_darks_hue_does_not_vouch_for_it_as_the_persons_material():
    """A dark grey with a faint teal cast beside a teal backdrop is a cast (kept near-neutral): the material a dark
    belongs to is the person's; beside the person's own teal cloth the same grey is that cloth's shade (left alone)."""
    grey, teal = patch((0.06, 0.085, 0.085), 32, 16), patch((0.0, 0.35, 0.33), 32, 24)  # C* ~25
    _, a, b = lab(grey)
    assert np.hypot(a, b) < 6 and a < 0  # a faint teal cast
    image = np.concatenate([teal, grey], axis=1)
    gain = np.broadcast_to(gain_of((1, 1, 1), 3.0, 1)[0, 0], image.shape).copy()
    plain = image * gain
    person = np.ones(image.shape[:2], bool)
    person[:, :24] = False  # the teal is the backdrop: not the person's
    kept = keep_neutral(plain, gain, neutral_darks(image, solid=person))
    assert chroma(kept[:, 24:]) < chroma(image[:, 24:]) + 1.5
    assert chroma(plain[:, 24:]) > chroma(image[:, 24:]) + 3  # what it would be left as
    # the teal is the person's own cloth: the grey beside it is its shade
    cloth = keep_neutral(plain, gain, neutral_darks(image, solid=np.ones(image.shape[:2], bool)))
    np.testing.assert_allclose(cloth, plain, rtol=1e-6)


def test_a_near_black_takes_the_hue_of_the_dark_around_it_not_of_the_skin_beside_it():
    """Near-black hair with a faint blue cast beside warm skin: its hue is the hair's (blue, a cast kept
    near-neutral), not the skin's (warm, which would read it as brown hair and leave it)."""
    hair = patch((0.022, 0.025, 0.034), 32, 32)  # L* ~ 9, C* ~ 3: its own hue is noise-level, blue
    skin = patch((0.7, 0.5, 0.4), 32, 16)
    _, a, b = lab(hair)
    assert np.hypot(a, b) < 4 and b < 0
    image = np.concatenate([skin, hair], axis=1)
    gain = np.broadcast_to(gain_of((1, 1, 1), 4.0, 1)[0, 0], image.shape).copy()
    plain = image * gain
    kept = keep_neutral(plain, gain, neutral_darks(image))
    assert chroma(plain[:, 16:]) > chroma(image[:, 16:]) + 2
    assert chroma(kept[:, 16:]) < chroma(plain[:, 16:]) - 1.5


def test_a_warm_pixel_within_a_near_neutral_dark_block_keeps_its_colour():
    """A warm strand of colour (skin at the edge of dark hair: C* past 12) inside a reduced pixel that reads as a
    near-neutral dark is its own material: left as relit, while the hair around it is kept near-neutral."""
    image = patch(BLUE_GREY, 32, 32)
    image[:, 15:16] = (0.22, 0.12, 0.07)  # a 1-px warm line: L* ~17, C* ~17, hue ~50 degrees
    _, a, b = cv2.cvtColor(image[:1, 15:16], cv2.COLOR_RGB2Lab)[0, 0]
    assert np.hypot(a, b) > 12 and a > 0 and b > 0
    gain = gain_of((1, 1, 1), 3.0, 32)
    plain = image * gain
    out = keep_neutral(plain, gain, neutral_darks(image))
    np.testing.assert_allclose(out[:, 15], plain[:, 15], rtol=1e-6)
    assert chroma(out[:, 20:]) < chroma(plain[:, 20:]) - 1.5


def test_a_near_neutral_dark_on_the_persons_outline_keeps_its_chroma_whatever_its_block_reads():
    """A near-black cloth with a faint teal cast against a green backdrop, its outline inside a reduced block: the
    block reads the cloth mixed with the leaves (coloured: not near-neutral), but the outline's pixels are held by
    their own colour as the cloth inside is (teal42: the outline's teal, p104, p224); a block farther in, read as
    before, is left as it was."""
    cloth, leaves = patch((0.07, 0.13, 0.13), 32, 18), patch((0.15, 0.45, 0.1), 32, 22)  # L* 11, C* 6.8; x = 22
    image = np.concatenate([leaves, cloth], axis=1)
    person = np.zeros(image.shape[:2], bool)
    person[:, 22:] = True
    gain = np.broadcast_to(gain_of((1, 1, 1), 4.0, 1)[0, 0], image.shape).copy()
    plain = image * gain
    kept = keep_neutral(plain, gain, neutral_darks(image, solid=person))
    edge = slice(22, 26)  # the outline's 4 px: in the block 20-23 with the backdrop, and the block beside it
    assert chroma(plain[:, edge]) > chroma(image[:, edge]) + 3  # what it would be left as
    assert chroma(kept[:, edge]) == pytest.approx(chroma(kept[:, 36:40]), abs=0.1)  # as the cloth inside
    assert chroma(kept[:, edge]) < chroma(plain[:, edge]) - 3
    np.testing.assert_allclose(kept[:, :22], plain[:, :22])  # the backdrop is not the person's: untouched
    # a near-black outline whose hue is noise (C* ~1.8) is left to its block's reading (its material's)
    # ... and so is a black one whose C* is JPEG's at the linear toe (half A's p186: (0, 13, 7), L* 2.8, C* 4.7)
    for dark in ((0.05, 0.07, 0.07), (0.0, 13 / 255, 7 / 255)):
        black = np.concatenate([leaves, patch(dark, 32, 18)], axis=1)
        held = neutral_darks(black, solid=person)
        weight = np.zeros(black.shape[0] * black.shape[1], np.float32)
        if held is not None:
            weight[held.index[0] // 3] = held.weight
        assert weight.reshape(black.shape[:2])[:, 22].max() < 0.5  # the mixed block's reading (0.35), not held
    # without a matte (solid None) there is no outline: the block's reading alone, as before
    alone = keep_neutral(plain, gain, neutral_darks(image))
    assert chroma(alone[:, edge]) > chroma(kept[:, edge]) + 1


def test_a_warm_or_coloured_pixel_on_the_outline_is_left_as_relit():
    """The outline rule takes near-neutral darks only: dark skin (warm) and a dark saturated colour on the outline
    keep the light's colour growth."""
    skin, blue = patch((0.16, 0.09, 0.06), 32, 12), patch((0.02, 0.03, 0.16), 32, 12)  # warm L* ~13; C* ~30
    backdrop = patch((0.8, 0.8, 0.8), 32, 8)
    image = np.concatenate([backdrop, skin, blue, backdrop], axis=1)
    person = np.zeros(image.shape[:2], bool)
    person[:, 8:32] = True
    gain = np.broadcast_to(gain_of((1, 1, 1), 3.0, 1)[0, 0], image.shape).copy()
    plain = image * gain
    np.testing.assert_allclose(keep_neutral(plain, gain, neutral_darks(image, solid=person)), plain, rtol=1e-6)
