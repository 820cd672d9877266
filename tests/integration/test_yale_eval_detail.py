"""benchmarks/yale_eval.py ``detail_shares``: the sheets' blotches as shares of the face, on synthetic pictures whose
answer is known (no Yale data needed)."""

import math

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


def test_relerr_is_the_change_s_relative_error_from_its_correlation_and_contrast(load_benchmark):
    ye = load_benchmark("yale_eval")
    rng = np.random.default_rng(1)
    h, w = 96, 84
    source = np.full((h, w, 3), 0.4, np.float32)
    truth = (0.4 * np.exp(0.3 * rng.standard_normal((h, w, 1)))).repeat(3, axis=2).astype(np.float32)
    region = np.ones((ye.GRID, ye.GRID), bool)
    same = ye.compare(source, truth, truth, region)
    assert abs(same["corr"] - 1) < 1e-6 and abs(same["contrast"] - 1) < 1e-6 and same["relerr"] < 1e-6
    # half the change in log (a weaker light) plus noise: relerr = sqrt(s^2 - 2 contrast + 1), s = contrast / corr
    noisy = (truth ** 0.5 * 0.4 ** 0.5 * np.exp(0.1 * rng.standard_normal((h, w, 1)))).astype(np.float32)
    f = ye.compare(source, noisy, truth, region)
    s = f["contrast"] / f["corr"]
    assert 0.3 < f["contrast"] < 0.7 and abs(f["relerr"] - math.sqrt(s * s - 2 * f["contrast"] + 1)) < 1e-6


def test_lamp_mix_has_the_asked_direction_and_directionality_and_true_is_yale_s_lamp(load_benchmark):
    ye = load_benchmark("yale_eval")
    from relight_rt.light import sh

    direction = np.array(ye.lamp_direction(-50, 10))
    for d in (0.2, 0.57, 0.9):
        got, strength = sh.dominant_direction(ye.lamp_mix(direction, d))
        assert abs(strength - d) < 1e-9 and np.allclose(got, direction)
    lamp = ye.lamp(-50, 10)[:, 0]
    true_d = sh.dominant_direction(lamp)[1]
    assert abs(true_d - 0.825) < 0.001  # a point lamp with 0.05 ambient
    assert np.allclose(ye.lamp_mix(direction, true_d), lamp)
    assert np.allclose(ye.lamp_mix(direction, 1.0), lamp - ye.lights.ambient(ye.AMBIENT)[:, 0])  # the lamp alone


def test_the_mirrored_set_reads_the_photo_from_the_other_side_flipped(load_benchmark, tmp_path, monkeypatch):
    """yale_eval ``--mirror``: the photo for azimuth a is the one lit from -a (Yale's negative azimuth lights the
    image's right), flipped left-right, so its lit side is again the side azimuth a names; the frontal one stays."""
    ye = load_benchmark("yale_eval")
    (tmp_path / "yaleB01").mkdir()
    lit_right = np.zeros((6, 8), np.uint8)
    lit_right[:, 4:] = 200  # lit from azimuth -50: the image's right bright
    cv2.imwrite(str(tmp_path / "yaleB01" / "yaleB01_P00A-050E+00.png"), lit_right)
    monkeypatch.setattr(ye, "MIRROR", False)
    plain = ye.read_grey(ye.find_file(tmp_path, "yaleB01", -50))
    assert plain[:, 4:].mean() > 0.7 and plain[:, :4].max() == 0
    monkeypatch.setattr(ye, "MIRROR", True)
    assert ye.find_file(tmp_path, "yaleB01", 50).name == "yaleB01_P00A-050E+00.png"
    assert ye.find_file(tmp_path, "yaleB01", 0).name == "yaleB01_P00A+000E+00.png"
    mirrored = ye.read_grey(ye.find_file(tmp_path, "yaleB01", 50))  # azimuth +50 lights the image's left
    assert mirrored[:, :4].mean() > 0.7 and mirrored[:, 4:].max() == 0


def test_yale_halves_pools_a_plain_and_a_mirrored_run(load_benchmark, tmp_path):
    import json

    yh = load_benchmark("yale_halves")

    def run(name, prefix, relerr):
        rows = [{"id": f"{prefix}relight:yaleB02:+0->{a:+d}", "task": "relight", "subject": "yaleB02",
                 "ours": {"corr": 0.9, "contrast": 0.8, "relerr": relerr}} for a in (-25, 25)]
        path = tmp_path / name / "yale.json"
        path.parent.mkdir()
        path.write_text(json.dumps({"pairs": rows}))
        return path

    plain, mirrored = run("plain", "", 0.4), run("mirrored", "mirror:", 0.6)
    pooled = yh.load(type(plain)(f"{plain}+{mirrored}"))
    assert len(pooled) == 4
    assert yh.medians(pooled, "relight", "all")["relerr"] == 0.5
    try:
        yh.load(type(plain)(f"{plain}+{plain}"))
    except ValueError:
        pass
    else:
        raise AssertionError("a run pooled with itself must be refused")
