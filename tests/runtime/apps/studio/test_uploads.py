"""relight_rt.apps.studio.uploads: an upload taken as bytes, never a path; its size, kind and pixel count checked before
any decoder runs; a file a reader needs written under a name of the module's own in a folder removed right after.

What test_studio.py (sniff's kinds, check_upload's refusals) and test_studio_hostile.py (bombs, memory) cover is not
repeated here: these are the limits' edges, the results' values and where the files go.
"""

from __future__ import annotations

import math
import tempfile

import cv2
import numpy as np
import pytest

from relight_rt import RelightError
from relight_rt.apps.studio import uploads
from relight_rt.apps.studio.uploads import (
    MAX_UPLOAD_PIXELS,
    background_upload_light,
    check_upload,
    decode_upload,
    envmap_upload_light,
    sniff,
)
from relight_rt.light import envmap
from relight_rt.light.from_background import light_from_background

IMAGE_KINDS = ("png", "jpeg", "webp", "bmp")


def _encoded(ext: str, rgb: np.ndarray) -> bytes:
    """``rgb`` (h, w, 3) uint8 RGB, or float32 for .hdr, encoded by OpenCV (which takes BGR)."""
    return cv2.imencode(ext, np.ascontiguousarray(rgb[..., ::-1]))[1].tobytes()


def _png_header(width: int, height: int) -> bytes:
    """A PNG's signature and IHDR chunk claiming ``width`` x ``height`` (8-bit RGB), no image data (PNG spec §11.2.2:
    width and height are the chunk's first two big-endian 32-bit words)."""
    ihdr = width.to_bytes(4, "big") + height.to_bytes(4, "big") + bytes([8, 2, 0, 0, 0])
    return b"\x89PNG\r\n\x1a\n" + len(ihdr).to_bytes(4, "big") + b"IHDR" + ihdr + bytes(4)


@pytest.fixture(autouse=True)
def own_temp(tmp_path, monkeypatch):
    """Temporary files of this test go under its own folder, so what is left behind can be seen."""
    folder = tmp_path / "temp"
    folder.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(folder))
    return folder


# ------------------------------------------------------------------------------------------------ sniff


def test_sniff_kinds_beside_the_common_ones():
    assert sniff(b"#?RGBE\n") == ("hdr", ".hdr")  # the older Radiance signature
    assert sniff(b"BM" + bytes(10)) == ("bmp", ".bmp")
    assert sniff(b"RIFF") is None  # too short to say WEBP
    assert sniff(b"") is None
    assert sniff(b"x\x89PNG\r\n\x1a\n") is None  # the signature at the start, not anywhere


# ------------------------------------------------------------------------------------------------ check_upload


@pytest.mark.parametrize(("ext", "kind"), [(".png", "png"), (".jpg", "jpeg"), (".webp", "webp"), (".bmp", "bmp"),
                                           (".hdr", "hdr")])
def test_check_upload_returns_the_suffix_of_its_kind(ext, kind):
    img = np.zeros((5, 7, 3), np.float32 if kind == "hdr" else np.uint8)
    suffix = ".jpg" if kind == "jpeg" else ext
    assert check_upload(_encoded(ext, img), "upload", (kind,)) == suffix
    others = tuple(k for k in (*IMAGE_KINDS, "hdr") if k != kind)
    with pytest.raises(RelightError, match=f"upload: expected .* \\(by content\\), got a {kind} file"):
        check_upload(_encoded(ext, img), "upload", others)


def test_check_upload_byte_limit_is_inclusive():
    data = _encoded(".png", np.zeros((4, 4, 3), np.uint8))
    assert check_upload(data, "photo", ("png",), limit=len(data)) == ".png"
    with pytest.raises(RelightError, match="photo: the upload is .* MiB, the limit is"):
        check_upload(data, "photo", ("png",), limit=len(data) - 1)


def test_check_upload_pixel_limit_is_inclusive():
    side = 5000
    assert MAX_UPLOAD_PIXELS % side == 0  # the edge case below is exact
    at_limit = _png_header(MAX_UPLOAD_PIXELS // side, side)
    assert check_upload(at_limit, "photo", ("png",)) == ".png"  # a header alone: nothing is decoded
    over = _png_header(MAX_UPLOAD_PIXELS // side + 1, side)
    with pytest.raises(RelightError, match=f"photo: the image is {MAX_UPLOAD_PIXELS // side + 1}x{side}, more than"):
        check_upload(over, "photo", ("png",))


@pytest.mark.parametrize("call", [lambda v: check_upload(v, "photo", ("png",)), lambda v: decode_upload(v, "photo"),
                                  envmap_upload_light, background_upload_light])
def test_a_path_is_refused_not_opened(tmp_path, call):
    """An upload is its bytes: a path (str or Path) to a readable image, or its name as bytes, is refused."""
    path = tmp_path / "on_disk.png"
    path.write_bytes(_encoded(".png", np.zeros((4, 8, 3), np.uint8)))
    for value in (str(path), path):
        with pytest.raises(RelightError, match="expected the upload's bytes"):
            call(value)
    with pytest.raises(RelightError, match="unknown type"):
        call(str(path).encode())


# ------------------------------------------------------------------------------------------------ decode_upload


def test_decode_upload_values_and_channel_order():
    rgba = np.array([[[255, 0, 0, 255], [0, 255, 0, 128]], [[0, 0, 255, 0], [51, 102, 153, 204]]], np.uint8)
    data = cv2.imencode(".png", cv2.cvtColor(rgba, cv2.COLOR_RGBA2BGRA))[1].tobytes()
    got = decode_upload(data, "photo")
    assert got.shape == (2, 2, 4) and got.dtype == np.float32
    np.testing.assert_allclose(got, rgba.astype(np.float32) / 255, rtol=1e-6)  # RGB(A) order, alpha kept, lossless
    gray = decode_upload(cv2.imencode(".png", np.array([[0, 51], [102, 255]], np.uint8))[1].tobytes(), "photo")
    assert gray.shape == (2, 2, 3)
    np.testing.assert_array_equal(gray[..., 0], gray[..., 2])
    np.testing.assert_allclose(gray[..., 1], [[0, 0.2], [0.4, 1]], atol=1e-7)


def test_decode_upload_shrinks_by_area_to_max_pixels():
    blocks = np.kron(np.array([[10, 200], [90, 250]], np.uint8), np.ones((3, 3), np.uint8))  # (6, 6)
    data = _encoded(".png", np.repeat(blocks[..., None], 3, axis=2))
    got = decode_upload(data, "photo", max_pixels=4)
    assert got.shape == (2, 2, 3)
    np.testing.assert_allclose(got[..., 1], np.array([[10, 200], [90, 250]]) / 255, atol=1e-7)  # each block's mean
    assert decode_upload(data, "photo", max_pixels=36).shape == (6, 6, 3)  # small enough: as it is


def test_decode_upload_refuses_hdr_and_a_body_that_does_not_decode():
    hdr = _encoded(".hdr", np.ones((4, 8, 3), np.float32))
    with pytest.raises(RelightError, match="background: expected PNG or JPEG or WEBP or BMP .*got a hdr file"):
        decode_upload(hdr, "background")
    png = _encoded(".png", np.zeros((4, 4, 3), np.uint8))
    with pytest.raises(RelightError, match="photo: cannot decode the image"):
        decode_upload(png[:40], "photo")  # its header says 4x4, its data is cut off


# ------------------------------------------------------------------------------------------------ env maps


def test_envmap_upload_of_a_constant_sky_is_its_dc_term(own_temp):
    """Radiance 1 everywhere: L00 = the integral of Y00 = 4 pi / (2 sqrt(pi)) = sqrt(4 pi), every other coefficient 0
    (DESIGN.md §3's basis); an sRGB white PNG is that same sky (sRGB 1.0 is linear 1.0)."""
    hdr = envmap_upload_light(_encoded(".hdr", np.ones((64, 128, 3), np.float32)))
    assert hdr.shape == (9, 3) and hdr.dtype == np.float32
    np.testing.assert_allclose(hdr[0], math.sqrt(4 * math.pi), rtol=1e-3)  # 64 x 128 quadrature: 3.5453
    np.testing.assert_allclose(hdr[1:], 0, atol=1e-3)  # (its Y20 is 8e-4: the rows' quadrature)
    png = envmap_upload_light(_encoded(".png", np.full((64, 128, 3), 255, np.uint8)))
    np.testing.assert_allclose(png, hdr, rtol=1e-6)
    assert not any(own_temp.iterdir())


def test_envmap_upload_is_read_under_our_name_and_removed(own_temp, monkeypatch):
    seen = []
    real = envmap.load_envmap

    def spy(path, **kwargs):
        seen.append((path, path.is_file(), kwargs))
        return real(path, **kwargs)

    monkeypatch.setattr(envmap, "load_envmap", spy)
    envmap_upload_light(_encoded(".jpg", np.full((8, 16, 3), 128, np.uint8)))
    ((path, existed, kwargs),) = seen
    assert existed and path.name == "upload.jpg" and path.parent.name.startswith("relight-studio-")
    assert path.parent.parent == own_temp and kwargs == {"max_pixels": uploads.UPLOAD_WORK_PIXELS}
    assert not path.parent.exists()  # the folder went with the file
    corrupt = _encoded(".hdr", np.ones((16, 32, 3), np.float32))
    with pytest.raises(RelightError, match="^environment map: cannot decode environment map") as refused:
        envmap_upload_light(corrupt[: len(corrupt) // 3])
    assert "relight-studio-" not in str(refused.value) and str(own_temp) not in str(refused.value)  # no server path
    assert not any(own_temp.iterdir())  # removed on failure too


def test_envmap_upload_refuses_kinds_it_cannot_read():
    with pytest.raises(RelightError, match="environment map: expected HDR or PNG or JPEG .*got a bmp file"):
        envmap_upload_light(_encoded(".bmp", np.zeros((4, 8, 3), np.uint8)))
    with pytest.raises(RelightError, match="environment map: the upload is empty"):
        envmap_upload_light(b"")


# ------------------------------------------------------------------------------------------------ backgrounds


def test_background_upload_is_the_light_of_its_rgb(own_temp):
    rng = np.random.default_rng(3)
    rgb = (rng.random((72, 108, 3)) * 255).astype(np.uint8)  # light_from_background takes 64 x 64 or more
    got = background_upload_light(_encoded(".png", rgb), key_light="30,20")
    want, _ = light_from_background(rgb.astype(np.float32) / 255, key_light=(30.0, 20.0))
    assert got.shape == (9, 3) and got.dtype == np.float32
    np.testing.assert_allclose(got, want, rtol=1e-6)
    rgba = np.concatenate([rgb, np.full((72, 108, 1), 7, np.uint8)], axis=2)  # its alpha plays no part
    data = cv2.imencode(".png", cv2.cvtColor(rgba, cv2.COLOR_RGBA2BGRA))[1].tobytes()
    np.testing.assert_array_equal(background_upload_light(data, key_light=(30, 20)), got)
    assert not any(own_temp.iterdir())  # a background is decoded in memory


def test_background_key_light_is_checked_before_the_upload():
    with pytest.raises(RelightError, match="key light: expected AZIMUTH,ELEVATION"):
        background_upload_light(b"", key_light="north")  # not "the upload is empty": the key light first
    with pytest.raises(RelightError, match=r"key light: expected .*elevation in \[-90, 90\]"):
        background_upload_light(b"", key_light=(0, 95))


def _flat_png(width: int, height: int) -> bytes:
    return _encoded(".png", np.full((height, width, 3), 128, np.uint8))


def test_large_uploads_are_worked_on_one_at_a_time(monkeypatch):
    """fuzz9: four 40-MP uploads at once (the server's four slots) took the studio from 0.3 to 1.6 GB, each decode
    ~310-640 MB; the work on those over UPLOAD_WORK_PIXELS now runs one after another, on smaller ones side by side."""
    import threading
    import time

    from relight_rt.apps.studio.uploads import one_large_at_a_time

    state = {"now": 0, "most": 0, "started": 0}
    lock = threading.Lock()

    def work(data: bytes) -> int:
        with lock:
            state["now"] += 1
            state["most"] = max(state["most"], state["now"])
        end = time.monotonic() + 10  # a bound on the wait, not a timing assertion
        while state["started"] < 3 and time.monotonic() < end:
            time.sleep(0.01)
        time.sleep(0.2)  # every thread has called: those not held back arrive while this one works
        with lock:
            state["now"] -= 1
        return len(data)

    def started(data: bytes) -> None:
        with lock:
            state["started"] += 1
        assert one_large_at_a_time(work, data, "upload") == len(data)

    def most_at_once(data: bytes) -> int:
        state["most"] = state["started"] = 0
        threads = [threading.Thread(target=started, args=(data,)) for _ in range(3)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        return state["most"]

    monkeypatch.setattr(uploads, "UPLOAD_WORK_PIXELS", 64 * 32)  # "large" at a test's size
    assert most_at_once(_flat_png(128, 64)) == 1
    assert most_at_once(b"\x89PNG\r\n\x1a\n garbage") == 1  # no size to read: as a large one
    assert most_at_once(_flat_png(64, 32)) > 1
