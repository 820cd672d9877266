"""relight_rt.relight.cast_shadow: a face mesh's own cast shadows (the nose's, the brows') under a light's lamp.

A synthetic mesh stands in for a face: a plane facing the camera with a tall narrow ridge down its middle (a nose);
a lamp from the image's right throws the ridge's shadow onto the plane at its left, as far as the ridge's height
times the tangent of the lamp's angle."""

import math

import numpy as np
import pytest

from relight_rt import lights
from relight_rt.image.color import REC709
from relight_rt.light import sh
from relight_rt.relight.cast_shadow import MeshView, lamp, shadow_factor, visibility

SIDE = 100
RIDGE_HEIGHT = 25.0  # pixels toward the camera
RIDGE_X = 50.0


def grid_mesh(ridge: float = RIDGE_HEIGHT, step: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """(N, 3) vertices (x right, y down, z away) of a plane at z = 0 over [10, 90]^2 with a ridge at x = 50,
    y 30-70, rising ``ridge`` toward the camera; (T, 3) its triangles."""
    xs = np.arange(10, 90 + 1e-9, step)
    gx, gy = np.meshgrid(xs, xs)
    bump = np.exp(-0.5 * ((gx - RIDGE_X) / 3.0) ** 2) * ((gy > 30) & (gy < 70))
    pts = np.stack([gx.ravel(), gy.ravel(), -ridge * bump.ravel()], axis=1)
    n = xs.size
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    tris = np.concatenate([np.stack([a, b, c], 1), np.stack([b, d, c], 1)])
    return pts, tris


def toward(azimuth_deg: float, elevation_deg: float = 0.0) -> np.ndarray:
    """A direction toward a lamp: azimuth > 0 toward the image's right (+y), elevation up (+z)."""
    a, e = math.radians(azimuth_deg), math.radians(elevation_deg)
    return np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])


def lum(light: np.ndarray) -> np.ndarray:
    return np.asarray(light, np.float64) @ REC709


def test_the_lamp_of_a_light_is_its_direction_strength_and_size_and_ambient_casts_nothing():
    d = toward(25, 10)
    for radius in (0.0, 0.2, 0.5):
        only = lum(lights.directional(d, (1, 1, 1), 1.0, angular_radius=radius))
        direction, cap, angle = lamp(only + lum(lights.ambient(0.2)))
        np.testing.assert_allclose(direction, d, atol=1e-6)
        assert angle == pytest.approx(radius, abs=0.02)
        np.testing.assert_allclose(cap, only, atol=1e-6)  # the lamp is all of the light but the ambient
    assert lamp(lum(lights.ambient(0.5))) is None  # no direction
    assert lamp(lum(lights.directional(d, (1, 1, 1), 1.0, angular_radius=1.3))) is None  # wider than MAX_ANGLE
    # a weak lamp in a strong ambient: below MIN_SHARE of the light, no shadow
    assert lamp(lum(lights.directional(d, (1, 1, 1), 0.1) + lights.ambient(2.0))) is None


def test_the_ridge_shadows_the_plane_on_the_side_away_from_the_lamp_as_far_as_its_height_reaches():
    pts, tris = grid_mesh()
    view = MeshView(pts, tris, (SIDE, SIDE))
    right = visibility(view, toward(25), 0.0)  # lamp from the image's right: shadow at the ridge's left
    reach = RIDGE_HEIGHT * math.tan(math.radians(25))  # ~11.7 px
    rows = slice(38, 62)
    assert right[rows, 42:46].mean() < 0.3  # in the shadow
    assert right[rows, 54:60].min() > 0.95  # the lit side
    assert right[rows, int(RIDGE_X - reach - 8) : int(RIDGE_X - reach - 4)].min() > 0.9  # beyond the shadow
    assert right[12:24, 15:85].min() > 0.97 and right[78:88, 15:85].min() > 0.97  # above and below the ridge
    left = visibility(view, toward(-25), 0.0)  # mirrored
    assert left[rows, 55:59].mean() < 0.3 and left[rows, 40:46].min() > 0.95
    # a larger lamp: a softer border, the same shadow in the middle
    soft = visibility(view, toward(25), 0.4)
    outer = int(RIDGE_X - reach - 5)
    assert np.abs(np.diff(soft[rows, 30:50], axis=1)).max() < np.abs(np.diff(right[rows, 30:50], axis=1)).max()
    assert soft[rows, outer].mean() < right[rows, outer].mean() - 0.05  # the penumbra reaches farther out
    assert soft[rows, 30:50].min() > right[rows, 30:50].min() + 0.1  # and the umbra is lighter


def test_a_surface_without_relief_casts_no_shadow_even_at_grazing_lamps():
    """A tilted plane lit at up to ~87 degrees from its normal: the lamp's map of it is a thin strip there, whose
    steps a depth bias cannot cover; a shadow is only trusted where the lamp meets the surface steeper than
    ``GRAZING`` (at grazing the lamp gives the surface little of its light anyway)."""
    pts, tris = grid_mesh(ridge=0.0)
    pts[:, 2] = 0.3 * pts[:, 0]  # tilted: its right side farther from the camera
    view = MeshView(pts, tris, (SIDE, SIDE))
    for az in (-70, -25, 0, 25, 70):
        for el in (-30, 0, 30):
            assert visibility(view, toward(az, el), 0.0).min() > 0.99, (az, el)


def test_the_shadow_takes_the_lamps_share_of_the_light_only_where_the_weight_says():
    pts, tris = grid_mesh()
    view = MeshView(pts, tris, (SIDE, SIDE))
    transport = np.broadcast_to(
        (sh.basis(np.array([1.0, 0.0, 0.0])) * sh.cosine_lobe()).astype(np.float32), (SIDE, SIDE, 9)).copy()
    weight = np.ones((SIDE, SIDE), np.float32)
    d = toward(25)
    hard = shadow_factor(transport, lum(lights.directional(d)), (view,), weight)
    soft = shadow_factor(transport, lum(lights.directional(d) + lights.ambient(1.0)), (view,), weight)
    rows = slice(38, 62)
    assert hard[rows, 42:46].mean() < 0.3 and hard[rows, 54:60].min() > 0.95
    assert 0.3 < soft[rows, 42:46].mean() < 0.8  # the ambient half of the light stays in the shadow
    assert np.all(hard <= 1) and np.all(hard > 0)
    half = weight.copy()
    half[:, :SIDE // 2] = 0  # the shadow only where the weight is: the face's skin
    assert shadow_factor(transport, lum(lights.directional(d)), (view,), half)[:, : SIDE // 2].min() == 1
    assert shadow_factor(transport, lum(lights.ambient(1.0)), (view,), weight) is None
    assert shadow_factor(transport, lum(lights.directional(toward(100))), (view,), weight) is None  # from behind
    assert shadow_factor(transport, lum(lights.directional(d)), (), weight) is None


def test_two_lamps_read_as_one_wide_lamp_toward_the_stronger():
    """Two lamps from opposite sides: the degree-1 band of the sum points to the stronger; its share is what the
    two do not cancel (``sh.dominant_direction``)."""
    a = lum(lights.directional(toward(40), (1, 1, 1), 1.0))
    b = lum(lights.directional(toward(-40), (1, 1, 1), 0.5))
    found = lamp(a + b)
    assert found is not None and found[0][1] > 0.2  # toward the image's right, the stronger lamp
    assert found[2] > 0.5  # two lamps far apart read as one wide lamp: a soft shadow
    assert lamp(a)[2] == pytest.approx(0, abs=1e-3)


@pytest.fixture(scope="module")
def portrait(reference_dir):
    """The reference photo's head and shoulders (its head pass's square), decomposed: a face the body pass meshes."""
    import cv2

    import relight_rt
    from relight_rt import RuntimeConfig

    r = relight_rt.open(RuntimeConfig(device="cpu"))
    full = r.decompose(reference_dir / "photo" / "sample.jpg", reference_dir / "photo" / "sample_mask.png")
    y0, y1, x0, x1 = full.head_box
    photo = cv2.cvtColor(cv2.imread(str(reference_dir / "photo" / "sample.jpg")), cv2.COLOR_BGR2RGB)[y0:y1, x0:x1]
    mask = cv2.imread(str(reference_dir / "photo" / "sample_mask.png"), cv2.IMREAD_GRAYSCALE)[y0:y1, x0:x1]
    dec = r.decompose(np.ascontiguousarray(photo), np.ascontiguousarray(mask))
    assert dec.face_meshes and r._factor.own(dec, with_residual=False)["mesh_views"]
    return r, dec


def test_a_lamp_beside_a_real_face_darkens_only_its_skin_on_the_side_away_from_the_lamp(portrait, monkeypatch):
    """A lamp 25 degrees to the image's right darkens the face beside the nose on the image's left, only on the
    face, and never lightens; the photo's own light still gives the photo back. Without the rule (``Factor.cast``
    off) nothing darkens. (Exposure "physical": the meter's share is the next test's.)"""
    from relight_rt.relight.factor import Factor

    r, dec = portrait
    np.testing.assert_allclose(r.relight(dec, dec), dec.image, atol=2e-3)
    light = lights.directional(toward(25, 10)) + lights.ambient(0.05)
    shadowed = r.relight(dec, light, exposure="physical")
    monkeypatch.setattr(Factor, "cast", lambda self, *args: None)
    plain = r.relight(dec, light, exposure="physical")
    darker = (plain - shadowed) @ REC709
    pts = dec.face_meshes[0]
    (fx0, fy0), (fx1, fy1) = pts[:, :2].min(0).astype(int), pts[:, :2].max(0).astype(int)
    m = (fx1 - fx0) // 10  # the edge-aware upsampling reaches a few pixels past the mesh
    outside = np.ones(darker.shape, bool)
    outside[fy0 - m : fy1 + m, fx0 - m : fx1 + m] = False
    # only on the mesh's skin: outside its box nothing visible (1e-4 is 0.03 of an 8-bit level; measured 7.6e-6, 8.2e-7
    # before faces17, whose fill reaches a near-black pixel beside the face, 0.30 against 0.11, and with it the cast
    # shadow's softened edge through the change the fill adds)
    assert np.abs(darker[outside]).max() < 1e-4
    assert darker.min() > -1e-3  # a shadow only darkens
    cx, half = (fx0 + fx1) // 2, (fx1 - fx0) // 2
    left, right = darker[fy0:fy1, cx - half : cx].mean(), darker[fy0:fy1, cx : cx + half].mean()
    assert darker.max() > 0.03 and left > 3 * right


def test_auto_exposure_meters_the_cast_shadow_as_part_of_the_light_as_seen(portrait, monkeypatch):
    """"auto" keeps the person's light as seen: a lamp whose shadow darkens the face is scaled up by what the shadow
    takes (``ExposureMeter.meter_shadows``), a light without a lamp (ambient) not at all."""
    from relight_rt.relight.exposure_meter import ExposureMeter
    from relight_rt.relight.factor import Factor

    r, dec = portrait
    light = (lights.directional(toward(25, 10)) + lights.ambient(0.05)).astype(np.float32)
    metered = r._factor.meter.meter_shadows(dec, light)
    assert 1.0001 < float(metered[0, 0] / light[0, 0]) < 1.2  # the face is a small part of the person here
    np.testing.assert_allclose(metered / metered[0, 0], light / light[0, 0], rtol=1e-6)  # a scale, not a new light
    flat = lights.ambient(0.5).astype(np.float32)
    np.testing.assert_array_equal(r._factor.meter.meter_shadows(dec, flat), flat)
    both = r._factor.meter.meter_shadows(dec, np.stack([light, flat]))
    np.testing.assert_allclose(both, np.stack([metered, flat]), rtol=1e-6)
    exposed = r._factor.meter.expose(dec, light, "auto")  # the relighter's exposure goes through the meter
    monkeypatch.setattr(ExposureMeter, "meter_shadows", lambda self, dec, lits: lits)
    unmetered = r._factor.meter.expose(dec, light, "auto")
    assert float(exposed[0, 0] / unmetered[0, 0]) == pytest.approx(float(metered[0, 0] / light[0, 0]), rel=1e-5)
    monkeypatch.undo()
    monkeypatch.setattr(Factor, "cast", lambda self, *args: None)
    np.testing.assert_array_equal(r._factor.meter.meter_shadows(dec, light), light)


@pytest.mark.parametrize("sampled", [True, False])
def test_a_wide_lamps_shadow_fades_with_the_distance_from_what_casts_it(monkeypatch, sampled):
    """A lamp 20 degrees in radius: near the ridge all of its disc is hidden, farther out only the part farther from
    the camera's axis still is (tested over the disc: ``CAP_SAMPLED``); one hard shadow blurred by the lamp's size
    is as dark far out as near."""
    from relight_rt.relight import cast_shadow

    if not sampled:
        monkeypatch.setattr(cast_shadow, "CAP_SAMPLED", 10.0)  # the disc never sampled
    pts, tris = grid_mesh(ridge=40.0)
    vis = visibility(MeshView(pts, tris, (SIDE, SIDE)), toward(25), 0.35)
    rows = slice(40, 60)
    near, far = vis[rows, int(RIDGE_X) - 7].mean(), vis[rows, int(RIDGE_X) - 15].mean()
    assert (far > near + 0.15) == sampled
    if sampled:
        assert near < 0.2


def test_the_cast_shadows_kept_per_decomposition_are_the_last_few_light_directions(portrait):
    """A light dragged about (the studio) leaves at most ``CAST_CACHE`` window-sized maps on its Decomposition; a
    direction asked again after being dropped gives the same map."""
    from relight_rt.relight import factor as F

    r, dec = portrait
    f = r._factor
    first = (lights.directional(toward(25, 10)) + lights.ambient(0.05)).astype(np.float32)
    own = f.own(dec)
    kept = f.cast(dec, own, first)
    assert kept is not None
    for az in range(5, 5 + 3 * (F.CAST_CACHE + 3), 3):
        f.cast(dec, own, (lights.directional(toward(az, 10)) + lights.ambient(0.05)).astype(np.float32))
    assert len(f.memo(dec)["cast"]) == F.CAST_CACHE
    np.testing.assert_array_equal(f.cast(dec, own, first), kept)


def test_a_cast_shadow_is_the_same_whichever_scale_of_its_light_came_first(portrait):
    """fuzz8: the meter's light and the exposed one (the same light, another scale) share one cached map, which was
    made from whichever came first; relights of one Decomposition then differed by their order (up to 7e-7 among 8
    lights from 8 threads, 4e-5 after a light at a thousandth of its scale). The map is made from the key."""
    r, dec = portrait
    f = r._factor
    own = f.own(dec)
    light = (lights.directional(toward(25, 10)) + lights.ambient(0.05)).astype(np.float32)
    f.memo(dec).pop("cast", None)
    first = f.cast(dec, own, light)
    for scale in (1e-3, 0.37, 3.1):
        f.memo(dec).pop("cast")
        f.cast(dec, own, light * np.float32(scale))  # another scale of the light first
        np.testing.assert_array_equal(f.cast(dec, own, light), first)


def test_one_decomposition_relit_from_several_threads_at_once_is_relit_as_by_one(portrait):
    """fuzz8: eight lights at once on one Decomposition (the studio's renders, a caller's pool) give each light's
    picture of a fresh Relighter, to the bit; the cast-shadow maps they share are kept under the memo's lock."""
    import threading

    import relight_rt
    from relight_rt import RuntimeConfig

    r, dec = portrait
    ls = [(lights.directional(toward(az, 10)) + lights.ambient(0.05)).astype(np.float32) for az in range(-40, 41, 10)]
    fresh = relight_rt.open(RuntimeConfig(device="cpu"))
    want = [fresh.relight(dec, light) for light in ls]
    got: list = [None] * len(ls)

    def relight(i: int) -> None:
        got[i] = r.relight(dec, ls[i])

    threads = [threading.Thread(target=relight, args=(i,)) for i in range(len(ls))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for a, b in zip(got, want, strict=True):
        np.testing.assert_array_equal(a, b)


def test_the_relighters_shadow_layer_is_where_the_final_result_darkens(reference_dir):
    """``Relighter.cast_shadows`` (what the studio's preview draws): the body pass's cast shadows. On the reference
    photo (its face mesh in the body pass's own frame) under a lamp from the image's left, the final result is
    darker than without the cast shadows where the layer says a deep shadow falls, and unchanged where it says none
    below the face (the exposure's meter aside). The head pass's own shadows go with its change of the face
    (``Relighter.head_change``; the bundled example's face, small in the body's frame, casts none there)."""
    from relight_rt import Relighter, RuntimeConfig
    from relight_rt.relight.factor import Factor

    relighter = Relighter(RuntimeConfig(device="cpu"))
    photo = reference_dir / "photo"
    dec = relighter.decompose(photo / "sample.jpg", photo / "sample_mask.png")
    side = lights.directional((0.35, -1.0, 0.25), (1, 1, 1), 1.0, 0.6) + lights.ambient(0.06)
    depth, meter = relighter.cast_shadows(dec, side)
    assert depth is not None and depth.shape == dec.image.shape[:2] and 0.999 <= meter < 1.1
    shaded = relighter.relight(dec, side, exposure="physical")
    real_cast = Factor.cast
    Factor.cast = lambda self, d, own, light: None
    try:
        plain = relighter.relight(dec, side, exposure="physical")
    finally:
        Factor.cast = real_cast
    y_shaded, y_plain = shaded @ REC709, plain @ REC709
    person = np.asarray(dec.mask) > 0.5
    deep = person & (depth > 0.2) & (y_plain > 0.005)  # (measured 1484 px)
    assert deep.sum() >= 10
    assert float(np.median(y_shaded[deep] / y_plain[deep])) < 0.85  # measured 0.75 (the example's, before: 0.68)
    far = person & (depth == 0)
    far[: int(np.nonzero(depth)[0].max()) + 40] = False  # below the head: the body, no shadow of the face's
    assert far.sum() > 100 and float(np.abs(y_shaded[far] - y_plain[far]).max()) < 2 / 255

