"""A fuzz test of the CLI over folders of generated bad files (issue 18, "must show").

For every bad file: exactly one line on stderr naming it, a non-zero exit, no traceback, no output for it;
afterwards the inputs are byte-identical and no partial or temporary file is left anywhere. The image
batch runs as a real process, so what native libraries (libpng, libjpeg, OpenCV, onnxruntime) write to
the process's stderr is checked too.
"""

from __future__ import annotations

import os
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest
from _graphs import OWN_LIGHT, models_dir, person
from _hostile import PEAK_LIMIT, run_cli_limited

from relight_rt import cli

__all__ = ["models_dir"]  # fixture

REPO = Path(__file__).resolve().parents[3]
H, W = 60, 40


def _png(img: np.ndarray) -> bytes:
    ok, buf = cv2.imencode(".png", img)
    assert ok
    return buf.tobytes()


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def bad_images(folder: Path, seed: int = 0) -> list[str]:
    """Write bad image files (and their masks) into ``folder``; return the bad files' names."""
    rng = np.random.default_rng(seed)
    img, mask = person(H, W, seed=seed, box=(10, 50, 10, 30))
    bgr = (img[..., ::-1] * 255).round().astype(np.uint8)
    m8 = (mask * 255).astype(np.uint8)
    good = _png(bgr)
    files: dict[str, bytes] = {
        "garbage.png": rng.integers(0, 256, 500, dtype=np.uint8).tobytes(),
        "zero.png": b"",
        "truncated.png": good[: len(good) // 2],
        "text.jpg": b"this is not a jpeg\n" * 10,
        "truncated.jpg": cv2.imencode(".jpg", bgr)[1].tobytes()[:40],
        "bomb.png": b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", struct.pack(">IIBBBBB", 90000, 90000, 8, 2, 0, 0, 0)),
        "gray.png": _png(bgr[..., 0]),
        "deep16.png": _png(bgr.astype(np.uint16) * 257),
        "tiny.png": _png(bgr[:1, :1]),
        "nomask.png": good,
        "wrongmask.png": good,
        "emptymask.png": good,
        "fullmask.png": good,
        "clearalpha.png": _png(np.dstack([bgr, np.zeros((H, W), np.uint8)])),
        "json.png": b'{"sh": [[1, 2, 3]]}',
    }
    masks = {"wrongmask": m8[:-1], "emptymask": np.zeros_like(m8), "fullmask": np.full_like(m8, 255)}
    # random damage to a good PNG: IHDR/IDAT bytes flipped (the CRCs then fail), chunks cut out
    body = bytearray(good)
    for k in range(12):
        damaged = bytearray(body)
        for pos in rng.integers(8, len(damaged), size=1 + k % 4):
            damaged[pos] ^= int(rng.integers(1, 256))
        files[f"damaged{k:02d}.png"] = bytes(damaged)
    i = good.find(b"IDAT")
    files["noidat.png"] = good[: i - 4] + good[i + 8 + struct.unpack(">I", good[i - 4 : i])[0] :]
    for name, data in files.items():
        (folder / name).write_bytes(data)
        stem = Path(name).stem
        if stem not in ("nomask", "clearalpha"):
            cv2.imwrite(str(folder / f"{stem}_mask.png"), masks.get(stem, m8))
    return sorted(files)


# issue 35 item 1: the OpenEXR magic and then no NUL byte: the attribute-name loop read b"" at EOF for ever
EXR_NO_NUL = b"v/1\x01\x02\x00\x00\x00" + b"A" * 50


def snapshot(folder: Path) -> dict:
    return {p: p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_fuzz_relight_over_a_folder_of_bad_images(tmp_path, models_dir):
    inputs = tmp_path / "in"
    inputs.mkdir()
    bad = bad_images(inputs)
    for k in range(2):  # two good photos: the batch goes on past the bad ones
        img, mask = person(H, W, seed=10 + k, box=(10, 50, 10, 30))
        cv2.imwrite(str(inputs / f"good{k}.png"), (img[..., ::-1] * 255).round().astype(np.uint8))
        cv2.imwrite(str(inputs / f"good{k}_mask.png"), (mask * 255).astype(np.uint8))
    (inputs / "folder.png").mkdir()  # not a file: not listed
    (inputs / "dangling.png").symlink_to(tmp_path / "nowhere.png")
    (inputs / "exrhang.png").write_bytes(EXR_NO_NUL)  # issue 35 item 1: hung the header parser for ever
    cv2.imwrite(str(inputs / "exrhang_mask.png"), np.full((H, W), 255, np.uint8))
    bad.append("exrhang.png")
    os.mkfifo(inputs / "fifo.png")  # issue 35 item 7: not a regular file, not listed (reading it would block)
    before = snapshot(tmp_path)
    route = ["relight", str(inputs), "--preset", "studio", "-o", str(tmp_path / "out"), "--device", "cpu"]
    codes, stderr, peak = run_cli_limited([route], cwd=tmp_path, env={"RELIGHT_RT_MODELS": str(models_dir)})
    assert codes == [2] and 0 < peak < PEAK_LIMIT, (codes, peak)  # under ulimit -v 4 GB, below 1 GB resident
    assert "Traceback" not in stderr
    lines = [x for x in stderr.splitlines() if x.strip() and "image/s" not in x]  # not the progress bar
    assert all(x.startswith("relight-rt: ") for x in lines), stderr  # nothing from native libraries
    errors = [x for x in lines if x.startswith("relight-rt: error: ")]
    written = {p.name for p in (tmp_path / "out").iterdir()}
    for name in bad + ["good0.png", "good1.png"]:
        stem = Path(name).stem
        mentioned = [x for x in errors if f"/{name}" in x or f" {name}" in x]
        if f"{stem}_relit.png" in written:  # some random damage is harmless (e.g. in a CRC libpng skips)
            assert mentioned == [], (name, mentioned)
        else:
            assert len(mentioned) == 1, (name, errors)
    assert {"good0_relit.png", "good1_relit.png"} <= written
    assert not {"garbage_relit.png", "bomb_relit.png", "nomask_relit.png", "fullmask_relit.png"} & written
    assert len(errors) == len(bad) + 2 - len(written)  # one line per bad file, nothing else
    assert lines[-1] == f"relight-rt: {len(errors)} failed, {len(written)} written"
    after = snapshot(tmp_path)
    assert {p: after[p] for p in before} == before  # inputs byte-identical
    assert set(after) - set(before) == {tmp_path / "out" / n for n in written}  # no temporary files anywhere
    for name in written:
        assert cv2.imread(str(tmp_path / "out" / name)).shape == (H, W, 3)  # complete files


def bad_lights(folder: Path, seed: int = 0) -> dict[str, str]:
    """Bad light files; returns name → a word the one-line error must contain."""
    rng = np.random.default_rng(seed)
    header = np.lib.format.header_data_from_array_1_0(np.zeros(3))
    header["shape"] = (1 << 21, 1 << 20, 1 << 20)
    with open(folder / "huge.npy", "wb") as f:
        np.lib.format.write_array_header_1_0(f, header)
    np.savez(folder / "npz.npz", OWN_LIGHT)
    (folder / "npz.npz").rename(folder / "npz.npy")
    np.save(folder / "obj.npy", np.array([None, 1], dtype=object), allow_pickle=True)
    for name, value in {"nan.npy": np.nan, "inf.npy": np.inf, "e300.npy": 1e300, "e38.npy": 4e38}.items():
        np.save(folder / name, np.full((9, 3), value))
    np.save(folder / "shape.npy", np.zeros((9, 4)))
    np.save(folder / "flat.npy", np.zeros(27))
    np.save(folder / "strings.npy", np.array(["a"] * 27))
    good = (folder / "huge.npy").read_bytes()
    (folder / "cut.npy").write_bytes(good[:30])
    texts = {
        "deep.json": '{"sh": ' + "[" * 100_000 + "]" * 100_000 + "}",
        "list.json": "[1, 2, 3]",
        "order.json": '{"sh": [[0, 0, 0]], "order": "xyz"}',
        "ragged.json": '{"sh": [[1, 2], [3]]}',
        "strings.json": '{"sh": [["a", "b", "c"]]}',
        "broken.json": '{"sh": [[1, 2, 3]',
        "e300.json": '{"sh": ' + str([[1e300] * 3] * 9) + "}",
        "binary.json": rng.integers(0, 256, 200, dtype=np.uint8).tobytes().decode("latin-1"),
    }
    for name, text in texts.items():
        (folder / name).write_bytes(text.encode("latin-1"))
    (folder / "zero.npy").write_bytes(b"")
    (folder / "zero.json").write_bytes(b"")
    return {"huge.npy": "announces", "npz.npy": "npz", "obj.npy": "pickled", "nan.npy": "NaN", "inf.npy": "NaN",
            "e300.npy": "too large", "e38.npy": "too large", "shape.npy": "(9, 3)", "flat.npy": "layout",
            "strings.npy": "numbers", "cut.npy": "npy", "deep.json": "nested", "list.json": "JSON object",
            "order.json": "order", "ragged.json": "cannot read", "strings.json": "cannot read",
            "broken.json": "cannot read", "e300.json": "too large", "binary.json": "cannot read",
            "zero.npy": "empty", "zero.json": "cannot read"}  # fmt: skip


def test_fuzz_light_files(tmp_path, models_dir):
    img, mask = person(H, W, box=(10, 50, 10, 30))
    cv2.imwrite(str(tmp_path / "p.png"), (img[..., ::-1] * 255).round().astype(np.uint8))
    cv2.imwrite(str(tmp_path / "p_mask.png"), (mask * 255).astype(np.uint8))
    expected = bad_lights(tmp_path)
    before = snapshot(tmp_path)
    routes = [argv for name in expected for argv in (["relight", "p.png", "--light", name, "-o", "o.png"],
                                                     ["lights", "show", name, "-o", "o.png"])]  # fmt: skip
    codes, stderr, peak = run_cli_limited(routes, cwd=tmp_path, env={"RELIGHT_RT_MODELS": str(models_dir)})
    assert codes == [2] * len(routes) and 0 < peak < PEAK_LIMIT, (codes, peak)
    lines = stderr.strip().splitlines()
    assert len(lines) == len(routes), stderr  # one line each
    for argv, line in zip(routes, lines, strict=True):
        name = argv[3] if argv[0] == "relight" else argv[2]
        assert line.startswith("relight-rt: error: ") and name in line and expected[name] in line, (argv, line)
    assert snapshot(tmp_path) == before  # nothing written, nothing changed, no temporary files


def test_fuzz_video_frames_skip_bad_frames(tmp_path, models_dir, monkeypatch, capsys):
    """A folder of frames with bad ones among them: with --skip-bad-frames one line per bad frame, the good
    frames written, exit 2; without it, one line and nothing written."""
    monkeypatch.setenv("RELIGHT_RT_MODELS", str(models_dir))
    frames = tmp_path / "frames"
    frames.mkdir()
    for k in range(4):
        img, mask = person(H, W, seed=k, box=(10, 50, 10, 30))
        cv2.imwrite(str(frames / f"f{k}.png"), (img[..., ::-1] * 255).round().astype(np.uint8))
        cv2.imwrite(str(frames / f"f{k}_mask.png"), (mask * 255).astype(np.uint8))
    bad = {"f1b.png": b"garbage", "f2b.png": b"", "f3b.png": (frames / "f0.png").read_bytes()[:60]}
    for name, data in bad.items():
        (frames / name).write_bytes(data)
    cv2.imwrite(str(frames / "f3c.png"), np.zeros((H + 2, W, 3), np.uint8))  # another size
    before = snapshot(tmp_path)
    argv = ["video", str(frames), "--preset", "studio", "-o", str(tmp_path / "o.avi"), "--device", "cpu"]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "f1b.png" in err and not (tmp_path / "o.avi").exists()
    assert cli.main([*argv, "--skip-bad-frames"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert "Traceback" not in "\n".join(lines)
    assert len(lines) == 5 and lines[-1] == "relight-rt: 4 frame(s) left out, 4 written"
    for name, line in zip(["f1b.png", "f2b.png", "f3b.png", "f3c.png"], lines, strict=False):
        assert line.startswith("relight-rt: error: ") and name in line and "skipped" in line
    after = snapshot(tmp_path)
    assert {p: after[p] for p in before} == before and set(after) - set(before) == {tmp_path / "o.avi"}


@pytest.mark.parametrize("seed", [1, 2])
def test_fuzz_relight_random_damage(tmp_path, models_dir, seed):
    """More random damage: only correct outputs or one RelightError line per file."""
    (tmp_path / "in").mkdir()
    bad_images(tmp_path / "in", seed)
    before = snapshot(tmp_path)
    codes, err, peak = run_cli_limited([["relight", "in", "--preset", "night", "-o", "out"]], cwd=tmp_path,
                                       env={"RELIGHT_RT_MODELS": str(models_dir)})  # fmt: skip
    assert codes == [2] and "Traceback" not in err and 0 < peak < PEAK_LIMIT
    after = snapshot(tmp_path)
    assert {p: after[p] for p in before} == before
    assert not [p for p in after if p.name.startswith(".")]


def test_exr_header_without_a_nul_byte_in_every_reader(tmp_path, models_dir):
    """issue 35 item 1: a 58-byte file with the OpenEXR magic and no NUL byte hung every reader (100 % CPU,
    memory growing): as a photo, --mask, --background, --envmap, lights from-envmap, a video frame. Each
    route now gives one error line; the routes run in one process, bounded in time."""
    (tmp_path / "evil.png").write_bytes(EXR_NO_NUL)
    (tmp_path / "evil.exr").write_bytes(EXR_NO_NUL)
    img, mask = person(H, W, box=(10, 50, 10, 30))
    cv2.imwrite(str(tmp_path / "p.png"), (img[..., ::-1] * 255).round().astype(np.uint8))
    cv2.imwrite(str(tmp_path / "p_mask.png"), (mask * 255).astype(np.uint8))
    frames = tmp_path / "frames"
    frames.mkdir()
    for k in range(2):
        cv2.imwrite(str(frames / f"f{k}.png"), (img[..., ::-1] * 255).round().astype(np.uint8))
        cv2.imwrite(str(frames / f"f{k}_mask.png"), (mask * 255).astype(np.uint8))
    (frames / "f2.png").write_bytes(EXR_NO_NUL)
    cv2.imwrite(str(frames / "f2_mask.png"), (mask * 255).astype(np.uint8))
    routes = [
        ["relight", "evil.png", "--preset", "studio", "-o", "o.png"],
        ["relight", "p.png", "--mask", "evil.png", "--preset", "studio", "-o", "o.png"],
        ["relight", "p.png", "--preset", "studio", "--background", "evil.png", "-o", "o.png"],
        ["relight", "p.png", "--envmap", "evil.exr", "-o", "o.png"],
        ["lights", "from-envmap", "evil.exr", "-o", "l.npy"],
        ["lights", "from-envmap", "evil.png", "-o", "l.npy"],
        ["video", "frames", "--preset", "studio", "-o", "o.avi"],
        ["mask", "evil.png", "-o", "m.png"],
    ]
    before = snapshot(tmp_path)
    codes, stderr, peak = run_cli_limited(routes, cwd=tmp_path, env={"RELIGHT_RT_MODELS": str(models_dir)})
    assert codes == [2] * len(routes) and 0 < peak < PEAK_LIMIT, (codes, peak, stderr)
    lines = [x for x in stderr.splitlines() if x.strip()]
    assert len(lines) == len(routes) and all(x.startswith("relight-rt: error: ") for x in lines), stderr
    assert all("evil" in x or "f2.png" in x for x in lines), stderr
    assert snapshot(tmp_path) == before


class _Unblocker:
    """Opens the FIFO's writing end after ``delay`` seconds (then closes it), so a reader that blocked on it
    comes back with an empty file instead of hanging the test; ``fired`` says it had to."""

    def __init__(self, fifo: Path, delay: float = 20.0) -> None:
        import threading

        self.fifo, self.fired = fifo, False
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, args=(delay,), daemon=True)
        self._thread.start()

    def _run(self, delay: float) -> None:
        while not self._stop.wait(delay):
            try:
                fd = os.open(self.fifo, os.O_WRONLY | os.O_NONBLOCK)  # ENXIO: nobody is reading
            except OSError:
                continue
            self.fired = True
            os.close(fd)

    def stop(self) -> None:
        self._stop.set()
        self._thread.join()


def test_fifo_inputs_are_refused_by_every_command(tmp_path, models_dir, monkeypatch, capsys):
    """issue 35 item 7: ``relight-rt video FIFO`` blocked for ever (FFmpeg waits for a writer). Anything that is
    not a regular file or a folder is refused, in every role, with one line naming it."""
    monkeypatch.setenv("RELIGHT_RT_MODELS", str(models_dir))
    monkeypatch.chdir(tmp_path)
    img, mask = person(H, W, box=(10, 50, 10, 30))
    cv2.imwrite("p.png", (img[..., ::-1] * 255).round().astype(np.uint8))
    cv2.imwrite("p_mask.png", (mask * 255).astype(np.uint8))
    Path("frames").mkdir()
    for k in range(2):
        cv2.imwrite(f"frames/f{k}.png", (img[..., ::-1] * 255).round().astype(np.uint8))
        cv2.imwrite(f"frames/f{k}_mask.png", (mask * 255).astype(np.uint8))
    fifos = {}
    for suffix in ("mp4", "png", "npy", "json", "hdr", "pth", "onnx"):
        fifos[suffix] = f"fifo.{suffix}"
        os.mkfifo(fifos[suffix])
    routes = [
        ["video", fifos["mp4"], "--preset", "studio", "-o", "o.mp4"],
        ["video", "frames", "--masks", fifos["mp4"], "--preset", "studio", "-o", "o.mp4"],
        ["video", "frames", "--lights", fifos["npy"], "-o", "o.mp4"],
        ["video", "frames", "--preset", "studio", "--dvp", fifos["onnx"], "-o", "o.mp4"],
        ["mask", fifos["mp4"], "-o", "m.avi"],
        ["mask", fifos["png"], "-o", "m.png"],
        ["relight", fifos["png"], "--preset", "studio", "-o", "o.png"],
        ["relight", "p.png", "--mask", fifos["png"], "--preset", "studio", "-o", "o.png"],
        ["relight", "p.png", "--light", fifos["npy"], "-o", "o.png"],
        ["relight", "p.png", "--light", fifos["json"], "-o", "o.png"],
        ["relight", "p.png", "--envmap", fifos["hdr"], "-o", "o.png"],
        ["relight", "p.png", "--light-from", fifos["png"], "-o", "o.png"],
        ["relight", "p.png", "--preset", "studio", "--background", fifos["png"], "-o", "o.png"],
        ["decompose", fifos["png"], "-o", "layers"],
        ["lights", "from-envmap", fifos["hdr"], "-o", "l.npy"],
        ["lights", "from-photo", fifos["png"], "-o", "l.npy"],
        ["lights", "show", fifos["npy"], "-o", "s.png"],
        ["import-reference", "--stage1", fifos["pth"], "--out", "graphs"],
        ["composite", fifos["png"], "--background", "p.png", "-o", "c.png"],
        ["composite", "p.png", "--background", fifos["png"], "-o", "c.png"],
        ["lights", "from-background", fifos["png"], "-o", "l.npy"],
    ]
    unblockers = [_Unblocker(tmp_path / f) for f in fifos.values()]
    try:
        for argv in routes:
            code = cli.main(argv)
            lines = capsys.readouterr().err.strip().splitlines()
            assert code == 2 and len(lines) == 1 and lines[0].startswith("relight-rt: error: "), (argv, lines)
            assert "fifo." in lines[0], (argv, lines)
    finally:
        for u in unblockers:
            u.stop()
    assert not any(u.fired for u in unblockers)  # nothing waited for a writer
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["p.png", "p_mask.png", "frames", *fifos.values()])
def header_bombs(folder: Path) -> dict[str, str]:
    """Issue 35: a JPEG whose frame header (30000 x 30000, 10.8 GB decoded as floats) sits behind a 0xFF fill
    byte, stray bytes and 0xFF 0x00 (libjpeg skips all three), and Radiance maps whose headers are longer than
    4 KB (long lines; a line of exactly 127 bytes, which OpenCV reads in two pieces). Returns name -> the size
    the refusal must name."""
    img = np.zeros((16, 16, 3), np.uint8)
    jpeg = bytearray(cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_PROGRESSIVE, 1])[1].tobytes())
    sof = jpeg.index(b"\xff\xc2")
    jpeg[sof + 5 : sof + 9] = (30000).to_bytes(2, "big") * 2
    (folder / "fill.jpg").write_bytes(jpeg[:sof] + b"\xff" + jpeg[sof:])
    (folder / "stray.jpg").write_bytes(jpeg[:sof] + b"ab\xff\x00cd\xff\xff" + jpeg[sof:])
    head = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n"
    size = b"-Y 15000 +X 30000\n" + bytes(64)
    (folder / "long.hdr").write_bytes(head + (b"#" + b"c" * 5000 + b"\n") * 300 + b"\n" + size)  # 1.5 MB header
    (folder / "long_lines.hdr").write_bytes(head + (b"# " + b"c" * 98 + b"\n") * 60 + b"\n" + size)  # 6 KB
    (folder / "split.hdr").write_bytes(head + b"#" + b"c" * 126 + b"\n" + size)  # the size line follows the 127
    return {"fill.jpg": "30000x30000", "stray.jpg": "30000x30000", "long.hdr": "longer than 1 MiB",
            "long_lines.hdr": "30000x15000", "split.hdr": "30000x15000"}  # fmt: skip


def _address_space(gib: int):
    def apply() -> None:
        import resource

        resource.setrlimit(resource.RLIMIT_AS, (gib << 30, gib << 30))

    return apply


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="RLIMIT_AS: Linux")
def test_fuzz_header_bombs_refused_before_decoding(tmp_path, models_dir):
    """Every bomb, as a photo, a background, an env map and to ``lights from-envmap``, in a real process under a
    4 GiB address-space limit: one line naming the file and the size it claims, exit 2, nothing written."""
    bombs = header_bombs(tmp_path)
    img, mask = person(H, W, box=(10, 50, 10, 30))
    cv2.imwrite(str(tmp_path / "p.png"), (img[..., ::-1] * 255).round().astype(np.uint8))
    cv2.imwrite(str(tmp_path / "p_mask.png"), (mask * 255).astype(np.uint8))
    for name in ("fill", "stray"):
        cv2.imwrite(str(tmp_path / f"{name}_mask.png"), np.full((30, 30), 255, np.uint8))
    before = snapshot(tmp_path)
    runs = []
    for name in ("fill.jpg", "stray.jpg"):
        runs += [(name, ["relight", name, "--preset", "studio", "-o", "o.png"]),
                 (name, ["relight", "p.png", "--preset", "studio", "--background", name, "-o", "o.png"])]  # fmt: skip
    for name in ("long.hdr", "long_lines.hdr", "split.hdr"):
        runs += [(name, ["relight", "p.png", "--envmap", name, "-o", "o.png"]),
                 (name, ["lights", "from-envmap", name, "-o", "l.npy"])]  # fmt: skip
    env = {**os.environ, "PYTHONPATH": str(REPO), "RELIGHT_RT_MODELS": str(models_dir)}
    for name, argv in runs:
        proc = subprocess.run([sys.executable, "-m", "relight_rt", *argv, "--device", "cpu"], cwd=tmp_path,
                              capture_output=True, text=True, env=env, timeout=120,
                              preexec_fn=_address_space(4))  # fmt: skip
        lines = proc.stderr.strip().splitlines()
        assert proc.returncode == 2 and len(lines) == 1, (argv, proc.stderr)
        assert lines[0].startswith("relight-rt: error: ") and name in lines[0] and bombs[name] in lines[0], argv
    assert snapshot(tmp_path) == before
