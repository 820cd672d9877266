"""relight_rt.lights: parametric lamps, presets and light sequences."""

import math

import numpy as np
import pytest

from relight_rt import RelightError, envmap, lights, sh

DIRECTION = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])


@pytest.mark.parametrize("radius", [0.0, 1e-3, 0.1, 0.5, 1.5, math.pi])
def test_directional_intensity_is_facing_irradiance(radius):
    light = lights.directional(DIRECTION, color=(1.0, 0.5, 0.2), intensity=2.0, angular_radius=radius)
    assert light.shape == (9, 3) and light.dtype == np.float64
    np.testing.assert_allclose(sh.irradiance(light, DIRECTION), [2.0, 1.0, 0.4], rtol=1e-12)


def test_directional_point_source_is_scaled_basis():
    # Radius 0: light[k] = (16/17) · intensity · Y_k(d) (degree-2 irradiance of a delta is 17/16 × power).
    light = lights.directional(DIRECTION, intensity=3.0)
    np.testing.assert_allclose(light, 16 / 17 * 3.0 * sh.basis(DIRECTION)[:, None] * np.ones(3), rtol=1e-12)


def test_directional_tiny_radius_converges_to_delta():
    delta = lights.directional(DIRECTION, angular_radius=0.0)
    errors = [np.abs(lights.directional(DIRECTION, angular_radius=r) - delta).max() for r in (0.1, 0.01, 0.001)]
    assert errors[0] > errors[1] > errors[2]
    assert errors[2] < 1e-6


def test_directional_is_the_exact_sh_of_a_cap():
    """Project a rasterised uniform cap and compare with the closed form (same overall scale)."""
    h, radius = 256, 0.5
    dirs = envmap.directions_envmap(h)
    env = np.zeros((h, 2 * h, 3))
    env[(dirs @ DIRECTION) > math.cos(radius)] = 1.0
    projected = envmap.project_envmap(env)
    closed = lights.directional(DIRECTION, angular_radius=radius)
    scale = closed[0, 0] / projected[0, 0]
    np.testing.assert_allclose(closed, scale * projected, atol=2e-3 * np.abs(closed).max())


def test_ambient_gives_constant_irradiance():
    light = lights.ambient((0.2, 0.3, 0.4))
    normals = np.random.default_rng(0).normal(size=(10, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    np.testing.assert_allclose(sh.irradiance(light, normals), np.tile([0.2, 0.3, 0.4], (10, 1)), rtol=1e-12)
    np.testing.assert_array_equal(lights.ambient(0.5)[0], lights.ambient((0.5, 0.5, 0.5))[0])


def test_sky_gradient():
    top, bottom = np.array([1.0, 0.8, 0.6]), np.array([0.1, 0.2, 0.3])
    light = lights.sky(top, bottom)
    e = sh.irradiance(light, np.array([[0, 0, 1.0], [0, 0, -1.0], [1.0, 0, 0]]))
    np.testing.assert_allclose(e, [(5 * top + bottom) / 6, (top + 5 * bottom) / 6, (top + bottom) / 2], rtol=1e-12)
    env = envmap.envmap_from_light(light, 16)
    assert (env >= 0).all()  # a physical (non-negative) radiance
    assert (np.diff(env[:, 0, 0]) < 0).all()  # brighter toward the zenith (top rows)
    np.testing.assert_allclose(lights.sky(top, top), lights.ambient(top), rtol=1e-12)


def test_lights_add():
    a, b = lights.directional((1, 0, 0)), lights.ambient(0.1)
    n = np.array([0.6, 0.0, 0.8])
    np.testing.assert_allclose(sh.irradiance(a + b, n), sh.irradiance(a, n) + sh.irradiance(b, n), rtol=1e-12)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"direction": (0, 0, 0)}, "non-zero"),
        ({"direction": (1, 0)}, "direction"),
        ({"direction": (np.nan, 0, 1)}, "direction"),
        ({"direction": (1, 0, 0), "color": (1, -1, 1)}, "non-negative"),
        ({"direction": (1, 0, 0), "color": "red"}, "color"),
        ({"direction": (1, 0, 0), "intensity": -1.0}, "intensity"),
        ({"direction": (1, 0, 0), "angular_radius": 4.0}, "angular_radius"),
        ({"direction": (1, 0, 0), "angular_radius": "wide"}, "angular_radius"),
    ],
)
def test_directional_rejects_bad_input(kwargs, match):
    with pytest.raises(RelightError, match=match):
        lights.directional(**kwargs)


def test_sky_and_ambient_reject_bad_colors():
    with pytest.raises(RelightError, match="zenith_color"):
        lights.sky((1, 1), (0, 0, 0))
    with pytest.raises(RelightError, match="ground_color"):
        lights.sky((1, 1, 1), (-1, 0, 0))
    with pytest.raises(RelightError, match="color"):
        lights.ambient((np.inf, 0, 0))


# ----------------------------------------------------------------------------------------- presets


def test_at_least_eight_presets():
    names = lights.list_presets()
    assert len(names) >= 8 and len(set(names)) == len(names)
    for expected in ("studio", "window-left", "overhead-noon", "golden-hour", "overcast", "neon", "rim", "night"):
        assert expected in names


@pytest.mark.parametrize("name", lights.list_presets())
def test_preset_scale_and_validity(name):
    light = lights.preset(name)
    assert light.shape == (9, 3) and np.isfinite(light).all()
    img = sh.render_sphere(light, 48)
    assert 0.45 <= img.max() <= 1.05  # brightest irradiance on the camera-facing sphere ≈ 1 (night: 0.5)
    assert img.max() > 0.9 or name == "night"
    light[0, 0] = 1e6  # a caller's edit does not leak into the next call
    assert lights.preset(name)[0, 0] < 10


def test_preset_directions_look_right():
    window = sh.render_sphere(lights.preset("window-left"), 32)
    assert window[16, 4].mean() > window[16, 27].mean()  # lit from the image's left
    noon = sh.render_sphere(lights.preset("overhead-noon"), 32)
    assert noon[4, 16].mean() > noon[27, 16].mean()  # lit from above
    rim = sh.render_sphere(lights.preset("rim"), 32, return_mask=False)
    assert rim[16, 16].mean() < 0.5 * rim.max()  # dark centre, bright edges


def _irradiance_where(name, pick):
    n = lights._visible_normals(48)
    e = lights.irradiance(lights.preset(name), n) @ np.array([0.2126, 0.7152, 0.0722])
    return float(e[pick(n)].mean()), float(e.max())


def test_rim_keeps_a_face_that_looks_at_the_camera_readable():
    """issue 32: the two backlights alone left the front of a face black on real photos (front/peak -0.01); issue
    48: with the front at 0.2-0.5 of the peak rim changed a real face least of all lights (0.42x a side lamp's)."""
    front, peak = _irradiance_where("rim", lambda n: n[:, 0] > 0.95)
    assert 0.15 * peak < front < 0.3 * peak  # a weak fill: readable, clearly darker than the rims (0.165)


def test_campfire_lights_from_below_without_blacking_out_what_faces_up():
    """issue 32: the fire from 45 degrees below left the forehead and hairline as a dark band (up/peak 0.04)."""
    up, peak = _irradiance_where("campfire", lambda n: n[:, 2] > 0.8)
    down, _ = _irradiance_where("campfire", lambda n: n[:, 2] < -0.8)
    assert up > 0.1 * peak and down > 2 * up  # still from below


def test_unknown_preset_lists_names():
    with pytest.raises(RelightError, match="known presets: .*studio"):
        lights.preset("disco")


# ----------------------------------------------------------------------------------------- sequences


def test_rotation_sequence_about_z():
    light = lights.preset("studio")
    seq = lights.rotation_sequence(light, 8)
    assert seq.shape == (8, 9, 3)
    np.testing.assert_allclose(seq[0], light, atol=1e-12)
    np.testing.assert_allclose(seq[3], sh.rotate_z(light, 2 * math.pi * 3 / 8), atol=1e-12)
    np.testing.assert_allclose(sh.rotate_z(seq[-1], 2 * math.pi / 8), light, atol=1e-12)  # loops seamlessly
    two = lights.rotation_sequence(light, 8, turns=2)
    np.testing.assert_allclose(two[1], seq[2], atol=1e-12)


@pytest.mark.parametrize(("axis", "vector"), [("x", (1, 0, 0)), ("y", (0, 1, 0)), ("z", (0, 0, 1))])
def test_rotation_sequence_axes(axis, vector):
    light = lights.preset("golden-hour")
    by_name = lights.rotation_sequence(light, 5, axis=axis, turns=-0.5)
    by_vector = lights.rotation_sequence(light, 5, axis=np.array(vector) * 3.0, turns=-0.5)
    np.testing.assert_allclose(by_name, by_vector, atol=1e-12)
    angle = -math.pi * 2 / 5
    kw = {"x": "roll", "y": "pitch", "z": "yaw"}[axis]
    np.testing.assert_allclose(by_name[2], sh.rotate(light, sh.rotation_matrix(**{kw: angle})), atol=1e-12)


def test_rotation_sequence_rejects_bad_input():
    light = lights.preset("studio")
    with pytest.raises(RelightError, match="axis"):
        lights.rotation_sequence(light, 4, axis="w")
    with pytest.raises(RelightError, match="axis"):
        lights.rotation_sequence(light, 4, axis=(0, 0, 0))
    with pytest.raises(RelightError, match="n_frames"):
        lights.rotation_sequence(light, 0)
    with pytest.raises(RelightError, match="turns"):
        lights.rotation_sequence(light, 4, turns=float("nan"))
    with pytest.raises(RelightError, match="light"):
        lights.rotation_sequence(np.zeros((2, 9, 3)), 4)


def test_interpolate():
    a, b, c = lights.preset("studio"), lights.preset("night"), lights.preset("neon")
    seq = lights.interpolate([a, b, c], 5)
    assert seq.shape == (5, 9, 3)
    np.testing.assert_allclose(seq[0], a, atol=1e-15)
    np.testing.assert_allclose(seq[2], b, atol=1e-15)
    np.testing.assert_allclose(seq[4], c, atol=1e-15)
    np.testing.assert_allclose(seq[1], (a + b) / 2, atol=1e-15)
    np.testing.assert_allclose(lights.interpolate(np.stack([a, b]), 3)[1], (a + b) / 2, atol=1e-15)
    np.testing.assert_allclose(lights.interpolate(a[None], 3), np.stack([a] * 3), atol=0)
    np.testing.assert_allclose(lights.interpolate([a, b], 1), a[None], atol=0)


def test_interpolate_rejects_bad_input():
    with pytest.raises(RelightError, match="at least one"):
        lights.interpolate([], 3)
    with pytest.raises(RelightError, match=r"\(K, 9, 3\)"):
        lights.interpolate(np.zeros((9, 3)), 3)
    with pytest.raises(RelightError, match="n_frames"):
        lights.interpolate(np.zeros((2, 9, 3)), 0)
    with pytest.raises(RelightError, match="NaN"):
        lights.interpolate(np.full((2, 9, 3), np.nan), 3)


def test_night_moon_leaves_skin_pale_not_violet():
    # skin's red times a saturated blue moon reads as lilac on real photos (the old moon (0.55, 0.65, 1.0): Lab
    # chroma 15.8 at hue -54 deg on the lit side of this skin); moonlight is cool and pale (docs/RESULTS.md)
    import cv2

    img = sh.render_sphere(lights.preset("night"), 48)
    lum = img @ np.array([0.2126, 0.7152, 0.0722])
    lit = img[np.unravel_index(np.argmax(lum), lum.shape)]
    skin = np.array([0.4, 0.3, 0.25])
    lab = cv2.cvtColor((lit / lum.max() * skin)[None, None].astype(np.float32), cv2.COLOR_RGB2Lab)[0, 0]
    assert np.hypot(lab[1], lab[2]) < 10
