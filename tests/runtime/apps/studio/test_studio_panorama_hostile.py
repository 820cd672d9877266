"""The studio's panorama routes against hostile requests (round 6): POST /api/panorama-view and
GET /api/panorama/ID.png take indexes and numbers only; anything else is a 400 with one line, never a 500."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
from _graphs import models_dir, person

from relight_rt import Relighter, RuntimeConfig
from relight_rt.apps.studio.core import Studio

__all__ = ["models_dir"]  # fixture
LOCAL = "127.0.0.1"
JSON = {"content-type": "application/json"}


@pytest.fixture(scope="module")
def client(tmp_path_factory, models_dir):
    pytest.importorskip("fastapi")
    pytest.importorskip("httpx")
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        from fastapi.testclient import TestClient

    from relight_rt.apps.studio import create_app

    folder = tmp_path_factory.mktemp("pano_hostile")
    img, mask = person(48, 32, box=(6, 42, 8, 24))
    rgba = np.concatenate([img, mask[..., None]], axis=2)
    photo = folder / "someone.png"
    cv2.imwrite(str(photo), cv2.cvtColor((rgba * 255 + 0.5).astype(np.uint8), cv2.COLOR_RGBA2BGRA))
    env = np.full((16, 32, 3), 0.2, np.float32)
    env[4, 8:11] = 20.0
    cv2.imwrite(str(folder / "good.hdr"), env)
    cv2.imwrite(str(folder / "black.hdr"), np.zeros((16, 32, 3), np.float32))
    (folder / "corrupt.hdr").write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 16 +X 32\n" + b"\x02\x02" * 9)
    panoramas = [folder / n for n in ("good.hdr", "black.hdr", "corrupt.hdr")]  # a 3:1 one: refused at the start
    relighter = Relighter(RuntimeConfig(models=models_dir, device="cpu"))
    studio = Studio(photo, None, "original", relighter, preview_pixels=4096, panoramas=panoramas)
    with TestClient(create_app(studio), base_url=f"http://{LOCAL}:8000", raise_server_exceptions=False) as c:
        yield c


def test_a_good_view_works(client):
    res = client.post("/api/panorama-view", content=json.dumps({"panorama": 0, "view": [10, 0, 60]}), headers=JSON)
    assert res.status_code == 200, res.text
    plate = client.get(f"/api/panorama/{res.json()['id']}.png")
    assert plate.status_code == 200 and plate.content[:4] == b"\x89PNG"


BIG = "1" + "0" * 400  # a JSON integer no float holds

# fmt: off
BAD_BODIES = [
    "", "null", "[]", "7", '"x"', "{", "[" * 5000, '{"panorama": 0}', '{"view": [0, 0]}',
    '{"panorama": 0, "view": null}', '{"panorama": 0, "view": 5}', '{"panorama": 0, "view": {"0": 1, "10": 2}}',
    '{"panorama": 0, "view": [true, false]}', '{"panorama": 0, "view": [0, false, 60]}',
    '{"panorama": 0, "view": ["0", "0"]}', '{"panorama": 0, "view": [NaN, 0]}',
    '{"panorama": 0, "view": [0, Infinity]}',
    '{"panorama": 0, "view": [0, 0, -Infinity]}', '{"panorama": 0, "view": [1e999, 0]}',
    f'{{"panorama": 0, "view": [{BIG}, 0]}}', f'{{"panorama": 0, "view": [0, 0, {BIG}]}}',
    '{"panorama": 0, "view": [0, 1e308]}', '{"panorama": 0, "view": [0, 0, 0]}', '{"panorama": 0, "view": [0]}',
    '{"panorama": 0, "view": [0, 0, 60, 1]}', '{"panorama": 0, "view": [[0], [0]]}', '{"panorama": 0, "view": "a,b"}',
    '{"panorama": 0, "view": "0,0,' + "9" * 5000 + '"}',
    '{"panorama": true, "view": [0, 0]}', '{"panorama": 0.0, "view": [0, 0]}', '{"panorama": -1, "view": [0, 0]}',
    '{"panorama": 4, "view": [0, 0]}', f'{{"panorama": {BIG}, "view": [0, 0]}}', '{"panorama": "0", "view": [0, 0]}',
    '{"panorama": "good.hdr", "view": [0, 0]}', '{"panorama": "/etc/passwd", "view": [0, 0]}',
    '{"panorama": NaN, "view": [0, 0]}', '{"panorama": [0], "view": [0, 0]}',
    '{"panorama": 1, "view": [0, 0]}', '{"panorama": 2, "view": [0, 0]}', '{"panorama": 3, "view": [0, 0]}',
]
# fmt: on


@pytest.mark.parametrize("body", BAD_BODIES, ids=range(len(BAD_BODIES)))
def test_bad_panorama_requests_are_400(client, body):
    res = client.post("/api/panorama-view", content=body, headers=JSON)
    assert res.status_code == 400, (body[:80], res.status_code, res.text[:300])
    error = res.json()["error"]
    assert error and "\n" not in error and "Traceback" not in error, error


@pytest.mark.parametrize("pid", ["nope", "..%2F..%2Fetc%2Fpasswd", "0" * 5000, "%00", "-1", "NaN"])
def test_unknown_plates_are_refused(client, pid):
    res = client.get(f"/api/panorama/{pid}.png")
    assert res.status_code in (400, 404), (pid, res.status_code)


@pytest.mark.parametrize("view", [[True, False], (0, False, 60), ["0", "0"], {"0": 1, "10": 2}, [10**400, 0],
                                  np.array([True, False]), 7, None])  # fmt: skip
def test_parse_view_takes_numbers_only(view):
    from relight_rt import RelightError
    from relight_rt.apps.panorama import parse_view

    with pytest.raises(RelightError, match=r"^view: expected"):
        parse_view(view)


def test_a_huge_view_is_quoted_short():
    from relight_rt import RelightError
    from relight_rt.apps.panorama import parse_view

    with pytest.raises(RelightError) as caught:
        parse_view("0,0," + "9" * 5000)
    assert len(str(caught.value)) < 200


BAD_FILES = [("wide.hdr", "not an equirectangular panorama"), ("pano.txt", "expected an equirectangular panorama file"),
             ("folder", "not a regular file"), ("missing.hdr", "file not found")]  # fmt: skip


@pytest.mark.parametrize("name, match", BAD_FILES)
def test_a_bad_panorama_is_refused_before_the_server_starts(tmp_path, models_dir, monkeypatch, name, match):
    """Round 6: a 3:1 or a text file given as --panorama started the server; each view of it was then a 400."""
    from relight_rt import RelightError
    from relight_rt.apps.studio import core

    monkeypatch.setattr(Relighter, "decompose", lambda *a, **k: pytest.fail("decomposed before the check"))
    cv2.imwrite(str(tmp_path / "wide.hdr"), np.ones((16, 48, 3), np.float32))
    (tmp_path / "pano.txt").write_text("0 0 0\n")
    (tmp_path / "folder").mkdir()
    img, mask = person(48, 32, box=(6, 42, 8, 24))
    photo = tmp_path / "someone.png"
    cv2.imwrite(str(photo), (img[..., ::-1] * 255).astype(np.uint8))
    relighter = Relighter(RuntimeConfig(models=models_dir, device="cpu"))
    with pytest.raises(RelightError, match=f"--panorama .*{match}"):
        core.Studio(photo, None, "original", relighter, preview_pixels=4096, panoramas=[tmp_path / name])


LIGHT = "[" + ", ".join(["0.5"] * 3 + ["0"] * 24) + "]"
BAD_RENDERS = [
    '{"light": [' + ", ".join(["true"] * 27) + "]}", '{"light": ' + LIGHT + ', "exposure": true}',
    '{"light": ' + LIGHT + ', "exposure": 1e999}', '{"light": ' + LIGHT + ', "exposure": NaN}',
    '{"light": ' + LIGHT + f', "exposure": {BIG}}}', '{"light": ' + LIGHT + ', "grade_background": "yes"}',
    '{"light": ' + LIGHT + ', "grade_background": 1}', '{"light": [' + ", ".join([BIG] * 27) + "]}",
    '{"light": [' + ", ".join(["NaN"] * 27) + "]}", '{"light": "night"}', '{"light": {"sh": 1}}',
    '{"light": [' + ", ".join(['"0.5"'] * 27) + "]}", '{"light": [' + ", ".join(["0.5"] * 26 + ["false"]) + "]}",
]


@pytest.mark.parametrize("body", BAD_RENDERS, ids=range(len(BAD_RENDERS)))
def test_bad_render_requests_are_400(client, body):
    res = client.post("/api/render", content=body, headers=JSON)
    assert res.status_code == 400, (body[:80], res.status_code, res.text[:300])
    error = res.json()["error"]
    assert error and "\n" not in error, error
