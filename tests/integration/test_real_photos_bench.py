"""benchmarks/real_photos.py and benchmarks/dpr_protocol.py: the light conversion into DPR's frame and the figures.

No DPR repository, no torch and no photos are needed: the conversion is checked against DPR's formulas (written in
dpr_protocol from its utils/utils_SH.py) and against geometry, the metrics on synthetic images whose answer is known.
"""

import math

import numpy as np
import pytest

from relight_rt import lights
from relight_rt.image.color import linear_to_srgb, srgb_to_linear
from relight_rt.light.sh import irradiance


@pytest.fixture(scope="module")
def dprp(load_benchmark):
    return load_benchmark("dpr_protocol")


@pytest.fixture(scope="module")
def rp(load_benchmark):
    return load_benchmark("real_photos")


def test_conversion_is_exact_and_a_signed_permutation(dprp):
    c, residual = dprp.conversion()
    assert residual < 1e-12
    # both bases are real SH without Condon-Shortley phase and with the same normalisation: only order and signs differ
    np.testing.assert_allclose(np.sort(np.abs(c), axis=1)[:, -1], 1.0, atol=1e-12)
    np.testing.assert_allclose(np.abs(c).sum(1), 1.0, atol=1e-12)


def test_dpr_basis_matches_its_formula_at_the_pole(dprp):
    # DPR's utils_SH.SH_basis at n = (0, 0, 1):
    # 0.5/sqrt(pi)*pi, sqrt(3)/2/sqrt(pi)*2pi/3 on Z, sqrt(5)/4/sqrt(pi)*2*pi/4 on 3z²−1
    b = dprp.dpr_basis(np.array([[0.0, 0.0, 1.0]]))[0]
    want = np.zeros(9)
    want[0] = 0.5 / math.sqrt(math.pi) * math.pi
    want[2] = math.sqrt(3) / 2 / math.sqrt(math.pi) * 2 * math.pi / 3
    want[6] = math.sqrt(5) / 4 / math.sqrt(math.pi) * 2 * math.pi / 4
    np.testing.assert_allclose(b, want, atol=1e-15)


@pytest.mark.parametrize("k, lit, dark", [
    (3, (0, 1, 0), (0, -1, 0)),   # DPR x: from the image's right → our +y
    (1, (-1, 0, 0), (1, 0, 0)),   # DPR y: away from the camera → our −x (behind the subject)
    (2, (0, 0, 1), (0, 0, -1)),   # DPR z: up → our +z
])
def test_dpr_directions_land_in_our_frame(dprp, k, lit, dark):
    sh = np.zeros(9)
    sh[0], sh[k] = 1.0, 0.8
    light = dprp.dpr_to_ours(sh)
    e = irradiance(light, np.array([lit, dark], np.float64))[:, 0]
    assert e[0] > e[1] + 0.5


def test_round_trip_and_dc_scaling(dprp):
    rng = np.random.default_rng(0)
    sh = rng.normal(size=9)
    np.testing.assert_allclose(dprp.ours_to_dpr(dprp.dpr_to_ours(sh)), sh, atol=1e-12)
    assert dprp.ours_to_dpr(lights.preset("window-left"), dc=0.7)[0] == pytest.approx(0.7)


def test_square_around_stays_inside(dprp):
    for box, shape in (((10, 10, 60, 90), (100, 80)), ((0, 0, 30, 30), (400, 300)), ((250, 350, 299, 399), (400, 300))):
        x0, y0, x1, y1 = dprp.square_around(box, shape)
        assert x1 - x0 == y1 - y0 and 0 <= x0 and 0 <= y0 and x1 <= shape[1] and y1 <= shape[0]


def _skin_face(h: int = 40, w: int = 40) -> np.ndarray:
    img = np.zeros((h, w, 3), np.float32)
    img[:] = (0.80, 0.60, 0.50)  # a skin colour (passes the YCrCb rule)
    return img


def test_brightness_alone_keeps_hue_and_a_tint_moves_it(rp):
    face = _skin_face()
    skin = rp.skin_pixels(face, np.ones(face.shape[:2], bool))
    assert skin.all()
    darker = linear_to_srgb(srgb_to_linear(face) * 0.5)
    same = rp.colour_change(face, darker, skin)
    # a pure scaling keeps each pixel's Lab hue angle (up to OpenCV's tabulated sRGB curve: 0.56 deg here)
    assert abs(same["hue_shift"]) < 1.0 and same["chroma_ratio"] < 0.95
    assert same["saturation_ratio"] == pytest.approx(1, abs=0.1)
    green = np.clip(face * np.array([0.9, 1.05, 1.0], np.float32), 0, 1)
    assert rp.colour_change(face, green, skin)["hue_shift"] > 3


def test_side_ratio_and_versus(rp):
    face = _skin_face()
    skin = np.ones(face.shape[:2], bool)
    ramp = np.linspace(1.0, 0.3, face.shape[1], dtype=np.float32)[None, :, None]
    lit_left = linear_to_srgb(srgb_to_linear(face) * ramp)
    assert rp.lr_ratio(lit_left, skin) > 1.5 > 1 / 1.5 > rp.lr_ratio(lit_left[:, ::-1], skin)
    d = rp.change(face, lit_left)
    same = rp.versus(d, d, skin)
    assert same["agree"] and same["corr"] == pytest.approx(1) and same["slope"] == pytest.approx(1)
    half = rp.versus(0.5 * d, d, skin)
    assert half["slope"] == pytest.approx(0.5) and half["corr"] == pytest.approx(1)
    assert not rp.versus(-d, d, skin)["agree"]


def test_head_box_and_spill(rp):
    alpha = np.zeros((200, 100), np.float32)
    alpha[20:190, 40:60] = 1  # a standing figure
    alpha[20:40, 42:58] = 1
    x0, y0, x1, y1 = rp.head_box(alpha)
    assert y0 == 20 and y1 - y0 == int(0.12 * 169) and x0 < 50 < x1
    img = np.full((200, 100, 3), 0.5, np.float32)
    out = img.copy()
    assert rp.spill(img, out, alpha) == 0
    out[:, 60:70] += 0.2  # light leaking to the right of the figure
    assert rp.spill(img, out, alpha) > 5
