"""relight_rt.apps.panorama: a panorama used exactly (the plate, the light in the view's frame, composite --view)."""

import math
import re

import cv2
import numpy as np
import pytest
from _cli import in_folder, run
from _graphs import diffuse_models_dir, models_dir, write_person

from relight_rt import Relighter, RelightError, RuntimeConfig, envmap, sh
from relight_rt.apps.panorama import (
    METER_GREY,
    composite_panorama,
    panorama_view,
    parse_size,
    parse_view,
    plate_blur,
    render_view,
    round_sources,
    source,
    view_rotation,
)
from relight_rt.image.color import REC709, srgb_to_linear
from relight_rt.light.from_background import envmap_view

__all__ = ["diffuse_models_dir", "models_dir"]  # fixtures

PANORAMAS = ("sunset", "apartment", "city")  # a low sun, an interior with windows, a street under the sky


@pytest.fixture(scope="module")
def hdri(shared_dir):
    folder = shared_dir / "hdri"
    if not (folder / "city.hdr").is_file():
        pytest.skip("../shared/hdri is not present")
    return folder


def lumpy_panorama(h=64):
    """A smooth map with a bright spot to the right of the view's centre (azimuth +40°, elevation 20°)."""
    d = envmap.directions_envmap(h)
    spot = np.array([-math.cos(math.radians(20)) * math.cos(math.radians(40)),
                     math.cos(math.radians(20)) * math.sin(math.radians(40)), math.sin(math.radians(20))])  # fmt: skip
    env = 0.2 + 0.1 * d[..., 2:3] + 20 * np.exp((d @ spot - 1) / 0.01)[..., None] * np.array([1.0, 0.8, 0.6])
    return env.astype(np.float32), spot


def rotated_map(env, rotation, height=128):
    """The map seen from the camera frame by resampling pixels (independent of the SH rotation): pixel ω_c of the
    new map shows the panorama at R · ω_c. Area-resized first so that bilinear look-up integrates well."""
    small = cv2.resize(env, (2 * 2 * height, 2 * height), interpolation=cv2.INTER_AREA)
    d = envmap.directions_envmap(height) @ np.asarray(rotation).T
    theta = np.arccos(np.clip(d[..., 2], -1, 1))
    phi = np.mod(np.arctan2(-d[..., 1], d[..., 0]), 2 * np.pi)
    eh, ew = small.shape[:2]
    padded = np.concatenate([small[:, -1:], small, small[:, :1]], axis=1)
    mapx = (phi / (2 * np.pi) * ew + 0.5).astype(np.float32)
    mapy = np.clip(theta / np.pi * eh - 0.5, 0, eh - 1).astype(np.float32)
    return cv2.remap(padded, mapx, mapy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)


def irradiance_error(light, truth) -> float:
    """RMS over all normals of the luminance irradiance difference, over the RMS of the truth's irradiance."""
    n = sh.sphere_directions(2000)
    a, b = sh.irradiance(light, n) @ REC709, sh.irradiance(truth, n) @ REC709
    return float(np.sqrt(np.mean((a - b) ** 2)) / np.sqrt(np.mean(b**2)))


# ------------------------------------------------------------------------------------------------ the view


@pytest.mark.parametrize("value, expected", [("30,0", (30, 0, 60)), ("-90, 10, 75", (-90, 10, 75)),
                                             ((370, -5), (10, -5, 60)), ("180,0", (180, 0, 60)),
                                             ("-180,0", (180, 0, 60))])  # fmt: skip
def test_parse_view(value, expected):
    assert parse_view(value) == pytest.approx(expected)


@pytest.mark.parametrize("value", ["30", "a,b", "0,95", "0,-81", "0,0,200", "0,0,5", "nan,0", "1,2,3,4", "", 5, None])
def test_bad_views_get_one_clear_error(value):
    with pytest.raises(RelightError, match=r"^view: .*(AZIMUTH,ELEVATION|elevation|field of view)"):
        parse_view(value)


@pytest.mark.parametrize("value, match", [("640x480", (640, 480)), ((128, 96), (128, 96))])
def test_parse_size(value, match):
    assert parse_size(value) == match


@pytest.mark.parametrize("value", ["640", "32x480", "640x-1", "axb", (64.5, 64), (True, 64), "100000x100000"])
def test_bad_sizes(value):
    with pytest.raises(RelightError, match="^size: (expected WxH|image is 100000x100000.*more than the limit)"):
        parse_size(value)


def test_view_rotation_points_the_camera_where_asked():
    forward = np.array([-1.0, 0, 0])
    np.testing.assert_allclose(view_rotation(90, 0) @ forward, [0, 1, 0], atol=1e-12)  # right = +y
    np.testing.assert_allclose(view_rotation(0, 30) @ forward, [-math.cos(math.pi / 6), 0, 0.5], atol=1e-12)
    r = view_rotation(-37, 12)
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(r) == pytest.approx(1)


def test_the_plate_is_oriented_as_envmap_view():
    env, _ = lumpy_panorama(64)
    env = env + np.linspace(0, 1, 128, dtype=np.float32)[None, :, None]  # columns told apart
    np.testing.assert_allclose(render_view(env, (48, 64), 0, 0, 60), envmap_view(env, (48, 64), 60), rtol=1e-4)
    # looking 90° to the right shows what envmap_view shows of the map turned so that that column is its centre
    turned = np.roll(env, -env.shape[1] // 4, axis=1)
    np.testing.assert_allclose(render_view(env, (48, 64), 90, 0, 60), envmap_view(turned, (48, 64), 60), rtol=1e-4)
    np.testing.assert_allclose(render_view(env, (48, 64), -180, 0, 60), render_view(env, (48, 64), 180, 0, 60),
                               atol=1e-5)  # fmt: skip


def test_the_spot_appears_where_the_view_puts_it():
    env, _ = lumpy_panorama(128)
    right = render_view(env, (60, 80), 0, 0, 120) @ REC709  # the spot 40° right, 20° up: upper right
    i, j = np.unravel_index(int(np.argmax(right)), right.shape)
    assert j > 40 and i < 30
    centred = render_view(env, (61, 81), 40, 20, 60) @ REC709  # looking at it: the centre
    i, j = np.unravel_index(int(np.argmax(centred)), centred.shape)
    assert abs(i - 30) <= 1 and abs(j - 40) <= 1


def test_the_plate_is_the_metered_view_and_the_light_is_in_its_units():
    env, spot = lumpy_panorama(64)
    pv = panorama_view(env, (96, 72), "0,0,70")
    linear = render_view(env, (72, 96), 0, 0, 70)
    assert pv.plate.shape == (72, 96, 3) and pv.plate.dtype == np.uint8
    assert pv.exposure == pytest.approx(METER_GREY / float((linear @ REC709).mean()), rel=1e-5)
    # the metered view, its map pixels brighter than white drawn round (round_sources)
    rounded = round_sources(linear, env, 1 / pv.exposure, view_rotation(0, 0), 70)
    np.testing.assert_allclose(srgb_to_linear(pv.plate), np.clip(rounded * pv.exposure, 0, 1), atol=0.01)
    assert np.abs(rounded - linear).max() * pv.exposure > 0.01  # the spot is brighter than white: it was redrawn
    far = np.abs(rounded - linear).max(axis=2) == 0  # elsewhere the plate is the view as it is
    assert far.mean() > 0.8
    np.testing.assert_allclose(srgb_to_linear(pv.plate)[far], np.clip(linear * pv.exposure, 0, 1)[far], atol=0.01)
    # a uniform panorama: a white surface gets shading equal to the plate's value
    flat = panorama_view(np.full((32, 64, 3), 3.0, np.float32), (64, 64), (0, 0))
    shading = sh.irradiance(flat.light, np.array([[1.0, 0, 0]]))[0]
    np.testing.assert_allclose(shading, srgb_to_linear(flat.plate)[32, 32], rtol=0.02)
    # the spot (40° right of the view, 20° up): the light comes from the right and above, from behind the person
    d, _ = sh.dominant_direction(pv.light @ REC709)
    assert d[1] > 0.3 and d[2] > 0.1 and d[0] < 0


@pytest.mark.parametrize("name", PANORAMAS)
@pytest.mark.parametrize("view", [(0, 0, 60), (135, 10, 75), (-60, -15, 50)])
def test_the_light_is_the_panoramas_in_the_views_frame(hdri, name, view):
    """The light equals the panorama resampled into the camera's frame and projected (irradiance error <= 2 %)."""
    env = envmap.load_envmap(hdri / f"{name}.hdr")
    pv = panorama_view(env, (96, 64), view)
    truth = envmap.project_envmap(rotated_map(env, view_rotation(*view[:2]))) * (pv.exposure / math.pi)
    assert irradiance_error(pv.light, truth) <= 0.02
    other = envmap.project_envmap(rotated_map(env, view_rotation(view[0] + 90, view[1]))) * (pv.exposure / math.pi)
    assert irradiance_error(other, truth) > 0.05  # the test can tell a view turned by 90°


@pytest.mark.parametrize(("height", "width", "fov"), [(32, 320, 60), (64, 320, 60), (32, 240, 90)])
def test_the_plate_blur_is_half_the_plate_pixels_of_a_map_pixel(height, width, fov):
    """A sharp meridian (a step in azimuth, area-averaged into the map's pixels as a map's camera records it) seen in
    the plate: the rms over 8 sub-pixel places of the edge of its profile's σ is ``plate_blur`` (within 3 %)."""
    variances = []
    for offset in (np.arange(8) + 0.5) / 8:
        cols = np.arange(2 * height) - height + 0.5  # a map column's centre, map pixels from the view's axis
        share = np.clip(cols + 0.5 - offset, 0, 1)  # of the column lying right of the edge (the edge at offset)
        env = np.repeat((0.1 + 0.9 * share[::-1])[None, :, None], height, 0)  # azimuth runs right to left
        env = np.repeat(env, 3, 2).astype(np.float32)
        row = render_view(env, (9, width), 0, 0, fov)[4, :, 0]
        t = np.diff((row - 0.1) / 0.9)  # the edge's profile as a density over the plate's columns
        c = np.arange(width - 1) + 0.5
        mean = float(t @ c / t.sum())
        variances.append(float(t @ (c - mean) ** 2 / t.sum()))
    assert math.sqrt(np.mean(variances)) == pytest.approx(plate_blur(height, width, fov), rel=0.03)
    assert plate_blur(2 * height, width, fov) == pytest.approx(plate_blur(height, width, fov) / 2)


@pytest.mark.parametrize(("args", "match"), [((0, 320, 60), "map height"), ((32, 2.5, 60), "view width"),
                                             ((32, 320, 180), "field of view")])  # fmt: skip
def test_bad_plate_blur_arguments(args, match):
    with pytest.raises(RelightError, match=match):
        plate_blur(*args)


def test_bad_round_sources_arguments():
    env, white = one_sun()
    view = render_view(env, (30, 40), 0, 0, 60)
    rot = view_rotation(0, 0)
    bad = [((view, env, 0.0, rot, 60), "white"), ((view, env, float("nan"), rot, 60), "white"),
           ((view[..., 0], env, white, rot, 60), "view"), ((view, env, white, rot[:2], 60), "rotation"),
           ((view, env[:, :40], white, rot, 60), "panorama"), ((view, env, white, rot, 5), "field")]  # fmt: skip
    for args, match in bad:
        with pytest.raises(RelightError, match=match):
            round_sources(*args)


def test_round_sources_hostile_maps_and_views():
    """fuzz7: an Inf in the map (a half-float file's 1e30) is one RelightError, not an OverflowError from the
    Gaussian's endless reach; a nested list is taken as the view it spells."""
    env, white = one_sun()
    rot = view_rotation(0, 0)
    view = render_view(env, (30, 40), 0, 0, 60)
    env[16, 32] = np.inf
    with pytest.raises(RelightError, match="NaN or Inf"):
        round_sources(view, env, white, rot, 60)
    env, white = one_sun()
    out = round_sources(view.tolist(), env, white, rot, 60)
    assert out.shape == view.shape and np.isfinite(out).all()


def test_a_panorama_of_subnormal_values_is_one_clear_error():
    """fuzz7: a map of float64 5e-324 everywhere has a view to meter, but its exposure (k / peak) overflows to
    Inf; one RelightError rather than a PanoramaView with an infinite exposure. 1e-300 is still exposed."""
    with pytest.raises(RelightError, match="too small"):
        panorama_view(np.full((8, 16, 3), 5e-324), (64, 64), "0,0")
    pv = panorama_view(np.full((8, 16, 3), 1e-300), (64, 64), "0,0")
    assert math.isfinite(pv.exposure) and np.isfinite(pv.light).all()


def one_sun(h=32, excess=1000.0, where=(0, 0)):
    """(map, white): a grey map (0.2) with one pixel ``excess`` × white brighter, near azimuth / elevation
    ``where`` (degrees from the view's axis), white = 1."""
    env = np.full((h, 2 * h, 3), 0.2, np.float32)
    az, el = where
    i = int((90 - el) / 180 * h)
    j = int((0.5 + az / 360) * 2 * h) % (2 * h)  # the map's centre column is the view's axis, its right the image's
    env[i, j] += excess
    return env, 1.0


def test_a_bright_pixel_is_drawn_round_with_its_power():
    """A one-pixel sun 1000 x brighter than white: bilinear look-up clips it as a square (its clipped box is
    filled), round_sources as a disc (the box filled about π/4) of the same size in every direction; its power on
    the plate is kept (within 3 %); a map with nothing over white is left as it is."""
    env, white = one_sun()
    rot = view_rotation(0, 0)
    size = (120, 160)
    linear = render_view(env, size, 0, 0, 60)
    rounded = round_sources(linear, env, white, rot, 60)

    def clipped_box(img):
        ys, xs = np.nonzero(img.max(axis=2) > white)
        box = (ys.max() - ys.min() + 1) * (xs.max() - xs.min() + 1)
        return len(ys) / box, (ys.max() - ys.min() + 1) / (xs.max() - xs.min() + 1)

    square_fill, _ = clipped_box(linear)
    round_fill, aspect = clipped_box(rounded)
    assert square_fill > 0.9 and 0.7 < round_fill < 0.86 and aspect == pytest.approx(1, abs=0.12)
    # the power: the added radiance times each plate pixel's solid angle, against the bilinear look-up's
    focal = 80 / math.tan(math.radians(30))
    yy, xx = np.mgrid[:120, :160]
    d_omega = 1 / (focal**2 * (1 + ((xx + 0.5 - 80) ** 2 + (yy + 0.5 - 60) ** 2) / focal**2) ** 1.5)
    base = render_view(np.full_like(env, 0.2), size, 0, 0, 60)
    power = lambda img: float(((img - base)[..., 0] * d_omega).sum())  # noqa: E731
    assert power(rounded) == pytest.approx(power(linear), rel=0.03)
    dull = np.full((32, 64, 3), 0.5, np.float32)
    flat = render_view(dull, size, 0, 0, 60)
    assert round_sources(flat, dull, 1.0, rot, 60) is flat
    wide = env.copy()
    wide[12:21, 20:28] += 5.0  # 72 map pixels over white in one region at the frame's left: a bright area
    seen = render_view(wide, size, 0, 0, 60)
    kept = round_sources(seen, wide, white, rot, 60)
    assert seen[:, :20].max() > 2 * white  # the area is in the frame ...
    np.testing.assert_array_equal(kept[:, :30], seen[:, :30])  # ... and its own outline is kept
    assert np.abs(kept - seen).max() > 1  # the sun, a region of its own, is still drawn round


def test_round_sources_is_the_gaussian_drawn_everywhere():
    """Against a brute-force drawing (every plate pixel, every hot pixel, the excess's bilinear part from
    envmap_view): equal within 1 % of white, for three hot pixels of a turned view."""
    env, white = one_sun(32, 50.0, (10, 5))
    env[10, 20] += 3.0
    env[14, 40] += 20.0
    view = (25, 8, 70)
    rot = view_rotation(*view[:2])
    size = (90, 120)
    linear = render_view(env, size, *view)
    excess = np.maximum(env - white, 0)
    expect = linear - envmap_view(excess, size, view[2], rot)
    ys, xs = np.nonzero(excess.max(axis=2) > 0)
    dirs = envmap.directions_envmap(32)[ys, xs] @ rot
    power = excess[ys, xs] * envmap.solid_angles_envmap(32)[ys, xs][:, None]
    focal = 60 / math.tan(math.radians(35))
    yy, xx = np.mgrid[:90, :120]
    rays = np.stack([-np.ones(xx.shape), (xx + 0.5 - 60) / focal, (45 - yy - 0.5) / focal], -1)
    rays /= np.linalg.norm(rays, axis=-1, keepdims=True)
    sigma = math.pi / 64
    angle = np.arccos(np.clip(rays @ dirs.T, -1, 1))
    expect = expect + np.exp(-(angle**2) / (2 * sigma**2)) / (2 * math.pi * sigma**2) @ power
    np.testing.assert_allclose(round_sources(linear, env, white, rot, view[2]), np.maximum(expect, 0),
                               atol=0.01 * white)  # fmt: skip


# ------------------------------------------------------------------------------------------------ composite


@pytest.fixture(scope="module")
def diffuse(diffuse_models_dir):
    return Relighter(RuntimeConfig(models=diffuse_models_dir, device="cpu", detail=False))


def flat_person(h=150, w=100):
    img = np.full((h, w, 3), 128, np.uint8)
    mask = np.zeros((h, w), np.float32)
    mask[20:140, 30:70] = 1.0
    return img, mask


@pytest.mark.parametrize("name", PANORAMAS)
def test_composite_lights_the_person_with_the_panoramas_light(hdri, diffuse, monkeypatch, name):
    seen = []
    relight = diffuse.relight

    def spy(dec, light, *args, **kwargs):
        seen.append(np.array(light, np.float64))
        return relight(dec, light, *args, **kwargs)

    monkeypatch.setattr(diffuse, "relight", spy)
    img, mask = flat_person()
    view = (30, 5, 70)
    out = composite_panorama(diffuse, img, hdri / f"{name}.hdr", view, mask=mask, meter="background")
    assert out.shape == (150, 100, 3)
    env = envmap.load_envmap(hdri / f"{name}.hdr")
    pv = panorama_view(env, (100, 150), view)
    truth = envmap.project_envmap(rotated_map(env, view_rotation(*view[:2]))) * (pv.exposure / math.pi)
    assert len(seen) == 1 and irradiance_error(seen[0], truth) <= 0.02
    np.testing.assert_allclose(out[:10, :10], pv.plate[:10, :10] / 255, atol=2 / 255)  # the plate, away from the person
    seen.clear()
    composite_panorama(diffuse, img, env, view, mask=mask, exposure=1.0, size="120x90", meter="background")
    wide = panorama_view(env, (120, 90), view).light  # another size: another view, metered again
    np.testing.assert_allclose(seen[0], 2 * wide, rtol=1e-4, atol=1e-6)  # EV +1 doubles it


def test_a_full_body_is_blurred_to_the_plates_own_blur(diffuse, monkeypatch):
    """A 512 x 256 map seen 60° wide on 640 pixels blurs the plate by σ ≈ 3.4 px (``plate_blur``), more than the
    plate's sharpest part measures (the bilinear ramps of a magnified map read as ~1.5 px): a full body is blurred
    to it (before, a sharp figure stood on a soft plate); a half body is not."""
    import relight_rt.apps.scene as scene

    seen = []
    match = scene.camera_match

    def spy(bg, placed, known_blur=0.0):
        seen.append(known_blur)
        return match(bg, placed, known_blur)

    monkeypatch.setattr(scene, "camera_match", spy)
    img, mask = flat_person()
    env, _ = lumpy_panorama(64)
    composite_panorama(diffuse, img, env, (0, 0, 60), mask=mask, size=(200, 150), meter="background")
    assert seen == [pytest.approx(plate_blur(64, 200, 60))] and seen[0] > 2
    seen.clear()
    half = mask.copy()
    half[100:] = half[99]
    composite_panorama(diffuse, img, env, (0, 0, 60), mask=half, size=(200, 150), meter="background")
    assert seen == [0.0]
    seen.clear()
    composite_panorama(diffuse, img, env, (0, 0, 60), mask=mask, size=(200, 150), match_camera=False)
    assert seen == []


def test_the_panorama_composite_reads_the_photo_once_and_estimates_no_light(diffuse_models_dir, tmp_path,
                                                                            monkeypatch):
    """Review: composite_panorama decoded the person photo just for its size, and scene.composite estimated the
    plate's light (relight_rt.light.from_background) though the panorama gives it."""
    import relight_rt.apps.scene as scene
    import relight_rt.image.io as io

    img, mask = flat_person()
    path = tmp_path / "person.png"
    cv2.imwrite(str(path), img[..., ::-1])
    r = Relighter(RuntimeConfig(models=diffuse_models_dir, device="cpu", detail=False),
                  matter=lambda rgb, name="image": mask)  # fmt: skip
    env, _ = lumpy_panorama(64)
    calls = []
    decode = io.decode_file
    monkeypatch.setattr(io, "decode_file", lambda *a, **k: calls.append(a[0]) or decode(*a, **k))
    monkeypatch.setattr(scene, "scene_light", lambda *a, **k: pytest.fail("the scene light was estimated"))
    out = composite_panorama(r, path, env, (10, 0), meter="background")
    assert calls == [path] and out.shape == (150, 100, 3)
    monkeypatch.undo()
    np.testing.assert_array_equal(out, composite_panorama(r, img, env, (10, 0), mask=mask, meter="background"))


# ------------------------------------------------------------------------------------------------ CLI


@pytest.fixture
def work(tmp_path, models_dir, monkeypatch):
    in_folder(tmp_path, models_dir, monkeypatch)
    write_person(tmp_path, seed=1)
    env, _ = lumpy_panorama(64)
    cv2.imwrite("pano.hdr", env[..., ::-1])
    cv2.imwrite("wide.hdr", np.ones((64, 96, 3), np.float32))
    return tmp_path


def test_cli_composite_with_a_view(work, capsys):
    code, _, err = run(["composite", "p.png", "--background", "pano.hdr", "--view", "40,5", "-o", "out.png"], capsys)
    assert code == 0, err
    assert cv2.imread("out.png").shape == (150, 100, 3)
    argv = ["composite", "p.png", "--background", "pano.hdr", "--view=-20,0,80", "--size", "160x96", "-o", "o.jpg",
            "--no-shadow", "--meter", "background", "--rim"]  # fmt: skip
    code, _, err = run(argv, capsys)
    assert code == 0, err
    assert cv2.imread("o.jpg").shape == (96, 160, 3)
    argv = ["composite", "p.png", "--background", "pano.hdr", "--view", "20,0", "--no-shadow", "--meter", "background"]
    for out, extra in (("on.png", []), ("rim.png", ["--rim"]), ("off.png", ["--no-rim"])):
        code, _, err = run([*argv, "-o", out, *extra], capsys)
        assert code == 0, err
    on, off = cv2.imread("on.png").astype(int), cv2.imread("off.png").astype(int)
    assert (on == cv2.imread("rim.png").astype(int)).all() and np.abs(on - off).max() > 2  # on by default with --view


@pytest.mark.parametrize(
    "extra, match",
    [
        (["--background", "pano.hdr"], r"holds radiance, not a photo.*--view AZIMUTH,ELEVATION"),
        (["--background", "pano.hdr", "--view", "10"], r"view: expected AZIMUTH,ELEVATION"),
        (["--background", "pano.hdr", "--view", "0,90"], r"view: elevation"),
        (["--background", "pano.hdr", "--view", "0,0,180"], r"view: field of view"),
        (["--background", "wide.hdr", "--view", "0,0"], r"not an equirectangular panorama"),
        (["--background", "pano.hdr", "--view", "0,0", "--preset", "studio"], r"drop --preset"),
        (["--background", "pano.hdr", "--view", "0,0", "--fov", "50"], r"drop --fov"),
        (["--background", "pano.hdr", "--view", "0,0", "--size", "10x10"], r"size: expected WxH"),
        (["--background", "p.png", "--size", "100x100"], r"--size: only with --view"),
        (["--background", "pano.hdr", "--view", "0,0", "--camera-height", "-1"], r"camera height: expected metres"),
    ],
)
def test_cli_view_errors(work, capsys, extra, match):
    code, _, err = run(["composite", "p.png", *extra, "-o", "out.png"], capsys)
    assert code == 2 and err.startswith("relight-rt: error:") and len(err.strip().splitlines()) == 1, err
    assert re.search(match, err), err
    assert not (work / "out.png").exists()


def test_an_hdr_background_photo_says_what_to_do(work):
    from relight_rt.light.from_background import read_background

    with pytest.raises(RelightError, match="holds radiance, not a photo.*composite --view"):
        read_background(work / "pano.hdr")


def test_the_source_is_the_bright_spot():
    env, spot = lumpy_panorama(128)
    direction, power = source(env)
    assert math.degrees(math.acos(min(1.0, float(direction @ spot)))) < 2
    d = envmap.directions_envmap(128)
    only_spot = (20 * np.exp((d @ spot - 1) / 0.01)[..., None] * np.array([1.0, 0.8, 0.6]))
    total = (only_spot * envmap.solid_angles_envmap(128)[..., None]).reshape(-1, 3).sum(0)
    assert 0.4 * total[0] < power[0] < total[0]  # the core of the spot (>= half the peak), not the sky
    np.testing.assert_allclose(power / power[0], [1.0, 0.8, 0.6], rtol=0.05)
    pv = panorama_view(env, (96, 72), (40, 20))  # looking straight at it: behind the person, along −x
    np.testing.assert_allclose(pv.source_direction, [-1, 0, 0], atol=0.03)


def test_a_sun_in_frame_puts_a_rim_on_its_side(diffuse):
    """The spot 40° right of the map's centre, 20° up, seen from azimuth 20: behind the person, to the right."""
    img, mask = flat_person()
    env, _ = lumpy_panorama(128)
    pv = panorama_view(env, (100, 150), (20, 0))
    assert pv.source_direction[0] < -0.8 and pv.source_direction[1] > 0.2
    kw = {"mask": mask, "meter": "background", "match_camera": False, "light_wrap": False, "shadow": False,
          "position": (0.5, 0.95), "height": 0.8}  # fmt: skip
    plain = composite_panorama(diffuse, img, env, (20, 0), rim=False, **kw)
    rim = composite_panorama(diffuse, img, env, (20, 0), **kw)  # on by default: the panorama holds the source
    gain = (srgb_to_linear(rim) @ REC709) / np.maximum(srgb_to_linear(plain) @ REC709, 1e-6)
    body = np.s_[60:110]  # rows between the head's top (lit too: the spot is 34° up) and the feet
    cols = np.flatnonzero(gain[body].max(0) > 1.08)  # linear: + the rim's radiance · facing · band
    assert cols.size and cols.min() > 50  # brightened: the right side of the outline (the person spans 31-69)
    assert np.abs(rim[body][:, :45] - plain[body][:, :45]).max() < 1e-6  # the left side as it was


def test_an_hdr_array_as_a_background_says_what_to_do():
    from relight_rt.light.from_background import read_background

    with pytest.raises(RelightError, match=r"values up to 7.*HDR image.*relight_rt.apps.panorama"):
        read_background(np.full((64, 64, 3), 7.0, np.float32))
    with pytest.raises(RelightError, match=r"expected finite float values in \[0, 1\]$"):
        read_background(np.full((64, 64, 3), -2.0, np.float32))


# issue 50, round 4 fuzz (benchmarks/fuzz_round5.py): a panorama of any finite scale, and clear errors for the rest


@pytest.mark.parametrize("scale", [3e38 / 20, 1e-38])
def test_a_panorama_of_any_finite_scale_gives_the_same_view(scale, recwarn):
    env, _ = lumpy_panorama(32)
    ref = panorama_view(env, (96, 64), (0, 0))
    pv = panorama_view((env.astype(np.float64) * scale / env.max()).astype(np.float32), (96, 64), (0, 0))
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]
    assert np.abs(pv.plate.astype(int) - ref.plate).max() <= 1
    np.testing.assert_allclose(pv.light, ref.light, rtol=1e-4, atol=1e-7)
    np.testing.assert_allclose(pv.source_shading, ref.source_shading, rtol=1e-4)
    assert pv.exposure == pytest.approx(ref.exposure * env.max() / scale, rel=1e-4)


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_nan_or_inf_pixels_say_so(bad):
    env, _ = lumpy_panorama(32)
    env[:] = bad
    with pytest.raises(RelightError, match="NaN or Inf"):
        panorama_view(env, (96, 64), (0, 0))


def test_a_black_view_names_azimuth_0_not_minus_0():
    with pytest.raises(RelightError, match=r"view 0,0 is black"):
        panorama_view(np.zeros((32, 64, 3), np.float32), (96, 64), (0, 0))


@pytest.mark.parametrize("bad", [{"height": math.nan}, {"height": 2.0}, {"horizon": math.inf}, {"horizon": -0.5},
                                 {"position": (0.5, math.nan)}, {"camera_height": 0.0}, {"meter": "spot"}])  # fmt: skip
def test_a_bad_placement_is_refused_before_the_view_is_made(monkeypatch, bad):
    """Round 6: composite_panorama's height, horizon, position, camera height and meter were checked only after
    the person's matte and the panorama's view had been made (seconds on a large photo and panorama)."""
    import relight_rt.apps.panorama as panorama
    import relight_rt.apps.scene as scene

    def too_late(*args, **kwargs):
        raise AssertionError("the work began before the check")

    monkeypatch.setattr(panorama, "panorama_view", too_late)
    monkeypatch.setattr(scene, "matte_on_the_photo", too_late)
    img, mask = flat_person(96, 64)
    with pytest.raises(RelightError, match=r"^(height|horizon|position|camera height|meter): "):
        composite_panorama(None, img, lumpy_panorama(16)[0], (0, 0), mask=mask, **bad)
