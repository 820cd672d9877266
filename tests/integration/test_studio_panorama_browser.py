"""The studio's panorama (issue 49): pick a panorama the server was started with, set the view, see the plate and the
person lit by the panorama's SH light turned to that view, in a real browser (Debian's chromium via Playwright;
skipped as tests/integration/test_studio_browser.py is)."""

from __future__ import annotations

import math
import os
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

pytest.importorskip("fastapi")
pytest.importorskip("uvicorn")
pytest.importorskip("playwright.sync_api")

import relight_rt  # noqa: E402
from relight_rt import RelightError, RuntimeConfig, envmap  # noqa: E402
from relight_rt.apps.panorama import panorama_view, view_rotation  # noqa: E402
from relight_rt.apps.studio.core import Studio  # noqa: E402
from relight_rt.cli.demo import example_path  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "benchmarks"))
from headless_studio import chromium, serving  # noqa: E402

CHROMIUM = os.environ.get("RELIGHT_RT_CHROMIUM", "/usr/bin/chromium")
BUNDLED = Path(relight_rt.__file__).resolve().parent / "models"

if not Path(CHROMIUM).is_file():
    pytest.skip(f"no chromium at {CHROMIUM} (run .ci/install-browser)", allow_module_level=True)


def sun_panorama(h: int = 64) -> np.ndarray:
    """A dim blue sky over a dark ground and a warm sun 60° right of the map's centre, 20° up."""
    dirs = envmap.directions_envmap(h)
    env = np.where(dirs[..., 2:] > 0, np.float32([0.3, 0.4, 0.6]), np.float32([0.1, 0.08, 0.06])).astype(np.float32)
    sun = view_rotation(0, 0) @ np.array([-math.cos(math.radians(20)) * math.cos(math.radians(60)),
                                          math.cos(math.radians(20)) * math.sin(math.radians(60)),
                                          math.sin(math.radians(20))])  # fmt: skip
    env[dirs @ sun > math.cos(math.radians(6))] = [60.0, 45.0, 25.0]
    return env


@pytest.fixture(scope="module")
def panoramas(tmp_path_factory):
    folder = tmp_path_factory.mktemp("panos")
    paths = []
    for name, env in (("sun.hdr", sun_panorama()), ("grey.hdr", np.full((32, 64, 3), 0.5, np.float32))):
        cv2.imwrite(str(folder / name), env[..., ::-1])
        paths.append(folder / name)
    return paths


@pytest.fixture(scope="module")
def studio(panoramas):
    rl = relight_rt.open(RuntimeConfig(models=BUNDLED, device="cpu"))
    return Studio(example_path(), None, "original", rl, panoramas=panoramas)


@pytest.fixture(scope="module")
def server(studio):
    with serving(studio) as url:
        yield url


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    with chromium(CHROMIUM, str(tmp_path_factory.mktemp("profile"))) as context:
        yield context


def test_a_panorama_view_shows_its_plate_and_lights_the_person_with_its_turned_light(browser, server, panoramas):
    page = browser.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(server)
    page.wait_for_selector("body[data-ready='1']", timeout=30_000)
    assert page.is_visible("#panorama-box")
    assert page.eval_on_selector_all("#panorama option", "os => os.map(o => o.textContent)") == ["sun.hdr", "grey.hdr"]
    env = cv2.imread(str(panoramas[0]), cv2.IMREAD_UNCHANGED)[..., ::-1].astype(np.float32)
    shown = []
    for az in (60, -120):  # facing the sun, then with it behind the camera
        page.evaluate(f"() => {{ document.getElementById('pano-az').value = '{az}'; }}")
        page.select_option("#panorama", "0")  # a change: the view is asked for
        page.wait_for_function(f"() => studio.state.panorama && studio.state.panorama.view[0] === {az}")
        page.wait_for_function("() => { const i = document.getElementById('panorama-plate');"
                               " return i.complete && i.naturalWidth > 0; }")  # fmt: skip
        pv = panorama_view(env, (studio_size(page)), (az, 0, 60))
        light = np.array(page.evaluate("() => studio.composedLight()")).reshape(9, 3)
        np.testing.assert_allclose(light, pv.light, rtol=1e-5, atol=1e-6)  # the person's light: the panorama's alone
        plate = page.evaluate("() => { const i = document.getElementById('panorama-plate'), c = document."
                              "createElement('canvas'); c.width = i.naturalWidth; c.height = i.naturalHeight;"
                              " const g = c.getContext('2d'); g.drawImage(i, 0, 0);"
                              " return Array.from(g.getImageData(0, 0, c.width, c.height).data); }")  # fmt: skip
        plate = np.array(plate, np.uint8).reshape(pv.plate.shape[0], pv.plate.shape[1], 4)[..., :3]
        np.testing.assert_array_equal(plate, pv.plate)  # the plate is composite --view's
        shown.append(float(plate.max()))
    assert shown[0] == 255 and shown[1] < 255  # the sun is in the first view, not the second
    assert page.evaluate("() => studio.state.lamp.on") is False and not errors, errors


def studio_size(page) -> tuple[int, int]:
    p = page.evaluate("() => studio.state.info.preview")
    return p["width"], p["height"]


def test_the_panorama_route_takes_an_index_never_a_path(studio, server):
    import json
    import urllib.error
    import urllib.request

    def post(body):
        req = urllib.request.Request(f"{server}/api/panorama-view", json.dumps(body).encode(),
                                     {"Content-Type": "application/json"})  # fmt: skip
        try:
            with urllib.request.urlopen(req, timeout=30) as r:
                return r.status, json.loads(r.read())
        except urllib.error.HTTPError as e:
            return e.code, json.loads(e.read())

    for bad in ({"panorama": "/etc/passwd", "view": [0, 0]}, {"panorama": 2, "view": [0, 0]},
                {"panorama": True, "view": [0, 0]}, {"panorama": 0, "view": [0, 95]}, {"panorama": 0}):  # fmt: skip
        code, out = post(bad)
        assert code == 400 and "error" in out, (bad, out)
    code, out = post({"panorama": 1, "view": "30,5,70"})
    assert code == 200 and out["view"] == [30.0, 5.0, 70.0] and out["name"] == "grey.hdr"
    light = np.array(out["light"])
    assert np.abs(light[1:]).max() < 1e-3 * light[0].min()  # a uniform map: ambient only
    with pytest.raises(RelightError, match="file not found"):
        Studio(example_path(), None, "original", studio.relighter, panoramas=["/nonexistent/x.hdr"])
