"""The original background following the light (Background.grade, issue 51): off by default; on, the backdrop and
what shows through the soft edge move by the person's change (one global grade per channel), the person's pixels
are untouched, and RGBA / colour backgrounds are never graded. Analytic graphs (tests/_graphs.py): a light k times
the photo's own light gives k times the photo inside the mask."""

from dataclasses import replace

import cv2
import numpy as np
import pytest
from _graphs import OWN_LIGHT, diffuse_models_dir, models_dir, person

import relight_rt
from relight_rt import RelightError
from relight_rt.cli import main
from relight_rt.engine.config import RuntimeConfig
from relight_rt.image.color import REC709, linear_to_srgb, srgb_to_linear
from relight_rt.image.compositing import Background, parse_background
from relight_rt.relight.compose import GradeSample, HeadBlend, background_grade, head_level, sampled_grade

__all__ = ["diffuse_models_dir", "models_dir"]  # fixtures

COOL = OWN_LIGHT * np.array([0.45, 0.55, 0.8], np.float32)  # darker and bluer than the photo's own light
GRADED = Background.original(grade=True)


@pytest.fixture(scope="module")
def relighter(models_dir):
    return relight_rt.open(RuntimeConfig(models=models_dir, device="cpu"))


def soft_person():
    img, mask = person(seed=3)
    return img, np.clip(cv2.GaussianBlur(mask, (9, 9), 3), 0, 1)


def linear_gain(after, before, weight):
    w = weight[..., None].astype(np.float64)
    return (srgb_to_linear(after) * w).sum((0, 1)) / (srgb_to_linear(before) * w).sum((0, 1))


def test_off_by_default(relighter):
    img, mask = soft_person()
    dec = relighter.decompose(img, mask)
    plain = relighter.relight(dec, COOL, exposure="physical")
    np.testing.assert_array_equal(plain, relighter.relight(dec, COOL, exposure="physical", background="original"))
    np.testing.assert_array_equal(plain[mask == 0], img[mask == 0])  # the background untouched
    assert not Background().grade and not Background.original().graded


def test_backdrop_moves_by_the_persons_change(relighter):
    img, mask = soft_person()
    dec = relighter.decompose(img, mask)
    plain = relighter.relight(dec, COOL, exposure="physical")
    graded = relighter.relight(dec, COOL, exposure="physical", background=GRADED)
    person, back = mask == 1, mask == 0
    np.testing.assert_allclose(graded[person], plain[person], atol=1e-6)  # the person's pixels unchanged (rounding)
    ratio = graded[back] / img[back]
    gain = ratio.mean(0)
    np.testing.assert_allclose(ratio, np.broadcast_to(gain, ratio.shape), rtol=2e-4)  # one global grade
    assert gain[0] < gain[1] < gain[2] < 1  # darker, and cooler: the light's colour
    # in light, the backdrop moves as the person did, per channel and in luminance (the grade is measured over
    # the whole soft matte and put back on the values with a 2.2 power, not the sRGB curve: within 12 %, 0.15 EV)
    person_gain = linear_gain(plain, img, person.astype(np.float32))
    back_gain = linear_gain(graded, img, back.astype(np.float32))
    assert (person_gain < 0.6).all()  # a change worth following: up to -2.5 EV per channel
    np.testing.assert_allclose(back_gain, person_gain, rtol=0.12)
    assert abs(np.log2((back_gain @ REC709) / (person_gain @ REC709))) < 0.15


def test_soft_edge_shows_the_graded_background(relighter):
    img, mask = soft_person()
    dec = relighter.decompose(img, mask)
    plain = relighter.relight(dec, COOL, exposure="physical")
    graded = relighter.relight(dec, COOL, exposure="physical", background=GRADED)
    # the backdrop's one grade, averaged in float64: a float32 mean down 10^4 ratios drifts by up to 1.5e-4 of itself
    # (the ratios agree to 1e-7), which alone moved the expected edge by 3e-5 once the crop changed (mirror33)
    gain = (graded[mask == 0] / img[mask == 0]).mean(0, dtype=np.float64).astype(np.float32)
    _, behind = dec.foreground
    y0, y1, x0, x1 = dec.geometry.box
    a = mask[y0:y1, x0:x1, None]
    soft = ((a > 0.05) & (a < 0.95))[..., 0]
    assert soft.sum() > 100
    expected = plain[y0:y1, x0:x1] + (1 - a) * (np.clip(behind * gain, 0, 1) - behind)
    np.testing.assert_allclose(graded[y0:y1, x0:x1][soft], expected[soft], atol=2e-5)


@pytest.mark.parametrize("background", ["transparent", "black", "#336699"])
def test_other_backgrounds_are_not_graded(relighter, background):
    img, mask = soft_person()
    dec = relighter.decompose(img, mask)
    plain_bg = parse_background(background)
    bg = replace(plain_bg, grade=True)
    assert not bg.graded
    np.testing.assert_array_equal(relighter.relight(dec, COOL, background=bg), relighter.relight(dec, COOL,
                                                                                               background=plain_bg))


def test_layers_and_many_grade_too(relighter):
    img, mask = soft_person()
    dec = relighter.decompose(img, mask)
    one = relighter.relight(dec, COOL, exposure="physical", background=GRADED)
    np.testing.assert_array_equal(relighter.layers(dec, COOL, exposure="physical", background=GRADED).image, one)
    many = relighter.relight_many(dec, [OWN_LIGHT, COOL], exposure="physical", background=GRADED)
    np.testing.assert_array_equal(many[1], one)
    np.testing.assert_allclose(many[0], img, atol=1e-5)  # the photo's own light: nothing to grade


def test_grade_of_a_black_person_is_one():
    z = np.zeros((4, 4, 3), np.float32)
    np.testing.assert_array_equal(background_grade(z, z, np.ones((4, 4), np.float32)), np.ones(3, np.float32))


def test_bad_grade_value():
    with pytest.raises(RelightError, match="grade"):
        Background("original", grade="yes")


def test_cli_grade_background(tmp_path, models_dir, capsys):
    img, mask = person(seed=4)
    cv2.imwrite(str(tmp_path / "p.png"), cv2.cvtColor((img * 255).round().astype(np.uint8), cv2.COLOR_RGB2BGR))
    cv2.imwrite(str(tmp_path / "p_mask.png"), (mask * 255).astype(np.uint8))
    args = [str(tmp_path / "p.png"), "--preset", "night", "--models", str(models_dir)]
    assert main(["relight", *args, "-o", str(tmp_path / "plain.png")]) == 0
    assert main(["relight", *args, "--grade-background", "-o", str(tmp_path / "graded.png")]) == 0
    plain = cv2.imread(str(tmp_path / "plain.png")).astype(int)
    graded = cv2.imread(str(tmp_path / "graded.png")).astype(int)
    back = mask == 0
    assert (graded[back] < plain[back]).mean() > 0.9  # night: the street darker too
    assert main(["relight", *args, "--grade-background", "--background", "black", "-o", str(tmp_path / "x.png")]) != 0
    err = capsys.readouterr().err
    assert "--grade-background" in err and "Traceback" not in err


def test_a_group_grades_the_background_by_the_groups_change():
    """matting="all" (relight_rt.relight.people): the group's backdrop follows the light by one grade; its people's
    opaque pixels are the ungraded run's."""
    from relight_rt.image.io import read_image

    rgba = read_image("relight_rt/data/example.png")
    a = rgba[..., 3:4]
    one = rgba[..., :3] * a + 0.55 * (1 - a)
    two = np.ascontiguousarray(np.hstack([one, one[:, ::-1]]))  # the example person and its mirror image
    rl = relight_rt.open(RuntimeConfig(device="cpu", matting="all"))
    dec = rl.decompose(two)
    assert len(dec.people) == 2
    plain = rl.relight(dec, "night")
    graded = rl.relight(dec, "night", background=GRADED)
    person = dec.mask == 1
    back = (dec.mask == 0) & (plain == two).all(axis=2)  # the backdrop no person's share reaches
    assert back.mean() > 0.3
    ratio = graded[back] / two[back]
    # one grade: every untouched backdrop pixel moves by the same gain (the mean taken in float64)
    np.testing.assert_allclose(ratio, np.broadcast_to(ratio.mean(0, dtype=np.float64), ratio.shape), rtol=2e-4)
    assert ratio.mean(0)[0] < 1  # night: darker
    np.testing.assert_allclose(graded[person], plain[person], atol=1e-6)


def _write_clip(folder, frames=4, feather=True):
    """A still backdrop with a textured person over it, the person's texture new in every frame; masks beside the
    frames."""
    folder.mkdir()
    rng = np.random.default_rng(7)
    back = (0.3 + 0.5 * rng.random((120, 90, 3))).astype(np.float32)
    mask = np.zeros((120, 90), np.float32)
    mask[15:110, 25:65] = 1
    if feather:
        mask = np.clip(cv2.GaussianBlur(mask, (7, 7), 2), 0, 1)
    for t in range(frames):
        body = (0.15 + (0.4 + 0.1 * (t % 2)) * rng.random((120, 90, 3))).astype(np.float32)
        img = back * (1 - mask[..., None]) + body * mask[..., None]
        cv2.imwrite(str(folder / f"f_{t:03d}.png"), cv2.cvtColor(np.rint(img * 255).astype(np.uint8),
                                                                  cv2.COLOR_RGB2BGR))
        cv2.imwrite(str(folder / f"f_{t:03d}_mask.png"), np.rint(mask * 255).astype(np.uint8))
    return folder, back, mask


def test_cli_video_grade_background(tmp_path, models_dir, capsys):
    """``video --grade-background``: every frame's backdrop moves by one grade (night: darker) and the person's
    opaque pixels are the ungraded run's (the grade over time: the next test)."""
    clip, back, mask = _write_clip(tmp_path / "clip")
    common = [str(clip), "--preset", "night", "--models", str(models_dir), "--device", "cpu", "--no-stabilize"]
    assert main(["-q", "video", *common, "--frames-out", str(tmp_path / "plain")]) == 0
    assert main(["-q", "video", *common, "--grade-background", "--frames-out", str(tmp_path / "graded")]) == 0
    read = lambda p: cv2.imread(str(p)).astype(np.float64)  # noqa: E731
    outside, opaque = mask == 0, mask >= 1 - 1 / 255
    for t in range(4):
        plain, graded = read(tmp_path / "plain" / f"f_{t:03d}.png"), read(tmp_path / "graded" / f"f_{t:03d}.png")
        assert np.abs(graded[opaque] - plain[opaque]).max() <= 1  # the person as ungraded (8-bit rounding)
        np.testing.assert_array_equal(plain[outside], read(clip / f"f_{t:03d}.png")[outside])  # off: untouched
        ratio = graded[outside] / np.maximum(plain[outside], 1)
        gain = np.median(ratio, axis=0)
        assert (np.abs(ratio - gain) < 0.03 + 1.5 / np.maximum(plain[outside], 1)).mean() > 0.99  # one grade
        assert (gain < 0.95).all()  # night: the backdrop darker too
    assert main(["-q", "video", *common, "--grade-background", "--background", "black", "--frames-out",
                 str(tmp_path / "x")]) != 0
    err = capsys.readouterr().err
    assert "--grade-background" in err and "Traceback" not in err


def test_clip_grade_follows_a_changing_light_without_flicker():
    """``BackgroundGrade``: a per-frame measurement that jitters by ±5 % moves the clip's grade by a fraction of
    that; a step in the light is followed within a few time constants; a frame of nobody keeps the grade."""
    from relight_rt.video.job import GRADE_SECONDS, BackgroundGrade

    fps = 25.0
    image = np.full((8, 8, 3), 0.5, np.float32)
    mask = np.zeros((8, 8), np.float32)
    mask[2:6, 2:6] = 1
    grade = BackgroundGrade(fps)

    def frame(light_gain):  # the person relit by a change in light of ``light_gain``
        lit = linear_to_srgb(srgb_to_linear(image) * light_gain)
        return np.where(mask[..., None] > 0, lit, image).astype(np.float32)

    first = grade.update(frame(0.5), image, mask)
    np.testing.assert_allclose(first, 0.5 ** (1 / 2.2), rtol=1e-5)  # the first frame takes its own grade
    seen = [grade.update(frame(0.5 * (1.05 if t % 2 else 0.95)), image, mask) for t in range(50)]
    assert np.abs(np.diff(np.log(np.array(seen)[:, 0]))).max() < 0.1 * np.log(1.05 / 0.95) / 2.2
    for _ in range(int(3 * GRADE_SECONDS * fps)):  # a step to a brighter light, followed over 3 time constants
        last = grade.update(frame(0.8), image, mask)
    assert abs(np.log(last[0] / 0.8 ** (1 / 2.2))) < 0.06 * abs(np.log(0.8 / 0.5) / 2.2)
    empty = np.zeros_like(mask)
    np.testing.assert_array_equal(grade.update(image, image, empty), last)  # nobody: the grade kept
    out = grade.apply(image, image, empty, last)
    np.testing.assert_allclose(out, image * last, rtol=1e-6)  # and the whole frame is the backdrop, graded


@pytest.mark.parametrize("detail", [True, False])
def test_the_studios_sample_grades_as_the_result(diffuse_models_dir, detail):
    """``Relighter.grade_inputs`` and ``sampled_grade`` (the studio's preview grade, relight_rt.apps.studio) give
    the grade the result puts on the backdrop where the result is what the sample models (no stage 2 residual: a
    diffuse-only runtime; a texture the network's frame resolves): the photo's own light 1, a brighter light its
    change with the highlight shoulder, a cooler light its change, within 0.5 % (0.1 % measured). The weights are
    the matte's."""
    rl = relight_rt.open(RuntimeConfig(models=diffuse_models_dir, device="cpu", detail=detail))
    img, mask = soft_person()
    img = cv2.GaussianBlur(img, (0, 0), 3)  # texture the network's frame (about 2 photo pixels a pixel) resolves
    dec = rl.decompose(img, mask)
    sample = rl.grade_inputs(dec)
    assert sample.weight.sum() * dec.geometry.scale ** 2 == pytest.approx(mask.sum(), rel=0.02)  # the matte's area
    assert np.isfinite(sample.knee).all() == detail  # the network's picture (no detail) has no shoulder
    back = mask == 0
    for light in (OWN_LIGHT, 1.3 * OWN_LIGHT, COOL):
        light = np.asarray(light, np.float32)
        graded = rl.relight(dec, light, exposure="physical", background=GRADED)
        result = (graded[back] / img[back]).mean(0)
        np.testing.assert_allclose(sampled_grade(sample, light), result, rtol=5e-3)


def _sample_with_head(rng, n=400, k=150):
    """A ``GradeSample`` of n pixels with the head pass's blend on k of them (``HeadBlend``), whose head pass sees
    exactly what the body does (its factor's inputs and transport the body's at those pixels)."""
    own = rng.uniform(0.05, 0.9, (n, 3)).astype(np.float32)
    scale = rng.uniform(0.5, 2.0, (n, 1)).astype(np.float32)
    stays = rng.uniform(0, 0.2, (n, 1)).astype(np.float32)
    transport = np.zeros((n, 9), np.float32)
    transport[:, 0] = 2.0
    transport[:, 1:4] = rng.uniform(-1, 1, (n, 3))
    sample = GradeSample(own * scale, own * stays, transport, rng.uniform(0.2, 1, n).astype(np.float32),
                         np.full(n, np.inf, np.float32), own, np.zeros(n, np.float32), HeadBlend.empty())
    at = np.sort(rng.choice(n, k, replace=False)).astype(np.int32)
    head = HeadBlend(at, rng.uniform(0.1, 1, k).astype(np.float32), rng.uniform(0, 1, k).astype(np.float32),
                     scale[at, 0], stays[at, 0], scale[at, 0], stays[at, 0], transport[at])
    return sample._replace(head=head)


def test_the_sample_blends_the_head_pass_at_the_bodys_level():
    """``sampled_grade`` blends the head pass's factor in as ``Factor.blend_head`` does, scaled to the body's level
    on the skin (``head_level``): a head pass that sees what the body sees leaves the grade as it was, whatever its
    weights; one that sees the same shape at twice the factor is scaled back to it (level 1/2), the grade again as
    it was; one whose light falls differently moves the grade, by its blend's weight (none at weight 0), and the
    thinned sample (``GradeSample.every``, what the studio sends) keeps the head pass's pixels that it keeps, and
    none where it keeps none of their skin."""
    rng = np.random.default_rng(3)
    sample = _sample_with_head(rng)
    light = (np.asarray(OWN_LIGHT, np.float32) * np.array([1.3, 1.0, 0.8], np.float32))
    light[1:4] += 0.3 * rng.standard_normal((3, 3)).astype(np.float32)
    body = sampled_grade(sample._replace(head=HeadBlend.empty()), light)
    head = sample.head
    np.testing.assert_allclose(head_level(sample, light)[0], 1.0, rtol=1e-5)
    np.testing.assert_allclose(sampled_grade(sample, light), body, rtol=1e-5)
    twice = head._replace(scale=2 * head.scale, stays=2 * head.stays)
    np.testing.assert_allclose(head_level(sample._replace(head=twice), light)[0], 0.5, rtol=1e-5)
    np.testing.assert_allclose(sampled_grade(sample._replace(head=twice), light), body, rtol=1e-5)
    turned = head._replace(transport=head.transport * np.array([1, -1, 1, -1, 1, 1, 1, 1, 1], np.float32))
    moved = sampled_grade(sample._replace(head=turned), light)
    assert np.abs(moved / body - 1).max() > 1e-2
    still = turned._replace(weight=np.zeros_like(turned.weight))
    np.testing.assert_allclose(sampled_grade(sample._replace(head=still), light), body, rtol=1e-6)
    thin = sample.every(3)
    assert thin.weight.shape[0] == -(-sample.weight.shape[0] // 3)
    np.testing.assert_array_equal(thin.head.index, sample.head.index[sample.head.index % 3 == 0] // 3)
    np.testing.assert_array_equal(thin.head.transport, sample.transport[::3][thin.head.index])
    # thinned past all of its skin, the blend has no level to match (head_level's would be 0): none is sent
    off_skin = head._replace(skin=np.where(head.index % 3 == 0, 0, head.skin).astype(np.float32))
    bare = sample._replace(head=off_skin).every(3)
    assert bare.head.index.size == 0
    np.testing.assert_array_equal(sampled_grade(bare, light),
                                  sampled_grade(thin._replace(head=HeadBlend.empty()), light))
