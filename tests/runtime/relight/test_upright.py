"""A person lying or tilted decomposed in their upright frame (relight_rt.relight.upright, Relighter._stage1)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from relight_rt import Relighter, RuntimeConfig
from relight_rt.image.io import read_image, read_mask
from relight_rt.light import sh
from relight_rt.light.sh import MIRROR_SIGNS
from relight_rt.relight.upright import (
    HEAD_OFF,
    LONG_BODY,
    matte_axis,
    mirror_averaged,
    mirror_picture,
    quarter_coefficients,
    quarter_rotation,
    standing,
    turn_picture,
    turned_back,
    unturn_point,
    upright_quarters,
)


def _sphere_normals(r: int) -> tuple[np.ndarray, np.ndarray]:
    """(r, r, 3) unit normals of a sphere filling an r x r picture seen from the camera (DESIGN.md §3: +x toward the
    camera, +y the picture's right, +z its top), and the (r, r) bool disc where it is."""
    c = (np.arange(r) + 0.5) / r * 2 - 1
    y = np.broadcast_to(c[None, :], (r, r))  # columns: +y to the right
    z = np.broadcast_to(-c[:, None], (r, r))  # rows: +z up
    inside = y * y + z * z < 1
    x = np.sqrt(np.clip(1 - y * y - z * z, 0, 1))
    return np.stack([x, y, z], axis=-1), inside


def _sphere_transport(normals: np.ndarray) -> np.ndarray:
    """(9, r, r) an unoccluded surface's transport A_l Y_k(n) (DESIGN.md §3), channel-first."""
    t = sh.basis(normals.reshape(-1, 3)) * sh.cosine_lobe()
    return t.reshape(normals.shape[:2] + (9,)).transpose(2, 0, 1)


@pytest.mark.parametrize("q", [1, 2, 3])
def test_a_turned_picture_is_the_scene_turned_about_the_view_axis(q):
    """np.rot90 by q quarters pictures the scene turned by ``quarter_rotation(q)``: each surface point, moved with its
    pixel, has its normal rotated by it. A sphere pictured turned is the same sphere, so rotating the moved normals
    gives the sphere's own normal map back (the picture's right goes to its top: +y toward +z, about +x)."""
    normals, inside = _sphere_normals(32)
    moved = turn_picture(normals, q)  # each pixel's normal, moved with it
    assert np.allclose((moved @ quarter_rotation(q).T)[inside], normals[inside], atol=1e-12)
    if q != 2:  # a half turn is its own inverse; a quarter turned the other way is not the picture's
        assert not np.allclose((moved @ quarter_rotation(q))[inside], normals[inside], atol=0.1)
    assert np.allclose(quarter_rotation(q) @ quarter_rotation(4 - q), np.eye(3))


@pytest.mark.parametrize("q", [1, 2, 3])
def test_transport_turned_back_gives_the_turned_scenes_shading(q):
    """Shading of the upright run with L_up = M @ L equals the turned-back transport's shading with L (to 1e-6), for a
    random transport field and light."""
    rng = np.random.default_rng(q)
    r = 24
    seen = {"albedo": rng.random((3, r, r), dtype=np.float32), "skin": rng.random((1, r, r), dtype=np.float32),
            "transport": rng.normal(size=(9, r, r)).astype(np.float32),
            "light": rng.normal(size=(9, 3)).astype(np.float32)}
    light = rng.normal(size=(9, 3))
    light_up = sh.rotate(light, quarter_rotation(q))
    assert np.allclose(light_up, quarter_coefficients(q) @ light)
    back = turned_back(seen, q)
    shading_up = np.einsum("khw,kc->hwc", seen["transport"].astype(np.float64), light_up)
    shading = np.einsum("khw,kc->hwc", back["transport"].astype(np.float64), light)
    assert np.abs(turn_picture(shading_up, -q) - shading).max() < 1e-6 * max(1.0, np.abs(shading).max())
    assert np.array_equal(back["albedo"], turn_picture(seen["albedo"], -q, (1, 2)))
    assert np.array_equal(back["skin"], turn_picture(seen["skin"], -q, (1, 2)))
    # the light estimated upright, turned back, is the one whose turn stage 1 saw
    assert np.allclose(sh.rotate(back["light"], quarter_rotation(q)), seen["light"], atol=1e-5)


@pytest.mark.parametrize("q", [1, 3])
def test_a_spheres_transport_seen_turned_comes_back_as_its_own(q):
    """The analytic transport of a sphere pictured turned (normals rotated by the turn), turned back, is the sphere's
    transport as pictured: the convention holds physically, not only algebraically."""
    normals, inside = _sphere_normals(32)
    own = _sphere_transport(normals)
    # the turned picture: each surface point moved with its pixel, its normal rotated by the turn
    seen_turned = _sphere_transport(turn_picture(normals, q) @ quarter_rotation(q).T)
    zero = np.zeros((1, 32, 32), np.float32)
    back = turned_back({"albedo": np.zeros((3, 32, 32), np.float32), "skin": zero,
                        "transport": seen_turned.astype(np.float32), "light": np.zeros((9, 3))}, q)
    assert np.abs(back["transport"][:, inside] - own[:, inside]).max() < 1e-5
    # and the turned picture's transport is not the picture's own turned (the coefficients had to turn)
    assert np.abs(turn_picture(seen_turned, -q, (1, 2))[:, inside] - own[:, inside]).max() > 0.5


def test_a_mirrored_lamps_shading_on_mirrored_normals_is_the_shading_mirrored():
    """The picture mirrored left-right is the scene mirrored y -> -y: a sphere's normals moved with their pixels and
    mirrored are the sphere's own again, and a lamp mirrored (``MIRROR_SIGNS`` times its coefficients) shades them as
    the original lamp shades the picture, mirrored. Each sign is needed: flipping any one breaks it."""
    normals, inside = _sphere_normals(32)
    moved = mirror_picture(normals) * np.array([1.0, -1.0, 1.0])  # each pixel's normal, moved and mirrored
    assert np.allclose(moved[inside], normals[inside], atol=1e-12)
    rng = np.random.default_rng(7)
    light = rng.normal(size=(9, 3))
    transport = _sphere_transport(normals)
    shading = np.einsum("khw,kc->hwc", transport, light)
    seen = np.einsum("khw,kc->hwc", _sphere_transport(moved), MIRROR_SIGNS[:, None] * light)
    assert np.abs(seen - mirror_picture(shading))[inside].max() < 1e-9
    for k in range(9):  # no sign can be other than it is
        wrong = MIRROR_SIGNS.copy()
        wrong[k] = -wrong[k]
        off = np.einsum("khw,kc->hwc", transport, wrong[:, None] * light)
        assert np.abs(off - mirror_picture(shading))[inside].max() > 0.05, k
    # the odd coefficients are those of DESIGN.md's basis odd in y: y, xy, yz
    assert np.flatnonzero(MIRROR_SIGNS < 0).tolist() == [1, 4, 5]


def test_mirror_averaged_answers_of_a_picture_and_its_mirror_are_each_others_mirrored():
    """Stage 1's answers for a picture (a) and its mirror (b), averaged one way and the other, are each other's
    mirror image: the images mirrored and the coefficients signed; their shading under mirrored lights is the
    shading mirrored."""
    rng = np.random.default_rng(3)
    r = 16

    def answer():
        return {"albedo": rng.random((3, r, r), dtype=np.float32), "skin": rng.random((1, r, r), dtype=np.float32),
                "transport": rng.normal(size=(9, r, r)).astype(np.float32),
                "light": rng.normal(size=(9, 3)).astype(np.float32)}

    a, b = answer(), answer()
    one, two = mirror_averaged(a, b), mirror_averaged(b, a)
    signs = MIRROR_SIGNS.astype(np.float32)
    for k in ("albedo", "skin"):
        assert np.allclose(two[k], mirror_picture(one[k], 2), atol=1e-6)
    assert np.allclose(two["transport"], signs[:, None, None] * mirror_picture(one["transport"], 2), atol=1e-6)
    assert np.allclose(two["light"], signs[:, None] * one["light"], atol=1e-6)
    # a picture that is its own mirror image with the answer's mirror image: nothing changes
    sym = mirror_averaged(a, {**{k: mirror_picture(a[k], 2) for k in ("albedo", "skin")},
                              "transport": signs[:, None, None] * mirror_picture(a["transport"], 2),
                              "light": signs[:, None] * a["light"]})
    for k in sym:
        assert np.allclose(sym[k], a[k], atol=1e-6), k
    light = rng.normal(size=(9, 3)).astype(np.float32)
    s1 = np.einsum("khw,kc->hwc", one["transport"], light)
    s2 = np.einsum("khw,kc->hwc", two["transport"], signs[:, None] * light)
    assert np.allclose(s2, mirror_picture(s1), atol=1e-5)


def test_unturn_point_inverts_rot90():
    a = np.arange(35).reshape(5, 7)
    for q in range(4):
        t = np.rot90(a, q)
        for r, c in ((0, 0), (1, 3), (t.shape[0] - 1, t.shape[1] - 1)):
            x, y = unturn_point(c, r, q, a.shape)
            assert a[int(y), int(x)] == t[r, c]


def _ellipse(r: int, long: float, short: float, horizontal: bool, dx: float = 0.0) -> np.ndarray:
    yy, xx = np.mgrid[0:r, 0:r].astype(np.float64)
    a, b = (long, short) if horizontal else (short, long)
    return (((xx - r / 2 - dx) / a) ** 2 + ((yy - r / 2) / b) ** 2 <= 1).astype(np.float32)


def test_matte_axis_finds_a_bodys_length_and_direction():
    centre, axis, long_ = matte_axis(_ellipse(128, 60, 15, horizontal=True))
    assert np.allclose(centre, 63.5, atol=0.5) and abs(axis[0]) > 0.99 and long_ == pytest.approx(4, rel=0.05)
    assert standing(_ellipse(128, 60, 15, horizontal=False))
    assert not standing(_ellipse(128, 60, 15, horizontal=True))
    assert not standing(_ellipse(128, 20, 18, horizontal=False))  # a head and shoulders: too round to tell


def test_a_lying_person_is_turned_head_up_and_an_upright_one_is_not():
    r = 128
    lying = _ellipse(r, 60, 15, horizontal=True)
    size, up, left, right, down = 14.0, (0.0, -1.0), (-1.0, 0.0), (1.0, 0.0), (0.0, 1.0)
    assert upright_quarters(lying, [(r / 2 + 50, r / 2, size, *up)]) == 1  # head on the right: turned left
    assert upright_quarters(lying, [(r / 2 - 50, r / 2, size, *up)]) == 3
    assert upright_quarters(lying, [(r / 2 + 50, r / 2, size, *right)]) == 1  # the face's own up does not decide
    assert upright_quarters(lying, [(r / 2 + 50, r / 2, size, *up)]) == 1
    assert upright_quarters(lying, []) == 0  # no face: nothing says where the head is
    assert upright_quarters(lying, [(r / 2 + 50, r / 2, size, *up), (r / 2 - 50, r / 2, size, *up)]) == 0  # a group
    assert upright_quarters(lying, [(r / 2 + 0.5 * HEAD_OFF * size, r / 2, size, *up)]) == 0  # a face near the middle
    assert upright_quarters(lying, [(r / 2 + 50, r / 2, size, *up)], cut_below=size) == 0  # goes on below the frame
    assert upright_quarters(lying, [(r / 2 + 40, r / 2 - 30, size, *up)]) == 1  # tilted 53 deg: turned
    assert upright_quarters(lying, [(r / 2 + 30, r / 2 - 40, size, *up)]) == 0  # tilted 37 deg: kept
    # a vaulting runner: legs stretched out sideways make the matte long across, the face above its centre
    vault = np.maximum(lying, _ellipse(r, 40, 12, horizontal=False) * (np.arange(r)[:, None] < r / 2))
    assert not standing(vault)
    assert upright_quarters(vault, [(r / 2, r / 2 - 36, size, *up)]) == 0
    # a mask given over four people standing in a row (one face found, at one end): a body's height across, kept
    row = np.maximum.reduce([_ellipse(r, 36, 12, horizontal=False, dx=dx) for dx in (-48, -16, 16, 48)])
    assert not standing(row) and matte_axis(row)[2] >= LONG_BODY
    assert upright_quarters(row, [(r / 2 - 48, r / 2 - 30, 9.0, *up)]) == 0
    standing_ = _ellipse(r, 60, 15, horizontal=False)
    for face in ([(r / 2, r / 2 - 50, size, *up)], [(r / 2, r / 2 + 50, size, *down)], []):
        assert upright_quarters(standing_, face) == 0
    round_ = _ellipse(r, 40, 40 / (LONG_BODY - 0.2), horizontal=True)  # a head and shoulders, or a face
    assert upright_quarters(round_, [(r / 2, r / 2 - 20, size, *up)]) == 0
    assert upright_quarters(round_, [(r / 2 - 20, r / 2, size, *right)]) == 3  # away from the shoulders: left
    assert upright_quarters(round_, [(r / 2, r / 2, size, *left)]) == 3  # a face filling it: its own up says
    assert upright_quarters(round_, [(r / 2, r / 2, size, *down)]) == 2
    assert upright_quarters(round_, [(r / 2, r / 2, size, 0.6, -0.8)]) == 0  # tilted less than 45 deg
    assert upright_quarters(round_, [(r / 2, r / 2, size, 0.0, 0.0)]) == 0  # its up not known


def test_a_faint_matte_is_turned_as_a_full_one():
    """A matte with no pixel above one half (a half-alpha mask the intake accepts: alpha >= 0.5) is measured as the
    same matte at full alpha (it raised numpy's ValueError on the empty pixel set)."""
    r, size, up = 128, 14.0, (0.0, -1.0)
    lying = _ellipse(r, 60, 15, horizontal=True)
    for faint in (0.5 * lying, 0.3 * lying):
        for x in (r / 2 + 50, r / 2 - 50, r / 2 + 30):
            face = [(x, r / 2, size, *up)]
            assert upright_quarters(faint, face) == upright_quarters(lying, face)


@pytest.fixture(scope="module")
def relighter():
    return Relighter(RuntimeConfig(device="cpu"))


@pytest.fixture(scope="module")
def sample(reference_dir):
    photo = reference_dir / "photo"
    image = read_image(photo / "sample.jpg")
    return image, read_mask(photo / "sample_mask.png", image.shape[:2])


def test_an_upright_photo_is_decomposed_bit_for_bit_as_without_the_rule(relighter, sample):
    image, mask = sample
    dec = relighter.decompose(image, mask)
    relighter.upright = False
    try:
        off = relighter.decompose(image, mask)
    finally:
        relighter.upright = True
    assert dec.upright == 0
    for name in ("albedo_chw", "transport_chw", "skin", "light"):
        assert np.array_equal(getattr(dec, name), getattr(off, name)), name


@pytest.mark.parametrize("q", [1, 3])
def test_a_photo_lying_on_its_side_is_decomposed_upright(relighter, sample, q):
    """The reference photo turned a quarter: stage 1 sees it upright again, and its light comes out as the upright
    photo's turned by the same quarter (without the rule it is far from it)."""
    image, mask = sample
    upright = relighter.decompose(image, mask)
    turned = relighter.decompose(turn_picture(image, q), turn_picture(mask, q))
    assert turned.upright == (4 - q) % 4
    # the head pass looks for a face in an upright person's upper part: a turned one gets none
    assert upright.head is not None and turned.head is None
    expected = sh.rotate(upright.light, quarter_rotation(q))
    relighter.upright = False
    try:
        off = relighter.decompose(turn_picture(image, q), turn_picture(mask, q))
    finally:
        relighter.upright = True
    err = np.abs(turned.light - expected).max()
    assert off.upright == 0 and err < 0.5 * np.abs(off.light - expected).max()
    # the transport is the upright one's turned, pixel grid and coefficients (the crop box differs by a pixel)
    own = np.einsum("khw,kc->hwc", upright.transport_chw, upright.white_light)
    seen = np.einsum("khw,kc->hwc", turned.transport_chw, sh.rotate(upright.white_light, quarter_rotation(q)))
    m = upright.network_mask > 0.5
    corr = np.corrcoef(turn_picture(own, q)[turn_picture(m, q)][:, 1], seen[turn_picture(m, q)][:, 1])[0, 1]
    assert corr > 0.95


def test_a_mirrored_photo_decomposes_to_the_photos_decomposition_mirrored(relighter, sample, monkeypatch):
    """Stage 1 mirror-averaged (network ``STAGE1_MIRROR``, on since mirror34 with the other three mirror-symmetric
    parts): the reference photo mirrored left-right decomposes to its decomposition mirrored, the light's
    coefficients signed (to the face mesh and head pass in between); without it the light's left-right terms differ
    ten times as much (0.157 against 0.013, measured with the other three parts off: the crop a pixel apart)."""
    from relight_rt.relight import network

    image, mask = sample
    signs = MIRROR_SIGNS[:, None]
    errors = {}
    for on in (False, True):
        monkeypatch.setattr(network, "STAGE1_MIRROR", on)
        dec = relighter.decompose(image, mask)
        mir = relighter.decompose(mirror_picture(image), mirror_picture(mask))
        errors[on] = np.abs(mir.light - signs * dec.light).max()
    assert errors[True] < 0.5 * errors[False], errors


def test_a_mirrored_photo_relights_to_the_result_mirrored_with_all_four_parts(relighter, monkeypatch):
    """Stage 1, the face mesh, the crop and stage 2 all mirror-symmetric (``STAGE1_MIRROR``, ``MESH_FLIP``,
    ``SYMMETRIC_CROP``, ``STAGE2_MIRROR``): the bundled example mirrored and relit under a side lamp mirrored is its
    result mirrored within 1 level (8-bit, p99 over the person, its mask given); with stage 2 alone left out the two
    differ by several levels, so each part is needed (mirror31's probe: 9 levels)."""
    import cv2

    import relight_rt
    from relight_rt.image import crop
    from relight_rt.light import presets
    from relight_rt.person import face_mesh
    from relight_rt.relight import network

    rgba = cv2.imread(str(Path(relight_rt.__file__).parent / "data" / "example.png"), cv2.IMREAD_UNCHANGED)
    rgb = cv2.cvtColor(rgba[..., :3], cv2.COLOR_BGR2RGB).astype(np.float32) / 255
    mask = rgba[..., 3].astype(np.float32) / 255
    lamp = (presets.directional((0.35, -1.0, 0.25), (1, 1, 1), 1.0, angular_radius=0.6)
            + presets.ambient(0.06)).astype(np.float32)
    for module, name in ((network, "STAGE1_MIRROR"), (face_mesh, "MESH_FLIP"), (crop, "SYMMETRIC_CROP")):
        monkeypatch.setattr(module, name, True)
    p99 = {}
    for stage2 in (False, True):
        monkeypatch.setattr(network, "STAGE2_MIRROR", stage2)
        a = relighter.relight(relighter.decompose(rgb, mask), lamp)
        b = relighter.relight(relighter.decompose(rgb[:, ::-1].copy(), mask[:, ::-1].copy()),
                              (MIRROR_SIGNS[:, None] * lamp).astype(np.float32))[:, ::-1]
        diff = np.abs(np.rint(np.clip(a, 0, 1) * 255) - np.rint(np.clip(b, 0, 1) * 255)).max(axis=2)
        p99[stage2] = float(np.percentile(diff[mask >= 0.5], 99))
    assert p99[True] <= 1.0 and p99[False] >= 3.0, p99
