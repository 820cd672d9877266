"""relight-rt studio, server side: the Studio state (layers, renders, uploads, store) and its HTTP routes.

The browser side (the page, WebGL preview, drag, export) is in tests/integration/test_studio_browser.py.
"""

from __future__ import annotations

import io
import json
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from _graphs import models_dir, person

import relight_rt
from relight_rt import Relighter, RelightError, RuntimeConfig, envmap, lights
from relight_rt.apps.studio.core import (
    EXPOSURE_SAMPLES,
    ResultStore,
    Studio,
    light_json,
    request_exposure,
    request_light,
)
from relight_rt.apps.studio.preview import preview_picture, shadow_plane, unpack_layers
from relight_rt.apps.studio.uploads import MAX_UPLOAD_BYTES, check_upload, sniff
from relight_rt.cli import main
from relight_rt.engine.limits import header_size
from relight_rt.image.compositing import Background
from relight_rt.light.exposure import DISPLAY_GAMMA, METER_POWER
from relight_rt.relight.compose import HeadBlend, sampled_grade, shown_mask
from relight_rt.relight.look import SKIN_CHROMA, skin_chroma
from relight_rt.relight.strength import restore_bands

__all__ = ["models_dir"]  # fixture
REPO = Path(__file__).resolve().parents[4]


def _png_bytes(rgb_or_rgba: np.ndarray) -> bytes:
    a = (np.clip(rgb_or_rgba, 0, 1) * 255 + 0.5).astype(np.uint8)
    a = cv2.cvtColor(a, cv2.COLOR_RGBA2BGRA if a.shape[2] == 4 else cv2.COLOR_RGB2BGR)
    return cv2.imencode(".png", a)[1].tobytes()


@pytest.fixture(scope="module")
def photo(tmp_path_factory):
    """A textured 'person' (rectangle) as an RGBA PNG whose alpha is the mask."""
    img, mask = person(90, 60, box=(10, 80, 15, 45))
    path = tmp_path_factory.mktemp("studio") / "someone.png"
    path.write_bytes(_png_bytes(np.concatenate([img, mask[..., None]], axis=2)))
    return path


@pytest.fixture(scope="module")
def studio(photo, models_dir):
    relighter = relight_rt.open(RuntimeConfig(models=models_dir, device="cpu"))
    return Studio(photo, None, "original", relighter, preview_pixels=4096, models=models_dir)


# ------------------------------------------------------------------------------------------------ core


def test_sniff_by_content_not_name():
    assert sniff(b"\x89PNG\r\n\x1a\n....") == ("png", ".png")
    assert sniff(b"\xff\xd8\xff\xe0") == ("jpeg", ".jpg")
    assert sniff(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe") == ("hdr", ".hdr")
    assert sniff(b"RIFF\x00\x00\x00\x00WEBPVP8 ") == ("webp", ".webp")
    assert sniff(b"RIFF\x00\x00\x00\x00WAVEfmt ") is None
    assert sniff(b"<html>not an image</html>") is None


def test_check_upload_refuses_bad_files():
    with pytest.raises(RelightError, match="empty"):
        check_upload(b"", "environment map", ("hdr",))
    with pytest.raises(RelightError, match="expected HDR or PNG .*unknown type"):
        check_upload(b"GIF89a....", "environment map", ("hdr", "png"))
    with pytest.raises(RelightError, match="expected HDR .*png file"):
        check_upload(b"\x89PNG\r\n\x1a\n" + bytes(20), "environment map", ("hdr",))
    with pytest.raises(RelightError, match="limit"):
        check_upload(b"#?RADIANCE" + bytes(100), "environment map", ("hdr",), limit=50)
    huge = b"\x89PNG\r\n\x1a\n" + b"\x00\x00\x00\rIHDR" + (100_000).to_bytes(4, "big") * 2 + bytes(10)
    with pytest.raises(RelightError, match="pixels"):
        check_upload(huge, "photo", ("png",))


@pytest.mark.parametrize("ext", [".png", ".jpg", ".bmp", ".webp", ".hdr"])
def test_image_size_from_the_header(ext):
    img = np.zeros((37, 53, 3), np.float32 if ext == ".hdr" else np.uint8)
    data = cv2.imencode(ext, img)[1].tobytes()
    assert sniff(data) is not None and header_size(data) == (53, 37)  # the runtime's one header parser


def test_huge_image_refused_before_decoding():
    data = bytearray(cv2.imencode(".jpg", np.zeros((8, 8, 3), np.uint8))[1].tobytes())
    sof = data.index(b"\xff\xc0")
    data[sof + 5 : sof + 9] = (30000).to_bytes(2, "big") * 2  # claims 30000 x 30000
    with pytest.raises(RelightError, match="pixels"):
        check_upload(bytes(data), "photo", ("jpeg",))


def test_result_store_is_bounded_and_expires():
    now = [0.0]
    store = ResultStore(capacity=2, ttl=10.0, clock=lambda: now[0])
    a = store.put("a")
    b = store.put("b")
    assert store.get(a) == "a"  # a is now the most recent
    c = store.put("c")  # evicts b, the least recently used
    assert store.get(b) is None and store.get(a) == "a" and store.get(c) == "c"
    now[0] = 25.0
    assert store.get(a) is None and len(store) == 0
    assert len({store.put(i) for i in range(50)}) == 50  # random, distinct ids
    assert len(store) == 2
    with pytest.raises(RelightError):
        ResultStore(capacity=0)


@pytest.mark.parametrize(
    "value, match",
    [([1.0] * 26, "27 numbers"), ("studio", "27 numbers"), ([float("nan")] * 27, "finite"), ([1e9] * 27, "finite")],
)
def test_request_light_rejects(value, match):
    with pytest.raises(RelightError, match=match):
        request_light(value)


def test_request_light_and_exposure():
    light = request_light(np.arange(27).tolist())
    assert light.shape == (9, 3) and light.dtype == np.float32 and light[1, 0] == 3
    assert request_exposure(None) == "auto" and request_exposure("physical") == "physical"
    assert request_exposure("-1.5") == -1.5
    for bad in ("bright", 50, float("inf")):
        with pytest.raises(RelightError, match="exposure"):
            request_exposure(bad)


def test_layers_match_the_decomposition(studio):
    info = studio.info()
    meta = info["preview"]
    assert (info["height"], info["width"]) == (90, 60)
    assert meta["height"] * meta["width"] <= 4096 and meta["height"] / meta["width"] == pytest.approx(1.5, rel=0.05)
    layers = unpack_layers(studio.layers_bytes(), meta)
    dec = studio.dec
    size = (meta["width"], meta["height"])
    full = dec.to_input(restore_bands(np.ascontiguousarray(dec.transport)))  # what the final result relights with
    transport = np.stack([cv2.resize(full[..., k], size, interpolation=cv2.INTER_AREA) for k in range(9)], axis=2)
    step = np.array(meta["transport_scale"])
    err = np.abs(layers["transport"].transpose(1, 2, 0) - transport)
    assert (err <= step * 0.51 + 1e-6).all()  # uint16 quantisation: half a step
    mask = cv2.resize(np.asarray(dec.mask), size, interpolation=cv2.INTER_AREA)
    np.testing.assert_allclose(layers["mask"], mask, atol=0.5 / 255 + 1e-6)
    photo = cv2.resize(np.asarray(dec.image), size, interpolation=cv2.INTER_AREA)
    np.testing.assert_allclose(layers["background"].transpose(1, 2, 0), photo, atol=0.5 / 255 + 1e-6)
    # the shaded-skin rule's inputs (relight_rt.relight.look.skin_chroma), as the page reads them
    chroma, weight = skin_chroma(dec.network_image, dec.skin)
    skin = dec.to_input(np.concatenate([chroma, weight[..., None]], axis=2))
    skin = np.stack([cv2.resize(skin[..., k], size, interpolation=cv2.INTER_AREA) for k in range(4)], axis=2)
    np.testing.assert_allclose(layers["skin_chroma"].transpose(1, 2, 0), skin[..., :3], atol=1 / 255 + 1e-5)
    np.testing.assert_allclose(layers["skin"], skin[..., 3], atol=0.5 / 255 + 1e-6)
    assert meta["skin_chroma"] == SKIN_CHROMA and len(meta["own_white"]) == 9
    assert meta["exposure_power"] == METER_POWER and meta["display_gamma"] == DISPLAY_GAMMA  # the page takes both
    assert info["presets"].keys() == set(lights.list_presets())
    np.testing.assert_allclose(info["own_light"], dec.light)
    with pytest.raises(RelightError, match="bytes"):
        unpack_layers(studio.layers_bytes()[:-1], meta)
    # the background grade's sample travels whole, and a count that cannot be is refused, not read as "all"
    assert meta["grade_samples"] > 0
    want = studio.relighter.grade_inputs(dec)
    step = -(-want.weight.shape[0] // EXPOSURE_SAMPLES)
    for got, full in zip(layers["grade"][:-1], want[:-1], strict=True):
        np.testing.assert_array_equal(got, full[::step])
    for got, full in zip(layers["grade"].head, want.head.every(step), strict=True):
        np.testing.assert_array_equal(got, full)
    with pytest.raises(RelightError, match="bytes"):
        unpack_layers(studio.layers_bytes()[: meta["grade_offset"] - 80], {**meta, "grade_samples": -1})


def test_render_is_the_relighters_result(studio, models_dir):
    light = lights.preset("window-left").astype(np.float32)
    rid, rec = studio.render(light.tolist())
    assert studio.renders.get(rid) is rec
    png = cv2.imdecode(np.frombuffer(rec.png, np.uint8), cv2.IMREAD_UNCHANGED)
    expected = Relighter(RuntimeConfig(models=models_dir, device="cpu")).relight(studio.photo, light)
    np.testing.assert_array_equal(png[..., ::-1], (np.clip(expected, 0, 1) * 255 + 0.5).astype(np.uint8))
    np.testing.assert_array_equal(rec.light, light)
    cmd = studio.command(rec, "someone_light.npy")
    assert cmd.startswith("relight-rt relight ") and "--light=someone_light.npy" in cmd
    assert "--output=someone_relit.png" in cmd
    assert json.loads(light_json(rec.light))["order"] == "rgb"


def test_render_grades_the_original_background_when_asked(studio, models_dir):
    """The studio's toggle: the full result is the Relighter's with Background.original(grade=True), and the
    command it shows asks for the same (--grade-background); not asked, nothing changes."""
    light = lights.preset("night").astype(np.float32)
    assert studio.info()["original_background"] is True
    _, rec = studio.render(light.tolist(), grade_background=True)
    png = cv2.imdecode(np.frombuffer(rec.png, np.uint8), cv2.IMREAD_UNCHANGED)
    rl = Relighter(RuntimeConfig(models=models_dir, device="cpu"))
    expected = rl.relight(studio.photo, light, background=Background.original(grade=True))
    np.testing.assert_array_equal(png[..., ::-1], (np.clip(expected, 0, 1) * 255 + 0.5).astype(np.uint8))
    assert rec.grade_background and studio.command(rec, "l.npy").split().count("--grade-background") == 1
    _, plain = studio.render(light.tolist())
    assert not plain.grade_background and "--grade-background" not in studio.command(plain, "l.npy")
    assert plain.png != rec.png
    with pytest.raises(RelightError, match="grade_background"):
        studio.render(light.tolist(), grade_background="yes")


def _check_preview_exposure(studio):
    layers = unpack_layers(studio.layers_bytes(), studio.info()["preview"])
    assert layers["exposure"]["mask"].size == int((studio.dec.network_mask > 0).sum())
    assert layers["highlight"]["lit"].shape[0] == int((studio.dec.network_mask > 0.5).sum())
    factors = []
    for name in ("studio", "rim", "window-left"):
        light = lights.preset(name).astype(np.float32)
        for exposure in ("auto", 1.0, "physical"):
            want = studio.relighter.layers(studio.dec, light, exposure=exposure).light
            np.testing.assert_allclose(studio.preview_light(light.tolist(), exposure), want, rtol=1e-5, atol=1e-7)
        mean_kept = studio.preview_light(light.tolist(), "auto")[0, 0] / exposure_scale_of(studio, light)
        factors.append(float(mean_kept / light[0, 0]))
    return factors


def exposure_scale_of(studio, light):
    """The mean-keeping scale alone (no highlight guard) on the page's exposure sample."""
    from relight_rt.light.exposure import exposure_scale

    albedo, transport, mask = studio._exposure
    return exposure_scale(albedo[None], transport[None], mask[None], light, studio.info()["preview"]["exposure_target"])


def test_preview_exposure_is_the_final_results(studio):
    """One exposure rule: the preview's light is the light the final result uses (relight_rt.light.exposure: the
    mean-keeping scale, the highlight guard, the EV), exactly when the samples hold every pixel of the person (as
    here: a 64² network)."""
    _check_preview_exposure(studio)


def test_preview_exposure_follows_the_highlight_guard(photo, models_dir, monkeypatch):
    """With a limit this test person's lit side passes (the guard acting), the preview still has the final's light."""
    from relight_rt.light import exposure

    monkeypatch.setattr(exposure, "HIGHLIGHT_LIMIT", 0.6)
    relighter = Relighter(RuntimeConfig(models=models_dir, device="cpu"))
    own = relighter._factor.meter.highlight_inputs  # what the final result and the preview both read
    # 5 % past the limit
    monkeypatch.setattr(relighter._factor.meter, "highlight_inputs", lambda dec: own(dec)._replace(allowed=0.05))
    guarded = Studio(photo, None, "original", relighter, preview_pixels=4096, models=models_dir)
    factors = _check_preview_exposure(guarded)
    assert min(factors) < 0.95, factors  # the guard lowered at least one light


def test_envmap_upload_gives_the_projected_light(studio, tmp_path):
    rng = np.random.default_rng(1)
    env = rng.random((16, 32, 3)).astype(np.float32) * 3
    path = tmp_path / "sky.hdr"
    cv2.imwrite(str(path), env[..., ::-1])
    light = studio.envmap_light(path.read_bytes())
    np.testing.assert_allclose(light, envmap.project_envmap(envmap.load_envmap(path)), rtol=1e-5, atol=1e-6)
    with pytest.raises(RelightError, match="width = 2"):
        cv2.imwrite(str(tmp_path / "square.hdr"), env[:, :16, ::-1].copy())
        studio.envmap_light((tmp_path / "square.hdr").read_bytes())
    with pytest.raises(RelightError, match="environment map: expected HDR"):
        studio.envmap_light(b"this is not an image")


def test_photo_light_alpha_else_automatic_matte(studio, photo):
    own = studio.photo_light(photo.read_bytes())
    np.testing.assert_allclose(own, studio.dec.light, rtol=1e-5, atol=1e-6)
    grey = np.full((64, 64, 3), 128, np.uint8)  # no alpha and nobody in it: the matte says so
    with pytest.raises(RelightError, match="no person found"):
        studio.photo_light(cv2.imencode(".png", grey)[1].tobytes())
    scene = (REPO / "relight_rt" / "data" / "example_scene.jpg").read_bytes()  # no alpha: the matte finds her
    assert studio.photo_light(scene).shape == (9, 3)
    with pytest.raises(RelightError, match="cannot read the image size from its PNG header"):
        studio.photo_light(b"\x89PNG\r\n\x1a\n" + bytes(40))  # no IHDR: refused before decoding
    ihdr = b"\x00\x00\x00\rIHDR" + (64).to_bytes(4, "big") * 2 + b"\x08\x02\x00\x00\x00"
    with pytest.raises(RelightError, match="cannot decode"):
        studio.photo_light(b"\x89PNG\r\n\x1a\n" + ihdr + bytes(40))  # a header, then nothing


def test_studio_checks_its_arguments(photo, models_dir, tmp_path):
    relighter = Relighter(RuntimeConfig(models=models_dir, device="cpu"))
    with pytest.raises(RelightError, match="--background"):
        Studio(photo, None, str(tmp_path / "missing.png"), relighter)
    with pytest.raises(RelightError, match="preview_pixels"):
        Studio(photo, None, "original", relighter, preview_pixels=10)


# ------------------------------------------------------------------------------------------------ routes


@pytest.fixture(scope="module")
def client(studio):
    pytest.importorskip("fastapi")
    pytest.importorskip("httpx")
    import warnings

    with warnings.catch_warnings():  # newer starlette prefers "httpx2"; httpx still works
        warnings.simplefilter("ignore")
        from fastapi.testclient import TestClient

    from relight_rt.apps.studio import create_app

    with TestClient(create_app(studio), base_url="http://127.0.0.1") as c:
        yield c


def test_routes_page_info_layers(client, studio):
    page = client.get("/")
    assert page.status_code == 200 and "relight-rt" in page.text
    assert "default-src 'self'" in page.headers["content-security-policy"]
    for name in ("studio.js", "sh.js", "preview.js", "view.js", "studio.css"):
        assert client.get(f"/static/{name}").status_code == 200
    assert client.get("/static/../core.py").status_code == 404
    info = client.get("/api/info").json()
    assert info["photo"] == "someone.png" and "exposure" in info
    assert client.get("/api/layers").content == studio.layers_bytes()


def test_route_photo_is_the_photo_the_pipeline_reads(client, studio):
    """The page's "before" view: the decoded photo (RGB, upright) at full resolution, as PNG."""
    res = client.get("/api/photo.png")
    assert res.status_code == 200 and res.headers["content-type"] == "image/png"
    got = cv2.imdecode(np.frombuffer(res.content, np.uint8), cv2.IMREAD_UNCHANGED)[..., ::-1]
    want = np.rint(np.clip(np.asarray(studio.dec.image)[..., :3], 0, 1) * 255).astype(np.uint8)
    assert got.shape == want.shape == (90, 60, 3)
    np.testing.assert_array_equal(got, want)


def test_routes_render_and_export(client):
    light = lights.preset("neon").astype(np.float32)
    out = client.post("/api/render", json={"light": light.tolist(), "exposure": "auto"}).json()
    png = client.get(f"/api/result/{out['id']}.png?download=1")
    assert png.status_code == 200 and png.content.startswith(b"\x89PNG")
    assert 'filename="someone_relit.png"' in png.headers["content-disposition"]
    npy = np.load(io.BytesIO(client.get(f"/api/result/{out['id']}/light.npy").content), allow_pickle=False)
    np.testing.assert_array_equal(npy, light)
    js = json.loads(client.get(f"/api/result/{out['id']}/light.json").content)
    np.testing.assert_array_equal(np.array(js["sh"], np.float32), light)
    assert client.get("/api/result/nope.png").status_code == 400


@pytest.mark.parametrize(
    "body, match",
    [(b"not json", "JSON body"), (b"[1, 2]", "JSON object"), (b'{"light": [1, 2]}', "27 numbers")],
)
def test_routes_render_bad_request(client, body, match):
    res = client.post("/api/render", content=body, headers={"content-type": "application/json"})
    assert res.status_code == 400 and match in res.json()["error"]


def test_routes_uploads(client, tmp_path):
    raw = {"content-type": "application/octet-stream"}  # what the page sends (studio.js, uploadLight)
    bad = client.post("/api/envmap", content=b"<svg>not an hdr</svg>", headers=raw)
    assert bad.status_code == 400 and "environment map: expected" in bad.json()["error"]
    big = client.post("/api/photo-light", content=b"\x89PNG" + bytes(MAX_UPLOAD_BYTES), headers=raw)
    assert big.status_code == 400 and "limit" in big.json()["error"]
    env = np.ones((8, 16, 3), np.float32)
    cv2.imwrite(str(tmp_path / "e.hdr"), env)
    good = client.post("/api/envmap", content=(tmp_path / "e.hdr").read_bytes(), headers=raw)
    assert good.status_code == 200 and np.array(good.json()["light"]).shape == (9, 3)
    scene = client.post("/api/background-light", content=cv2.imencode(".jpg", np.full((80, 120, 3), 90, np.uint8))[1]
                        .tobytes(), headers=raw)
    assert scene.status_code == 200 and np.array(scene.json()["light"]).shape == (9, 3)
    photo = cv2.imencode(".jpg", np.full((80, 120, 3), 90, np.uint8))[1].tobytes()
    keyed = client.post("/api/background-light?key=180,30", content=photo, headers=raw)
    assert keyed.status_code == 200 and not np.allclose(keyed.json()["light"], scene.json()["light"])
    bad_key = client.post("/api/background-light?key=up", content=photo, headers=raw)
    assert bad_key.status_code == 400 and "key light" in bad_key.json()["error"]
    assert client.get("/api/info").status_code == 200  # still serving


def test_foreign_host_header_refused(client):
    assert client.get("/api/info", headers={"host": "attacker.example"}).status_code == 400


# ------------------------------------------------------------------------------------------------ CLI


def test_import_and_cli_stay_lean():
    code = (
        "import sys, relight_rt, relight_rt.apps.studio, relight_rt.apps.studio.core; "
        "from relight_rt.cli import build_parser; "
        "build_parser(); bad = [m for m in ('fastapi', 'uvicorn', 'starlette') if m in sys.modules]; "
        "sys.exit(1 if bad else 0)"
    )
    assert subprocess.run([sys.executable, "-c", code], check=False).returncode == 0


def test_cli_studio_errors(tmp_path, capsys):
    pytest.importorskip("fastapi")
    pytest.importorskip("uvicorn")
    assert main(["studio", str(tmp_path / "missing.png")]) == 2
    assert "not found" in capsys.readouterr().err
    assert main(["studio", str(tmp_path / "x.png"), "--port", "70000"]) == 2
    assert "--port" in capsys.readouterr().err


def test_missing_extra_is_named(monkeypatch):
    from relight_rt.apps import studio as studio_pkg

    monkeypatch.setitem(sys.modules, "fastapi", None)  # makes ``import fastapi`` fail
    with pytest.raises(RelightError, match=r"relight-rt\[studio\]"):
        studio_pkg.create_app(None)


def test_exposure_reaches_the_relighter_and_the_command(photo, models_dir):
    class Recording(Relighter):
        seen: list = []

        def relight(self, image, light, *, mask=None, background="original", exposure="auto"):
            self.seen.append(exposure)
            return super().relight(image, light, mask=mask, background=background, exposure=exposure)

    recording = Recording(RuntimeConfig(models=models_dir, device="cpu"))
    studio = Studio(photo, None, "original", recording, preview_pixels=4096)
    assert studio.info()["exposure"] is True
    _, rec = studio.render(lights.preset("studio").tolist(), exposure=1.5)
    assert Recording.seen == [1.5] and "--exposure=1.5" in studio.command(rec, "l.npy")
    _, rec = studio.render(lights.preset("studio").tolist(), exposure="auto")
    assert "--exposure" not in studio.command(rec, "l.npy")  # auto is the CLI's default too


def test_cli_serves_and_prints_its_url(photo, models_dir):
    pytest.importorskip("fastapi")
    pytest.importorskip("uvicorn")
    import urllib.request

    cmd = [sys.executable, "-m", "relight_rt", "studio", str(photo), "--port", "0", "--models", str(models_dir)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO)
    try:
        line = proc.stdout.readline()
        assert "relight-rt studio: someone.png at http://127.0.0.1:" in line, (line, proc.stderr.read())
        url = line.split(" at ", 1)[1].split()[0]
        with urllib.request.urlopen(url + "api/info", timeout=10) as res:
            assert json.load(res)["photo"] == "someone.png"
    finally:
        proc.terminate()
        proc.wait(10)
        proc.stdout.close()
        proc.stderr.close()


def test_cli_start_line_escapes_a_name_holding_a_line_break(photo, models_dir, tmp_path):
    """A CR/LF in the photo's file name split the start line a caller reads for the URL (fuzz9)."""
    pytest.importorskip("fastapi")
    pytest.importorskip("uvicorn")
    odd = tmp_path / "two\nlines\r.png"
    shutil.copyfile(photo, odd)
    cmd = [sys.executable, "-m", "relight_rt", "studio", str(odd), "--port", "0", "--models", str(models_dir)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO)
    try:
        line = proc.stdout.readline()
        assert line.startswith("relight-rt studio: two\\nlines\\r.png at http://127.0.0.1:"), (line, proc.stderr.read())
    finally:
        proc.terminate()
        proc.wait(10)
        proc.stdout.close()
        proc.stderr.close()


def test_background_image_and_transparent(photo, models_dir, tmp_path):
    relighter = Relighter(RuntimeConfig(models=models_dir, device="cpu"))
    bg = np.zeros((90, 60, 3), np.float32)
    bg[..., 2] = 0.8  # blue
    bg_path = tmp_path / "blue.png"
    bg_path.write_bytes(_png_bytes(bg))
    studio = Studio(photo, None, str(bg_path), relighter, preview_pixels=5400)
    layers = unpack_layers(studio.layers_bytes(), studio.info()["preview"])
    np.testing.assert_allclose(layers["background"][2], 0.8, atol=1 / 255)
    _, rec = studio.render(lights.preset("front").tolist())
    png = cv2.imdecode(np.frombuffer(rec.png, np.uint8), cv2.IMREAD_UNCHANGED)
    assert tuple(png[0, 0]) == (204, 0, 0)  # BGR: the blue background outside the person
    assert f"--background={bg_path}" in studio.command(rec, "l.npy")
    clear = Studio(photo, None, "transparent", relighter, preview_pixels=5400)
    assert clear.info()["background"] == "transparent"
    _, rec = clear.render(lights.preset("front").tolist())
    png = cv2.imdecode(np.frombuffer(rec.png, np.uint8), cv2.IMREAD_UNCHANGED)
    assert png.shape == (90, 60, 4) and png[0, 0, 3] == 0 and png[45, 30, 3] == 255
    with pytest.raises(RelightError, match="expected the photo's"):
        small = tmp_path / "small.png"
        small.write_bytes(_png_bytes(bg[:50]))
        Studio(photo, None, str(small), relighter)


def test_cli_port_in_use_is_one_error_line(photo, models_dir, capsys):
    pytest.importorskip("fastapi")
    pytest.importorskip("uvicorn")
    import socket

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen(1)
        port = taken.getsockname()[1]
        assert main(["studio", str(photo), "--port", str(port), "--models", str(models_dir), "--device", "cpu"]) == 2
    assert f"cannot listen on 127.0.0.1:{port}" in capsys.readouterr().err


def test_ci_install_browser_script(tmp_path):
    script = REPO / ".ci" / "install-browser"
    fake = tmp_path / "chromium"
    fake.write_text("#!/bin/sh\necho 'Chromium 1.2.3'\n")
    fake.chmod(0o755)
    found = subprocess.run(
        ["/bin/bash", str(script)], env={"RELIGHT_RT_CHROMIUM": str(fake), "PATH": "/usr/bin:/bin"},
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert found.returncode == 0 and "found Chromium 1.2.3" in found.stdout
    missing = subprocess.run(
        ["/bin/bash", str(script)], env={"RELIGHT_RT_CHROMIUM": str(tmp_path / "none"), "PATH": str(tmp_path)},
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert missing.returncode == 1 and "no apt-get" in missing.stderr


def test_background_light_comes_from_the_scene(studio):
    scene = np.full((120, 160, 3), 40, np.uint8)
    scene[:, 120:] = 250  # a bright window on the photo's right: light from +y (DESIGN.md §3)
    light = studio.background_light(cv2.imencode(".png", scene)[1].tobytes())
    assert light.shape == (9, 3) and (light[1] > 0.2 * light[0]).all()
    with pytest.raises(RelightError, match="background"):
        studio.background_light(b"\x89PNG\r\n\x1a\n" + bytes(40))
    # the key light can be steered (the handle of the scene's light): from the image's left, less light from +y
    left = studio.background_light(cv2.imencode(".png", scene)[1].tobytes(), "-90,20")
    assert (left[1] < light[1]).all()
    with pytest.raises(RelightError, match="key light"):
        studio.background_light(cv2.imencode(".png", scene)[1].tobytes(), "east")


def test_cli_studio_takes_every_runtime_option(photo, models_dir, monkeypatch):
    """issue 31: studio accepted --precision/--preprocess/--no-detail and ignored them; they reach its Relighter."""
    pytest.importorskip("fastapi")
    pytest.importorskip("uvicorn")
    import relight_rt.apps.studio as studio_cli

    served = []
    monkeypatch.setattr(studio_cli, "serve", lambda studio, host, port, open_browser: served.append(studio))
    args = ["studio", str(photo), "--models", str(models_dir), "--device", "cpu", "--no-detail", "--preprocess",
            "reference"]
    assert main(args) == 0
    assert served and served[0].relighter.detail is False and served[0].relighter.preprocess == "reference"


def test_a_signal_the_server_swallowed_still_ends_the_serve(photo, models_dir, monkeypatch):
    """uvicorn raises the signal that stopped it again from inside its event loop, where asyncio's own Ctrl-C
    handling can swallow it: under load a Ctrl-C'd studio once exited with status 0 and no line. A run that
    ends quietly after a signal now raises it again: KeyboardInterrupt for Ctrl-C."""
    pytest.importorskip("fastapi")
    uvicorn = pytest.importorskip("uvicorn")
    import signal

    from relight_rt.apps import studio as studio_pkg

    def quiet_run(self, sockets=None):
        self.handle_exit(signal.SIGINT, None)  # stopped by Ctrl-C, the re-raise lost

    monkeypatch.setattr(uvicorn.Server, "run", quiet_run)
    session = Studio(photo, None, "original", Relighter(RuntimeConfig(models=models_dir, device="cpu")))
    with pytest.raises(KeyboardInterrupt):
        studio_pkg.serve(session, port=0)


@pytest.mark.parametrize("ev", [-1e-05, -2e-07, -3.0, 1e-05])
@pytest.mark.parametrize("name", ["-x.png", "--help.png", "-o.png", "a b;rm -rf.png"])
def test_exported_command_parses_as_it_reads(studio, monkeypatch, name, ev):
    """Issue 50 bugs 10, 11: an EV of -1e-05 was written "--exposure -1e-05" (argparse took it for an option), and a
    photo named -x.png gave "relight -x.png --light -x_light.npy" (INPUT missing). Every option is one --name=VALUE
    word and a relative path that starts with "-" gets ./, so the command parses to what the studio used."""
    import shlex

    from relight_rt.apps.studio.core import Render
    from relight_rt.cli import build_parser

    monkeypatch.setattr(studio, "photo", Path(name))
    monkeypatch.setattr(studio, "mask", Path("-" + name))
    cmd = studio.command(Render(b"", np.zeros((9, 3), np.float32), ev, 0.0), Path(name).stem + "_light.npy")
    args = build_parser().parse_args(shlex.split(cmd)[1:])
    operand = f"./{name}" if name.startswith("-") else name
    assert args.inputs == [operand] and args.mask == f"-{name}" and args.exposure == str(ev), cmd
    assert args.light == Path(name).stem + "_light.npy" and args.output == Path(name).stem + "_relit.png"


# ------------------------------------------------------------------------------------------------ cast shadows


def _disc_depth(h: int, w: int, depth: float = 0.6) -> np.ndarray:
    """(h, w) a cast shadow as ``Relighter.cast_shadows`` gives it: 1 - the factor on the shading, a disc."""
    yy, xx = np.mgrid[0:h, 0:w]
    return np.where((yy - 0.4 * h) ** 2 + (xx - 0.5 * w) ** 2 < (0.15 * h) ** 2, depth, 0).astype(np.float32)


def test_shadow_layer_is_the_final_results_at_the_previews_size(photo, models_dir, monkeypatch):
    """``Studio.shadow``: the faces' cast shadows the relighter reports for a light (here a disc the test sets),
    reduced to the preview's size and cut to its box as uint8; its meter goes into the preview's exposure; one
    answer per light, the latest SHADOW_CACHE kept; no shadow (box empty, meter 1) where the relighter has none."""
    from relight_rt.apps.studio import core

    relighter = relight_rt.open(RuntimeConfig(models=models_dir, device="cpu"))
    plain = Studio(photo, None, "original", relighter, preview_pixels=4096, models=models_dir)
    light = lights.preset("window-left").astype(np.float32)
    none = plain.shadow(light.tolist())
    assert none == {"box": [], "meter": 1.0, "depth": b"", "head_box": [], "head": b""}  # no face mesh, no head
    calls = []
    h, w = plain.dec.image.shape[:2]
    monkeypatch.setattr(relighter, "cast_shadows", lambda dec, lit: calls.append(lit) or (_disc_depth(h, w), 1.25))
    studio = Studio(photo, None, "original", relighter, preview_pixels=4096, models=models_dir)
    meta = studio.info()["preview"]
    answer = studio.shadow(light.tolist())
    assert studio.shadow(light.tolist()) is answer and len(calls) == 1  # kept
    plane = shadow_plane(answer, meta["height"], meta["width"])
    want = 1 - cv2.resize(_disc_depth(h, w), (meta["width"], meta["height"]), interpolation=cv2.INTER_AREA)
    np.testing.assert_allclose(plane, want, atol=0.5 / 255 + 1e-6)
    assert answer["meter"] == 1.25 and plane.min() < 0.5
    # the meter lifts the mean-keeping light before the shoulder's gain and the guard (ExposureMeter.expose's order)
    from relight_rt.light.exposure import exposure_scale, guarded

    albedo, transport, mask = studio._exposure
    scale = exposure_scale(albedo[None], transport[None], mask[None], light, meta["exposure_target"], "auto",
                           METER_POWER)
    kept = (light * np.float32(scale)).astype(np.float32)
    want = guarded(kept * np.float32(1.25), "auto", studio._highlight)
    np.testing.assert_allclose(studio.preview_light(light, "auto", 1.25), want, rtol=1e-5)
    for i in range(core.SHADOW_CACHE):
        studio.shadow((light * (1 + 0.01 * (i + 1))).tolist())
    assert len(studio._shadows) == core.SHADOW_CACHE
    studio.shadow(light.tolist())
    assert len(calls) == core.SHADOW_CACHE + 2  # the first light was dropped and asked again
    with pytest.raises(RelightError, match="27 numbers"):
        studio.shadow([1, 2])


def test_preview_picture_darkens_only_where_the_shadow_falls(studio):
    meta = studio.info()["preview"]
    layers = unpack_layers(studio.layers_bytes(), meta)
    light = studio.preview_light(lights.preset("front"))
    plane = 1 - _disc_depth(meta["height"], meta["width"], 0.5)
    plain, shaded = preview_picture(layers, meta, light), preview_picture(layers, meta, light, plane)
    dark = (plane < 1) & (layers["mask"] > 0.5) & (plain.max(axis=2) > 0.05)
    assert dark.any()
    np.testing.assert_allclose(shaded[plane == 1], plain[plane == 1])
    assert float(np.median((shaded[dark] @ REC709_) / (plain[dark] @ REC709_))) < 0.75  # the shaded-skin gain aside


REC709_ = np.array([0.2126, 0.7152, 0.0722], np.float32)


def _head_studio(photo, models_dir, monkeypatch, change):
    """A Studio whose relighter reports a disc of cast shadow (depth 0.6, meter 1) and the head pass's (before,
    after) that ``change`` builds from the frame's crop box (the relit person's luminance, 0 outside it)."""
    relighter = relight_rt.open(RuntimeConfig(models=models_dir, device="cpu"))
    probe = Studio(photo, None, "original", relighter, preview_pixels=4096, models=models_dir)
    h, w = probe.dec.image.shape[:2]
    y0, y1, x0, x1 = probe.dec.geometry.box
    inside = np.zeros((h, w), bool)
    inside[y0:y1, x0:x1] = True
    before, after = change(inside, (y0, y1, x0, x1))
    monkeypatch.setattr(relighter, "cast_shadows", lambda dec, lit: (_disc_depth(h, w, 0.6), 1.0))
    monkeypatch.setattr(relighter, "head_change", lambda dec, lit: (before, after))
    return Studio(photo, None, "original", relighter, preview_pixels=4096, models=models_dir), before, after


def _drawn_change(studio, before, after, light):
    """What the page should draw for the head pass's change, found from the page's own layers (``unpack_layers``,
    the whole preview): the preview's luminance with the cast shadows (premultiplied), ``before`` and ``after``
    reduced by area, their ratio, the gain that adds their difference to that luminance, and the cast shadows'
    factor (uint8)."""
    meta = studio.info()["preview"]
    size = (meta["width"], meta["height"])
    small_before, small_after = (cv2.resize(a, size, interpolation=cv2.INTER_AREA) for a in (before, after))
    depth = cv2.resize(_disc_depth(*before.shape, 0.6), size, interpolation=cv2.INTER_AREA)
    cast = 1 - np.rint(np.clip(depth, 0, 1) * 255) / 255  # as the page gets it: uint8
    layers = unpack_layers(studio.layers_bytes(), meta)
    shown = preview_picture(layers, meta, studio.preview_light(light), cast) @ REC709_
    ratio = np.where(small_before > 1e-4, np.maximum(small_after, 0) / np.maximum(small_before, 1e-4), 1)
    added = shown + layers["mask"] * (small_after - small_before)
    gain = np.where(shown > 1e-4, added / np.maximum(shown, 1e-4), 1)
    return meta, shown, layers["mask"], ratio, gain, cast


def test_the_head_pass_change_is_drawn_as_its_ratio_capped_by_its_difference(photo, models_dir, monkeypatch):
    """``Studio.shadow``'s head pass's change (``Relighter.head_change``: the relit person's luminance before and
    after the head pass's blend, here two planes the test sets): both reduced to the preview's pixels by area, then
    carried into the preview as a factor on its shading: their ratio (1 where no luminance is left), where it
    brightens no more than the gain that adds their difference to the preview's own luminance (the page's drawing
    under the light, with the cast shadows; no gain where the preview draws nothing); cut to the box where it is
    not 1, float32. ``shadow_plane`` puts it on the cast shadows' factor, both where they overlap."""
    def change(inside, box):
        before = np.where(inside, 0.4, 0).astype(np.float32)
        after = before.copy()
        after[_disc_depth(*inside.shape, 1.0) > 0] *= 0.5  # the head pass darkens a disc by half ...
        y0, y1, x0, x1 = box
        after[y0 : y0 + 20, x0 : x0 + 20] = 0.0  # ... one corner of the crop box to black ...
        low = slice(y1 - (y1 - y0) // 4, y1)
        before[low, x0:x1], after[low, x0:x1] = 0.02, 0.06  # ... and triples its dark lower quarter
        return before, after

    studio, before, after = _head_studio(photo, models_dir, monkeypatch, change)
    light = lights.preset("rim").astype(np.float32)
    answer = studio.shadow(light.ravel().tolist())
    assert answer["head_box"] and len(answer["head"]) == 4 * np.prod(np.diff(answer["head_box"])[::2])
    meta, shown, mask, ratio, gain, cast = _drawn_change(studio, before, after, light)
    plane = shadow_plane(answer, meta["height"], meta["width"])
    np.testing.assert_allclose(plane, cast * np.minimum(ratio, np.maximum(gain, 1)), atol=1e-4)
    darker = np.abs(ratio - 0.5) < 1e-3
    assert darker.sum() > 20 and np.abs(plane[darker] / cast[darker] - 0.5).max() < 1e-3  # darkening: the ratio
    assert (plane[ratio == 0] == 0).sum() > 20  # the black corner
    capped = (np.abs(ratio - 3) < 1e-3) & (gain < 2.5) & (mask > 0.99)  # the preview brighter than "before"
    assert capped.sum() > 20 and np.abs(plane[capped] / cast[capped] - gain[capped]).max() < 1e-3  # not 3
    assert plane[-1, -1] == 1  # below the crop box: 1


def test_the_head_pass_change_does_not_amplify_a_brighter_preview(photo, models_dir, monkeypatch):
    """Where the result without the head pass is far darker than the preview (dark cloth, the preview's own
    approximations), the head pass's ratio would multiply the preview's light: the preview instead gains the
    luminance the head pass adds, not that ratio."""
    def change(inside, box):
        before = np.where(inside, 0.01, 0).astype(np.float32)
        return before, np.where(inside, 0.05, 0).astype(np.float32)  # five times as bright, 0.04 more

    studio, before, after = _head_studio(photo, models_dir, monkeypatch, change)
    light = lights.preset("campfire").astype(np.float32)
    answer = studio.shadow(light.ravel().tolist())
    meta, shown, mask, ratio, gain, cast = _drawn_change(studio, before, after, light)
    head = shadow_plane(answer, meta["height"], meta["width"]) / cast
    solid = (mask > 0.99) & (shown > 0.05) & (shown < 0.8)
    assert solid.sum() > 50 and np.abs(ratio[solid] - 5).max() < 1e-3
    assert head[solid].max() < 2  # the ratio (5) would have amplified the preview's own light
    np.testing.assert_allclose(shown[solid] * head[solid], shown[solid] + 0.04, atol=1e-3)  # the luminance added


def test_route_shadow(client, studio):
    light = lights.preset("window-left").astype(np.float32)
    out = client.post("/api/shadow", json={"light": light.tolist()}).json()
    assert out == {"box": [], "meter": 1.0, "depth": "", "head_box": [], "head": ""}
    res = client.post("/api/shadow", json={"light": [1, 2]})
    assert res.status_code == 400 and "27 numbers" in res.json()["error"]


def test_preview_composites_with_the_automatic_mattes_shown_edge(tmp_path, models_dir):
    """Over the photo's own background the render takes the automatic matte's edge as the photo shows it
    (relight_rt.relight.compose.shown_edge); the preview's mask and albedo follow it, so that the preview does not
    draw the halo the render no longer has. A new or transparent background keeps the matte."""
    h, w = 150, 100
    img = np.empty((h, w, 3), np.float32)
    img[...] = (0.85, 0.85, 0.8)
    hard = np.zeros((h, w), np.float32)
    img[20:140, 30:70], hard[20:140, 30:70] = (0.35, 0.25, 0.2), 1
    soft = np.clip(cv2.GaussianBlur(hard, (0, 0), 4.0), 0, 1)  # the matte feathered 4 px past a sharp outline
    path = tmp_path / "someone.png"
    path.write_bytes(_png_bytes(img))
    relighter = Relighter(RuntimeConfig(models=str(models_dir), device="cpu"), matter=lambda rgb, name="image": soft)
    kept = Studio(path, None, "original", relighter, preview_pixels=h * w)
    clear = Studio(path, None, "transparent", relighter, preview_pixels=h * w)
    assert kept.dec.edge is not None
    shown = shown_mask(kept.dec)
    assert np.abs(shown - soft).max() > 0.2  # the edge the photo shows is not the matte's
    on, off = (unpack_layers(s.layers_bytes(), s.info()["preview"]) for s in (kept, clear))
    np.testing.assert_allclose(on["mask"], shown, atol=0.5 / 255 + 1e-6)
    np.testing.assert_allclose(off["mask"], np.asarray(clear.dec.mask), atol=0.5 / 255 + 1e-6)
    ratio = np.divide(shown, soft, out=np.zeros_like(shown), where=soft > 0)
    np.testing.assert_allclose(on["albedo"], np.clip(off["albedo"] * ratio, 0, 1), atol=1.5 / 255)


def test_preview_grade_is_the_full_results_on_the_bundled_street_photo():
    """The preview's background grade (``Studio.preview_grade``, what sh.js backgroundGrade computes) is the full
    result's (relight_rt.relight.compose.background_grade) within 0.1 EV per channel on the bundled models' street
    photo (benchmarks/studio_preview_gap.py), under every preset that script measures. It reads what the result
    grades: the person's own colour under the matte, weighted by it, relit with the shoulder, and the head pass's
    blend. Read from the network's image over its solid pixels, it took the street behind the soft edge for the
    person, which the rim and side lamps brighten most (0.58 and 0.31 EV), and without the shoulder it missed what
    night's highlights lose (0.12 EV). The head pass's box holds two thirds of the person's own light here (the
    face and the white-striped top), and its blend scales the head pass's factor to the body's level on the head
    pass's skin: 0.79 x under window-left, a grade 0.11 EV lower than the body's factor alone gives; without the
    blend (``HeadBlend``) the preview missed window-left's by 0.14 EV."""
    models = Path(relight_rt.__file__).resolve().parent / "models"
    studio = Studio(Path(relight_rt.__file__).resolve().parent / "data" / "example_scene.jpg", None, "original",
                    relight_rt.open(RuntimeConfig(models=models, device="cpu")))
    meta, data = studio.info()["preview"], studio.layers_bytes()
    sample = unpack_layers(data, meta)["grade"]
    assert sample.head.index.size > 0.2 * sample.weight.size  # the head pass's box covers much of the person
    full = studio.relighter.grade_inputs(studio.dec)  # the blend travels whole, on the pixels the page gets
    for got, want in zip(sample.head, full.head.every(-(-full.weight.shape[0] // EXPOSURE_SAMPLES)), strict=True):
        np.testing.assert_array_equal(got, want)
    at, nb = meta["grade_head_offset"], sample.head.index.size  # and pixels it cannot name are refused
    wrong = data[:at] + np.full(nb, sample.weight.size, "<i4").tobytes() + data[at + 4 * nb :]
    with pytest.raises(RelightError, match="head pass"):
        unpack_layers(wrong, meta)
    back = np.asarray(studio.dec.mask) == 0
    rgb = lambda png: cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)[..., ::-1].astype(float)  # noqa: E731
    for name in ("rim", "window-left", "studio", "night", "campfire", "golden-hour"):
        light = lights.preset(name).astype(np.float32)
        _, off = studio.render(light.tolist(), grade_background=False)
        _, on = studio.render(light.tolist(), grade_background=True)
        a, b = rgb(off.png), rgb(on.png)
        keep = back & (a.min(axis=2) > 20) & (a.max(axis=2) < 235)  # clear of rounding and of the clip at white
        result = np.median(b[keep] / a[keep], axis=0)
        shown = studio.preview_light(light.tolist())
        ev = np.log2(studio.preview_grade(shown) / result) * DISPLAY_GAMMA
        assert np.abs(ev).max() < 0.1, (name, ev)
        if name == "window-left":  # the head pass's blend is what brings it within the bar
            body_only = sampled_grade(sample._replace(head=HeadBlend.empty()), shown)
            assert np.abs(np.log2(body_only / result) * DISPLAY_GAMMA).max() > 0.1


def _fibred_photo(tmp_path) -> tuple[Path, np.ndarray]:
    """A dark 'person' before a bright background whose automatic matte and photo both fray into strands along its
    sides (fibres: the kept rim's whole reach), as a PNG without alpha, and that matte."""
    h, w = 150, 100
    rng = np.random.default_rng(11)
    hard = np.zeros((h, w), np.float32)
    hard[20:140, 30:70] = 1
    strands = (rng.random((h, 1)) < 0.5).astype(np.float32) * np.linspace(1, 0, 12, dtype=np.float32)[None]
    hard[20:140, 70:82] = np.maximum(hard[20:140, 70:82], strands[20:140])
    hard[20:140, 18:30] = np.maximum(hard[20:140, 18:30], strands[20:140, ::-1])
    soft = np.clip(cv2.GaussianBlur(hard, (0, 0), 1.5), 0, 1)
    img = soft[..., None] * np.float32([0.3, 0.22, 0.18]) + (1 - soft[..., None]) * np.float32([0.9, 0.88, 0.8])
    path = tmp_path / "someone.png"
    path.write_bytes(_png_bytes(img))
    return path, soft


def test_preview_gets_the_kept_rim_where_the_render_applies_it(tmp_path, models_dir):
    """The kept background's rim (relight_rt.relight.kept_rim) reaches the preview over the photo's own background
    with the automatic matte: at the photo's size, its pixels and straight colour are the relighter's (those of
    at least half a level); at a smaller preview, its premultiplied sum is the area-reduced one. A new or transparent
    background, or a given mask, has none (the render applies none there)."""
    path, soft = _fibred_photo(tmp_path)
    relighter = Relighter(RuntimeConfig(models=str(models_dir), device="cpu"), matter=lambda rgb, name="image": soft)
    h, w = soft.shape
    kept = Studio(path, None, "original", relighter, preview_pixels=h * w)
    rim = relighter.kept_rim(kept.dec)
    assert rim is not None and rim.index.size > 50
    got = unpack_layers(kept.layers_bytes(), kept.info()["preview"])["rim"]
    y0, _, x0, x1 = kept.dec.geometry.box
    ys, xs = np.divmod(rim.index, x1 - x0)
    flat = (ys + y0) * w + xs + x0
    assert got["index"].size > 0.8 * rim.index.size and np.isin(got["index"], flat).all()
    np.testing.assert_allclose(got["rim"], rim.rim[np.searchsorted(flat, got["index"])], rtol=1e-4, atol=1e-6)
    small = Studio(path, None, "original", relighter, preview_pixels=h * w // 2)
    meta = small.info()["preview"]
    part = unpack_layers(small.layers_bytes(), meta)
    m = part["mask"].reshape(-1)[part["rim"]["index"]]
    alpha = shown_mask(kept.dec).reshape(-1)[flat]
    scale = meta["height"] * meta["width"] / (h * w)
    np.testing.assert_allclose((part["rim"]["rim"] * m[:, None]).sum(0), (rim.rim * alpha[:, None]).sum(0) * scale,
                               rtol=0.05)
    for other in (Studio(path, None, "transparent", relighter, preview_pixels=h * w),
                  Studio(path, None, tmp_path / "someone.png", relighter, preview_pixels=h * w)):
        assert other.info()["preview"]["rim_samples"] == 0
    mask = tmp_path / "mask.png"
    mask.write_bytes(_png_bytes(np.repeat(soft[..., None], 3, axis=2)))
    given = Studio(path, mask, "original", relighter, preview_pixels=h * w)
    assert relighter.kept_rim(given.dec) is None and given.info()["preview"]["rim_samples"] == 0
