"""relight_rt.sh: basis, rotations, irradiance, shading (DESIGN.md §3); env maps and light files: test_envmap.py,
test_lightfile.py."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from _sh_samples import RNG_SEED, random_dirs, random_light

from relight_rt import RelightError, envmap, sh


def random_rotation(seed=RNG_SEED):
    q, r = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def band_energy(light):
    return np.stack([(light[..., s, :] ** 2).sum(axis=-2) for s in (slice(0, 1), slice(1, 4), slice(4, 9))])


# ----------------------------------------------------------------------------------------- basis


# Golden values copied from ../shared/vectors/sh_golden.json ("basis", computed with pyshtools 4.14,
# norm=4, csphase=1, converted to DESIGN.md §3 order): directions[6] and basis[6].
GOLDEN_DIR = [-0.38323720870680267, 0.11624417424290794, -0.9163059171571484]
GOLDEN_BASIS = [
    0.28209479177387814,
    0.05679719552916553,
    -0.4477093727944916,
    -0.18725066282880748,
    -0.04867204149426166,
    -0.11637304157339914,
    0.47903235318498916,
    0.38366206230787664,
    0.07285006416739868,
]


def test_basis_inline_golden():
    np.testing.assert_allclose(sh.basis(np.array(GOLDEN_DIR)), GOLDEN_BASIS, rtol=0, atol=1e-12)


def test_basis_axes():
    # DESIGN.md §3 table at the axes: Y_3 = 0.488603 x, Y_8 = 0.546274 (x² − y²), Y_6 = 0.315392 (3z² − 1).
    y = sh.basis(np.eye(3))
    np.testing.assert_allclose(y[0, [0, 3, 6, 8]], [0.282095, 0.488603, -0.315392, 0.546274], atol=1e-6)
    np.testing.assert_allclose(y[1, [1, 6, 8]], [0.488603, -0.315392, -0.546274], atol=1e-6)
    np.testing.assert_allclose(y[2, [2, 6]], [0.488603, 0.630783], atol=1e-6)


def test_basis_golden_file(shared_dir):
    golden = json.loads((shared_dir / "vectors" / "sh_golden.json").read_text())
    dirs = np.array(golden["directions"])
    np.testing.assert_allclose(sh.basis(dirs), np.array(golden["basis"]), rtol=0, atol=1e-12)


@pytest.mark.parametrize("shape", [(3,), (5, 3), (2, 4, 3), (0, 3)])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_basis_shapes_and_dtype(shape, dtype):
    dirs = random_dirs(max(1, int(np.prod(shape[:-1])))).astype(dtype)[: int(np.prod(shape[:-1]))].reshape(shape)
    out = sh.basis(dirs)
    assert out.shape == shape[:-1] + (9,)
    assert out.dtype == dtype
    if out.size:
        np.testing.assert_allclose(out.reshape(-1, 9), sh.basis(dirs.reshape(-1, 3).astype(np.float64)), atol=1e-6)


def test_basis_orthonormal_by_quadrature():
    h = 128
    y = sh.basis(envmap.directions_envmap(h)).reshape(-1, 9)
    w = envmap.solid_angles_envmap(h).reshape(-1)
    gram = (y * w[:, None]).T @ y
    np.testing.assert_allclose(gram, np.eye(9), atol=2e-4)


@pytest.mark.parametrize("bad", [np.zeros((4, 2)), np.zeros(4), np.array(["a", "b", "c"]), np.float64(1.0)])
def test_basis_rejects_bad_dirs(bad):
    with pytest.raises(RelightError, match=r"dirs: expected \(\.\.\., 3\)"):
        sh.basis(bad)


def test_cosine_lobe_matches_quadrature():
    """Unoccluded transport ∫ max(0, n·ω) Y_k(ω) dω equals A_l Y_k(n)."""
    a = sh.cosine_lobe()
    np.testing.assert_allclose(a, [math.pi] + [2 * math.pi / 3] * 3 + [math.pi / 4] * 5, rtol=0, atol=0)
    h = 256
    dirs = envmap.directions_envmap(h).reshape(-1, 3)
    w = envmap.solid_angles_envmap(h).reshape(-1)
    y = sh.basis(dirs)
    for n in random_dirs(3):
        transport = (np.maximum(0, dirs @ n) * w) @ y
        np.testing.assert_allclose(transport, a * sh.basis(n), atol=2e-4)


# ----------------------------------------------------------------------------------------- lights / shading


def test_check_light_returns_float64_copy():
    light = random_light().astype(np.float32)
    out = sh.check_light(light)
    assert out.dtype == np.float64 and out.shape == (9, 3)
    out[0, 0] = 99
    assert light[0, 0] != 99


@pytest.mark.parametrize(
    ("bad", "match"),
    [
        (np.zeros((9, 4)), r"shape \(9, 3\)"),
        (np.zeros(27), r"shape \(9, 3\)"),
        (np.zeros((2, 9, 3)), r"shape \(9, 3\)"),
        (np.full((9, 3), np.nan), "NaN or Inf"),
        (np.full((9, 3), np.inf), "NaN or Inf"),
        (np.full((9, 3), "x"), "numeric|unreadable"),
        ([[1, 2], [3]], "unreadable|shape"),
    ],
)
def test_check_light_rejects(bad, match):
    with pytest.raises(RelightError, match=match):
        sh.check_light(bad, name="my_light")


@pytest.mark.parametrize(
    ("bad", "match"),
    [
        ([[10**400, 0, 0]] + [[0.0] * 3] * 8, "too large for a float"),  # OverflowError in numpy (fuzz9)
        ([[True, 0.5, 0.5]] + [[0.0] * 3] * 8, "true/false"),  # read as 1.0 beside floats (fuzz9)
        ((((0.1, 0.1, False),) * 9), "true/false"),
    ],
)
def test_check_light_refuses_what_numpy_reads_oddly(bad, match):
    with pytest.raises(RelightError, match=match):
        sh.check_light(bad)


def test_check_light_names_input():
    with pytest.raises(RelightError, match="^new_light:"):
        sh.check_light(np.zeros(3), name="new_light")


@pytest.mark.parametrize("shape", [(9,), (4, 9), (3, 5, 9)])
def test_shading_matches_definition(shape):
    rng = np.random.default_rng(0)
    transport = rng.normal(size=shape).astype(np.float32)
    light = rng.normal(size=(9, 3))
    before = transport.copy()
    out = sh.shading(transport, light)
    assert out.dtype == np.float32 and out.shape == shape[:-1] + (3,)
    np.testing.assert_allclose(out, np.maximum(0, transport.astype(np.float64) @ light), rtol=1e-5, atol=1e-5)
    assert (out >= 0).all()
    np.testing.assert_array_equal(transport, before)


def test_shading_non_contiguous_and_float64_transport():
    transport = np.random.default_rng(1).normal(size=(6, 8, 9))[:, ::2]
    light = random_light()
    np.testing.assert_allclose(sh.shading(transport, light), np.maximum(0, transport @ light), rtol=1e-5, atol=1e-5)


def test_shading_of_unoccluded_sphere_is_irradiance():
    n = random_dirs(20)
    light = random_light()
    transport = sh.cosine_lobe() * sh.basis(n)
    np.testing.assert_allclose(sh.shading(transport, light), np.maximum(0, sh.irradiance(light, n)), atol=1e-5)


def test_shading_rejects_bad_input():
    with pytest.raises(RelightError, match=r"transport: expected \(\.\.\., 9\)"):
        sh.shading(np.zeros((4, 4, 8), np.float32), random_light())
    with pytest.raises(RelightError, match="light"):
        sh.shading(np.zeros((4, 4, 9), np.float32), np.zeros((3, 9)))


# ----------------------------------------------------------------------------------------- rotation


def test_rotate_z_inline_golden():
    # ../shared/vectors/sh_golden.json rotations[0] (pyshtools SHRotateRealCoef, converted to §3), column 0.
    light = np.zeros((9, 3))
    light[:, 0] = [-0.5190133298294971, 0.8767181724687065, -0.8258165208830098, 0.7197279364283922,
                   2.5594577984058473, 0.8271065315552476, -0.4426921491035081, 0.2838299564910305,
                   -0.9854038336302882]  # fmt: skip
    expected = [-0.5190133298294971, 0.8236181965493566, -0.8258165208830097, -0.7799334091607598,
                -2.723848789929132, 0.38493725514424315, -0.442692149103508, -0.7851674778956831,
                0.3201448215345313]  # fmt: skip
    np.testing.assert_allclose(sh.rotate_z(light, 1.4455383750553397)[:, 0], expected, atol=1e-12)


def test_rotate_golden_file(shared_dir):
    golden = json.loads((shared_dir / "vectors" / "sh_golden.json").read_text())
    assert len(golden["rotations"]) == 6
    for case in golden["rotations"]:
        light, angle, expected = np.array(case["light"]), case["angle"], np.array(case["rotate_z"])
        np.testing.assert_allclose(sh.rotate_z(light, angle), expected, atol=1e-12)
        np.testing.assert_allclose(sh.rotate(light, sh.rotation_matrix(yaw=angle)), expected, atol=1e-12)
        # The reference's sh_rotate(light, a) is rotate_z(light, -a): undoing our rotation restores it.
        np.testing.assert_allclose(sh.rotate_z(expected, -angle), light, atol=1e-12)


def test_rotate_z_carries_x_toward_y():
    light = sh.basis(np.array([1.0, 0.0, 0.0]))[:, None] * np.ones(3)
    np.testing.assert_allclose(sh.rotate_z(light, math.pi / 2)[:, 0], sh.basis(np.array([0.0, 1.0, 0.0])), atol=1e-12)


@pytest.mark.parametrize("seed", range(4))
def test_rotate_moves_a_delta_light_with_r(seed):
    r = random_rotation(seed)
    d = random_dirs(5, seed)
    lights = sh.basis(d)[..., None] * np.array([1.0, 0.5, 2.0])  # (5, 9, 3) point lights
    np.testing.assert_allclose(sh.rotate(lights, r), sh.basis(d @ r.T)[..., None] * [1.0, 0.5, 2.0], atol=1e-12)


@pytest.mark.parametrize("seed", range(4))
def test_rotate_preserves_band_energy(seed):
    light = random_light(seed)
    out = sh.rotate(light, random_rotation(seed + 10))
    np.testing.assert_allclose(band_energy(out), band_energy(light), rtol=1e-12)


def test_rotation_by_two_pi_is_identity():
    light = random_light()
    np.testing.assert_allclose(sh.rotate_z(light, 2 * math.pi), light, atol=1e-12)
    for kw in ({"yaw": 2 * math.pi}, {"pitch": 2 * math.pi}, {"roll": 360.0, "degrees": True}):
        np.testing.assert_allclose(sh.rotate(light, sh.rotation_matrix(**kw)), light, atol=1e-12)


@pytest.mark.parametrize("angle", [-2.0, 0.0, 0.3, math.pi, 5.0])
def test_rotate_z_equals_rotate_of_rz(angle):
    light = random_light()
    c, s = math.cos(angle), math.sin(angle)
    rz = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    np.testing.assert_allclose(sh.rotate_z(light, angle), sh.rotate(light, rz), atol=1e-12)


def test_rotate_composition():
    light = random_light()
    r1, r2 = random_rotation(1), random_rotation(2)
    np.testing.assert_allclose(sh.rotate(sh.rotate(light, r1), r2), sh.rotate(light, r2 @ r1), atol=1e-12)
    np.testing.assert_allclose(sh.rotate(sh.rotate(light, r1), r1.T), light, atol=1e-12)


def test_rotate_batches_and_does_not_modify_input():
    lights = random_light(batch=(4,))
    before = lights.copy()
    rots = np.stack([random_rotation(s) for s in range(4)])
    out = sh.rotate(lights, rots)
    assert out.shape == (4, 9, 3)
    for i in range(4):
        np.testing.assert_allclose(out[i], sh.rotate(lights[i], rots[i]), atol=1e-12)
    np.testing.assert_array_equal(lights, before)
    angles = np.array([0.1, 0.2, 0.3])
    assert sh.rotate_z(lights[0], angles).shape == (3, 9, 3)
    np.testing.assert_allclose(sh.rotate_z(lights[0], angles)[2], sh.rotate_z(lights[0], 0.3), atol=1e-12)


@pytest.mark.parametrize(
    ("bad", "match"),
    [
        (np.diag([1.0, 1.0, -1.0]), "reflection"),
        (2 * np.eye(3), "not orthonormal"),
        (np.eye(3) + 0.01, "not orthonormal"),
        (np.eye(4), r"\(3, 3\)"),
        (np.full((3, 3), np.nan), "NaN"),
    ],
)
def test_rotate_rejects_non_rotations(bad, match):
    with pytest.raises(RelightError, match=match):
        sh.rotate(random_light(), bad)
    with pytest.raises(RelightError, match=match):
        sh.rotation_coefficients(bad)


@pytest.mark.parametrize("seed", range(3))
def test_rotation_coefficients_are_rotate_as_an_orthogonal_matrix(seed):
    """M = rotation_coefficients(R): rotate(L, R) == M @ L, M.T undoes it, and a row vector T turns by T @ M so that
    (T @ M) . L == T . rotate(L, R) (a transport seen in the rotated frame, relight_rt.relight.upright)."""
    r, light = random_rotation(seed), random_light(seed)
    m = sh.rotation_coefficients(r)
    assert m.shape == (9, 9)
    np.testing.assert_allclose(m @ light, sh.rotate(light, r), atol=1e-12)
    np.testing.assert_allclose(m.T @ m, np.eye(9), atol=1e-12)
    t = np.random.default_rng(seed).normal(size=9)
    np.testing.assert_allclose((t @ m) @ light, t @ sh.rotate(light, r), atol=1e-12)
    assert sh.rotation_coefficients(np.stack([r, r.T])).shape == (2, 9, 9)


def test_rotate_z_rejects_bad_input():
    with pytest.raises(RelightError, match="angle"):
        sh.rotate_z(random_light(), float("nan"))
    with pytest.raises(RelightError, match="light"):
        sh.rotate_z(np.zeros((9, 2)), 0.1)
    with pytest.raises(RelightError, match="broadcast"):
        sh.rotate_z(np.zeros((4, 9, 3)), np.zeros(3))


def test_rotation_matrix_axes_and_order():
    q = math.pi / 2
    np.testing.assert_allclose(sh.rotation_matrix(yaw=q) @ [1, 0, 0], [0, 1, 0], atol=1e-15)  # +x → +y
    np.testing.assert_allclose(sh.rotation_matrix(pitch=q) @ [0, 0, 1], [1, 0, 0], atol=1e-15)  # +z → +x
    np.testing.assert_allclose(sh.rotation_matrix(roll=q) @ [0, 1, 0], [0, 0, 1], atol=1e-15)  # +y → +z
    yaw, pitch, roll = 0.4, -0.7, 1.9
    expected = sh.rotation_matrix(yaw=yaw) @ sh.rotation_matrix(pitch=pitch) @ sh.rotation_matrix(roll=roll)
    np.testing.assert_allclose(sh.rotation_matrix(yaw, pitch, roll), expected, atol=1e-15)
    np.testing.assert_allclose(
        sh.rotation_matrix(30, 45, -60, degrees=True), sh.rotation_matrix(*np.deg2rad([30, 45, -60])), atol=1e-15
    )
    r = sh.rotation_matrix(yaw, pitch, roll)
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-14)
    assert np.linalg.det(r) == pytest.approx(1.0)
    assert sh.rotation_matrix(yaw=np.zeros(5)).shape == (5, 3, 3)
    with pytest.raises(RelightError, match="finite"):
        sh.rotation_matrix(yaw=float("inf"))


# ----------------------------------------------------------------------------------------- irradiance / preview


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_irradiance_shapes(dtype):
    n = random_dirs(12).reshape(3, 4, 3).astype(dtype)
    e = sh.irradiance(random_light(), n)
    assert e.shape == (3, 4, 3) and e.dtype == dtype


def test_irradiance_of_constant_radiance_is_pi_times_it():
    light = envmap.project_envmap(np.full((32, 64, 3), 0.5))
    np.testing.assert_allclose(sh.irradiance(light, random_dirs(10)), 0.5 * math.pi, rtol=1e-3)


def test_render_sphere_orientation():
    size = 32
    # A point light from the image's right (+y) and one from above (+z).
    right = sh.basis(np.array([0.0, 1.0, 0.0]))[:, None] * np.ones(3)
    top = sh.basis(np.array([0.0, 0.0, 1.0]))[:, None] * np.ones(3)
    img, mask = sh.render_sphere(right, size, return_mask=True)
    assert img.shape == (size, size, 3) and img.dtype == np.float32 and mask.shape == (size, size)
    assert (img[~mask] == 0).all() and (img >= 0).all()
    mid = size // 2
    assert img[mid, size - 4, 0] > img[mid, 3, 0]  # column → +y
    img = sh.render_sphere(top, size)
    assert img[3, mid, 0] > img[size - 4, mid, 0]  # row → −z
    assert mask.sum() == pytest.approx(math.pi * size**2 / 4, rel=0.05)
    # The centre pixel looks along +x: its value is the irradiance at n = +x.
    light = random_light()
    centre = sh.render_sphere(light, 33)[16, 16]
    np.testing.assert_allclose(centre, np.maximum(0, sh.irradiance(light, np.array([1.0, 0.0, 0.0]))), rtol=1e-5)


@pytest.mark.parametrize("size", [0, -3, 2.5, True])
def test_render_sphere_rejects_bad_size(size):
    with pytest.raises(RelightError, match="size"):
        sh.render_sphere(random_light(), size)


def test_dominant_direction_of_a_lamp_and_of_ambient_light():
    from relight_rt import lights

    lamp = lights.directional((0.0, 1.0, 1.0))[:, 0]
    d, how = sh.dominant_direction(lamp)
    np.testing.assert_allclose(d, np.array([0.0, 1.0, 1.0]) / np.sqrt(2), atol=1e-9)
    assert how > 0.5
    assert sh.dominant_direction(lights.ambient(0.5)[:, 0]) == (None, 0.0)
    with pytest.raises(RelightError, match="9 SH coefficients"):
        sh.dominant_direction(np.zeros((9, 3)))


@pytest.mark.parametrize("k", [1, 3])
def test_shading_chw_is_shading_channel_first(k):
    """sh.shading_chw (the relight hot path, in pixel blocks) is the formula of sh.shading for each light."""
    rng = np.random.default_rng(k)
    t = rng.standard_normal((9, 37, 300)).astype(np.float32)  # 11,100 pixels: several blocks for k = 3
    lits = rng.standard_normal((k, 9, 3)) * 0.4
    albedo = rng.random((3, 37, 300)).astype(np.float32)
    got = sh.shading_chw(t, lits)
    dif = sh.shading_chw(t, lits, albedo)
    assert got.shape == dif.shape == (k, 3, 37, 300) and got.dtype == dif.dtype == np.float32
    for i in range(k):
        want = sh.shading(np.moveaxis(t, 0, -1), lits[i])
        np.testing.assert_allclose(np.moveaxis(got[i], 0, -1), want, rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(dif[i], np.clip(albedo * got[i], 0, 1), rtol=1e-6, atol=1e-6)
    np.testing.assert_array_equal(sh.shading_chw(t, lits[0]), got[:1])  # one (9, 3) light: K = 1


@pytest.mark.parametrize(
    ("transport", "lights", "albedo", "match"),
    [
        (np.zeros((37, 30, 9), np.float32), np.zeros((9, 3)), None, r"transport: expected \(9, H, W\)"),
        (np.zeros((9, 4, 4), np.float32), np.zeros((9, 4)), None, "lights: expected an SH light"),
        (np.zeros((9, 4, 4), np.float32), np.full((2, 9, 3), np.nan), None, "NaN"),
        (np.zeros((9, 4, 4), np.float32), np.zeros((1, 1, 9, 3)), None, r"lights: expected \(K, 9, 3\)"),
        (np.zeros((9, 4, 4), np.float32), np.zeros((9, 3)), np.zeros((3, 4, 5), np.float32), "albedo"),
    ],
)
def test_shading_chw_refuses_bad_input(transport, lights, albedo, match):
    with pytest.raises(RelightError, match=match):
        sh.shading_chw(transport, lights, albedo)


def test_sphere_directions_are_unit_and_cover_the_sphere_evenly():
    d = sh.sphere_directions(2000)
    assert d.shape == (2000, 3)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(d.mean(axis=0), 0.0, atol=2e-3)  # no side favoured
    # the mean of Y_k over the sphere is 0 for k > 0: sums over these directions integrate the basis
    np.testing.assert_allclose(sh.basis(d)[:, 1:].mean(axis=0), 0.0, atol=5e-3)


def test_mirror_signs_are_the_basis_seen_in_a_mirror():
    """A direction mirrored y -> -y (a picture mirrored left-right) has the basis times ``MIRROR_SIGNS``."""
    dirs = random_dirs(64)
    mirrored = dirs * np.array([1.0, -1.0, 1.0])
    np.testing.assert_allclose(sh.basis(mirrored), sh.basis(dirs) * sh.MIRROR_SIGNS, atol=1e-12)
