"""relight_rt.engine.limits: image sizes from headers (checked against OpenCV's decoder), the pixel limit, .npy
headers."""

import os
import struct

import cv2
import numpy as np
import pytest

from relight_rt import RelightError
from relight_rt.engine.limits import check_pixels, header_size, load_npy, max_pixels, pixel_limit
from relight_rt.image.io import read_image, read_mask


@pytest.mark.parametrize("suffix", [".png", ".jpg", ".bmp", ".webp", ".tif", ".hdr"])
@pytest.mark.parametrize(("h", "w"), [(37, 53), (1, 300), (480, 2)])
def test_header_size_matches_the_decoder(tmp_path, suffix, h, w):
    img = np.random.default_rng(0).integers(0, 255, (h, w, 3), dtype=np.uint8)
    path = tmp_path / f"x{suffix}"
    assert cv2.imwrite(str(path), img.astype(np.float32) / 255 if suffix == ".hdr" else img)
    decoded = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert header_size(path) == (decoded.shape[1], decoded.shape[0])


def test_header_size_variants(tmp_path):
    img = np.zeros((21, 34, 4), np.uint8)
    cv2.imwrite(str(tmp_path / "lossless.webp"), img[..., :3], [cv2.IMWRITE_WEBP_QUALITY, 101])  # VP8L
    cv2.imwrite(str(tmp_path / "alpha.webp"), img)
    cv2.imwrite(str(tmp_path / "prog.jpg"), img[..., :3], [cv2.IMWRITE_JPEG_PROGRESSIVE, 1])
    for name in ("lossless.webp", "alpha.webp", "prog.jpg"):
        assert header_size(tmp_path / name) == (34, 21), name
    # an OpenEXR header (this OpenCV may not write EXR): magic, version, then attributes up to dataWindow
    attr = b"channels\x00chlist\x00" + struct.pack("<i", 1) + b"\x00"
    attr += b"dataWindow\x00box2i\x00" + struct.pack("<i", 16) + struct.pack("<iiii", 0, 0, 4999, 2999)
    (tmp_path / "e.exr").write_bytes(b"v/1\x01" + struct.pack("<I", 2) + attr + b"\x00")
    assert header_size(tmp_path / "e.exr") == (5000, 3000)
    cv2.imwrite(str(tmp_path / "x.ppm"), img[..., :3])
    assert header_size(tmp_path / "x.ppm") is None  # not parsed: checked after decoding
    (tmp_path / "t.png").write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00")  # truncated: the decoder will say so
    assert header_size(tmp_path / "t.png") is None


def _png_header(w: int, h: int) -> bytes:
    """A PNG signature and IHDR claiming w x h, without any image data (a 'decompression bomb' header)."""
    return b"\x89PNG\r\n\x1a\n" + struct.pack(">I", 13) + b"IHDR" + struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)


def test_huge_image_is_refused_from_its_header(tmp_path):
    path = tmp_path / "bomb.png"
    path.write_bytes(_png_header(60000, 60000) + b"\x00" * 64)
    with pytest.raises(RelightError, match=r"60000x60000 \(3600.0 megapixels\), more than the limit of 100 megapixels"):
        read_image(path)
    with pytest.raises(RelightError, match="more than the limit"):
        read_mask(path, (60000, 60000))


def test_pixel_limit_is_scoped_and_checked_after_decoding_too(tmp_path):
    cv2.imwrite(str(tmp_path / "x.ppm"), np.zeros((20, 30, 3), np.uint8))  # no header parser: after decoding
    cv2.imwrite(str(tmp_path / "x.png"), np.zeros((20, 30, 3), np.uint8))
    assert max_pixels() == 100_000_000
    with pixel_limit(599):
        for name in ("x.ppm", "x.png"):
            with pytest.raises(RelightError, match="30x20"):
                read_image(tmp_path / name)
        with pixel_limit(0):  # no limit
            assert read_image(tmp_path / "x.png").shape == (20, 30, 3)
    assert max_pixels() == 100_000_000
    check_pixels(10_000, 10_000, "x")
    with pytest.raises(RelightError, match="whole number"):
        with pixel_limit(-1):
            pass


def test_load_npy_checks_the_header_first(tmp_path):
    good = np.arange(27.0).reshape(9, 3)
    np.save(tmp_path / "good.npy", good)
    np.testing.assert_array_equal(load_npy(tmp_path / "good.npy"), good)
    np.save(tmp_path / "v2.npy", good)  # version 2.0 header
    with open(tmp_path / "v2.npy", "wb") as f:
        np.lib.format.write_array(f, good, version=(2, 0))
    np.testing.assert_array_equal(load_npy(tmp_path / "v2.npy"), good)

    header = np.lib.format.header_data_from_array_1_0(good)
    header["shape"] = (1 << 20, 1 << 20, 2)  # 16 TiB claimed, 100 bytes present
    with open(tmp_path / "huge.npy", "wb") as f:
        np.lib.format.write_array_header_1_0(f, header)
        f.write(b"\x00" * 100)
    np.savez(tmp_path / "z.npz", a=good)
    (tmp_path / "z.npz").rename(tmp_path / "z.npy")
    (tmp_path / "zero.npy").write_bytes(b"")
    (tmp_path / "text.npy").write_text('{"sh": []}')
    np.save(tmp_path / "obj.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
    np.save(tmp_path / "str.npy", np.array(["a", "b"]))
    np.save(tmp_path / "big.npy", np.zeros(2000))
    cases = {
        "huge.npy": r"announces a \(1048576, 1048576, 2\) float64 array .* holds 100 bytes",
        "z.npy": r"zip archive \(an \.npz\)",
        "zero.npy": r"empty \(0 bytes\)",
        "text.npy": "not a .npy file .*JSON",
        "obj.npy": "pickled",
        "str.npy": "expected numbers",
        "missing.npy": "cannot read",
    }
    for name, match in cases.items():
        with pytest.raises(RelightError, match=match):
            load_npy(tmp_path / name)
    with pytest.raises(RelightError, match="more than 1,000"):
        load_npy(tmp_path / "big.npy", max_bytes=1000)


def test_special_files_are_refused_without_blocking(tmp_path):
    fifo = tmp_path / "pipe.png"
    os.mkfifo(fifo)  # opening it for reading would block forever
    with pytest.raises(RelightError, match="not a regular file"):
        read_image(fifo)
    with pytest.raises(RelightError, match="not a regular file"):
        read_mask(tmp_path, (2, 2))
    os.mkfifo(tmp_path / "pipe.npy")
    with pytest.raises(RelightError, match="not a regular file"):
        load_npy(tmp_path / "pipe.npy")
    with pytest.raises(RelightError, match="not found"):
        read_image(tmp_path / "missing.png")


class _CountingFile:
    """A binary file that counts what is read from it and fails a parser that reads on and on."""

    def __init__(self, f, stats: dict) -> None:
        self._f, self._stats = f, stats

    def _count(self, data: bytes) -> bytes:
        self._stats["bytes"] += len(data)
        self._stats["calls"] += 1
        assert self._stats["calls"] < 2 << 20, "the parser keeps reading"
        return data

    def read(self, n=-1):
        return self._count(self._f.read(n))

    def readline(self, n=-1):
        return self._count(self._f.readline(n))

    def __getattr__(self, name):
        return getattr(self._f, name)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self._f.close()


_MAGICS = [b"\x89PNG\r\n\x1a\n", b"\xff\xd8", b"BM", b"RIFF", b"II*\x00", b"MM\x00*", b"#?", b"v/1\x01\x02\x00\x00\x00"]


# (JPEG + a run of 0xFF fill bytes is left out: the budget ends it too, but after ~1M one-byte reads, slow here;
# the JPEG parser's fill-byte handling is issue 35 item 3)
@pytest.mark.parametrize(("magic", "fill"), [(m, f) for m in _MAGICS for f in (b"A", b"\x00", b"\xff")
                                             if (m, f) != (b"\xff\xd8", b"\xff")])
def test_header_parsers_are_bounded(tmp_path, monkeypatch, magic, fill):
    """issue 35 item 1: every header parser reads a bounded number of bytes and ends, whatever follows the magic
    (the OpenEXR one read attribute names byte by byte up to a NUL, and at EOF read b"" for ever); a header
    that would go on past the budget is refused, never passed on to the decoder unchecked."""
    from relight_rt.engine import limits

    path = tmp_path / "junk"
    path.write_bytes(magic + fill * (3 << 20))
    stats = {"bytes": 0, "calls": 0}
    monkeypatch.setattr(limits, "open", lambda p, mode: _CountingFile(open(p, mode), stats), raising=False)
    try:
        size = header_size(path)
    except RelightError as exc:  # refused: past the byte budget, or past a parser's own bound
        assert "goes on past" in str(exc) or "refused" in str(exc)
    else:
        assert size is None or all(isinstance(v, int) for v in size)
    assert stats["bytes"] <= limits.HEADER_MAX_BYTES + 16 and stats["calls"] <= limits.HEADER_MAX_BYTES + 16


def test_exr_header_variants_end(tmp_path):
    """issue 35 item 1: forged OpenEXR headers (no NUL, a name past 255 bytes, endless attributes, a reversed
    data window) give None (the decoder then says what is wrong), never a hang."""
    magic = b"v/1\x01" + struct.pack("<I", 2)
    attr = b"a\x00int\x00" + struct.pack("<i", 4) + b"\x00" * 4
    window = b"dataWindow\x00box2i\x00" + struct.pack("<i", 16) + struct.pack("<iiii", 10, 10, 0, 0)
    for name, data in {"nonul": magic + b"A" * 50, "longname": magic + b"B" * 300 + b"\x00box2i\x00",
                       "endless": magic + attr * 5000, "reversed": magic + window + b"\x00",
                       "cut": magic + b"dataWindow\x00box2i\x00" + struct.pack("<i", 16) + b"\x00" * 3}.items():
        (tmp_path / name).write_bytes(data)
        assert header_size(tmp_path / name) is None, name


def test_a_header_past_the_budget_is_refused(tmp_path, monkeypatch):
    """A parser that runs out of budget refuses the file (it is not decoded with its size unchecked)."""
    from relight_rt.engine import limits

    monkeypatch.setattr(limits, "HEADER_MAX_BYTES", 64)
    (tmp_path / "long.hdr").write_bytes(b"#?RADIANCE\n" + b"# comment\n" * 50 + b"\n-Y 9 +X 9\n")
    with pytest.raises(RelightError, match="goes on past 64 bytes"):
        header_size(tmp_path / "long.hdr")
    with pytest.raises(RelightError, match="goes on past"):
        read_image(tmp_path / "long.hdr")
# ------------------------------------------------------------------------------------- issue 35: headers
# The size read from a header must be the size the decoder finds, however the header is dressed up; where
# no size can be found within the parser's bounds, the file is refused before it is decoded.


def _decoded_size(data: bytes):
    try:
        img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    except cv2.error:
        return None
    return None if img is None else (img.shape[1], img.shape[0])


def _jpeg_variants() -> dict[str, bytes]:
    good = cv2.imencode(".jpg", np.zeros((8, 16, 3), np.uint8), [cv2.IMWRITE_JPEG_PROGRESSIVE, 1])[1].tobytes()
    sof = good.index(b"\xff\xc2")
    dqt = good.index(b"\xff\xdb")
    return {
        "fill before SOF": good[:sof] + b"\xff\xff" + good[sof:],
        "stray bytes before SOF": good[:sof] + b"zz" + good[sof:],
        "0xFF 0x00 before SOF": good[:sof] + b"\xff\x00" + good[sof:],
        "stray, 0xFF00, fill before DQT": good[:dqt] + b"ab\xff\x00cd\xff\xff" + good[dqt:],
        "COM of length 1": good[:2] + b"\xff\xfe\x00\x01" + good[2:],
        "RST and TEM": good[:2] + b"\xff\xd0\xff\x01" + good[2:],
        "fill after SOI": good[:2] + b"\xff" + good[2:],
    }


@pytest.mark.parametrize("case", sorted(_jpeg_variants()))
def test_jpeg_header_found_as_libjpeg_finds_it(case):
    data = _jpeg_variants()[case]
    assert _decoded_size(data) == (16, 8)  # the decoder reads it...
    assert header_size(data) == (16, 8)  # ...and so does the header parser, from bytes...


@pytest.mark.parametrize("case", ["fill before SOF", "stray bytes before SOF", "0xFF 0x00 before SOF"])
def test_jpeg_bomb_behind_stray_bytes_is_refused(tmp_path, case):
    data = bytearray(_jpeg_variants()[case])
    sof = data.rindex(b"\xff\xc2")
    data[sof + 5 : sof + 9] = (30000).to_bytes(2, "big") * 2  # 30000 x 30000 in a few hundred bytes
    (tmp_path / "bomb.jpg").write_bytes(data)
    assert header_size(tmp_path / "bomb.jpg") == (30000, 30000)
    with pytest.raises(RelightError, match=r"30000x30000 .*more than the limit"):
        read_image(tmp_path / "bomb.jpg")


def test_jpeg_header_without_a_frame_within_bounds_is_refused():
    from relight_rt.engine.limits import JPEG_MAX_SEGMENTS, JPEG_MAX_STRAY

    good = _jpeg_variants()["fill before SOF"]
    many = good[:2] + b"\xff\xfe\x00\x02" * (JPEG_MAX_SEGMENTS + 1) + good[2:]  # empty comments, then the frame
    with pytest.raises(RelightError, match=f"photo: no JPEG frame header within its first {JPEG_MAX_SEGMENTS}"):
        header_size(many, "photo")
    assert header_size(good[:2] + b"\xff\xfe\x00\x02" * 100 + good[2:]) == (16, 8)
    stray = good[:2] + b"\xff\xfe\x00\x02" + b"z" * (JPEG_MAX_STRAY + 1) + good[2:]
    with pytest.raises(RelightError, match="stray bytes"):
        header_size(stray)
    assert header_size(good[: good.index(b"\xff\xc2")]) is None  # truncated before the frame: the decoder says so
    assert header_size(good[:2] + b"\xff\xd9" + good[2:]) is None  # EOI first: no image


def _hdr_parts() -> tuple[bytes, bytes]:
    data = cv2.imencode(".hdr", np.ones((4, 8, 3), np.float32))[1].tobytes()
    head, rest = data.split(b"\n\n", 1)
    return head + b"\n", rest.split(b"\n", 1)[1]  # "#?RADIANCE\nFORMAT=...\n", the pixels


def _hdr_variants() -> dict[str, bytes]:
    head, pixels = _hdr_parts()
    return {
        "plain": head + b"\n-Y 4 +X 8\n" + pixels,
        "header over 4 KB": head + (b"#" + b"c" * 200 + b"\n") * 50 + b"\n-Y 4 +X 8\n" + pixels,
        "spaces and signs": head + b"\n-Y  +4\t+X 8 junk\n" + pixels,
        # a line of exactly 127 bytes: OpenCV reads it in two pieces, the second a bare newline that ends the
        # header, so the next line is the size (a line-based parser takes it for a header line)
        "127-byte line": head + b"#" + b"d" * 126 + b"\n-Y 4 +X 8\n" + pixels,
    }


@pytest.mark.parametrize("case", sorted(_hdr_variants()))
def test_radiance_header_read_as_opencv_reads_it(case):
    data = _hdr_variants()[case]
    assert _decoded_size(data) == (8, 4)
    assert header_size(data) == (8, 4)


def test_radiance_bombs_are_refused(tmp_path):
    from relight_rt.engine.limits import HDR_MAX_HEADER

    head, pixels = _hdr_parts()
    long = head + (b"#" + b"c" * 5000 + b"\n") * 100 + b"\n-Y 30000 +X 60000\n" + pixels  # 500 KB header
    (tmp_path / "long.hdr").write_bytes(long)
    with pytest.raises(RelightError, match=r"60000x30000 .*more than the limit"):
        read_image(tmp_path / "long.hdr")
    endless = head + b"#" * (HDR_MAX_HEADER + 10) + b"\n\n-Y 4 +X 8\n" + pixels
    with pytest.raises(RelightError, match="the Radiance header is longer than 1 MiB"):
        header_size(endless)
    wraps = head + b"\n-Y 4294967300 +X 8\n" + pixels  # C's int wraps it to 4: OpenCV decodes 8 x 4
    assert _decoded_size(wraps) == (8, 4)
    with pytest.raises(RelightError, match="32-bit"):
        header_size(wraps)
    hidden = head + b"#" + b"d" * 126 + b"\n-Y 30000 +X 30000\n" + pixels  # the 127-byte line of above
    assert header_size(hidden) == (30000, 30000)
    assert header_size(head + b"\n+Y 30000 +X 60000\n") == (60000, 30000)  # orientations OpenCV refuses
    assert header_size(head + b"\n-Y 0 +X 8\n") is None  # the decoder refuses an empty image
    assert header_size(head + b"\n") is None  # truncated


def test_shrink_holds_an_image_to_a_pixel_count():
    """``shrink``: at most the pixels asked, the aspect kept, a panorama exactly 2:1, a small image as it is."""
    from relight_rt.engine.limits import shrink

    pano = np.zeros((1000, 2000, 3), np.uint16)
    for budget in (2 * 37 * 37, 2 * 37 * 37 + 5, 200_001):
        h, w = shrink(pano, budget).shape[:2]
        assert w == 2 * h and h * w <= budget and 2 * (h + 1) ** 2 > budget  # the largest (h, 2h) within it
    photo = np.zeros((1302, 1950), np.uint8)
    h, w = shrink(photo, 500_000).shape
    assert h * w <= 500_000 and abs(w / h - 1950 / 1302) < 0.01
    assert shrink(photo, 1302 * 1950) is photo
