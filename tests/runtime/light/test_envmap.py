"""relight_rt.envmap: the equirectangular grid, projection to SH and back, env map files (DESIGN.md §3)."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from _sh_samples import random_dirs, random_light

from relight_rt import RelightError, envmap, sh

# ----------------------------------------------------------------------------------------- env maps


def test_envmap_layout():
    h = 8
    d = envmap.directions_envmap(h)
    assert d.shape == (h, 2 * h, 3)
    np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 1, atol=1e-12)
    assert (d[0, :, 2] > 0.9).all() and (d[-1, :, 2] < -0.9).all()  # top row = sky
    # Pixel (H/2, W/2) sits just past the centre: straight ahead of the camera, behind the subject (−x).
    assert d[h // 2, h, 0] < -0.95
    assert d[h // 2, h // 2, 1] < -0.95  # the quarter left of centre lies to the image's left (−y)
    assert d[h // 2, 0, 0] > 0.95 and d[h // 2, -1, 0] > 0.95  # the edges are behind the camera (+x)
    w = envmap.solid_angles_envmap(h)
    assert w.shape == (h, 2 * h)
    assert w.sum() == pytest.approx(4 * math.pi, rel=1e-2)


def test_project_constant_map_gives_only_dc():
    value = np.array([0.5, 1.0, 2.0])
    env = np.broadcast_to(value, (64, 128, 3)).astype(np.float32)
    light = envmap.project_envmap(env)
    # ∫ c · Y_0 dω = c · 4π / (2√π) = c · √(4π); the midpoint rule in θ errs by ≈ (π/H)²/24 = 1e-4.
    np.testing.assert_allclose(light[0], value * math.sqrt(4 * math.pi), rtol=2e-4)
    np.testing.assert_allclose(light[[2, 6]], 0, atol=2e-3)  # even in θ about the equator: midpoint error only
    np.testing.assert_allclose(light[[1, 3, 4, 5, 7, 8]], 0, atol=1e-6)  # odd in φ: cancel exactly


def test_project_single_pixel_is_basis_times_power():
    h = 32
    i, j = 9, 41
    power = np.array([1.0, 2.0, 3.0])
    env = np.zeros((h, 2 * h, 3))
    env[i, j] = power / envmap.solid_angles_envmap(h)[i, j]
    direction = envmap.directions_envmap(h)[i, j]
    np.testing.assert_allclose(envmap.project_envmap(env), sh.basis(direction)[:, None] * power, atol=1e-12)


def test_project_small_bright_spot_matches_basis():
    h = 256
    dirs = envmap.directions_envmap(h)
    target = np.array([0.3, -0.8, 0.5]) / np.linalg.norm([0.3, -0.8, 0.5])
    spot = (dirs @ target) > math.cos(math.radians(2.0))
    env = np.zeros((h, 2 * h, 3), np.float32)
    env[spot] = [10.0, 5.0, 1.0]
    power = (envmap.solid_angles_envmap(h) * spot).sum() * np.array([10.0, 5.0, 1.0])
    np.testing.assert_allclose(envmap.project_envmap(env), sh.basis(target)[:, None] * power, atol=2e-3 * power.max())


def test_envmap_round_trip():
    light = random_light()
    env = envmap.envmap_from_light(light, 64)
    assert env.shape == (64, 128, 3) and env.dtype == np.float32
    np.testing.assert_allclose(envmap.project_envmap(env.astype(np.float64)), light, atol=2e-3)
    np.testing.assert_allclose(env, sh.basis(envmap.directions_envmap(64)) @ light, atol=1e-5)


def brute_force_irradiance(env, normals):
    h = env.shape[0]
    dirs = envmap.directions_envmap(h).reshape(-1, 3)
    radiance = env.reshape(-1, 3) * envmap.solid_angles_envmap(h).reshape(-1, 1)
    return np.maximum(0, normals @ dirs.T) @ radiance


def test_irradiance_matches_brute_force_within_degree2_bound():
    """The degree-2 irradiance of a projected map vs ∫ L(ω) max(0, n·ω) dω over the same pixels.

    By the addition theorem the difference is ∫ L(ω) (max(0, t) − K₂(t)) dω with t = n·ω and K₂ the
    degree-2 truncation of the clamped cosine, K₂(t) = 1/4 + t/2 + 5(3t² − 1)/32. On [−1, 1]
    |max(0, t) − K₂(t)| ≤ 3/32 (at t = 0), so for a non-negative map |error| ≤ (3/32) ∫ L dω.
    Smooth maps do much better; we check both the bound on a spiky map and 3% on a smooth one.
    """
    h = 48
    dirs = envmap.directions_envmap(h)
    rng = np.random.default_rng(5)
    normals = random_dirs(40, seed=6)
    spiky = np.zeros((h, 2 * h, 3))
    for d in random_dirs(4, seed=7):
        spiky += ((dirs @ d) > 0.97)[..., None] * rng.uniform(1, 5, size=3)
    power = (spiky * envmap.solid_angles_envmap(h)[..., None]).sum(axis=(0, 1))
    err = sh.irradiance(envmap.project_envmap(spiky), normals) - brute_force_irradiance(spiky, normals)
    assert (np.abs(err) <= 3 / 32 * power + 1e-9).all()
    assert np.abs(err).max() > 0.01 * power.max()  # the bound is not vacuous here: truncation shows

    smooth = 1.0 + 0.5 * dirs[..., 2:3] * np.array([1.0, 0.5, 0.2]) + 0.3 * dirs[..., 0:1] ** 2
    exact = brute_force_irradiance(smooth, normals)
    approx = sh.irradiance(envmap.project_envmap(smooth), normals)
    np.testing.assert_allclose(approx, exact, rtol=0.03)


def test_project_envmap_full_size_float32_matches_float64():
    """A 1024×2048 map (the size the issue times: ~6 ms on one core here; tests never assert timings)
    projects in float32 as in float64: the float32 path sums rows first, so its error stays tiny."""
    env = np.random.default_rng(0).random((1024, 2048, 3), dtype=np.float32)
    light = envmap.project_envmap(env)
    assert light.shape == (9, 3) and light.dtype == np.float64
    np.testing.assert_allclose(light, envmap.project_envmap(env.astype(np.float64)), rtol=0, atol=1e-6)


@pytest.mark.parametrize(
    ("bad", "match"),
    [
        (np.zeros((8, 8, 3), np.float32), r"\(H, 2H, 3\)"),
        (np.zeros((8, 16), np.float32), r"\(H, 2H, 3\)"),
        (np.zeros((8, 16, 4), np.float32), r"\(H, 2H, 3\)"),
        (np.zeros((8, 16, 3), np.uint8), "float linear RGB"),
    ],
)
def test_project_envmap_rejects_bad_maps(bad, match):
    with pytest.raises(RelightError, match=match):
        envmap.project_envmap(bad)


def test_project_envmap_rejects_nan():
    env = np.ones((8, 16, 3), np.float32)
    env[3, 4, 1] = np.nan
    with pytest.raises(RelightError, match="NaN or Inf"):
        envmap.project_envmap(env)


def test_envmap_height_checked():
    for fn in (envmap.directions_envmap, envmap.solid_angles_envmap):
        with pytest.raises(RelightError, match="height"):
            fn(0)
    with pytest.raises(RelightError, match="height"):
        envmap.envmap_from_light(random_light(), 2.5)


def test_load_envmap_hdr_is_rgb(tmp_path):
    bgr = np.zeros((8, 16, 3), np.float32)
    bgr[..., 2] = 4.0  # red, in OpenCV's B, G, R order
    bgr[..., 0] = 0.25
    path = tmp_path / "red.hdr"
    assert cv2.imwrite(str(path), bgr)
    env = envmap.load_envmap(path)
    assert env.shape == (8, 16, 3) and env.dtype == np.float32
    np.testing.assert_allclose(env[0, 0], [4.0, 0.0, 0.25], rtol=0.02)  # RGBE keeps ~1% precision


def test_load_envmap_png_is_linearised(tmp_path):
    path = tmp_path / "grey.png"
    assert cv2.imwrite(str(path), np.full((4, 8, 3), 128, np.uint8))
    env = envmap.load_envmap(path)
    np.testing.assert_allclose(env, ((128 / 255 + 0.055) / 1.055) ** 2.4, rtol=1e-5)


def test_load_envmap_grey_and_rgba(tmp_path):
    grey = tmp_path / "grey.png"
    assert cv2.imwrite(str(grey), np.full((4, 8), 255, np.uint8))
    np.testing.assert_allclose(envmap.load_envmap(grey), 1.0)
    rgba = tmp_path / "rgba.png"
    bgra = np.zeros((4, 8, 4), np.uint8)
    bgra[..., 0] = 255  # blue
    bgra[..., 3] = 10  # alpha is ignored
    assert cv2.imwrite(str(rgba), bgra)
    np.testing.assert_allclose(envmap.load_envmap(rgba)[0, 0], [0.0, 0.0, 1.0])


def test_load_envmap_wrong_aspect(tmp_path):
    path = tmp_path / "square.hdr"
    assert cv2.imwrite(str(path), np.ones((8, 8, 3), np.float32))
    with pytest.raises(RelightError, match=r"width = 2 × height, got 8×8"):
        envmap.load_envmap(path)


def test_load_envmap_bad_files(tmp_path, monkeypatch):
    with pytest.raises(RelightError, match="not found"):
        envmap.load_envmap(tmp_path / "missing.hdr")
    with pytest.raises(RelightError, match="unsupported"):
        envmap.load_envmap(tmp_path / "map.bmp")
    corrupt = tmp_path / "corrupt.hdr"
    corrupt.write_bytes(b"not an image")
    with pytest.raises(RelightError, match="cannot decode"):
        envmap.load_envmap(corrupt)
    exr = tmp_path / "map.exr"
    exr.write_bytes(b"not an exr")
    monkeypatch.delenv("OPENCV_IO_ENABLE_OPENEXR", raising=False)
    with pytest.raises(RelightError, match="OPENCV_IO_ENABLE_OPENEXR=1"):
        envmap.load_envmap(exr)


def test_a_map_whose_light_no_command_reads_is_refused(tmp_path, capsys):
    """Issue 50 bug 13: an RGBE map with exponent 255 (values ~1e38, a 32 KB file) gave `lights from-envmap` exit 0
    and a light of 6e38 that every other command refused; the projection holds its light to sh.MAX_COEFF."""
    from relight_rt import cli

    hot = tmp_path / "exp255.hdr"
    hot.write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 64 +X 128\n" + b"\xff" * (4 * 128 * 64))
    with pytest.raises(RelightError, match=r"environment map's light: SH light coefficient .* is too large"):
        envmap.project_envmap(envmap.load_envmap(hot))
    assert cli.main(["lights", "from-envmap", str(hot), "-o", str(tmp_path / "hot.npy")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "too large" in err[0] and not (tmp_path / "hot.npy").exists(), err
    bright = np.full((8, 16, 3), 1e29, np.float32)  # within the bound: projected, written, read back
    assert np.abs(envmap.project_envmap(bright)).max() < sh.MAX_COEFF
