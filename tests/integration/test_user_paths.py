"""What users hit, pinned by its effect (issue 26): light flags, soft masks, compositing, the stabiliser.

Every test here uses data on which the bug it guards against is visible: directional and coloured lights
on a graph whose normals face -y on the left and +y on the right (tests/_graphs.py
``stage1_sides_model``), soft irregular masks with hair-like strands and a hole, and backgrounds unlike
the person (tests/_scenes.py). Each was checked to fail under the one-line bug named in its docstring.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from _graphs import OWN_LIGHT, make_models_dir, models_dir, save, stage1_model, stage1_sides_model
from _scenes import ambient, backdrop, directional, side_means, soft_person, write_scene

from relight_rt import Relighter, RelightError, RuntimeConfig, cli, envmap
from relight_rt.image.compositing import Background
from relight_rt.video.job import Frame, FrameLayers, LightSchedule, RelighterEngine, composite, relight_frames
from relight_rt.video.stabilize import Stabilizer

__all__ = ["models_dir"]  # fixture

RED_HEAVY = (0.6, 0.3, 0.1)


@pytest.fixture(scope="session")
def sides_dir(tmp_path_factory):
    """Stage 1 with -y / +y normals (left / right) and the toy stage 2."""
    return make_models_dir(tmp_path_factory.mktemp("sides"), 64, stage1=stage1_sides_model())


@pytest.fixture(scope="session")
def sides(sides_dir):
    return Relighter(RuntimeConfig(models=sides_dir, device="cpu"))


@pytest.fixture
def work(tmp_path, models_dir, monkeypatch):
    """A folder with the soft scene p.png + p_mask.png; $RELIGHT_RT_MODELS points at the PLAIN analytic models."""
    monkeypatch.setenv("RELIGHT_RT_MODELS", str(models_dir))
    monkeypatch.chdir(tmp_path)
    write_scene(tmp_path)
    return tmp_path


def run(argv, capsys) -> np.ndarray:
    code = cli.main([str(a) for a in argv])
    _, err = capsys.readouterr()
    assert code == 0, err
    out = cv2.imread(str(argv[argv.index("-o") + 1]), cv2.IMREAD_UNCHANGED)
    assert out is not None
    rgb = out[..., 2::-1] if out.shape[2] == 3 else out[..., [2, 1, 0, 3]]
    return rgb.astype(np.float64) / 255


def scene_mask(folder) -> np.ndarray:
    return cv2.imread(str(folder / "p_mask.png"), cv2.IMREAD_GRAYSCALE).astype(np.float32) / 255


def brighter_side(image, mask) -> str:
    left, right = side_means(image, mask)
    lum_l, lum_r = left.mean(), right.mean()
    assert abs(lum_l - lum_r) > 0.15, (lum_l, lum_r)  # clearly one-sided, not noise
    return "right" if lum_r > lum_l else "left"


# ----------------------------------------------------------------------------------------- CLI light flags


def test_rotate_turns_which_side_is_lit(work, sides_dir, capsys):
    """A light from +y lights the right side; --rotate 180 turns it to -y (bug: --rotate ignored)."""
    np.save("from_y.npy", directional((0, 1, 0), strength=0.5))
    mask = scene_mask(work)
    plain = run(["relight", "p.png", "--models", sides_dir, "--light", "from_y.npy", "-o", "a.png"], capsys)
    turned = run(["relight", "p.png", "--models", sides_dir, "--light", "from_y.npy", "--rotate", "180",
                  "-o", "b.png"], capsys)  # fmt: skip
    assert brighter_side(plain, mask) == "right"
    assert brighter_side(turned, mask) == "left"
    quarter = run(["relight", "p.png", "--models", sides_dir, "--preset", "studio", "--rotate", "90", "-o", "c.png"],
                  capsys)  # fmt: skip
    studio = run(["relight", "p.png", "--models", sides_dir, "--preset", "studio", "-o", "d.png"], capsys)
    assert np.abs(quarter - studio)[mask >= 1].mean() > 0.02  # a preset turns too


def test_bgr_reads_the_columns_as_blue_green_red(work, sides_dir, capsys):
    """A red-heavy light file read with --bgr gives a blue-heavy person (bug: --bgr ignored, or reversed)."""
    np.save("warm.npy", ambient(RED_HEAVY))
    mask = scene_mask(work)
    # physical exposure: auto would rescale each by its own luminance (Rec. 709 weighs R and B differently)
    common = ["--models", sides_dir, "--light", "warm.npy", "--exposure", "physical"]
    rgb = run(["relight", "p.png", *common, "-o", "rgb.png"], capsys)
    bgr = run(["relight", "p.png", *common, "--bgr", "-o", "bgr.png"], capsys)
    r, g, b = rgb[mask >= 1][:, :3].mean(axis=0)
    assert r > 1.5 * g > 2.2 * b
    r2, g2, b2 = bgr[mask >= 1][:, :3].mean(axis=0)
    assert b2 > 1.5 * g2 > 2.2 * r2
    # the same light, columns reversed: the same colour balance reversed (not the same brightness: a blue light
    # of the red one's channel values is darker, Rec. 709 luminance weighs blue least)
    np.testing.assert_allclose(np.array([r2, g2, b2]) / (r2 + g2 + b2), np.array([b, g, r]) / (r + g + b), atol=0.02)


def test_envmap_reaches_the_relighter_and_turns(work, sides_dir, capsys):
    """An environment map bright toward +y lights the right side, turned by --rotate (bug: either dropped)."""
    env = envmap.envmap_from_light(directional((0, 1, 0), strength=0.5), 32).astype(np.float32)
    cv2.imwrite("env.hdr", np.ascontiguousarray(np.maximum(env, 0)[..., ::-1]))
    mask = scene_mask(work)
    out = run(["relight", "p.png", "--models", sides_dir, "--envmap", "env.hdr", "-o", "e.png"], capsys)
    turned = run(["relight", "p.png", "--models", sides_dir, "--envmap", "env.hdr", "--rotate", "180", "-o", "f.png"],
                 capsys)  # fmt: skip
    assert brighter_side(out, mask) == "right"
    assert brighter_side(turned, mask) == "left"


def test_light_from_uses_the_other_photos_estimated_light(work, tmp_path_factory, capsys):
    """--light-from PHOTO relights with the estimate for PHOTO (here a warm light the graph reports, refit to the
    photo: relight_rt.relight.strength.refit_light), taken as white as a photo's own light is (its colour estimate is
    not trusted: photos are white-balanced)."""
    warm = ambient(RED_HEAVY).astype(np.float32)
    folder = make_models_dir(tmp_path_factory.mktemp("warm"), 64, stage1=stage1_sides_model(light=warm))
    write_scene(work, "other", seed=3)
    mask = scene_mask(work)
    r = Relighter(RuntimeConfig(models=folder, device="cpu"))
    other = r.decompose(str(work / "other.png"), str(work / "other_mask.png"))
    own = r.decompose(str(work / "p.png"), str(work / "p_mask.png"))
    np.testing.assert_allclose(other.light[0] / other.light[0, 1], warm[0] / warm[0, 1], rtol=1e-4)  # warm still
    out = run(["relight", "p.png", "--models", folder, "--light-from", "other.png", "-o", "o.png"], capsys)
    expected = r.relight(str(work / "p.png"), other.white_light, mask=str(work / "p_mask.png"))
    assert not np.allclose(out, r.relight(str(work / "p.png"), other.light, mask=str(work / "p_mask.png")),
                           atol=0.02)
    np.testing.assert_allclose(out, expected, atol=1 / 255 + 1e-6)
    # p.png's own estimate, from the same file: p.png comes back ...
    photo = cv2.imread("p.png")[..., ::-1] / 255
    back = run(["relight", "p.png", "--models", folder, "--light-from", "p.png", "-o", "s.png"], capsys)
    np.testing.assert_allclose(back[mask >= 1], photo[mask >= 1], atol=1.5 / 255)
    # ... and so does a grey light of its luminance (the estimate's colour is not applied inversely) ...
    np.save("grey.npy", own.white_light.astype(np.float64))
    neutral = run(["relight", "p.png", "--models", folder, "--light", "grey.npy", "-o", "n.png"], capsys)
    np.testing.assert_allclose(neutral[mask >= 1], photo[mask >= 1], atol=1.5 / 255)
    # ... while a coloured light tints it
    np.save("blue.npy", ambient((0.3, 0.5, 0.9)))
    blue = run(["relight", "p.png", "--models", folder, "--light", "blue.npy", "-o", "b.png"], capsys)
    assert (blue - out)[mask >= 1][:, 2].mean() > 0.05 and (blue - out)[mask >= 1][:, 0].mean() < -0.05


def test_models_option_wins_over_environment(work, sides_dir, models_dir, capsys):
    """$RELIGHT_RT_MODELS names the plain graphs, --models the sides graphs: the output is the sides graphs'."""
    light = directional((0, 1, 0), strength=0.5)
    np.save("from_y.npy", light)
    out = run(["relight", "p.png", "--models", sides_dir, "--light", "from_y.npy", "-o", "o.png"], capsys)
    photo, mask = str(work / "p.png"), str(work / "p_mask.png")
    want = Relighter(RuntimeConfig(models=sides_dir, device="cpu")).relight(photo, light, mask=mask)
    other = Relighter(RuntimeConfig(models=models_dir, device="cpu")).relight(photo, light, mask=mask)
    np.testing.assert_allclose(out, want, atol=1 / 255 + 1e-6)
    assert np.abs(out - other).max() > 0.2


# ----------------------------------------------------------------------------------------- soft masks


def test_soft_mask_blends_proportionally(sides):
    """out = bg + (colour - bg) * alpha at every pixel, alpha the soft mask (bug: a thresholded mask)."""
    img, mask = soft_person()
    light = directional((0, 1, 0), (1.0, 0.8, 0.6), strength=0.5)
    rgba = sides.relight(img, light, mask=mask, background="transparent")
    np.testing.assert_array_equal(rgba[..., 3], mask)  # alpha IS the soft mask, not (mask > 0.5)
    soft = (mask > 0.02) & (mask < 0.98)
    assert soft.sum() > 500
    colour = rgba[..., :3]
    bg = backdrop(*mask.shape)
    # (over the original photo, what lies behind a soft edge is the photo's background colour estimated there,
    # not the photo's mixed pixel: tests/runtime/relight/test_head.py checks that the photo's own light gives the photo
    # back)
    for background, behind in ((Background.solid((1.0, 0.0, 1.0)), np.array([1.0, 0.0, 1.0], np.float32)),
                               (bg, bg)):  # fmt: skip
        out = sides.relight(img, light, mask=mask, background=background)
        want = behind + (colour - behind) * mask[..., None]  # new backdrops share the RGBA's (decontaminated) colour
        np.testing.assert_allclose(out[mask > 0], np.broadcast_to(want, out.shape)[mask > 0], atol=2e-6)
        np.testing.assert_array_equal(out[mask == 0], np.broadcast_to(behind, out.shape)[mask == 0])
    out = sides.relight(img, light, mask=mask, background="original")
    np.testing.assert_array_equal(out[mask == 0], img[mask == 0])
    white = sides.relight(img, light, mask=mask, background="white")
    black = sides.relight(img, light, mask=mask, background="black")
    np.testing.assert_allclose(white - black, np.repeat(1 - mask[..., None], 3, axis=2), atol=2e-6)


def test_transparent_png_alpha_is_the_soft_mask(work, sides_dir, capsys):
    """The CLI's RGBA output carries the soft mask file's alpha exactly, strands and feathering included."""
    out = run(["relight", "p.png", "--models", sides_dir, "--preset", "studio", "--background", "transparent",
               "-o", "o.png"], capsys)  # fmt: skip
    mask8 = cv2.imread(str(work / "p_mask.png"), cv2.IMREAD_GRAYSCALE)
    assert ((mask8 > 5) & (mask8 < 250)).sum() > 500
    np.testing.assert_array_equal((out[..., 3] * 255).round().astype(np.uint8), mask8)


# ----------------------------------------------------------------------------------------- video compositing


@pytest.mark.parametrize("premultiplied", [False, True])
@pytest.mark.parametrize("background", ["original", "black", "image"])
def test_composite_keeps_the_person_and_blends_only_where_soft(premultiplied, background):
    """Where alpha = 1 the output is the relit person exactly; where 0, the background; between, the blend
    (bug: ``person + image``, the background leaking into the person)."""
    img, mask = soft_person(seed=1)
    relit = np.clip(np.random.default_rng(2).random(img.shape), 0.05, 0.95).astype(np.float32)
    behind = {"original": img, "black": np.zeros_like(img), "image": backdrop(*mask.shape)[::-1].copy()}[background]
    bg = Background.from_image(behind, fit="exact") if background == "image" else background
    given = relit * mask[..., None] if premultiplied else relit
    out = composite(given, img, mask, bg, premultiplied=premultiplied)
    one, zero = mask == 1, mask == 0
    np.testing.assert_allclose(out[one], relit[one], atol=1e-6)
    np.testing.assert_allclose(out[zero], behind[zero], atol=1e-6)
    if background == "original":
        want = relit * mask[..., None] + behind * (1 - mask[..., None])
        np.testing.assert_allclose(out, want, atol=1e-6)
    else:  # a new backdrop: the soft edge's colour is decontaminated (issue 33), the same over any backdrop
        white = composite(given, img, mask, "white", premultiplied=premultiplied)
        np.testing.assert_allclose(white - out, (1 - behind) * (1 - mask[..., None]), atol=1e-6)


def test_engine_path_blends_only_where_soft(sides):
    """The runtime's video path (RelighterEngine): the person where alpha = 1 does not depend on the
    background; the background shows through by exactly 1 - alpha."""
    frames = []
    for i in range(2):
        img, mask = soft_person(seed=i)
        frames.append(Frame(i, f"f{i}", img, mask))
    light = LightSchedule.constant(directional((0, 1, 0), strength=0.5))
    outs = {}
    for bg in ("black", "white", "original"):
        outs[bg] = [out for _, out, _ in relight_frames(iter(frames), light, fps=25.0,
                                                        engine=RelighterEngine(sides), background=bg)]  # fmt: skip
    for i, f in enumerate(frames):
        m = f.mask[..., None]
        np.testing.assert_allclose(outs["white"][i] - outs["black"][i], np.repeat(1 - m, 3, axis=2), atol=2e-6)
        one = f.mask == 1
        np.testing.assert_allclose(outs["original"][i][one], outs["black"][i][one], atol=1e-6)
        np.testing.assert_array_equal(outs["original"][i][f.mask == 0], f.image[f.mask == 0])


# ----------------------------------------------------------------------------------------- stabiliser


def _flat(value: float, h: int = 32, w: int = 48) -> np.ndarray:
    return np.full((h, w, 3), value, np.float32)


def _layers(seed: int, h: int = 32, w: int = 48):
    rng = np.random.default_rng(seed)
    return rng.random((h, w, 3)).astype(np.float32), rng.random((h, w, 9)).astype(np.float32)


def test_stabilizer_distrusts_an_inconsistent_flow(monkeypatch):
    """Forward and backward flows that disagree (an occlusion) switch the history off there, even where the
    frames look alike (bug: the forward-backward check dropped)."""
    h, w = 32, 48
    backward = np.zeros((h, w, 2), np.float32)
    forward = np.zeros((h, w, 2), np.float32)
    forward[:, w // 2 :, 0] = 6.0  # right half: t-1 -> t says "moved 6 px", t -> t-1 says "stayed"
    flows = iter([backward, forward])
    stab = Stabilizer(strength=0.8, flow_max_side=None)
    monkeypatch.setattr(stab, "_flow", lambda src, dst: next(flows))
    a0, t0 = _layers(0)
    a1, t1 = _layers(1)
    stab.update(_flat(0.5), None, a0, t0)
    out_a, out_t = stab.update(_flat(0.5), None, a1, t1)
    left, right = np.s_[1:-1, 1 : w // 2 - 8], np.s_[:, w // 2 :]  # (the frame border warps to nothing)
    np.testing.assert_allclose(stab.last_weight[left], 0.8, atol=1e-6)  # consistent, identical frames: full trust
    np.testing.assert_array_equal(stab.last_weight[right], 0.0)
    np.testing.assert_allclose(out_a[left], 0.8 * a0[left] + 0.2 * a1[left], atol=1e-6)
    np.testing.assert_array_equal(out_a[right], a1[right])
    np.testing.assert_array_equal(out_t[right], t1[right])


def test_stabilizer_blends_only_inside_both_masks():
    """History is used only where this frame's mask and the warped previous mask hold the person (bug: either
    mask test dropped)."""
    h, w = 32, 48
    prev_mask = np.zeros((h, w), np.float32)
    prev_mask[:, : w * 3 // 4] = 1  # columns 0..35
    mask = np.zeros((h, w), np.float32)
    mask[:, w // 4 :] = 1  # columns 12..47
    stab = Stabilizer(strength=0.6, flow_max_side=None)
    a0, t0 = _layers(0)
    a1, t1 = _layers(1)
    stab.update(_flat(0.4), prev_mask, a0, t0)
    out_a, _ = stab.update(_flat(0.4), mask, a1, t1)
    both, only_now, only_before = np.s_[1:-1, 14:34], np.s_[:, 38:], np.s_[:, :10]  # (border: see above)
    np.testing.assert_allclose(stab.last_weight[both], 0.6, atol=1e-5)
    np.testing.assert_array_equal(stab.last_weight[only_now], 0.0)
    np.testing.assert_array_equal(stab.last_weight[only_before], 0.0)
    np.testing.assert_array_equal(out_a[only_now], a1[only_now])
    np.testing.assert_allclose(out_a[both], 0.6 * a0[both] + 0.4 * a1[both], atol=1e-5)


def test_smooth_light_is_an_exponential_moving_average():
    stab = Stabilizer(strength=0.75)
    rng = np.random.default_rng(0)
    base = ambient((0.5, 0.5, 0.5))
    lights = [base + rng.normal(0, 0.2, base.shape) for _ in range(60)]
    first = stab.smooth_light(lights[0])
    np.testing.assert_allclose(first, lights[0], rtol=1e-6)
    second = stab.smooth_light(lights[1])
    np.testing.assert_allclose(second, 0.75 * lights[0] + 0.25 * lights[1], rtol=1e-5, atol=1e-6)
    smoothed = [second] + [stab.smooth_light(v) for v in lights[2:]]
    raw_sd = np.std(np.stack(lights[10:]), axis=0).mean()
    smooth_sd = np.std(np.stack(smoothed[9:]), axis=0).mean()
    assert smooth_sd < 0.5 * raw_sd  # sqrt((1 - s) / (1 + s)) = 0.38 for white noise
    assert first is not stab.smooth_light(lights[0])  # a new array each time
    stab.reset()
    np.testing.assert_allclose(stab.smooth_light(lights[5]), lights[5], rtol=1e-6)  # history forgotten
    with pytest.raises(RelightError, match="light"):
        stab.smooth_light(np.full((9, 3), np.nan))


class _RecordingEngine:
    """Frames' own light flickers; records which own light the pipeline hands to render."""

    def __init__(self, own_lights):
        self.own_lights = list(own_lights)
        self.rendered: list = []

    def decompose(self, images, masks, automatic=None):
        return [
            FrameLayers(img, m, img.copy(), np.ones((*img.shape[:2], 9), np.float32), self.own_lights.pop(0))
            for img, m in zip(images, masks, strict=True)
        ]

    def render(self, layers, albedo, transport, own_light, light, background):
        self.rendered.append(None if own_light is None else np.array(own_light))
        return composite(albedo, layers.image, layers.mask, background)

    def to_input(self, layers, layer):
        return np.array(layer)


def test_video_renders_with_the_smoothed_own_light():
    """With a stabiliser, the original video's light estimate reaches render smoothed (bug: the raw one)."""
    rng = np.random.default_rng(1)
    own = [ambient((0.5, 0.5, 0.5)) + rng.normal(0, 0.2, (9, 3)) for _ in range(4)]
    img, mask = soft_person(48, 32)
    frames = [Frame(i, f"f{i}", img, mask) for i in range(4)]
    engine = _RecordingEngine(own)
    list(relight_frames(iter(frames), LightSchedule.constant(OWN_LIGHT), fps=25.0, engine=engine,
                        stabilizer=Stabilizer(strength=0.5), batch_size=2))  # fmt: skip
    want = own[0]
    np.testing.assert_allclose(engine.rendered[0], want, rtol=1e-5)
    for i in range(1, 4):
        want = 0.5 * want + 0.5 * own[i]
        np.testing.assert_allclose(engine.rendered[i], want, rtol=1e-5, atol=1e-6)


# ----------------------------------------------------------------------------------------- models refused


def test_stage1_with_a_non_finite_light_is_refused(tmp_path):
    """A stage 1 that estimates a NaN light: a RelightError naming the model (bug: the check dropped)."""
    folder = tmp_path / "nan_models"
    make_models_dir(folder, 64, stage2=False, stage1=stage1_model(64, light=np.full((9, 3), np.nan, np.float32)))
    img, mask = soft_person()
    rl = Relighter(RuntimeConfig(models=folder, device="cpu"))
    with pytest.raises(RelightError, match=r"stage1\.onnx.*(non-finite light|'light' holds NaN or Inf)"):
        rl.decompose(img, mask)
    with pytest.raises(RelightError, match="(non-finite|NaN or Inf)"):
        rl.relight(img, ambient(), mask=mask)


# ----------------------------------------------------------------------------------------- mutation survivors
# (docs/MUTATION.md: each test below kills a mutant the suite let through)


def test_decomposition_holds_float32_read_only_arrays(sides):
    img, mask = soft_person()
    dec = sides.decompose(img.astype(np.float64), mask.astype(np.float64))
    again = type(dec)(dec.albedo_chw, dec.skin, dec.transport_chw, dec.light.astype(np.float64), dec.network_mask,
                      dec.network_image, mask.astype(np.float64), img.astype(np.float64), dec.geometry)  # fmt: skip
    for d in (dec, again):
        for name in ("albedo_chw", "skin", "transport_chw", "light", "network_mask", "network_image", "mask", "image"):
            arr = getattr(d, name)
            assert arr.dtype == np.float32 and not arr.flags.writeable, name


def test_precision_picks_its_own_graph_else_fp32(tmp_path, caplog):
    """--precision fp16 runs stage1_fp16.onnx when the folder has one, else stage1.onnx (logged)."""
    folder = make_models_dir(tmp_path / "m", 64)
    save(stage1_sides_model(), folder / "stage1_fp16.onnx")
    img, mask = soft_person()
    light = directional((0, 1, 0), strength=0.5)
    plain = Relighter(RuntimeConfig(models=folder, device="cpu")).relight(img, light, mask=mask)
    fp16 = Relighter(RuntimeConfig(models=folder, device="cpu", precision="fp16")).relight(img, light, mask=mask)
    assert brighter_side(fp16, mask) == "right" and np.abs(fp16 - plain).max() > 0.2
    with caplog.at_level("WARNING"):
        int8 = Relighter(RuntimeConfig(models=folder, device="cpu", precision="int8")).relight(img, light, mask=mask)
    np.testing.assert_array_equal(int8, plain)
    assert "no stage1_int8.onnx" in caplog.text


def test_relight_layers_names_its_layers(sides):
    img, mask = soft_person()
    result = sides.layers(img, ambient(), mask=mask)
    assert set(result.layers) == {"albedo", "shading", "diffuse", "residual", "relit", "mask"}
    np.testing.assert_array_equal(result.layers["mask"], mask)


def test_lights_show_reads_bgr_files_and_checks_its_size(work, capsys):
    np.save("warm.npy", ambient(RED_HEAVY))
    rgb = run(["lights", "show", "warm.npy", "-o", "a.png"], capsys)
    bgr = run(["lights", "show", "warm.npy", "--bgr", "-o", "b.png"], capsys)
    lit = rgb[..., :3].sum(axis=2) > 0
    r, g, b = rgb[lit][:, :3].mean(axis=0)
    r2, g2, b2 = bgr[lit][:, :3].mean(axis=0)
    assert r > 1.5 * g > 2.2 * b and b2 > 1.5 * g2 > 2.2 * r2
    assert cli.main(["lights", "show", "studio", "--size", "8193", "-o", "c.png"]) == 2
    assert "--size is 8193, expected 8 to 8192" in capsys.readouterr().err
    assert cli.main(["lights", "show", "studio", "--bgr", "-o", "c.png"]) == 2
    assert "--bgr: it says how to read a light file" in capsys.readouterr().err


def test_usage_errors_name_the_command():
    """argparse's usage lines say relight-rt (not the Python file), and a command group needs its subcommand."""
    import contextlib
    import io

    for argv, usage in ((["relight"], "see relight-rt relight -h"), (["lights"], "see relight-rt lights -h")):
        err = io.StringIO()
        with contextlib.redirect_stderr(err):
            assert cli.main(argv) == 2
        assert err.getvalue().startswith("relight-rt: error: ") and usage in err.getvalue()
        assert "required" in err.getvalue()


def test_video_fits_an_image_background_and_passes_empty_frames(sides):
    """An image background of another size is fitted to every frame (once per size); a frame with nobody in it
    passes through over that background, its layers float32 zeros."""
    from relight_rt.image.compositing import fit_image

    img, mask = soft_person()
    empty = np.zeros_like(mask)
    frames = [Frame(0, "f0", img, mask), Frame(1, "f1", img, empty), Frame(2, "f2", img, mask)]
    small = backdrop(75, 50)[::-1].copy()
    bg = Background.from_image(small, fit="stretch")
    outs = list(relight_frames(iter(frames), LightSchedule.constant(ambient()), fps=25.0,
                               engine=RelighterEngine(sides), background=bg, with_layers=True))  # fmt: skip
    want = fit_image(small, mask.shape, "stretch")
    for (_, out, extras), m in zip(outs, (mask, empty, mask), strict=True):
        np.testing.assert_array_equal(out[m == 0], want[m == 0])
        assert extras["albedo"].dtype == np.float32 and extras["transport"].dtype == np.float32
    assert not outs[1][2]["transport"].any() and outs[1][2]["transport"].shape == (*mask.shape, 9)


def test_video_with_no_readable_frame_says_so(tmp_path, sides):
    from relight_rt.video.job import FrameSink, relight_video

    class Unreadable:  # a source whose frames all fail to decode
        fps, path = 25.0, tmp_path / "broken.avi"

        def __iter__(self):
            return iter(())

    sink = FrameSink(frames_dir=tmp_path / "out")
    with pytest.raises(RelightError, match=r"broken\.avi: no frames could be read"):
        relight_video(Unreadable(), LightSchedule.constant(ambient()), sink, engine=RelighterEngine(sides))
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


@pytest.mark.parametrize("channel", [0, 1, 2])
def test_stabilizer_photometric_check_sees_every_channel(monkeypatch, channel):
    """A change in any one of R, G, B where the flow says "nothing moved" lowers the history's weight there
    by exp(-(mean |difference| / tolerance)^2)."""
    h, w = 32, 48
    stab = Stabilizer(strength=0.8, photometric_tolerance=0.05, flow_max_side=None)
    monkeypatch.setattr(stab, "_flow", lambda src, dst: np.zeros((h, w, 2), np.float32))
    before, after = _flat(0.4), _flat(0.4)
    after[:, w // 2 :, channel] += 0.15  # mean |difference| over RGB: 0.05 = the tolerance
    a0, t0 = _layers(0)
    a1, t1 = _layers(1)
    stab.update(before, None, a0, t0)
    stab.update(after, None, a1, t1)
    np.testing.assert_allclose(stab.last_weight[1:-1, 1 : w // 2 - 1], 0.8, atol=1e-5)
    np.testing.assert_allclose(stab.last_weight[1:-1, w // 2 + 1 : -1], 0.8 * np.exp(-1.0), rtol=1e-4)


def test_stabilizer_returns_float32_and_strength_zero_computes_no_flow(monkeypatch):
    """Layers come back float32 whatever comes in; strength 0 turns the stabiliser off: no optical flow at all."""
    stab = Stabilizer(strength=0.0, flow_max_side=None)

    def no_flow(src, dst):
        raise AssertionError("strength 0 computed an optical flow")

    monkeypatch.setattr(stab, "_flow", no_flow)
    for seed in (0, 1):
        a, t = _layers(seed)
        out_a, out_t = stab.update(_flat(0.5), None, a.astype(np.float64), t.astype(np.float64))
        assert out_a.dtype == np.float32 and out_t.dtype == np.float32
        np.testing.assert_array_equal(out_a, a)
        np.testing.assert_array_equal(out_t, t)


def test_light_schedules_name_the_bad_light():
    for make in (LightSchedule.constant, lambda v: LightSchedule.rotating(v, 1.0)):
        with pytest.raises(RelightError, match=r"^light: expected an SH light of shape \(9, 3\)"):
            make(np.zeros((4, 3)))


def test_quiet_and_verbose_set_the_log_level(work, sides_dir):
    """A fresh process (logging is configured once per process): INFO by default, -q warnings only."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(root), os.environ.get("PYTHONPATH", "")]))
    base = [sys.executable, "-m", "relight_rt"]
    args = ["relight", "p.png", "--models", str(sides_dir), "--preset", "studio", "--device", "cpu"]
    loud = subprocess.run([*base, *args, "-o", "a.png"], env=env, capture_output=True, text=True, timeout=120)
    quiet = subprocess.run([*base, "-q", *args, "-o", "b.png"], env=env, capture_output=True, text=True, timeout=120)
    assert loud.returncode == 0 and quiet.returncode == 0, loud.stderr + quiet.stderr
    assert "p.png -> a.png" in loud.stderr
    assert quiet.stderr == ""
