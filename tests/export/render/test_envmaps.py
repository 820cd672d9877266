"""export.render.envmaps and the `lights` command: procedural maps, scale, rotation, files."""

from __future__ import annotations

import math

import numpy as np
import pytest

from export import dataset
from export.__main__ import main
from export.render import envmaps
from export.render.lights_cli import environment, list_environments, load_environment
from relight_rt import RelightError
from relight_rt.light.envmap import load_envmap, project_envmap
from relight_rt.light.sh import rotate_z


@pytest.mark.parametrize("kind", envmaps.KINDS)
def test_kinds_are_valid_and_normalised(kind):
    env = envmaps.procedural_envmap(kind, np.random.default_rng(1), height=20, target=1.3)
    assert env.shape == (20, 40, 3) and env.dtype == np.float32
    assert np.isfinite(env).all() and env.min() >= 0
    assert envmaps.max_irradiance(project_envmap(env)) == pytest.approx(1.3, rel=1e-4)


@pytest.mark.parametrize("kind", ["sun_sky", "overcast"])
def test_skies_light_from_above(kind):
    for seed in range(3):
        light = project_envmap(envmaps.procedural_envmap(kind, np.random.default_rng(seed), height=16))
        assert (light[2] > 0).all()  # coefficient 2 ∝ z: more light from above than from below


def test_default_scale_is_in_the_reference_range():
    rng = np.random.default_rng(0)
    peaks = [envmaps.max_irradiance(project_envmap(envmaps.procedural_envmap(k, rng, 16))) for k in envmaps.KINDS * 3]
    assert envmaps.TARGET_RANGE[0] - 1e-6 <= min(peaks) and max(peaks) <= envmaps.TARGET_RANGE[1] + 1e-6


def test_same_seed_same_map():
    a = envmaps.procedural_envmap("window", np.random.default_rng(7), 16)
    b = envmaps.procedural_envmap("window", np.random.default_rng(7), 16)
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("steps", [1, 3, 7])
def test_rotation_matches_sh_rotate_z(steps):
    """Turning the map by whole columns is the same rotation as relight_rt.sh.rotate_z (+x toward +y)."""
    env = envmaps.procedural_envmap("softbox", np.random.default_rng(3), height=20)
    turned = project_envmap(envmaps.rotate_envmap(env, steps, 10))
    expected = rotate_z(project_envmap(env), 2 * math.pi * steps / 10)
    np.testing.assert_allclose(turned, expected, atol=1e-5 * np.abs(expected).max())
    np.testing.assert_array_equal(envmaps.rotate_envmap(env, 10, 10), env)


def test_rotation_needs_whole_columns():
    with pytest.raises(RelightError, match="divisible"):
        envmaps.rotate_envmap(np.zeros((16, 32, 3), np.float32), 1, 10)


def test_bad_kind_and_dark_map():
    with pytest.raises(RelightError, match="expected one of"):
        envmaps.procedural_envmap("disco", np.random.default_rng(0))
    with pytest.raises(RelightError, match="no positive irradiance"):
        envmaps.normalize_envmap(np.zeros((8, 16, 3), np.float32))


def test_hdr_round_trip(tmp_path):
    env = envmaps.procedural_envmap("lamps", np.random.default_rng(2), height=16)
    envmaps.write_hdr(tmp_path / "a.hdr", env)
    back = load_envmap(tmp_path / "a.hdr")
    np.testing.assert_allclose(back, env, rtol=2e-2, atol=1e-3 * env.max())  # RGBE keeps ~8 bits of mantissa


def test_lights_command(tmp_path):
    out = tmp_path / "lights"
    assert main(["lights", "--out", str(out), "--n", "3", "--height", "10", "--rotations", "10"]) == 0
    lights = dataset.read_lights(out)
    assert lights.shape == (30, 9, 3)
    names = list_environments(out)
    assert len(names) == 30 and names[0] == "env0000_sun_sky_r00"
    # the light file is the SH of the (rotated) map that render-photos will use
    for name in (names[0], names[4]):
        proj = project_envmap(environment(out, name))
        np.testing.assert_allclose(proj, dataset.read_light(out, name), rtol=0.03, atol=0.01)
    assert (out / "hdr" / "env0001_overcast.hdr").is_file()


def test_lights_from_real_hdr_folder(tmp_path):
    src = tmp_path / "maps"
    src.mkdir()
    for i in range(2):
        envmaps.write_hdr(src / f"m{i}.hdr", 5.0 * envmaps.procedural_envmap("window", np.random.default_rng(i), 20))
    out = tmp_path / "lights"
    assert main(["lights", "--out", str(out), "--hdr", str(src), "--height", "10", "--rotations", "2"]) == 0
    assert sorted(dataset.list_lights(out)) == ["m0_r00", "m0_r01", "m1_r00", "m1_r01"]
    peak = envmaps.max_irradiance(dataset.read_light(out, "m0_r00"))
    assert envmaps.TARGET_RANGE[0] * 0.97 <= peak <= envmaps.TARGET_RANGE[1] * 1.03  # rescaled
    assert load_environment(src, "m1.hdr", height=10).shape == (10, 20, 3)  # a plain folder of maps works too
    assert main(["lights", "--out", str(out), "--hdr", str(tmp_path / "none")]) == 2


def _cast(light: np.ndarray) -> np.ndarray:
    """Chromaticity of a light's average radiance (coefficient 0), summing to 1."""
    return light[0] / light[0].sum()


def test_white_balance_removes_that_fraction_of_the_cast_and_keeps_luminance():
    env = envmaps.procedural_envmap("lamps", np.random.default_rng(3), height=16) * np.array([1.6, 1.0, 0.5])
    dc = project_envmap(env)[0]
    rec709 = np.array([0.2126, 0.7152, 0.0722])
    full = project_envmap(envmaps.white_balance(env, 1.0))[0]
    np.testing.assert_allclose(full / full.mean(), 1.0, atol=1e-4)  # neutral on average
    half = project_envmap(envmaps.white_balance(env, 0.5))[0]
    np.testing.assert_allclose(np.log(half / half.mean()), 0.5 * np.log(dc / dc.mean()), atol=0.02)
    for out in (full, half):
        assert out @ rec709 == pytest.approx(dc @ rec709, rel=1e-4)
    np.testing.assert_array_equal(envmaps.white_balance(env, 0.0), env.astype(np.float32))
    with pytest.raises(RelightError, match="white balance"):
        envmaps.white_balance(env, 1.5)


def test_lights_command_white_balance(tmp_path):
    plain, balanced = tmp_path / "plain", tmp_path / "wb"
    assert main(["lights", "--out", str(plain), "--n", "6", "--height", "10", "--rotations", "2"]) == 0
    assert main(["lights", "--out", str(balanced), "--n", "6", "--height", "10", "--rotations", "2",
                 "--white-balance", "1"]) == 0
    a, b = dataset.read_lights(plain), dataset.read_lights(balanced)
    spread = lambda ls: np.ptp([_cast(x) for x in ls], axis=0).max()  # noqa: E731
    assert spread(b) < 0.1 * spread(a)
    name = dataset.list_lights(balanced)[0]  # the written map is the balanced one (photos use it)
    np.testing.assert_allclose(project_envmap(environment(balanced, name)), dataset.read_light(balanced, name),
                               rtol=0.03, atol=0.01)
    assert main(["lights", "--out", str(tmp_path / "x"), "--white-balance", "2"]) == 2


# The seed-0 map of each kind the shipped stage 1's lights were drawn from (height 16; coefficients 0, 2 and 3 of the
# green channel of its projection), recorded from this code before the flash, low_lamp and ground_albedo options
# were added: adding kinds or options must not change them (the shipped lights are reproducible from their command).
SHIPPED_KINDS = {
    "sun_sky": [0.744759, 0.85524, -0.0608724],
    "overcast": [1.25016, 1.0129, 0.142388],
    "softbox": [0.266958, 0.292515, 0.218931],
    "window": [0.346952, 0.233341, 0.319594],
    "lamps": [0.424166, 0.450316, 0.38276],
    "night": [0.302308, 0.250396, -0.0734354],
}


@pytest.mark.parametrize("kind", sorted(SHIPPED_KINDS))
def test_the_shipped_kinds_draw_the_same_maps(kind):
    light = project_envmap(envmaps.procedural_envmap(kind, np.random.default_rng(0), 16))
    np.testing.assert_allclose(light[[0, 2, 3], 1], SHIPPED_KINDS[kind], rtol=1e-4)
    # the ground option belongs to sun_sky: every other kind ignores it and draws the same map
    if kind != "sun_sky":
        np.testing.assert_array_equal(
            envmaps.procedural_envmap(kind, np.random.default_rng(0), 16, ground_albedo=(0.1, 0.4)),
            envmaps.procedural_envmap(kind, np.random.default_rng(0), 16))


def test_the_lights_command_draws_the_shipped_kinds_unless_told(tmp_path):
    """flash and low_lamp only when named: `export lights` and the quickstart make the same set as before them."""
    assert envmaps.DEFAULT_KINDS == tuple(SHIPPED_KINDS)
    assert main(["lights", "--out", str(tmp_path), "--n", "8", "--height", "10", "--rotations", "2"]) == 0
    kinds = sorted({n.split("_", 1)[1].rsplit("_r", 1)[0] for n in dataset.list_lights(tmp_path)})
    assert kinds == sorted(SHIPPED_KINDS)


def _direction(light: np.ndarray) -> tuple[float, float]:
    """(elevation in degrees, toward-the-camera component x) of a light's luminance by its degree-1 band."""
    from relight_rt.image.color import REC709
    from relight_rt.light.sh import dominant_direction

    d, _ = dominant_direction(light @ np.asarray(REC709))
    return math.degrees(math.asin(d[2])), float(d[0])


@pytest.mark.parametrize("kind", ["flash", "low_lamp"])
def test_face_height_kinds_light_from_about_the_face_height(kind):
    """The source is drawn at elevation -15..+20 deg; a room and a ceiling lamp pull the whole light's direction up
    a little, never to the sky kinds' 45 deg median."""
    maps = [envmaps.procedural_envmap(kind, np.random.default_rng(s), 32) for s in range(24)]
    read = [_direction(project_envmap(m)) for m in maps]
    el, x = np.array(read).T
    assert el.min() > -20 and el.max() < 40 and -5 < np.median(el) < 20
    if kind == "flash":  # at the camera
        assert x.min() > 0.7
    else:  # from anywhere around: in front of and behind the subject
        assert (x > 0.5).any() and (x < -0.5).any()


def test_lit_ground_bounces_the_sky_and_sun_at_its_albedo():
    """sun_sky with ground_albedo: the ground's luminance is albedo x the horizontal irradiance / pi (the albedo
    drawn in the range, its tint of unit luminance), so it lowers the light's direction against the dim default."""
    from relight_rt.image.color import REC709
    from relight_rt.light.envmap import directions_envmap, solid_angles_envmap

    z = directions_envmap(32)[..., 2]
    omega = solid_angles_envmap(32)
    for seed in range(4):
        env = envmaps.procedural_envmap("sun_sky", np.random.default_rng(seed), 32, ground_albedo=(0.2, 0.3))
        lum = env @ np.asarray(REC709, np.float32)
        irradiance = float((lum * omega * np.clip(z, 0, 1)).sum())
        ground = lum[z < 0]
        assert np.ptp(ground) < 1e-6 * ground.max()  # one flat diffuse ground
        # the tint's luminance is 1 before the overall white-balance draw (a few % per channel)
        assert 0.2 * 0.85 < ground.mean() * math.pi / irradiance < 0.3 * 1.15
        dim = envmaps.procedural_envmap("sun_sky", np.random.default_rng(seed), 32)
        assert _direction(project_envmap(env))[0] < _direction(project_envmap(dim))[0]
    with pytest.raises(RelightError, match="ground albedo"):
        envmaps.procedural_envmap("sun_sky", np.random.default_rng(0), 16, ground_albedo=(0.5, 0.2))


def test_lights_command_keeps_the_flash_at_the_camera(tmp_path):
    out = tmp_path / "lights"
    assert main(["lights", "--out", str(out), "--n", "4", "--height", "30", "--rotations", "10",
                 "--kinds", "flash", "low_lamp", "--camera-turn", "30"]) == 0
    names = list_environments(out)
    flash = [n for n in names if "_flash_" in n]
    lamp = [n for n in names if "_low_lamp_" in n]
    assert len(flash) == len(lamp) == 20
    # the flash maps turn through +-30 deg (whole columns: 6 deg at height 30), the low lamps the whole circle
    import json

    index = json.loads((out / "lights.json").read_text())["lights"]
    assert [index[n]["columns"] for n in flash[:10]] == [-5, -4, -3, -2, -1, 1, 2, 3, 4, 5]
    assert all("columns" not in index[n] for n in lamp)
    assert min(_direction(dataset.read_light(out, n))[1] for n in flash) > 0.5
    assert min(_direction(dataset.read_light(out, n))[1] for n in lamp) < -0.5
    # the light file is the SH of the turned map render-photos will use
    for name in (flash[0], flash[7], lamp[3]):
        np.testing.assert_allclose(project_envmap(environment(out, name)), dataset.read_light(out, name),
                                   rtol=0.03, atol=0.01)
    assert main(["lights", "--out", str(tmp_path / "x"), "--camera-turn", "200"]) == 2
    assert main(["lights", "--out", str(tmp_path / "x"), "--ground-albedo", "0.4", "0.1"]) == 2


def test_direction_figures_of_known_lights():
    from export.render.lights_cli import direction_figures
    from relight_rt import lights

    def toward(el_deg, az_deg):
        el, az = math.radians(el_deg), math.radians(az_deg)
        return lights.directional([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])

    # 2 frontal at face height, 1 frontal from below, 1 from the side at the horizon, 1 from above, 1 uniform
    set_ = np.stack([toward(5, 0), toward(-10, 20), toward(-30, 0), toward(0, 90), toward(60, 0),
                     lights.ambient(1.0)])
    f = direction_figures(set_)
    assert f["n"] == 6
    assert f["frontal_horizon"] == pytest.approx(2 / 6, abs=1e-4)
    assert f["below_0"] == pytest.approx(2 / 6, abs=1e-4) and f["below_10"] == pytest.approx(4 / 6, abs=1e-4)
    assert f["elevation_quantiles"]["50"] == pytest.approx(2.5, abs=0.2)  # between 0 and 5 deg
    with pytest.raises(RelightError, match="expected"):
        direction_figures(np.zeros((3, 9)))
