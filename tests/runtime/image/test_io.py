"""relight_rt.image.io: reading images/masks with clear errors; writing images (atomic, never over an input)."""

import cv2
import numpy as np
import pytest

from relight_rt import RelightError
from relight_rt.image.io import list_images, read_image, read_mask, sibling_mask, write_image


@pytest.fixture
def rgb_u8():
    rng = np.random.default_rng(0)
    return rng.integers(0, 256, (12, 10, 3), dtype=np.uint8)


def test_png_file_is_read_as_rgb(tmp_path, rgb_u8):
    path = tmp_path / "a.png"
    cv2.imwrite(str(path), rgb_u8[..., ::-1])  # OpenCV writes BGR
    img = read_image(path)
    assert img.shape == (12, 10, 3) and img.dtype == np.float32
    np.testing.assert_allclose(img, rgb_u8 / 255.0, atol=1e-6)


def test_rgba_file_keeps_alpha(tmp_path, rgb_u8):
    alpha = np.full((12, 10, 1), 128, np.uint8)
    cv2.imwrite(str(tmp_path / "a.png"), np.concatenate([rgb_u8[..., ::-1], alpha], 2))
    img = read_image(tmp_path / "a.png")
    assert img.shape == (12, 10, 4)
    np.testing.assert_allclose(img[..., :3], rgb_u8 / 255.0, atol=1e-6)
    np.testing.assert_allclose(img[..., 3], 128 / 255, atol=1e-6)


@pytest.mark.parametrize("dtype", [np.uint8, np.float32, np.float64, np.float16])
def test_arrays_of_each_dtype(dtype, rgb_u8):
    src = rgb_u8 if dtype == np.uint8 else (rgb_u8 / 255.0).astype(dtype)
    keep = src.copy()
    img = read_image(src)
    assert img.dtype == np.float32 and img is not src
    np.testing.assert_allclose(img, rgb_u8 / 255.0, atol=1e-3)
    np.testing.assert_array_equal(src, keep)


@pytest.mark.parametrize(
    ("make", "match"),
    [
        (lambda: np.zeros((8, 8, 2), np.uint8), r"\(H, W, 3\)"),
        (lambda: np.zeros((8, 8, 5), np.uint8), r"\(H, W, 3\)"),
        (lambda: np.zeros((1, 8), np.uint8), "too small"),
        (lambda: np.full((8, 8, 3), np.nan, np.float32), "NaN"),
        (lambda: np.full((8, 8, 3), 2.0, np.float32), r"\[0, 1\]"),
        (lambda: np.zeros((8, 8, 3), np.int32), "uint8, uint16 or float"),
        (lambda: np.zeros((8, 8, 3), complex), "uint8, uint16 or float"),
        (lambda: [[1, 2, 3]], "path or"),
    ],
)
def test_bad_arrays(make, match):
    with pytest.raises(RelightError, match=match):
        read_image(make())


def test_bad_files(tmp_path):
    with pytest.raises(RelightError, match="cannot read"):
        read_image(tmp_path / "missing.png")
    (tmp_path / "junk.png").write_bytes(b"not an image at all")
    with pytest.raises(RelightError, match="cannot decode"):
        read_image(tmp_path / "junk.png")
    (tmp_path / "empty.png").write_bytes(b"")
    with pytest.raises(RelightError, match="cannot decode"):
        read_image(tmp_path / "empty.png")


def gray_alpha_png(la: np.ndarray) -> bytes:
    """An 8-bit gray + alpha PNG (colour type 4) of ``la`` (H, W, 2) uint8, written by hand."""
    import struct
    import zlib

    def chunk(kind: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    rows = b"".join(b"\0" + row.tobytes() for row in la)  # filter type 0 on every row
    head = struct.pack(">IIBBBBB", la.shape[1], la.shape[0], 8, 4, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", head) + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b"")


@pytest.mark.parametrize("form", ["gray", "gray1", "gray16", "gray-alpha"])
def test_grayscale_is_read_as_colour(tmp_path, form):
    """issue 34: black-and-white photos were refused ("expected an (H, W, 3) colour image, got grayscale")."""
    gray = np.random.default_rng(1).integers(0, 256, (12, 10), dtype=np.uint8)
    if form == "gray":
        data, expected = gray, gray / 255
    elif form == "gray1":
        data, expected = gray[..., None], gray / 255
    elif form == "gray16":
        data, expected = gray.astype(np.uint16) * 257, gray / 255
    else:
        data, expected = np.dstack([gray, np.full_like(gray, 200)]), gray / 255
    if form == "gray-alpha":  # OpenCV cannot write a 2-channel PNG
        (tmp_path / "g.png").write_bytes(gray_alpha_png(data))
    else:
        cv2.imwrite(str(tmp_path / "g.png"), data)
    for src in (tmp_path / "g.png", data if form != "gray-alpha" else None):
        if src is None:
            continue
        img = read_image(src)
        assert img.dtype == np.float32 and img.shape[2] == (4 if form == "gray-alpha" else 3)
        for c in range(3):
            np.testing.assert_allclose(img[..., c], expected, atol=1e-6)
    if form == "gray-alpha":
        np.testing.assert_allclose(img[..., 3], 200 / 255, atol=1e-6)


def test_16_bit_colour_keeps_its_precision(tmp_path, rgb_u8):
    deep = rgb_u8.astype(np.uint16) * 257 + 100  # values between 8-bit levels
    cv2.imwrite(str(tmp_path / "deep.png"), deep[..., ::-1])
    for src in (tmp_path / "deep.png", deep):
        img = read_image(src)
        assert img.shape == (12, 10, 3) and img.dtype == np.float32
        np.testing.assert_allclose(img, deep / 65535, atol=1e-6)


def cmyk_jpeg(rgb: np.ndarray) -> bytes:
    """A CMYK JPEG (Adobe APP14 marker, inverted CMYK as Photoshop writes it) of ``rgb`` (H, W, 3) uint8.
    OpenCV cannot write CMYK, so Pillow does (a dev dependency); the test skips without it."""
    pil = pytest.importorskip("PIL.Image")
    import io

    buf = io.BytesIO()
    pil.fromarray(rgb).convert("CMYK").save(buf, "JPEG", quality=100)
    return buf.getvalue()


def test_cmyk_jpeg_is_read_as_rgb(tmp_path):
    rgb = np.zeros((16, 16, 3), np.uint8)
    rgb[:8] = (200, 50, 30)
    rgb[8:] = (20, 180, 90)
    data = cmyk_jpeg(rgb)
    assert b"Adobe" in data[:64]
    (tmp_path / "c.jpg").write_bytes(data)
    img = read_image(tmp_path / "c.jpg")
    assert img.shape == (16, 16, 3)
    np.testing.assert_allclose(img * 255, rgb, atol=4)


def soft_mask(h=12, w=10):
    m = np.zeros((h, w), np.float32)
    m[2:9, 3:7] = 1.0
    m[1, 3:7] = 0.3
    return m


@pytest.mark.parametrize(
    "convert",
    [
        lambda m: m,
        lambda m: (m * 255).round().astype(np.uint8),
        lambda m: (m * 65535).round().astype(np.uint16),
        lambda m: m[..., None],
        lambda m: np.repeat(m[..., None], 3, axis=2),
        lambda m: m.astype(np.float64),
    ],
)
def test_mask_forms(convert):
    m = read_mask(convert(soft_mask()), (12, 10))
    assert m.shape == (12, 10) and m.dtype == np.float32
    np.testing.assert_allclose(m, soft_mask(), atol=1 / 255)


def test_mask_file_and_bool(tmp_path):
    cv2.imwrite(str(tmp_path / "m.png"), (soft_mask() * 255).round().astype(np.uint8))
    np.testing.assert_allclose(read_mask(tmp_path / "m.png", (12, 10)), soft_mask(), atol=1 / 255)
    assert read_mask(soft_mask() > 0.5, (12, 10)).max() == 1.0


@pytest.mark.parametrize(
    ("mask", "match"),
    [
        (np.zeros((12, 10), np.float32), "empty"),
        (np.full((12, 10), 0.3, np.float32), "empty"),
        (np.ones((12, 10), np.float32), "whole image"),
        (np.ones((12, 11), np.float32), r"12x11 .* image is 12x10"),
        (np.ones((12, 10, 4), np.float32), r"\(H, W\) or \(H, W, 3\)"),
        (np.full((12, 10), np.inf, np.float32), "NaN or Inf"),
        (np.full((12, 10), -1.0, np.float32), r"\[0, 1\]"),
    ],
)
def test_bad_masks(mask, match):
    with pytest.raises(RelightError, match=match):
        read_mask(mask, (12, 10))


def test_write_image_round_trip_and_atomicity(tmp_path, rgb_u8):
    img = rgb_u8 / 255.0
    out = write_image(tmp_path / "o.png", img)
    np.testing.assert_allclose(read_image(out), img, atol=1 / 255)
    rgba = np.concatenate([img, np.full((12, 10, 1), 0.5)], 2)
    write_image(tmp_path / "o4.png", rgba)
    assert read_image(tmp_path / "o4.png").shape == (12, 10, 4)
    write_image(tmp_path / "g.png", img[..., 0])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["g.png", "o.png", "o4.png"]  # no temporary files left


def test_write_refuses_inputs_and_bad_targets(tmp_path, rgb_u8):
    src = tmp_path / "in.png"
    cv2.imwrite(str(src), rgb_u8)
    before = src.read_bytes()
    with pytest.raises(RelightError, match="refusing to overwrite"):
        write_image(tmp_path / "." / "in.png", np.zeros((4, 4, 3)), protect=[src])
    assert src.read_bytes() == before
    with pytest.raises(RelightError, match="does not exist"):
        write_image(tmp_path / "no" / "o.png", np.zeros((4, 4, 3)))
    with pytest.raises(RelightError, match="transparency"):
        write_image(tmp_path / "o.jpg", np.zeros((4, 4, 4)))
    with pytest.raises(RelightError, match="cannot encode"):
        write_image(tmp_path / "o.xyz", np.zeros((4, 4, 3)))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.png"]


def test_list_images_and_sibling_mask(tmp_path):
    for name in ["b.jpg", "a.png", "a_mask.png", "notes.txt"]:
        (tmp_path / name).write_bytes(b"x")
    assert [p.name for p in list_images(tmp_path)] == ["a.png", "b.jpg"]
    assert sibling_mask(tmp_path / "a.png") == tmp_path / "a_mask.png"
    assert sibling_mask(tmp_path / "b.jpg") is None
