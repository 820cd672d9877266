"""export.render.photos and the render / render-photos commands end to end (tiny sizes)."""

from __future__ import annotations

import filecmp

import numpy as np
import pytest

pytest.importorskip("embreex")
pytest.importorskip("tqdm")

from export import dataset  # noqa: E402
from export.__main__ import main  # noqa: E402
from export.render import envmaps, shapes  # noqa: E402
from export.render.camera import fit_camera  # noqa: E402
from export.render.photos import EnvSampler, full_shading, median_cut, pixel_size, render_photo  # noqa: E402
from export.render.raycast import Tracer  # noqa: E402
from export.render.scene import Subject  # noqa: E402
from export.render.transport import render_gbuffer, transport  # noqa: E402
from relight_rt import RelightError  # noqa: E402
from relight_rt.light.envmap import directions_envmap, project_envmap, solid_angles_envmap  # noqa: E402

RES = 24


def _setup(**material):
    subject = Subject([shapes.sphere(radius=0.5, albedo=(0.7, 0.5, 0.4), rows=24, **material)])
    cam = fit_camera(subject, RES)
    tracer = Tracer(subject)
    g = render_gbuffer(subject, cam, tracer)
    t = transport(tracer, g, 16, rng=np.random.default_rng(0))
    return tracer, g, t, pixel_size(cam.half_extent, RES)


@pytest.fixture(scope="module")
def env() -> np.ndarray:
    return envmaps.procedural_envmap("window", np.random.default_rng(0), height=16)


def test_zero_specular_and_subsurface_is_the_diffuse_image(env):
    tracer, g, t, px = _setup(specular=0.0, subsurface=0.0, skin=1.0)
    out = render_photo(tracer, g, t, env, pixel_size=px, rng=np.random.default_rng(0))
    np.testing.assert_array_equal(out["photo"], out["diffuse"])
    light = project_envmap(env)
    np.testing.assert_allclose(out["light"], light)
    expected = g.albedo * np.maximum(0.0, t @ light.astype(np.float32))
    np.testing.assert_allclose(out["diffuse"].reshape(-1, 3)[g.index], expected, rtol=1e-5, atol=1e-6)
    np.testing.assert_array_equal(out["mask"], g.mask)


def test_specular_adds_light(env):
    tracer, g, t, px = _setup(specular=0.2, roughness=0.3)
    out = render_photo(tracer, g, t, env, pixel_size=px, rng=np.random.default_rng(0))
    extra = out["photo"] - out["diffuse"]
    assert (extra >= 0).all() and extra.max() > 0
    assert (extra[out["mask"] == 0] == 0).all()


def test_specular_under_uniform_light_is_about_f0():
    """A white furnace: under uniform radiance 1 with nothing in the way, the GGX lobe seen head-on
    reflects its directional albedo, about its normal-incidence reflectance 0.04 (a bit more from the
    Fresnel rise, less from masking)."""
    tracer, g, t, px = _setup(specular=0.04, roughness=0.3)
    uniform = np.ones((16, 32, 3), np.float32)
    out = render_photo(tracer, g, t, uniform, pixel_size=px, n_samples=64, rng=np.random.default_rng(0))
    centre = (out["photo"] - out["diffuse"])[RES // 2 - 1 : RES // 2 + 1, RES // 2 - 1 : RES // 2 + 1]
    assert 0.03 < centre.mean() < 0.06


def test_subsurface_changes_only_skin():
    ball = shapes.sphere(center=(0, -0.3, 0), radius=0.25, subsurface=1.0, skin=1.0, name="skin")
    cloth = shapes.sphere(center=(0, 0.3, 0), radius=0.25, name="cloth")
    subject = Subject([ball, cloth])
    cam = fit_camera(subject, 48)
    tracer = Tracer(subject)
    g = render_gbuffer(subject, cam, tracer)
    t = transport(tracer, g, 16, rng=np.random.default_rng(0))
    env = envmaps.procedural_envmap("softbox", np.random.default_rng(1), height=16)
    out = render_photo(tracer, g, t, env, pixel_size=0.02, rng=np.random.default_rng(0))
    diff = np.abs(out["photo"] - out["diffuse"]).sum(-1)
    skin = g.image(g.skin) > 0.5
    assert diff[skin].max() > 0
    assert (diff[~skin] == 0).all()


def test_median_cut_keeps_the_power_and_finds_the_sun():
    h = 32
    env = np.full((h, 2 * h, 3), 0.05, np.float32)
    env[5, 40] = (400.0, 300.0, 200.0)  # a one-pixel sun
    dirs, power = median_cut(env, 64)
    assert dirs.shape == power.shape == (64, 3)
    np.testing.assert_allclose(np.linalg.norm(dirs, axis=1), 1, atol=1e-9)
    total = (env * solid_angles_envmap(h)[..., None]).sum(axis=(0, 1))
    np.testing.assert_allclose(power.sum(axis=0), total, rtol=1e-9)
    sun = np.argmax(power[:, 0])
    # the sun's region is cut down to the sun: its light points at the sun's pixel and carries nearly all of it
    assert dirs[sun] @ directions_envmap(h)[5, 40] > 0.99
    assert power[sun, 0] > 0.95 * 400.0 * solid_angles_envmap(h)[5, 40]
    # a uniform map is cut into regions of equal power
    _, even = median_cut(np.ones((h, 2 * h, 3), np.float32), 16)
    assert even[:, 0].max() < 1.3 * even[:, 0].min()


def test_full_shading_agrees_with_sh_shading_where_sh_suffices(env):
    """On a lone convex sphere (nothing casts a shadow) under a soft map, the SH irradiance is close to the
    exact one; a wrong direction convention in the point lights would make them disagree grossly."""
    tracer, g, t, _ = _setup()
    t = transport(tracer, g, 256, rng=np.random.default_rng(1))
    exact = full_shading(tracer, g, env)
    sh = np.maximum(0.0, t @ project_envmap(env).astype(np.float32))
    assert np.abs(exact - sh).mean() < 0.06 * sh.mean()
    uniform = full_shading(tracer, g, np.ones((16, 32, 3), np.float32))
    np.testing.assert_allclose(uniform, np.pi, rtol=0.04)  # ∫ max(0, n·ω) dω = π


def test_full_shading_casts_hard_shadows():
    """A sun straight above (+z, DESIGN.md §3) and a ball above a big ball: the shadow on the big ball is
    black in the exact shading, while the SH projection of the same map can only dim it."""
    big = shapes.sphere(radius=0.5, rows=24, name="big")
    blocker = shapes.sphere(center=(0, 0, 0.9), radius=0.2, rows=12, name="blocker")
    subject = Subject([big, blocker])
    cam = fit_camera(subject, RES)
    tracer = Tracer(subject)
    g = render_gbuffer(subject, cam, tracer)
    h = 16
    env = np.zeros((h, 2 * h, 3), np.float32)
    env[0, :] = 50.0  # the top row: a small bright cap around +z
    exact = full_shading(tracer, g, env)
    t = transport(tracer, g, 64, rng=np.random.default_rng(0))
    sh = np.maximum(0.0, t @ project_envmap(env).astype(np.float32))
    top_of_big = (g.part == 0) & (g.normal[:, 2] > 0.9)  # under the blocker
    assert top_of_big.any()
    assert exact[top_of_big].max() < 0.05 * exact.max()
    assert sh[top_of_big].mean() > 0.1 * sh.max()


def test_env_sampler_density_integrates_to_one(env):
    s = EnvSampler(env)
    d = s.sample((4000,), np.random.default_rng(0))
    np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 1, atol=1e-5)
    _, pdf = s.lookup(d)
    # E[1/pdf] over samples drawn from pdf = the area of the sphere
    assert np.mean(1.0 / pdf) == pytest.approx(4 * np.pi, rel=0.05)
    with pytest.raises(RelightError, match=r"\(H, 2H, 3\)"):
        EnvSampler(np.ones((4, 4, 3)))


def test_bad_transport_shape(env):
    tracer, g, t, px = _setup()
    with pytest.raises(RelightError, match="transport"):
        render_photo(tracer, g, t[:-1], env, pixel_size=px, rng=np.random.default_rng(0))


def _render(out, *extra):
    args = ["render", "--subject", "shapes", "--n", "2", "--resolution", "32", "--dirs", "16", "--workers", "1",
            "--out", str(out), *extra]
    assert main(args) == 0


def test_render_is_deterministic_and_readable(tmp_path):
    _render(tmp_path / "a")
    _render(tmp_path / "b")
    names = dataset.list_samples(tmp_path / "a")
    assert names == ["shapes_000000", "shapes_000001"]
    files = sorted(p.name for p in (tmp_path / "a").iterdir())
    match, mismatch, errors = filecmp.cmpfiles(tmp_path / "a", tmp_path / "b", files, shallow=False)
    assert not mismatch and not errors and len(match) == 10
    s = dataset.read_sample(tmp_path / "a", names[0])
    assert s["albedo"].shape == (32, 32, 3) and s["transport"].shape == (32, 32, 9)
    assert 0.05 < s["mask"].mean() < 0.9
    assert (s["transport"][s["mask"] == 0] == 0).all()
    assert (s["transport"][..., 0][s["mask"] > 0] > 0).all()
    # the skin parts of the figure (head, hands) use a skin tone whose red exceeds its blue
    skin = s["skin"] > 0.5
    assert skin.any() and (s["albedo"][skin][:, 0] > s["albedo"][skin][:, 2]).all()


def test_render_photos_end_to_end(tmp_path):
    data, lights, photos = tmp_path / "data", tmp_path / "lights", tmp_path / "photos"
    _render(data, "--preview")
    assert (data / "contact_sheet.png").is_file()
    assert main(["lights", "--out", str(lights), "--n", "2", "--height", "10"]) == 0
    args = ["render-photos", "--data", str(data), "--envmaps", str(lights), "--out", str(photos), "--k", "2",
            "--samples", "4", "--workers", "2", "--preview"]
    assert main(args) == 0
    names = dataset.list_photos(photos)
    assert names == ["shapes_000000__L0", "shapes_000000__L1", "shapes_000001__L0", "shapes_000001__L1"]
    p = dataset.read_photo(photos, names[0])
    s = dataset.read_sample(data, "shapes_000000")
    np.testing.assert_array_equal(p["mask"], s["mask"])
    env_name = (photos / f"{names[0]}_env.txt").read_text().strip()
    np.testing.assert_allclose(p["light"], dataset.read_light(lights, env_name), rtol=0.03, atol=0.01)
    assert (photos / "contact_sheet.png").is_file()
    # --full-shading: same light, mask and (SH) diffuse image; another photo
    full = tmp_path / "full"
    assert main([*args[:6], str(full), *args[7:], "--full-shading"]) == 0
    q = dataset.read_photo(full, names[0])
    for key in ("mask", "diffuse", "light"):
        np.testing.assert_array_equal(q[key], p[key])
    assert np.abs(q["photo"] - p["photo"]).max() > 0.01
    assert main(["render-photos", "--data", str(tmp_path / "empty"), "--envmaps", str(lights),
                 "--out", str(photos)]) == 2


def test_gloss_makes_the_non_diffuse_part_larger_and_keeps_the_diffuse_image(env):
    from export.render.photos import glossier

    tracer, g, t, px = _setup(specular=0.06, roughness=0.5)
    shiny = glossier(g, 1.0)
    np.testing.assert_allclose(shiny.specular, 0.3, rtol=1e-6)
    np.testing.assert_allclose(shiny.roughness, 0.25, rtol=1e-6)
    assert glossier(g, 0.0) is g
    with pytest.raises(RelightError, match="gloss"):
        glossier(g, 1.5)
    plain = render_photo(tracer, g, t, env, pixel_size=px, rng=np.random.default_rng(0))
    glossy = render_photo(tracer, shiny, t, env, pixel_size=px, rng=np.random.default_rng(0))
    np.testing.assert_array_equal(glossy["diffuse"], plain["diffuse"])
    extra = lambda out: float(np.abs(out["photo"] - out["diffuse"]).mean())  # noqa: E731
    assert extra(glossy) > 3 * extra(plain) > 0
