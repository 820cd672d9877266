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
