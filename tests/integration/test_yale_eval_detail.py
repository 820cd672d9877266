"""benchmarks/yale_eval.py ``detail_shares``: the sheets' blotches as shares of the face, on synthetic pictures whose
answer is known (no Yale data needed)."""

import cv2
import numpy as np


def test_speckle_and_flat_shares_name_where_the_fine_detail_is_multiplied_or_lost(load_benchmark):
    ye = load_benchmark("yale_eval")
    rng = np.random.default_rng(0)
    h, w = 96, 84
    skin = 0.5 * np.exp(0.05 * rng.standard_normal((h, w))).astype(np.float32)  # the real photo's texture
    truth = np.repeat(skin[..., None], 3, axis=2)
    face = ye.ellipse((h, w))
    same = ye.detail_shares(truth, truth, face)
    assert same == {"speckle": 0.0, "flat": 0.0}
    speckled = truth.copy()
    speckled[:, : w // 2] = 0.5 * (truth[:, : w // 2] / 0.5) ** 3  # the left half's detail x3 in log
    smooth = cv2.GaussianBlur(truth, (0, 0), 3.0)  # the texture gone
    s, f = ye.detail_shares(speckled, truth, face), ye.detail_shares(smooth, truth, face)
    assert 0.35 < s["speckle"] < 0.65 and s["flat"] == 0.0  # about the left half of the face
    assert f["flat"] > 0.95 and f["speckle"] == 0.0


def test_socket_ratio_is_one_when_the_socket_is_as_much_darker_than_the_face_as_the_real_ones(load_benchmark):
    ye = load_benchmark("yale_eval")
    h, w = 96, 84
    face = ye.ellipse((h, w)) > 0
    points = np.zeros((468, 2), np.float32)
    points[list(ye.RIGHT_EYE)] = [(20, 36), (27, 32), (34, 36), (27, 40)] * 4  # an eye on the image's left
    eye = ye.eye_region(points, ye.RIGHT_EYE, (h, w))
    assert eye.sum() > 0 and not eye[:, w // 2:].any()
    truth = np.full((h, w, 3), 0.5, np.float32)
    truth[eye] = 0.2
    assert abs(ye.socket_ratio(truth, truth, face, eye) - 1) < 1e-6
    bright = truth.copy()
    bright[eye] = 0.5  # the socket as bright as the face
    assert ye.socket_ratio(bright, truth, face, eye) > 1.5
    rows = [{"sockets": {"dark": 2.0, "lit": 1.0}}, {"sockets": {"dark": 0.5, "lit": 1.0}}, {}]
    figures = ye.sockets(rows)
    assert figures["pairs"] == 2 and figures["dark_over_1.5x"] == 1
    assert abs(figures["dark_mean_abs_log"] - np.log(2)) < 1e-6 and figures["lit_mean_abs_log"] == 0
