"""Issue 18 against ``relight-rt video`` and relight_rt.video.frames: inputs (mask videos and folders) never
overwritten, unpredictable temporary files, frames written = frames read (or --skip-bad-frames, reported, exit 2), H.264
with the audio and frame rate kept (PyAV), the OpenCV fallback, and one line for every bad input."""

from __future__ import annotations

import fractions
import logging
import os
import re
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from _cli import in_folder, run
from _graphs import models_dir
from _scenes import write_noise_clip

from relight_rt import RelightError
from relight_rt.video import frames as _video_io
from relight_rt.video.job import FrameSink, FrameSource

__all__ = ["models_dir"]  # fixture

H, W = 48, 64


def _rgb(t: int, h: int = H, w: int = W) -> np.ndarray:
    img = np.zeros((h, w, 3), np.uint8)
    img[:] = (60 + 3 * t, 100, 150)
    img[h // 5 : -h // 5, w // 3 : -w // 3] = (200, 150, 120)
    return img


def _mask8(h: int = H, w: int = W) -> np.ndarray:
    m = np.zeros((h, w), np.uint8)
    m[h // 5 : -h // 5, w // 3 : -w // 3] = 255
    return m


def _frames(folder: Path, n: int, sizes: dict | None = None) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for t in range(n):
        h, w = (sizes or {}).get(t, (H, W))
        cv2.imwrite(str(folder / f"f_{t:03d}.png"), _rgb(t, h, w)[..., ::-1])
        cv2.imwrite(str(folder / f"f_{t:03d}_mask.png"), _mask8(h, w))
    return folder


def _mask_folder(folder: Path, n: int) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for t in range(n):
        cv2.imwrite(str(folder / f"m_{t:03d}.png"), _mask8())
    return folder


def _av_clip(path: Path, n: int, *, rate=fractions.Fraction(30000, 1001), audio=False, mask=False, h=H, w=W,
             codec="libx264"):
    av = pytest.importorskip("av")
    with av.open(str(path), "w") as out:
        v = out.add_stream(codec, rate=rate)
        v.width, v.height, v.pix_fmt = w, h, "yuv420p"
        a = out.add_stream("aac", rate=44100) if audio else None
        for t in range(n):
            img = np.dstack([_mask8(h, w)] * 3) if mask else _rgb(t, h, w)
            out.mux(v.encode(av.VideoFrame.from_ndarray(img, format="rgb24")))
        out.mux(v.encode(None))
        if a is not None:
            tone = (0.2 * np.sin(np.arange(1024) * 0.05)).astype(np.float32)[None]
            for k in range(int(n / float(rate) * 44100 / 1024) + 1):
                frame = av.AudioFrame.from_ndarray(tone, format="fltp", layout="mono")
                frame.sample_rate, frame.pts = 44100, k * 1024
                out.mux(a.encode(frame))
            out.mux(a.encode(None))
    return path


@pytest.fixture
def work(tmp_path, models_dir, monkeypatch):
    in_folder(tmp_path, models_dir, monkeypatch)
    return tmp_path


@pytest.fixture(params=["pyav", "opencv"])
def backend(request, monkeypatch):
    if request.param == "pyav":
        pytest.importorskip("av")
    else:
        monkeypatch.setitem(sys.modules, "av", None)  # import av raises ImportError: the OpenCV path
    return request.param


def error_lines(err: str) -> list[str]:
    assert "Traceback" not in err, err
    return [x for x in err.splitlines() if x.startswith("relight-rt:")]


def snapshot(folder: Path) -> dict:
    return {p: p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


# ------------------------------------------------------------------------------------------- item 9


def test_h264_keeps_audio_frame_rate_and_frame_count(work, capsys):
    av = pytest.importorskip("av")
    _av_clip(work / "clip.mp4", 24, audio=True, h=49, w=65, codec="mpeg4")  # odd size: H.264 4:2:0 needs even
    masks = work / "masks"
    masks.mkdir()
    for t in range(24):
        cv2.imwrite(str(masks / f"m_{t:03d}.png"), _mask8(49, 65))
    code, _, err = run(["video", "clip.mp4", "--masks", "masks", "--preset", "studio",
                        "-o", "out.mp4", "--device", "cpu"], capsys)  # fmt: skip
    assert code == 0, err
    with av.open("out.mp4") as c:
        v = c.streams.video[0]
        assert v.codec_context.name == "h264" and v.codec_context.pix_fmt == "yuv420p"
        assert (v.codec_context.width, v.codec_context.height) == (66, 50)
        assert v.average_rate == fractions.Fraction(30000, 1001)
        assert [s.codec_context.name for s in c.streams.audio] == ["aac"]
        frames = [f.to_ndarray(format="rgb24") for f in c.decode(video=0)]
    assert len(frames) == 24
    with av.open("clip.mp4") as c:
        src = next(iter(c.decode(video=0))).to_ndarray(format="rgb24")

    def audio(name):
        with av.open(name) as c:
            return [(p.pts, bytes(p)) for p in c.demux(audio=0) if p.size]

    assert audio("clip.mp4") == audio("out.mp4") and len(audio("out.mp4")) > 30  # copied packet by packet
    # outside the person the frame is the input's (H.264 at crf 18: a few levels)
    outside = _mask8(49, 65) == 0
    assert np.abs(frames[0][:49, :65][outside].astype(int) - src[outside].astype(int)).mean() < 3
    assert not [p for p in work.iterdir() if p.name.startswith(".")]


def test_opencv_fallback_without_pyav(work, capsys, caplog, monkeypatch):
    monkeypatch.setitem(sys.modules, "av", None)  # import av raises ImportError
    monkeypatch.setattr(_video_io, "_noted", set())
    _frames(work / "in", 3)
    with caplog.at_level(logging.INFO):
        code, _, err = run(["video", "in", "--preset", "studio", "-o", "out.mp4", "--device", "cpu"], capsys)
    assert code == 0, err
    cap = cv2.VideoCapture("out.mp4")
    fourcc = int(cap.get(cv2.CAP_PROP_FOURCC)).to_bytes(4, "little").decode()
    assert fourcc.lower() in ("mp4v", "fmp4") and int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 3  # MPEG-4 part 2
    cap.release()
    assert "PyAV is not installed" in caplog.text and 'pip install "relight-rt[video]"' in caplog.text


def test_frame_rate_is_exact_and_fps_must_be_positive(work, capsys, backend):
    _frames(work / "in", 2)
    code, _, err = run(["video", "in", "--preset", "studio", "-o", "o.mp4", "--fps", "-5"], capsys)
    assert code == 2 and error_lines(err) == ["relight-rt: error: --fps: must be > 0 and at most 1000, got -5"]
    with pytest.raises(RelightError, match="fps: must be > 0"):
        FrameSink(video=work / "x.mp4", fps=0)
    assert not (work / "o.mp4").exists()


@pytest.mark.parametrize("fps", ["3e9", "1e300", "inf"])
def test_fps_is_bounded(work, capsys, backend, fps):
    """issue 35 item 6: ``--fps 3e9`` was an OverflowError traceback in the writer, leaving its hidden temporary
    file; the rate is bounded before any work, in the CLI and in the API (FrameSource, FrameSink)."""
    _frames(work / "in", 2)
    code, _, err = run(["video", "in", "--preset", "studio", "-o", "o.mp4", "--fps", fps], capsys)
    assert code == 2 and error_lines(err) == [f"relight-rt: error: --fps: must be > 0 and at most 1000, "
                                              f"got {float(fps):g}"]
    for make in (lambda: FrameSink(video=work / "x.mp4", fps=float(fps)), lambda: FrameSource(work / "in", fps=3e9)):
        with pytest.raises(RelightError, match="fps: must be > 0 and at most 1000"):
            make()
    assert sorted(p.name for p in work.iterdir()) == ["in"]  # no output, no temporary file


def test_sink_removes_its_temporary_file_when_the_writer_cannot_start(tmp_path, backend):
    """issue 35 item 6: an error while the writer starts (here a rate the container cannot hold) left the
    mkstemp file behind: the sink had no writer yet, so close() did not know it."""
    sink = FrameSink(video=tmp_path / "o.mp4", fps=25)
    sink.rate = fractions.Fraction(3 * 10**9)  # as a rate past the check would
    sink.fps = float(sink.rate)
    with pytest.raises(Exception):  # noqa: B017  (whatever the backend raises; the point is the file)
        with sink:
            sink.write("f", np.zeros((8, 8, 3), np.float32))
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------------------------------------- item 1


def test_mask_video_and_mask_folder_are_inputs(work, capsys):
    _av_clip(work / "clip.mp4", 4)
    _av_clip(work / "m.mp4", 4, mask=True)
    _frames(work / "frames", 3)
    for t in range(3):
        (work / "frames" / f"f_{t:03d}_mask.png").unlink()
    _mask_folder(work / "masks", 3)
    (work / "alias.mp4").symlink_to(work / "m.mp4")
    before = snapshot(work)
    cases = [
        ["clip.mp4", "--masks", "m.mp4", "-o", "m.mp4"],
        ["clip.mp4", "--masks", "m.mp4", "-o", "alias.mp4"],
        ["frames", "--masks", "masks", "--frames-out", "masks"],
        ["frames", "--masks", "masks", "--frames-out", "masks/../masks"],
        ["frames", "--masks", "masks", "--frames-out", "o", "--lights-out", "masks/m_000.png"],
        ["frames", "--masks", "masks", "--frames-out", "o", "--metrics", "masks/m_001.png"],
    ]
    for extra in cases:
        code, _, err = run(["video", *extra, "--preset", "studio", "--device", "cpu"], capsys)
        lines = error_lines(err)
        assert code == 2 and len(lines) == 1 and "refusing" in lines[0], (extra, err)
    assert snapshot(work) == before


def test_video_temp_file_is_not_predictable(work, capsys):
    """A symlink planted under the old temporary name (.NAME.tmp<PID>.ext) must not be followed."""
    _frames(work / "in", 2)
    victim = work / "victim.txt"
    victim.write_text("keep me")
    (work / "out").mkdir()
    for name in (f".o.tmp{os.getpid()}.mp4", f".o.mp4.tmp{os.getpid()}.mp4"):
        (work / "out" / name).symlink_to(victim)
    code, _, err = run(["video", "in", "--preset", "studio", "-o", "out/o.mp4", "--device", "cpu"], capsys)
    assert code == 0, err
    assert victim.read_text() == "keep me" and (work / "out" / "o.mp4").stat().st_size > 0
    umask = os.umask(0)
    os.umask(umask)
    assert (work / "out" / "o.mp4").stat().st_mode & 0o777 == 0o666 & ~umask  # not mkstemp's 0600
    assert len([p for p in (work / "out").iterdir() if p.name.startswith(".")]) == 2  # only the planted links


# ------------------------------------------------------------------------------------------- item 3


def test_damaged_video_is_an_error_or_reported_frame_by_frame(work, capsys, backend):
    clip = write_noise_clip(work / "clip.mp4", 40, W, H)
    data = bytearray(clip.read_bytes())
    n = len(data)
    data[n // 3 : n // 2] = np.random.default_rng(1).integers(0, 255, n // 2 - n // 3, dtype=np.uint8).tobytes()
    clip.write_bytes(bytes(data))
    _mask_folder(work / "masks", 40)
    argv = ["video", "clip.mp4", "--masks", "masks", "--preset", "studio", "-o", "out.mp4", "--device", "cpu"]
    code, _, err = run(argv, capsys)
    lines = error_lines(err)
    assert code == 2 and len(lines) == 1 and "--skip-bad-frames" in lines[0], err
    assert not (work / "out.mp4").exists() and not [p for p in work.iterdir() if p.name.startswith(".")]
    code, _, err = run([*argv, "--skip-bad-frames", "--frames-out", "fo"], capsys)
    lines = error_lines(err)
    assert code == 2 and len(lines) >= 2 and all("skipped" in x for x in lines[:-1]), err
    assert "frame(s) left out" in lines[-1]
    lost, written = map(int, re.fullmatch(r"relight-rt: (\d+) frame\(s\) left out, (\d+) written", lines[-1]).groups())
    cap = cv2.VideoCapture("out.mp4")
    assert 0 < written < 40 and int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == written and lost + written == 40
    cap.release()
    names = sorted(int(p.stem.split("_")[1]) for p in (work / "fo").iterdir())
    assert len(names) == written
    if backend == "pyav":  # each frame keeps its place in the video (a decoder may also drop frames silently:
        # those are counted against the header's frame count, without a place)
        reported = {int(x.split("(frame ")[1].split(")")[0]) for x in lines[:-1] if "(frame " in x}
        assert reported and not set(names) & reported and set(names) | reported <= set(range(40))
        assert names[-1] == 39 and names[0] == 0


def test_frame_of_another_size(work, capsys, backend):
    _frames(work / "in", 4, sizes={2: (40, 64)})
    argv = ["video", "in", "--preset", "studio", "-o", "out.avi", "--device", "cpu"]
    code, _, err = run(argv, capsys)
    lines = error_lines(err)
    assert code == 2 and len(lines) == 1 and "f_002.png: frame is 64x40, the first frame is 64x48" in lines[0]
    assert not (work / "out.avi").exists()
    code, _, err = run([*argv, "--skip-bad-frames"], capsys)
    lines = error_lines(err)
    assert code == 2 and len(lines) == 2 and "f_002.png" in lines[0] and "3 written" in lines[1]
    cap = cv2.VideoCapture("out.avi")
    count = 0
    while cap.read()[0]:
        count += 1
    assert count == 3


def test_sink_refuses_a_frame_of_another_size(tmp_path, backend):
    sink = FrameSink(video=tmp_path / "o.mp4")
    sink.write("a", np.zeros((H, W, 3), np.float32))
    with pytest.raises(RelightError, match="frame b is 64x40, the video's frames are 64x48"):
        sink.write("b", np.zeros((40, W, 3), np.float32))
    sink.close(ok=False)
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------------------------------------- items 4, 7


def test_bad_video_inputs_are_one_line(work, capsys, backend):
    _frames(work / "in", 2)
    (work / "text.mp4").write_text("not a video")
    (work / "l.json").write_text('{"sh": [[0.1, 0.1, 0.1]]}')
    (work / "zero.npy").write_bytes(b"")
    header = np.lib.format.header_data_from_array_1_0(np.zeros(3))
    header["shape"] = (1 << 40, 9, 3)
    with open(work / "huge.npy", "wb") as f:
        np.lib.format.write_array_header_1_0(f, header)
    np.save(work / "big.npy", np.full((2, 9, 3), 4e38))
    cases = {
        ("in/f_000.png", "--preset", "studio"): "is a still image",
        ("text.mp4", "--preset", "studio"): "text.mp4",
        ("in", "--lights", "l.json"): "for one light from a .json file use --light",
        ("in", "--lights", "zero.npy"): "empty (0 bytes)",
        ("in", "--lights", "huge.npy"): "announces",
        ("in", "--lights", "big.npy"): "too large",
        ("in", "--preset", "studio", "--max-pixels", "1000"): "more than the limit",
    }
    for args, match in cases.items():
        code, _, err = run(["video", *args, "-o", "o.mp4", "--device", "cpu"], capsys)
        lines = error_lines(err)
        assert code == 2 and len(lines) == 1 and match in lines[0], (args, err)
    assert not (work / "o.mp4").exists()


def test_source_paths_hold_every_input(tmp_path):
    _frames(tmp_path / "in", 2)
    src = FrameSource(tmp_path / "in")
    assert sorted(p.name for p in src.paths) == ["f_000.png", "f_000_mask.png", "f_001.png", "f_001_mask.png"]
    _mask_folder(tmp_path / "masks", 2)
    src = FrameSource(tmp_path / "in", tmp_path / "masks")
    assert {p.name for p in src.paths} >= {"m_000.png", "m_001.png"}


def test_hidden_temp_files_are_not_frames(tmp_path):
    """Temporary files a SIGKILLed writer left behind (.NAME.XXXX.tmp.png) are not taken as frames."""
    _frames(tmp_path / "in", 2)
    (tmp_path / "in" / ".f_002.png.k2j3.tmp.png").write_bytes(b"half a png")
    src = FrameSource(tmp_path / "in")
    assert len(src) == 2 and len(list(src)) == 2


def test_rotated_video_is_read_upright_as_opencv_reads_it(tmp_path):
    """A phone video's display matrix (here a 90° turn patched into the track header) is applied by both
    readers, so masks made with other tools line up."""
    import struct

    _av_clip(tmp_path / "r.mp4", 2)
    data = bytearray((tmp_path / "r.mp4").read_bytes())
    i = data.find(b"tkhd")
    matrix = i + 4 + 4 + (32 if data[i + 4] == 1 else 20) + 16  # version/flags, times + ids, reserved, layer...
    assert struct.unpack(">9i", data[matrix : matrix + 36])[0] == 0x10000  # the identity is there
    data[matrix : matrix + 36] = struct.pack(">9i", 0, 0x10000, 0, -0x10000, 0, 0, 0, 0, 0x40000000)
    (tmp_path / "r.mp4").write_bytes(bytes(data))
    _, via_av = next(_video_io._decoded_frames(tmp_path / "r.mp4", "video"))
    ok, bgr = cv2.VideoCapture(str(tmp_path / "r.mp4")).read()
    assert ok and via_av.shape == bgr.shape == (W, H, 3)
    assert np.abs(via_av.astype(int) - bgr[..., ::-1].astype(int)).mean() < 2


def test_audio_the_output_cannot_hold_is_left_out_with_a_warning(tmp_path, caplog):
    av = pytest.importorskip("av")
    clip = tmp_path / "in.avi"
    with av.open(str(clip), "w") as out:
        v = out.add_stream("mjpeg", rate=25)
        v.width, v.height, v.pix_fmt = W, H, "yuvj420p"
        a = out.add_stream("pcm_u8", rate=8000)  # .mp4 cannot hold unsigned 8-bit PCM
        for t in range(5):
            out.mux(v.encode(av.VideoFrame.from_ndarray(_rgb(t), format="rgb24")))
        out.mux(v.encode(None))
        frame = av.AudioFrame.from_ndarray(np.full((1, 1600), 128, np.uint8), format="u8", layout="mono")
        frame.sample_rate, frame.pts = 8000, 0
        out.mux(a.encode(frame))
        out.mux(a.encode(None))
    src = FrameSource(clip, _mask_folder(tmp_path / "m", 5))
    assert src.has_audio
    with caplog.at_level(logging.WARNING), FrameSink(video=tmp_path / "o.mp4", fps=src.rate, audio_from=clip) as sink:
        for f in src:
            sink.write(f.name, f.image)
    assert "pcm_u8" in caplog.text and "left out" in caplog.text
    with av.open(str(tmp_path / "o.mp4")) as c:
        assert [s.type for s in c.streams] == ["video"] and c.streams.video[0].frames == 5
