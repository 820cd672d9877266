"""relight_rt.light.preview and ``relight-rt lights show`` with environment maps (issue 34 item 5)."""

from __future__ import annotations

import math
import re

import cv2
import numpy as np
import pytest

from relight_rt import cli, envmap, sh
from relight_rt.light.preview import back_to_front, brightest_direction, envmap_sheet, notes, turned_envmap

H = 32


def sunset_map(sun_column: int = H) -> np.ndarray:
    """(H, 2H, 3) linear map: blue sky, dark ground, a small bright sun just above the horizon at
    ``sun_column`` (H: the centre column, straight behind the subject)."""
    env = np.zeros((H, 2 * H, 3), np.float32)
    env[: H // 2] = (0.15, 0.3, 0.8)
    env[H // 2 :] = (0.05, 0.04, 0.03)
    env[H // 2 - 3 : H // 2 - 1, sun_column - 1 : sun_column + 1] = (400.0, 250.0, 120.0)
    return env


def _turn_in(lines: list[str]) -> float:
    found = re.search(r"--rotate (-?\d+)", " ".join(lines))
    assert found, lines
    return float(found.group(1))


def test_turning_the_map_turns_its_light_as_rotate_z_does():
    env = sunset_map(H - 5)
    for degrees in (90.0, -45.0, 180.0, 11.25):  # whole columns (360 / 64 = 5.625 degrees each)
        turned = envmap.project_envmap(turned_envmap(env, degrees))
        np.testing.assert_allclose(turned, sh.rotate_z(envmap.project_envmap(env), math.radians(degrees)),
                                   rtol=1e-4, atol=1e-4 * np.abs(turned).max())  # fmt: skip


def test_a_sun_behind_the_subject_is_said_and_the_turn_that_fixes_it():
    env = sunset_map()
    light = envmap.project_envmap(env)
    assert back_to_front(light) > 1
    az, elev = brightest_direction(env)
    assert abs(abs(az) - 180) < 6 and 0 < elev < 30  # behind the subject, low
    lines = notes(light, 0.0, az)
    assert "behind the subject" in lines[0]
    turn = _turn_in(lines)
    assert abs(abs(turn) - 180) < 6
    fixed = envmap.project_envmap(turned_envmap(env, turn))
    assert back_to_front(fixed) < 0.5 and notes(fixed, turn) == []  # turned as advised: the sun lights the face
    assert notes(envmap.project_envmap(sunset_map(H // 2 + 2)), 0.0) != []  # sun off to the side-back: still said
    front = sunset_map(1)
    assert notes(envmap.project_envmap(front), 0.0) == []  # a sun near the camera: nothing to say


def test_sheet_layout():
    env = sunset_map()
    sheet, lines = envmap_sheet(env, envmap.project_envmap(env), 0.0, 128)
    assert sheet.dtype == np.uint8 and sheet.shape[1] == 3 * 128 + 4 and sheet.shape[0] > 128
    assert lines and "behind" in lines[0]
    sky, ground = sheet[24:40, 36:56].reshape(-1, 3).mean(0), sheet[90:110, 36:56].reshape(-1, 3).mean(0)
    assert sky[2] > sky[0] + 20 and ground.mean() < sky.mean()  # the map's panel shows the map, sky on top
    assert sheet[64, 3 * 128 + 4 - 64].min() > 40  # the sphere's panel, lit


@pytest.fixture
def work(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    return tmp_path


def test_cli_lights_show_takes_an_environment_map(work, caplog):
    """issue 34: ``relight-rt lights show sunset.hdr`` said "unknown light preset"."""
    cv2.imwrite("sunset.hdr", np.ascontiguousarray(sunset_map()[..., ::-1]))
    assert cli.main(["lights", "show", "sunset.hdr", "--size", "128", "-o", "sheet.png"]) == 0
    err = caplog.text
    assert "behind the subject" in err
    sheet = cv2.imread("sheet.png")
    assert sheet.shape[1] == 3 * 128 + 4 and sheet.shape[0] > 128
    turn = _turn_in(err.splitlines())
    caplog.clear()
    assert cli.main(["lights", "show", "sunset.hdr", "--rotate", str(turn), "-o", "turned.png"]) == 0
    assert "behind" not in caplog.text
    ldr = (np.clip(sunset_map(), 0, 1) * 255).astype(np.uint8)[..., ::-1]
    cv2.imwrite("pano.png", ldr)  # an equirectangular LDR image is a map too
    assert cli.main(["lights", "show", "pano.png", "-o", "p.png"]) == 0
    assert cv2.imread("p.png").shape[1] == 3 * 256 + 8


def test_cli_lights_show_sphere_for_presets_and_files(work, capsys, caplog):
    np.save("l.npy", envmap.project_envmap(sunset_map()).astype(np.float64))
    assert cli.main(["lights", "show", "l.npy", "--size", "64", "-o", "s.png"]) == 0
    assert cv2.imread("s.png").shape == (64, 64, 3)
    assert "behind the subject" in caplog.text  # the same note, in the log
    assert cli.main(["lights", "show", "l.npy", "--bgr", "-o", "s2.png"]) == 0
    assert cli.main(["lights", "show", "studio", "--bgr", "-o", "s3.png"]) == 2
    assert cli.main(["lights", "show", "nope", "-o", "x.png"]) == 2
    assert "known presets" in capsys.readouterr().err
