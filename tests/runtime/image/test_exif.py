"""EXIF orientation (relight_rt.image.exif): a phone photo comes out the way the phone shows it, at every intake.

The test files carry a hand-written EXIF block (an APP1 segment in a JPEG, an eXIf chunk in a PNG), so the
tests need no other imaging library. The expected pictures come from the orientation's definition in the
EXIF standard (where row 0 and column 0 of the stored image are shown) and, independently, from OpenCV's
own orientation handling (cv2.IMREAD_COLOR applies it).
"""

from __future__ import annotations

import struct
import zlib

import cv2
import numpy as np
import pytest

from relight_rt.image.exif import apply_orientation, exif_orientation
from relight_rt.image.io import read_image, read_mask

H, W = 48, 80  # a landscape sensor image: turned 90°, the photo is 80 high and 48 wide


def tiff_block(orientation: int, big_endian: bool = True) -> bytes:
    """A minimal EXIF (TIFF) block: header, IFD0 with one entry, tag 0x0112 (SHORT) = orientation."""
    o = ">" if big_endian else "<"
    entry = struct.pack(o + "HHIHH", 0x0112, 3, 1, orientation, 0)
    return (b"MM" if big_endian else b"II") + struct.pack(o + "HI", 42, 8) + struct.pack(o + "H", 1) + entry + b"\0" * 4


def jpeg_with_orientation(bgr: np.ndarray, orientation: int, big_endian: bool = True) -> bytes:
    """A JPEG with an APP1 Exif segment right after SOI (where phones write it)."""
    jpeg = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, 100])[1].tobytes()
    payload = b"Exif\0\0" + tiff_block(orientation, big_endian)
    app1 = b"\xff\xe1" + struct.pack(">H", len(payload) + 2) + payload
    return jpeg[:2] + app1 + jpeg[2:]


def png_with_orientation(image: np.ndarray, orientation: int) -> bytes:
    """A PNG with an eXIf chunk before its image data."""
    png = cv2.imencode(".png", image)[1].tobytes()
    body = tiff_block(orientation)
    chunk = struct.pack(">I", len(body)) + b"eXIf" + body + struct.pack(">I", zlib.crc32(b"eXIf" + body))
    at = png.index(b"IDAT") - 4
    return png[:at] + chunk + png[at:]


def picture() -> np.ndarray:
    """(H, W, 3) uint8 BGR with a distinct block in each corner (JPEG keeps blocks of flat colour)."""
    img = np.full((H, W, 3), 128, np.uint8)
    img[:16, :16] = (0, 0, 255)  # top left: red
    img[:16, -16:] = (0, 255, 0)  # top right: green
    img[-16:, :16] = (255, 0, 0)  # bottom left: blue
    return img


# EXIF 2.3, tag 0x0112: which side of the shown picture row 0 and column 0 of the stored image are.
SHOWN_TOP_LEFT = {1: "red", 2: "green", 3: None, 4: "blue", 5: "red", 6: "blue", 7: None, 8: "green"}


def test_the_tag_is_read_from_jpeg_png_and_both_byte_orders():
    for k in range(1, 9):
        assert exif_orientation(jpeg_with_orientation(picture(), k)) == k
        assert exif_orientation(jpeg_with_orientation(picture(), k, big_endian=False)) == k
        assert exif_orientation(png_with_orientation(picture(), k)) == k
    assert exif_orientation(cv2.imencode(".jpg", picture())[1].tobytes()) == 1  # no tag
    assert exif_orientation(b"not an image") == 1


@pytest.mark.parametrize("data", [
    jpeg_with_orientation(picture(), 6)[:30],  # cut inside the EXIF block
    jpeg_with_orientation(picture(), 9),  # out of range
    b"\xff\xd8\xff\xe1\xff\xff" + b"Exif\0\0" + b"XX",  # bad byte order mark
    b"\xff\xd8" + b"\xff\xe0\x00\x02" * 5000,  # many empty segments
])  # fmt: skip
def test_damaged_tags_count_as_none(data):
    assert exif_orientation(data) == 1


@pytest.mark.parametrize("k", range(1, 9))
def test_turning_matches_opencv(k):
    data = np.frombuffer(jpeg_with_orientation(picture(), k), np.uint8)
    stored = cv2.imdecode(data, cv2.IMREAD_COLOR | cv2.IMREAD_IGNORE_ORIENTATION)
    np.testing.assert_array_equal(apply_orientation(stored, k), cv2.imdecode(data, cv2.IMREAD_COLOR))


@pytest.mark.parametrize("k", range(1, 9))
def test_a_phone_photo_comes_out_as_the_phone_shows_it(tmp_path, k):
    path = tmp_path / "phone.jpg"
    path.write_bytes(jpeg_with_orientation(picture(), k))
    rgb = read_image(path)
    assert rgb.shape[:2] == ((H, W) if k <= 4 else (W, H))
    corner = rgb[:8, :8].mean(axis=(0, 1))
    expected = SHOWN_TOP_LEFT[k]
    colours = {"red": [1, 0, 0], "green": [0, 1, 0], "blue": [0, 0, 1]}
    if expected is None:  # 3 and 7 show the stored bottom-right (gray) at the top left
        np.testing.assert_allclose(corner, 128 / 255, atol=0.03)
    else:
        np.testing.assert_allclose(corner, colours[expected], atol=0.03)


def test_grayscale_and_alpha_files_are_turned_too(tmp_path):
    gray = picture()[..., 2]  # red channel: the top-left block is bright
    (tmp_path / "g.jpg").write_bytes(jpeg_with_orientation(gray, 6))
    out = read_image(tmp_path / "g.jpg")
    assert out.shape == (W, H, 3) and out[:8, -8:].mean() > 0.9  # red block: top right after turning clockwise
    rgba = np.dstack([picture(), np.full((H, W), 255, np.uint8)])
    (tmp_path / "a.png").write_bytes(png_with_orientation(rgba, 8))
    out = read_image(tmp_path / "a.png")
    assert out.shape == (W, H, 4)
    np.testing.assert_allclose(out[:8, :8, :3].mean(axis=(0, 1)), [0, 1, 0], atol=0.01)  # green, top left


def test_masks_backgrounds_uploads_and_the_mask_command_are_turned(tmp_path):
    from relight_rt.apps.studio.uploads import decode_upload
    from relight_rt.cli.mask import read_photo
    from relight_rt.light.from_background import read_background

    mask = np.zeros((H, W), np.uint8)
    mask[:16, :16] = 255
    (tmp_path / "m.png").write_bytes(png_with_orientation(mask, 6))
    m = read_mask(tmp_path / "m.png", (W, H))
    assert m[:16, -16:].min() == 1 and m.sum() == 16 * 16
    big = cv2.resize(picture(), (2 * W, 2 * H), interpolation=cv2.INTER_NEAREST)  # backgrounds: >= 64 px
    (tmp_path / "bg.jpg").write_bytes(jpeg_with_orientation(big, 8))
    bg = read_background(tmp_path / "bg.jpg")
    assert bg.shape == (2 * W, 2 * H, 3)
    np.testing.assert_allclose(bg[:8, :8].mean(axis=(0, 1)), [0, 255, 0], atol=8)  # green, top left
    data = jpeg_with_orientation(picture(), 6)
    (tmp_path / "p.jpg").write_bytes(data)
    expected = read_image(tmp_path / "p.jpg")
    np.testing.assert_array_equal(decode_upload(data, "upload"), expected)
    np.testing.assert_array_equal(read_photo(tmp_path / "p.jpg"), expected)
