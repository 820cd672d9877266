"""relight_rt.scene.composite and the CLI commands `composite` and `lights from-background`."""

import cv2
import numpy as np
import pytest
from _cli import in_folder, run
from _graphs import diffuse_models_dir, models_dir, write_person

from relight_rt import Relighter, RelightError, RuntimeConfig, lights
from relight_rt.apps.scene import composite, parse_position
from relight_rt.apps.scene_rim import RIM_PHOTO
from relight_rt.image.color import linear_to_srgb, srgb_to_linear

__all__ = ["diffuse_models_dir", "models_dir"]  # fixtures


@pytest.fixture(scope="module")
def diffuse(diffuse_models_dir):
    return Relighter(RuntimeConfig(models=diffuse_models_dir, device="cpu", detail=False))


def flat_person(h=150, w=100, colour=(150, 110, 90)):
    img = np.zeros((h, w, 3), np.uint8)
    img[:] = colour
    mask = np.zeros((h, w), np.float32)
    mask[20:140, 30:70] = 1.0
    mask[20:140, 30:35] = 0.5  # a soft band on the left
    return img, mask


def strands(mask, side):
    """``mask`` with its box's last 8 columns on ``side`` ("left" or "right") a ramp of alpha from 1 to 1/8 outward:
    a soft, wide edge (hair, fuzz) where the rest of the outline is hard: scene_rim.fibre_share 1 there."""
    out = mask.copy()
    ramp = np.arange(8, 0, -1, dtype=np.float32) / 8
    if side == "right":
        out[20:140, 62:70] = ramp
    else:
        out[20:140, 30:38] = ramp[::-1]
    return out


# the flat person (150 x 100, body rows 20-140, centred) put back on its own pixels of a same-size background
SAME = {"position": (0.5, 140 / 150), "height": 120 / 150, "meter": "background", "shadow": False,
        "match_camera": False, "light_wrap": False}  # fmt: skip


def test_output_has_the_background_size(diffuse):
    img, mask = flat_person()
    bg = np.full((120, 260, 3), 90, np.uint8)
    out = composite(diffuse, img, bg, mask=mask, meter="background")
    assert out.shape == (120, 260, 3) and out.dtype == np.float32 and 0 <= out.min() and out.max() <= 1
    far = out[:, 200:]  # away from the person: the background, unchanged
    np.testing.assert_allclose(far, 90 / 255, atol=1e-5)
    out2 = composite(diffuse, img, bg, mask=mask, position=(0.8, 1.0), height=0.5, shadow=True)
    assert out2.shape == (120, 260, 3)


def test_alpha_blending_is_proportional_in_linear_light(diffuse):
    """Same-size background, default placement: the person lands on its own pixels, scale 1. A uniform grey
    background of linear value g lights the analytic person (albedo = linear photo, camera-facing normals) with
    shading g, so inside the person the linear result is a·P + (1 − a)·g for matte a, with P the relit colour,
    the same in the soft band as where a = 1 (issue 33: over a new backdrop the band's colour is the
    decontaminated foreground times the relighting's gain; before, the analytic stage 1's masking scaled it by
    a once more)."""
    img, mask = flat_person()
    bg = np.full((150, 100, 3), 128, np.uint8)
    g = float(srgb_to_linear(np.uint8(128)))
    out = composite(diffuse, img, bg, mask=mask, **SAME)
    lin = srgb_to_linear(out)
    core = lin[40:120, 45:65].reshape(-1, 3).mean(0)  # a = 1: the relit colour P itself
    band = lin[40:120, 31:34].reshape(-1, 3).mean(0)  # a = 0.5: the same colour, half over the grey
    np.testing.assert_allclose(band, 0.5 * core + 0.5 * g, rtol=0.03)
    np.testing.assert_allclose(out[:10], linear_to_srgb(np.full((10, 100, 3), g, np.float32)), atol=1e-5)
    # EV +1 doubles the person's light; "physical" with the background's light is the same as auto
    brighter = srgb_to_linear(composite(diffuse, img, bg, mask=mask, exposure=1.0, **SAME))
    np.testing.assert_allclose(brighter[40:120, 45:65].mean((0, 1)), 2 * core, rtol=0.03)
    np.testing.assert_allclose(composite(diffuse, img, bg, mask=mask, exposure="physical", **SAME), out, atol=1e-6)


def test_shadow_darkens_the_ground_under_the_feet(diffuse):
    img, mask = flat_person()
    bg = np.full((150, 100, 3), 160, np.uint8)
    kw = {"position": (0.5, 0.9), "meter": "background"}
    plain = composite(diffuse, img, bg, mask=mask, shadow=False, **kw)
    shaded = composite(diffuse, img, bg, mask=mask, **kw)  # shadows are on by default
    below = np.s_[135:138, 42:58]  # at and just under the feet (they stand on row 135, 68 px tall, 23 wide)
    assert shaded[below].mean() < plain[below].mean() - 0.05
    np.testing.assert_allclose(shaded[:40], plain[:40])  # far above: untouched


@pytest.mark.parametrize("azimuth, dark_side", [(90, "left"), (-90, "right")])
def test_the_cast_shadow_falls_away_from_the_key_light(diffuse, azimuth, dark_side):
    """A key from the image's right (azimuth 90) casts the shadow to the left of the feet, and the other way."""
    img, mask = flat_person()
    bg = np.full((150, 300, 3), 170, np.uint8)
    kw = {"position": (0.5, 0.9), "meter": "background", "match_camera": False, "key_light": (azimuth, 30)}
    shaded = composite(diffuse, img, bg, mask=mask, **kw)
    plain = composite(diffuse, img, bg, mask=mask, shadow=False, **kw)
    drop = (plain - shaded).mean(2)
    left, right = drop[110:150, 40:120].sum(), drop[110:150, 180:260].sum()  # beside the feet (x 135-165)
    assert (left > 3 * right) if dark_side == "left" else (right > 3 * left)
    assert max(left, right) > 1.0


def test_perspective_sets_the_height_from_the_feet_and_the_horizon(diffuse):
    """A level camera: a person whose feet are twice as far below the horizon is twice as tall."""
    img, mask = flat_person()
    bg = np.full((200, 200, 3), 90, np.uint8)
    kw = {"meter": "background", "shadow": False, "match_camera": False}

    def height(y, **extra):
        out = composite(diffuse, img, bg, mask=mask, position=(0.5, y), **kw, **extra)
        rows = np.flatnonzero((np.abs(out - 90 / 255).max(2) > 0.02).any(1))
        return rows[-1] + 1 - rows[0]

    assert height(0.9) == pytest.approx(2 * height(0.7), abs=2)
    assert height(0.9, horizon=0.3) == pytest.approx(1.5 * height(0.9), abs=2)
    with pytest.raises(RelightError, match="horizon"):
        composite(diffuse, img, bg, mask=mask, position=(0.5, 0.45))


def test_a_cut_off_person_stands_on_the_bottom_edge(diffuse):
    img, mask = flat_person()
    mask[100:] = mask[99]  # the body runs off the photo's bottom edge: a half body
    bg = np.full((120, 260, 3), 90, np.uint8)
    out = composite(diffuse, img, bg, mask=mask, meter="background")
    changed = np.abs(out - 90 / 255).max(2) > 0.02
    rows = np.flatnonzero(changed.any(1))
    assert rows[-1] == 119  # on the bottom edge
    assert rows[-1] + 1 - rows[0] == pytest.approx(130 / 150 * 120, abs=2)  # its height as in its own photo


def test_the_person_takes_the_backgrounds_noise_and_blur(diffuse):
    img, mask = flat_person()
    rng = np.random.default_rng(0)
    clean = np.full((150, 100, 3), 120, np.uint8)
    noisy = np.clip(120 + rng.normal(0, 8, clean.shape), 0, 255).astype(np.uint8)
    kw = {**SAME, "match_camera": True}
    inner = np.s_[50:110, 42:66]
    flat = composite(diffuse, img, clean, mask=mask, **kw)[inner]
    grainy = composite(diffuse, img, noisy, mask=mask, **kw)[inner]
    # the flat person becomes as grainy as the background
    assert flat.std(axis=(0, 1)).max() < 0.005 and grainy.std(axis=(0, 1)).min() > 0.02
    # a sharp step in a sharp background leaves the person's edge sharp; a blurred background softens it
    sharp = np.full((150, 100, 3), 40, np.uint8)
    sharp[:, 50:] = 220
    soft = cv2.GaussianBlur(sharp, (0, 0), 3)
    edge = np.s_[80, 24:40]  # across the person's left edge (column 30, a soft band to 35)

    def steepest(bg):
        row = composite(diffuse, img, bg, mask=mask, **kw)[edge].mean(1)
        return float(np.abs(np.diff(row)).max())

    assert steepest(soft) < 0.6 * steepest(sharp)


def test_a_background_soft_only_around_the_person_leaves_the_person_sharp(diffuse):
    """Defocus belongs to the background's depth, not to the person the camera focuses on: a photo sharp in parts
    (a checker at its sides) and soft only around the person (the checker blurred there) adds no blur to the
    person; before, the blur was measured around the person only and the person was blurred by it."""
    img, mask = flat_person()
    yy, xx = np.mgrid[:150, :300]
    checker = np.where(((yy // 12) + (xx // 12)) % 2 == 0, 60, 190).astype(np.uint8)
    bg = np.repeat(checker[..., None], 3, axis=2)
    soft = cv2.GaussianBlur(bg, (0, 0), 3)
    bg[:, 80:220] = soft[:, 80:220]  # the person stands at columns 130-170
    kw = {**SAME, "position": (0.5, 140 / 150)}
    matched = composite(diffuse, img, bg, mask=mask, **{**kw, "match_camera": True})
    plain = composite(diffuse, img, bg, mask=mask, **kw)
    np.testing.assert_allclose(matched, plain, atol=2e-3)


def test_a_half_body_takes_the_cameras_own_blur(diffuse):
    """A background soft everywhere (a soft camera, not depth) softens a cut-off person's edge too; before, a
    cut-off person was never blurred."""
    img, mask = flat_person()
    mask[100:] = mask[99]  # a half body
    yy, xx = np.mgrid[:150, :100]
    checker = np.where(((yy // 12) + (xx // 12)) % 2 == 0, 60, 190).astype(np.uint8)
    sharp = np.repeat(checker[..., None], 3, axis=2)
    soft = cv2.GaussianBlur(sharp, (0, 0), 3)
    kw = {k: v for k, v in SAME.items() if k not in ("position", "height")}

    def steepest(bg, match):
        row = composite(diffuse, img, bg, mask=mask, **{**kw, "match_camera": match})[80, 20:45].mean(1)
        return float(np.abs(np.diff(row)).max())

    assert steepest(soft, True) < 0.7 * steepest(soft, False)
    assert steepest(sharp, True) == pytest.approx(steepest(sharp, False), rel=0.05)


def test_a_known_plate_blur_blurs_a_full_body_to_it(diffuse):
    """``plate_blur`` (a panorama's plate, whose blur is known) blurs a full-body person where the plate's measured
    blur would not (a flat plate has no edge to measure); a half body, close to the camera, stays sharp; a bad
    value is refused."""
    img, mask = flat_person()
    plate = np.full((150, 100, 3), 40, np.uint8)
    kw = {**SAME, "match_camera": True}

    def steepest(blur, m=mask, **extra):
        row = composite(diffuse, img, plate, mask=m, plate_blur=blur, **{**kw, **extra})[80, 20:45].mean(1)
        return float(np.abs(np.diff(row)).max())

    assert steepest(3.0) < 0.6 * steepest(0.0)
    half = mask.copy()
    half[100:] = half[99]  # cut by the bottom border: placed as framed
    loose = {"position": None, "height": None}
    assert steepest(3.0, half, **loose) == pytest.approx(steepest(0.0, half, **loose), rel=1e-6)
    for bad in (-1.0, float("nan"), "3"):
        with pytest.raises(RelightError, match="plate_blur"):
            composite(diffuse, img, plate, mask=mask, plate_blur=bad, **kw)
    # fuzz7: a huge finite blur is the largest blur (8 px), not an OverflowError from squaring it
    assert steepest(1e200) == pytest.approx(steepest(1e3), rel=1e-6)


def test_the_person_hides_some_sky_from_the_ground_around_its_feet(diffuse):
    """Ambient occlusion (step 6): under an even light the ground beside the feet, beyond the small contact
    ellipse, is darker by the share of the sky the body hides, less the farther it is; before, it was unchanged
    a contact ellipse's width away."""
    img, mask = flat_person()
    bg = np.full((150, 300, 3), 150, np.uint8)
    even = np.zeros((9, 3), np.float32)
    even[0] = 0.3  # no direction: no cast shadow
    kw = {"meter": "background", "match_camera": False, "light_wrap": False, "light": even, "exposure": "physical"}
    lit = srgb_to_linear(composite(diffuse, img, bg, mask=mask, shadow=False, **kw))
    shaded = srgb_to_linear(composite(diffuse, img, bg, mask=mask, shadow=True, **kw))
    ratio = (shaded / lit).mean(2)
    feet = round(0.92 * 150) - 1  # the feet's row (default place), the person centred at column 150
    near, far = ratio[feet, [150 - 22, 150 + 22]], ratio[feet, [150 - 50, 150 + 50]]
    assert near.max() < 0.95  # a few body widths' reach, well outside the contact ellipse's
    assert (near < far).all() and far.max() < 0.995
    assert ratio[:50].min() > 0.999  # above the horizon: no ground, nothing hidden


def test_a_float_background_is_matched_as_its_8_bit_copy(diffuse):
    img, mask = flat_person()
    rng = np.random.default_rng(3)
    bg8 = cv2.GaussianBlur(rng.integers(0, 256, (150, 200, 3)).astype(np.uint8), (0, 0), 2)
    kw = {"meter": "background", "match_camera": True}
    eight = composite(diffuse, img, bg8, mask=mask, **kw)
    for dtype in (np.float32, np.float64):
        as_float = composite(diffuse, img, bg8.astype(dtype) / 255, mask=mask, **kw)
        np.testing.assert_allclose(as_float, eight, atol=1.5 / 255)


def test_a_bright_background_wraps_its_light_over_the_persons_edge(diffuse):
    """Light wrap (step 7): a dark person before a bright background takes some of its light in a thin band inside
    the edge, none deep inside; a darker background gives nothing (and takes nothing); off, the edge is as before."""
    img, mask = flat_person()
    mask[20:140, 30:35] = 1.0  # a hard edge: the band is the wrap's alone
    dim = np.zeros((9, 3), np.float32)
    dim[0] = 0.05  # a dim light: a dark person
    off = {**SAME, "light": dim, "exposure": "physical"}
    kw = {**off, "light_wrap": True}
    bright = np.full((150, 100, 3), 230, np.uint8)
    wrapped = srgb_to_linear(composite(diffuse, img, bright, mask=mask, **kw))
    plain = srgb_to_linear(composite(diffuse, img, bright, mask=mask, **off))
    edge, deep = np.s_[40:120, 30], np.s_[40:120, 45:55]  # the left edge column, and the body's middle
    lift = (wrapped[edge] - plain[edge]).mean()
    assert lift > 0.05 * (230 / 255) ** 2.2  # a visible share of the background's light
    np.testing.assert_allclose(wrapped[deep], plain[deep], atol=1e-6)
    np.testing.assert_allclose(wrapped[:10], plain[:10], atol=1e-6)  # the background itself untouched
    dark = np.full((150, 100, 3), 2, np.uint8)
    on, plain_dark = (composite(diffuse, img, dark, mask=mask, **k) for k in (kw, off))
    np.testing.assert_allclose(on, plain_dark, atol=1e-6)


def test_a_back_key_puts_a_rim_on_its_side_of_the_outline(diffuse):
    """Step 7's rim (``rim=True``; off by default): a key from behind the person and the image's right brightens
    the right edge of the outline, not the left one, nor the body's middle; a key from the camera's side gives
    no rim (both edges alike)."""
    img, mask = flat_person()
    mask[20:140, 30:35] = 1.0  # hard edges: left at column 30, right at 69
    bg = np.full((150, 100, 3), 110, np.uint8)  # uniform: the light wrap is the same on both sides
    left, right, deep = np.s_[40:120, 30], np.s_[40:120, 69], np.s_[40:120, 45:55]

    def ratios(key):
        kw = {**SAME, "key_light": key}
        on = srgb_to_linear(composite(diffuse, img, bg, mask=mask, **kw, rim=True))
        off = srgb_to_linear(composite(diffuse, img, bg, mask=mask, **kw))
        np.testing.assert_array_equal(srgb_to_linear(composite(diffuse, img, bg, mask=mask, **kw, rim=False)), off)
        return [float(on[s].mean() / off[s].mean()) for s in (left, right, deep)]

    l, r, d = ratios("150,30")
    assert r > l + 0.15 and d == pytest.approx(1.0, abs=1e-5)
    l, r, d = ratios("30,30")
    assert r == pytest.approx(l, abs=0.02) and d == pytest.approx(1.0, abs=1e-5)


def test_rim_auto_where_a_source_is_in_frame_and_the_light_reads_back_lit(diffuse):
    """Step 7's ``rim="auto"``: a clipped sun upper right in the photo puts a rim on the outline's right when the
    key is a back key, none when the key is in front (the same sun), none from a back key with no source in frame
    (``rim=True`` gives that one); by default (``rim=False``) none; a rim neither a bool nor "auto" is refused."""
    img, mask = flat_person()
    mask[20:140, 30:35] = 1.0  # hard edges: left at column 30
    mask = strands(mask, "right")  # the right edge soft: the full rim (a hard one keeps a thin line)
    bg = np.full((150, 100, 3), 110, np.uint8)
    sun = bg.copy()
    sun[8:12, 86:90] = 255  # upper right, beside the person's box
    left, right = np.s_[40:120, 26:40], np.s_[40:120, 58:74]

    def gain(background, key, rim="auto"):  # the light the rim adds across each edge, per row, over RIM_PHOTO
        args = {**SAME, "key_light": key}
        on = srgb_to_linear(composite(diffuse, img, background, mask=mask, **args, rim=rim))
        off = srgb_to_linear(composite(diffuse, img, background, mask=mask, **args, rim=False))
        return [float((on[s] - off[s]).mean(axis=(0, 2)).sum()) / RIM_PHOTO for s in (left, right)]

    l, r = gain(sun, "150,30")
    assert r > 0.3 and r > 4 * l  # RIM_PHOTO over a third of a pixel at least (0.43) on the sun's side
    assert gain(sun, "30,30") == pytest.approx([0, 0], abs=1e-6)  # a front key: the source in frame is not behind
    assert gain(bg, "150,30") == pytest.approx([0, 0], abs=1e-6)  # a back key, no source in frame
    assert gain(bg, "150,30", rim=True)[1] > 0.05  # asked for: the back key's rim
    assert gain(sun, "150,30", rim=False) == pytest.approx([0, 0], abs=1e-6)  # the default: none
    assert composite.__kwdefaults__["rim"] is False
    with pytest.raises(RelightError, match="rim"):
        composite(diffuse, img, sun, mask=mask, rim="on")


def test_a_key_nearly_behind_still_lights_its_side_of_the_outline():
    """A sun nearly behind the person (dawn's: 16° right of the axis, 5° up) lights the outline on its side with its
    whole rim: the rim takes the key's side in the image plane, not the Lambertian n · d (0.28 of it here), and a
    key straight behind lights the whole outline."""
    from relight_rt.apps.scene_rim import key_rim

    alpha = np.zeros((120, 120), np.float32)
    alpha[20:100, 40:80] = 1.0
    composed = np.full((120, 120, 3), 0.1, np.float32)
    d = np.array([-0.96, 0.27, 0.09])
    out = key_rim(composed, alpha, d / np.linalg.norm(d), 1.0, 2.0)
    right, left = out[60, 79, 0] / 0.1 - 1, out[60, 40, 0] / 0.1 - 1
    assert right > 0.6 and 0 <= left < 0.15 * right  # most of the gain (Lambertian: at most 0.28); the far side
    # little: the body hides a source 16° to the right from it (scene_rim.rim_facing)
    behind = key_rim(composed, alpha, np.array([-1.0, 0.0, 0.0]), 1.0, 2.0)
    assert behind[60, 40, 0] == pytest.approx(behind[60, 79, 0], rel=1e-3) and behind[20, 60, 0] > 0.15
    assert behind[60, 60, 0] == pytest.approx(0.1)  # the body's middle untouched


def test_the_wrap_and_the_rim_share_the_light_behind_the_outline(diffuse):
    """Both lift the outline by the light behind it (step 7): with both on, each pixel takes the larger lift, not
    the sum (summed, the lab view's half body drew a white outline); the rim alone and the wrap alone as before."""
    img, mask = flat_person()
    mask = strands(mask, "left")  # the left edge soft: the full rim, as wide as the wrap
    dim = np.zeros((9, 3), np.float32)
    dim[0] = 0.05  # a dark person before a bright background: the wrap lifts the edge
    kw = {**SAME, "light": dim, "exposure": "physical"}
    bright = np.full((150, 100, 3), 230, np.uint8)
    ray = np.array([-1.0, (30.5 - 50) / 86.6, (75 - 80.5) / 86.6])  # the left edge's ray (fov 60: focal 86.6 px)
    key = (ray / np.linalg.norm(ray), np.full(3, 0.15))  # a source straight behind the left edge: a rim there

    def lin(wrap, rim):
        return srgb_to_linear(composite(diffuse, img, bright, mask=mask, **{**kw, "light_wrap": wrap}, rim=rim,
                                        rim_key=key if rim else None))  # fmt: skip

    plain = lin(False, False)
    wrap, rim, both = lin(True, False) - plain, lin(False, True) - plain, lin(True, True) - plain
    edge = np.s_[60:100, 30:34]
    assert wrap[edge].mean() > 0.01 and rim[edge].mean() > 0.01  # each lifts the edge on its own
    np.testing.assert_allclose(both[edge], np.maximum(wrap[edge], rim[edge]), atol=2e-3)
    assert both[edge].sum() < 0.8 * (wrap[edge] + rim[edge]).sum()  # not the sum


def test_frame_metering_keeps_the_frames_mean_and_background_metering_keeps_its_pixels(diffuse):
    img, mask = flat_person(colour=(250, 250, 250))
    bg = np.full((150, 100, 3), 60, np.uint8)
    bg[:, :20] = 200
    light = np.zeros((9, 3), np.float32)
    light[0] = 3.0  # a bright white light: the person outshines the background
    kw = {k: v for k, v in SAME.items() if k != "meter"}
    kept = composite(diffuse, img, bg, mask=mask, light=light, exposure="physical", meter="background", **kw)
    metered = composite(diffuse, img, bg, mask=mask, light=light, exposure="physical", **kw)
    np.testing.assert_allclose(kept[:, :20], 200 / 255, atol=1e-5)
    ratio = srgb_to_linear(metered[:5, :20]) / srgb_to_linear(kept[:5, :20])
    assert 0.5 - 1e-4 <= ratio.mean() < 0.95 and np.ptp(ratio) < 1e-3  # one factor on the whole frame, <= 1 EV
    lum = np.array([0.2126, 0.7152, 0.0722], np.float32)
    bg_mean = float((srgb_to_linear(bg) @ lum).mean())
    if ratio.mean() > 0.5 + 1e-3:  # inside the limit: the frame's mean is the background's
        assert float((srgb_to_linear(metered) @ lum).mean()) == pytest.approx(bg_mean, rel=0.02)


def test_a_given_light_is_white_balanced_and_exposed_to_the_background(diffuse, monkeypatch):
    # the background's light coloured all round (the fitted rule makes the unseen ambient neutral: saturation 0)
    monkeypatch.setattr("relight_rt.light.from_background.COLOUR_SATURATION", 1.0)
    img, mask = flat_person(colour=(128, 128, 128))
    warm_bg = np.zeros((150, 100, 3), np.uint8)
    warm_bg[:] = (200, 140, 90)
    out = composite(diffuse, img, warm_bg, mask=mask, light="front", **SAME)  # a white preset
    own = composite(diffuse, img, warm_bg, mask=mask, **SAME)
    person_px = np.s_[40:120, 45:65]
    ratio = out[person_px].mean((0, 1)) / own[person_px].mean((0, 1))
    np.testing.assert_allclose(ratio, ratio.mean(), rtol=0.05)  # same colour balance as the background's light
    neutral = composite(diffuse, img, warm_bg, mask=mask, light="front", white_balance=False, **SAME)
    neutral = neutral[person_px].mean((0, 1))
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
        ({"key_light": "45"}, "key light"),
        ({"key_light": (0, 95)}, "key light"),
        ({"horizon": 1.5}, "horizon"),
        ({"meter": "spot"}, "meter"),
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
        (np.zeros((100, 100, 2), np.uint8), r"\(H, W, 3\)"),
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
    in_folder(tmp_path, models_dir, monkeypatch)
    write_person(tmp_path, seed=1)
    bg = np.zeros((96, 160, 3), np.uint8)
    bg[:] = (60, 90, 140)
    bg[:, 110:] = 240  # bright on the right
    cv2.imwrite("bg.png", bg[..., ::-1])
    return tmp_path


def test_cli_composite(work, capsys):
    code, _, err = run(["composite", "p.png", "--background", "bg.png", "-o", "out.png", "--shadow"], capsys)
    assert code == 0, err
    assert cv2.imread("out.png").shape == (96, 160, 3)
    argv = ["composite", "p.png", "--background", "bg.png", "-o", "o3.png", "--key-light", "180,30", "--horizon", "0.4",
            "--no-shadow", "--meter", "background", "--no-match-camera"]  # fmt: skip
    code, _, err = run(argv, capsys)
    assert code == 0, err
    code, _, err = run([*argv[:5], "o4.png", *argv[6:], "--no-light-wrap"], capsys)
    assert code == 0, err
    wrapped, plain = cv2.imread("o3.png").astype(int), cv2.imread("o4.png").astype(int)
    assert np.abs(wrapped - plain).max() > 2  # the wrap is on by default; --no-light-wrap turns it off
    code, _, err = run([*argv[:5], "o5.png", *argv[6:], "--rim"], capsys)  # the key from behind: a rim on top
    assert code == 0, err
    assert np.abs(cv2.imread("o5.png").astype(int) - wrapped).max() > 2  # off by default; --rim turns it on
    code, _, err = run([*argv[:5], "o6.png", *argv[6:], "--rim-auto"], capsys)  # no clipped source: no rim
    assert code == 0, err
    np.testing.assert_array_equal(cv2.imread("o6.png"), cv2.imread("o3.png"))
    code, _, err = run(["composite", "--rim", *argv[1:5], "o7.png", *argv[6:]], capsys)  # a flag: takes no value
    assert code == 0, err
    np.testing.assert_array_equal(cv2.imread("o7.png"), cv2.imread("o5.png"))
    sun = cv2.imread("bg.png")
    sun[6:10, 140:144] = 255  # a clipped sun upper right: --rim-auto puts a rim on (the key is behind)
    cv2.imwrite("sun.png", sun)
    sun_argv = [*argv[:3], "sun.png", *argv[4:]]
    for out, extra in (("s0.png", []), ("s1.png", ["--rim-auto"])):
        code, _, err = run([*sun_argv[:5], out, *sun_argv[6:], *extra], capsys)
        assert code == 0, err
    assert np.abs(cv2.imread("s1.png").astype(int) - cv2.imread("s0.png").astype(int)).max() > 10
    argv = ["composite", "p.png", "--background", "bg.png", "-o", "o2.jpg", "--preset", "studio"]
    code, _, err = run([*argv, "--position", "0.3,0.9", "--height", "0.6", "--exposure", "-1", "--fov", "80"], capsys)
    assert code == 0, err
    assert cv2.imread("o2.jpg").shape == (96, 160, 3)
    argv = ["composite", "p.png", "--background", "bg.png", "--no-shadow", "--meter", "background"]
    sizes = []
    for name, extra in (("c1.png", []), ("c2.png", ["--camera-height", "3"])):  # a camera twice as high
        code, _, err = run([*argv, "-o", name, *extra], capsys)
        assert code == 0, err
        changed = np.abs(cv2.imread(name).astype(int) - cv2.imread("bg.png").astype(int)).max(axis=2) > 6
        rows = np.flatnonzero(changed[:, :100].any(axis=1))  # the person, left of the bright part
        sizes.append(rows[-1] + 1 - rows[0])
    assert sizes[1] == pytest.approx(sizes[0] / 2, abs=3)  # sees the feet twice as far: half as tall


@pytest.mark.parametrize(
    "extra, match",
    [
        (["--position", "2,0.5"], "position"),
        (["--fov", "5"], "field of view"),
        (["--height", "3"], "height"),
        (["--exposure", "loud"], "exposure"),
        (["--light", "none.npy"], "none.npy"),
        (["--key-light", "north"], "key light"),
        (["--horizon", "2"], "horizon"),
        (["--camera-height", "tall"], "camera height"),
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
    code, _, err = run(["lights", "from-background", "bg.png", "-o", "k.npy", "--key-light=-90,20"], capsys)
    assert code == 0, err
    assert np.all(np.load("k.npy")[1] < light[1])  # the key moved to the image's left: less light from +y
    code, _, err = run(["lights", "from-background", "bg.png", "-o", "l2.npy", "--fov", "180"], capsys)
    assert code == 2 and "field of view" in err and not (work / "l2.npy").exists()
    code, _, err = run(["lights", "from-background", "p_mask.png", "-o", "l3.npy"], capsys)
    assert code == 0, err  # issue 34: a black-and-white photo is a background like any other
    gray = np.load("l3.npy", allow_pickle=False)
    np.testing.assert_allclose(gray[:, 0], gray[:, 1], rtol=1e-5, atol=1e-7)  # gray light


def test_the_automatic_matte_sees_the_photo_not_its_linear_copy(diffuse_models_dir):
    img, mask = flat_person()
    seen = []

    def matter(rgb, name="image"):
        seen.append(float(rgb.mean()))
        return mask

    # the automatic matte handed in: one that records its input
    r = Relighter(RuntimeConfig(models=diffuse_models_dir, device="cpu", detail=False), matter=matter)
    bg = np.full((120, 260, 3), 90, np.uint8)
    with_matte = composite(r, img, bg)
    assert seen and seen[0] == pytest.approx(img.mean() / 255, abs=1e-6)  # sRGB values, as in every other command
    np.testing.assert_array_equal(with_matte, composite(r, img, bg, mask=mask))  # the same as that mask given


def test_a_portrait_wider_than_the_background_fits_it_by_default(diffuse):
    """A head-and-shoulders photo cut by its bottom edge into a narrower place: without --height it is made as
    large as fits across (it was an error asking for a smaller --height) and kept whole in the picture."""
    img = np.zeros((120, 200, 3), np.uint8)
    img[:] = (150, 110, 90)
    mask = np.zeros((120, 200), np.float32)
    mask[20:, 10:190] = 1.0  # runs off the bottom: a portrait, 180 px wide
    bg = np.full((150, 100, 3), 90, np.uint8)
    out = composite(diffuse, img, bg, mask=mask, shadow=False, match_camera=False, meter="background")
    assert out.shape == (150, 100, 3)
    changed = np.abs(out - 90 / 255).max(axis=2) > 0.02
    cols = np.flatnonzero(changed.any(axis=0))
    assert cols[0] <= 1 and cols[-1] >= 98  # across the whole width, nothing cut at one side only
    with pytest.raises(RelightError, match="smaller --height"):  # a height the user gives is obeyed
        composite(diffuse, img, bg, mask=mask, height=1.0, shadow=False)


def test_a_person_photo_file_is_decoded_once(diffuse_models_dir, tmp_path, monkeypatch):
    """composite read a person's file twice (once for the automatic matte, once for the linear copy stage 1
    gets); it decodes it once and gives both the same pixels, with the same result as the array."""
    import relight_rt.image.io as io

    img, mask = flat_person()
    path = tmp_path / "person.png"
    cv2.imwrite(str(path), img[..., ::-1])
    r = Relighter(RuntimeConfig(models=diffuse_models_dir, device="cpu", detail=False),
                  matter=lambda rgb, name="image": mask)
    calls = []
    decode = io.decode_file
    monkeypatch.setattr(io, "decode_file", lambda *a, **k: calls.append(a[0]) or decode(*a, **k))
    bg = np.full((120, 260, 3), 90, np.uint8)
    from_file = composite(r, path, bg)
    assert calls == [path]
    np.testing.assert_array_equal(from_file, composite(r, img, bg))


# ------------------------------------------------------------------------------ composite's steps, each alone


def _box_rgba(h=100, w=60, box=(10, 80, 20, 40), colour=(0.5, 0.4, 0.3)) -> np.ndarray:
    rgba = np.zeros((h, w, 4), np.float32)
    y0, y1, x0, x1 = box
    rgba[y0:y1, x0:x1] = (*colour, 1.0)
    return rgba


def test_place_stands_a_full_body_person_on_the_ground_by_perspective():
    from relight_rt.apps.scene_place import CAMERA_M, DEFAULT_FEET, PERSON_M, place

    placed = place(_box_rgba(), (300, 400, 3), None, None, 0.5)  # the box does not reach the photo's bottom
    assert placed.full_body and placed.feet_y == round(DEFAULT_FEET * 300)
    assert placed.height == round((DEFAULT_FEET - 0.5) * 300 * PERSON_M / CAMERA_M)  # d · PERSON_M / CAMERA_M rows
    assert placed.premult.shape[:2] == (placed.height, placed.width) and placed.premult[..., 3].max() == 1
    np.testing.assert_allclose(placed.premult[placed.height // 2, placed.width // 2], (0.5, 0.4, 0.3, 1.0))
    assert placed.width == round(20 * placed.height / 70)  # the box's aspect kept
    portrait = place(_box_rgba(box=(40, 100, 20, 40)), (300, 400, 3), None, None, 0.5)  # cut by its bottom edge
    assert not portrait.full_body and portrait.feet_y == 300 and portrait.height == round(0.6 * 300)
    given = place(_box_rgba(), (300, 400, 3), (0.25, 0.8), 0.5, 0.5)
    assert given.height == 150 and given.feet_y == 240 and given.feet_x == pytest.approx(0.25 * 400, abs=0.5)
    assert abs(given.left + given.width / 2 - 0.25 * 400) <= 1  # a straight body: its feet under the box's centre
    with pytest.raises(RelightError, match="above the horizon"):
        place(_box_rgba(), (300, 400, 3), (0.5, 0.4), None, 0.5)


def test_scene_lighting_takes_the_backgrounds_key_or_a_given_light(diffuse):
    from relight_rt.apps.scene import scene_lighting
    from relight_rt.light.from_background import key_direction, parse_key_light, scene_light

    img, mask = flat_person()
    dec = diffuse.decompose(img.astype(np.float32) / 255, mask)
    bg = np.zeros((120, 160, 3), np.uint8)
    bg[:60], bg[60:] = (240, 200, 140), (120, 100, 80)  # a warm bright sky over a darker ground
    parts = scene_light(bg, 60.0)
    key = parse_key_light("30,40")
    own = scene_lighting(diffuse, dec, parts, parts.light(key), key, None)
    np.testing.assert_array_equal(own.light, parts.light(key))
    np.testing.assert_allclose(own.shadow_dir, key_direction(30, 40))
    assert own.directional >= 0.35 and own.rim_dir is None
    lamp = lights.directional((0.2, -1.0, 0.3)).astype(np.float32)
    given = scene_lighting(diffuse, dec, parts, parts.light(key), key, lamp, white_balance=False)
    np.testing.assert_array_equal(given.light, lamp)
    assert given.shadow_dir is not None and given.shadow_dir[1] < 0  # the lamp's own direction
    balanced = scene_lighting(diffuse, dec, parts, parts.light(key), key, lamp)
    assert not np.allclose(balanced.light, lamp)  # its colour matched to the background's


def test_shadows_darken_the_ground_around_the_feet_only():
    from relight_rt.apps.scene import CONTACT_STRENGTH, SceneLighting, place, shade, shadows

    placed = place(_box_rgba(), (300, 400, 3), (0.5, 0.9), 0.4, 0.5)
    none = SceneLighting(np.zeros((9, 3), np.float32), np.zeros((9, 3), np.float32), None, 0.0)
    cast = shadows(placed, (300, 400, 3), 0.5, 60.0, none)
    y0, y1, x0, x1 = cast.box
    assert cast.cast is None and y0 <= placed.feet_y < y1 and x0 < 200 < x1
    lin = np.ones((300, 400, 3), np.float32)
    shade(lin, (0, 0), cast)
    foot_x, foot_y = cast.foot
    assert lin[int(foot_y), int(foot_x), 0] == pytest.approx(1 - CONTACT_STRENGTH, abs=0.02)  # the contact shadow
    assert lin[10, 10, 0] == 1 and lin[:150].min() == 1  # nothing above the horizon, nothing far away
    from relight_rt.light.from_background import key_direction

    keyed = SceneLighting(none.light, none.light, key_direction(40, 35), 0.8)
    long = shadows(placed, (300, 400, 3), 0.5, 60.0, keyed)
    assert long.cast is not None  # a directional key casts the body's shadow on the ground


def test_grade_meters_the_frame_or_keeps_the_background():
    from relight_rt.apps.scene import METER_LIMIT_EV, grade

    bg = np.full((40, 60, 3), 100, np.uint8)
    lin = np.full((10, 20, 3), 1.0, np.float32)  # a bright person in the region
    box = (10, 20, 20, 40)
    before = float((srgb_to_linear(np.full((10, 20, 3), 100 / 255, np.float32)) @ np.array(
        [0.2126, 0.7152, 0.0722], np.float32)).sum())
    kept = grade(bg, lin.copy(), box, before, meter="background")
    np.testing.assert_allclose(kept[:10], 100 / 255, atol=1e-6)  # away from the person: the background as it was
    np.testing.assert_allclose(kept[10:20, 20:40], 1.0)
    metered = grade(bg, lin.copy(), box, before, meter="frame")
    assert metered[0, 0, 0] < 100 / 255  # the bright person darkens the whole frame a little
    assert srgb_to_linear(metered[:1, :1])[0, 0, 0] >= 2.0**-METER_LIMIT_EV * srgb_to_linear(kept[:1, :1])[0, 0, 0]
