"""Hostile input against this session's surfaces: composite --view (a panorama seen one way), video
--grade-background, decompose --format (round 6).

Every bad input: exit 2, one ``relight-rt: error:`` line, no traceback, no output written, the inputs unchanged.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import cv2
import numpy as np
import pytest
from _cli import in_folder, run
from _graphs import models_dir, write_person

__all__ = ["models_dir"]  # fixture


def _pano(h: int = 32) -> np.ndarray:
    """A 2:1 float panorama: a bright spot on a dim sky over a darker ground."""
    env = np.full((h, 2 * h, 3), 0.2, np.float32)
    env[h // 2 :] = 0.05
    env[h // 4, h // 2 : h // 2 + 3] = 20.0
    return env


@pytest.fixture
def work(tmp_path, models_dir, monkeypatch):
    in_folder(tmp_path, models_dir, monkeypatch)
    write_person(tmp_path, seed=1)
    env = _pano()
    cv2.imwrite("pano.hdr", env[..., ::-1])
    cv2.imwrite("pano8.jpg", (np.clip(env, 0, 1) * 255).astype(np.uint8))
    cv2.imwrite("one.hdr", np.ones((1, 1, 3), np.float32))
    cv2.imwrite("wide3.hdr", np.ones((32, 96, 3), np.float32))
    cv2.imwrite("black.hdr", np.zeros((32, 64, 3), np.float32))
    Path("corrupt.hdr").write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 32 +X 64\n" + b"\x02\x02\x00" * 7)
    Path("corrupt.exr").write_bytes(b"\x76\x2f\x31\x01\x02\x00\x00\x00" + b"channels\x00chlist\x00" + b"\xff" * 40)
    Path("empty.hdr").write_bytes(b"")
    Path("text.hdr").write_text("not a radiance file\n" * 5)
    return tmp_path


def _digest(folder: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir()) if p.is_file()}


def _refused(work, capsys, argv, match: str | None = None) -> str:
    before = _digest(work)
    code, _, err = run(argv, capsys)
    assert code == 2, (argv, code, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("relight-rt: error:"), (argv, err)
    assert "Traceback" not in err
    if match is not None:
        assert match in err, (argv, err)
    assert _digest(work) == before, argv  # nothing written, nothing changed
    return err


VIEW = ["composite", "p.png", "--background", "pano.hdr", "-o", "out.png"]

# fmt: off
BAD_COMPOSITE = [
    # --view
    ["--view", "nan,0"], ["--view", "inf,0"], ["--view", "0,nan"], ["--view", "0,0,nan"], ["--view", "0,0,inf"],
    ["--view", "0"], ["--view", "1,2,3,4"], ["--view", "a,b"], ["--view", ""], ["--view", ","], ["--view", "0,0,0"],
    ["--view", "0,0,-0"], ["--view", "0,1e308"], ["--view", "0,0,1e308"], ["--view", "0x10,0"], ["--view", "0,,0"],
    # --size
    ["--view", "0,0", "--size", "0x0"], ["--view", "0,0", "--size", "1x1"],
    ["--view", "0,0", "--size", "100000x100000"],
    ["--view", "0,0", "--size", "-5x5"], ["--view", "0,0", "--size", "1e3x10"], ["--view", "0,0", "--size", "64"],
    ["--view", "0,0", "--size", "99999999999999999999x64"],
    ["--view", "0,0", "--size", "64x100000"],  # within the pixel limit, past OpenCV remap's 32767: was a traceback
    # --camera-height
    *(["--view", "0,0", "--camera-height", v] for v in ("0", "-1", "nan", "inf", "1e9", "abc", "")),
    # --height / --horizon / --position / --exposure
    *(["--view", "0,0", "--height", v] for v in ("nan", "inf", "0", "-1", "2", "1e308")),
    *(["--view", "0,0", "--horizon", v] for v in ("nan", "inf", "-1", "2", "-inf")),
    *(["--view", "0,0", "--position", v] for v in ("nan,0.5", "0.5,inf", "1,2", "a,b", "0.5", "0.5,0.5,0.5")),
    *(["--view", "0,0", "--exposure", v] for v in ("nan", "inf", "1e308", "-1e308", "abc")),
]
# fmt: on


@pytest.mark.parametrize("extra", BAD_COMPOSITE, ids=lambda e: " ".join(e))
def test_bad_view_options_are_refused(work, capsys, extra):
    _refused(work, capsys, [*VIEW, *extra])


@pytest.mark.parametrize("pano", ["one.hdr", "wide3.hdr", "black.hdr", "corrupt.hdr", "corrupt.exr",
                                  "empty.hdr", "text.hdr", "p.png", "missing.hdr"])  # fmt: skip
def test_bad_panoramas_are_refused(work, capsys, pano):
    _refused(work, capsys, ["composite", "p.png", "--background", pano, "--view", "0,0", "-o", "out.png"])


@pytest.mark.parametrize("out", ["p.png", "p_mask.png", "pano.hdr", "pano8.jpg", "out.exr", "out"])
def test_the_output_never_lands_on_an_input(work, capsys, out):
    pano = "pano8.jpg" if out.endswith(".jpg") else "pano.hdr"  # an 8-bit panorama is a panorama too (held)
    _refused(work, capsys, ["composite", "p.png", "--background", pano, "--view", "0,0", "-o", out])


# ---------------------------------------------------------------------------------------- video --grade-background


def _video(work, capsys, clip: str, *extra: str) -> tuple[int, str]:
    code, _, err = run(["-q", "video", clip, "--preset", "night", "--grade-background", "--device", "cpu",
                        "--no-stabilize", *extra], capsys)  # fmt: skip
    assert "Traceback" not in err
    return code, err


def test_video_grade_background_edge_clips(work, capsys):
    img = cv2.imread("p.png")
    h, w = img.shape[:2]
    # one frame: graded as a still
    Path("one").mkdir()
    cv2.imwrite("one/f_000.png", img)
    cv2.imwrite("one/f_000_mask.png", cv2.imread("p_mask.png"))
    code, err = _video(work, capsys, "one", "--frames-out", "one_out")
    assert code == 0, err
    assert len(list(Path("one_out").glob("*.png"))) == 1
    # all black, no person in the mask: the backdrop stays as it is (a grade of 1), no NaN
    Path("black").mkdir()
    for t in range(3):
        cv2.imwrite(f"black/f_{t:03d}.png", np.zeros((h, w, 3), np.uint8))
        cv2.imwrite(f"black/f_{t:03d}_mask.png", np.zeros((h, w), np.uint8))
    code, err = _video(work, capsys, "black", "--frames-out", "black_out/frames", "-o", "new/o.mp4")
    assert not Path("new").exists()  # a failed run leaves no new folder behind (an empty one was left)
    assert code == 2 and "no person found in any of the 3 frames" in err and not Path("black_out").exists(), err
    # all black with a person mask: the grade stays finite, the frames black
    for t in range(3):
        cv2.imwrite(f"black/f_{t:03d}_mask.png", cv2.imread("p_mask.png", cv2.IMREAD_GRAYSCALE))
    code, err = _video(work, capsys, "black", "--frames-out", "black_out2")
    assert code == 0, err
    outs = sorted(Path("black_out2").glob("*.png"))
    assert len(outs) == 3 and not any(cv2.imread(str(f)).any() for f in outs)


def test_video_grade_background_refusals(work, capsys):
    Path("empty").mkdir()
    cv2.VideoWriter("zero.mp4", cv2.VideoWriter_fourcc(*"mp4v"), 10, (64, 64)).release()  # no frame
    Path("nothing.mp4").write_bytes(b"")
    Path("one").mkdir()
    cv2.imwrite("one/f_000.png", cv2.imread("p.png"))
    cases = [("empty", ["-o", "o.mp4"]), ("nothing.mp4", ["-o", "o.mp4"]), ("zero.mp4", ["-o", "o.mp4"]),
             ("one", ["-o", "one/f_000.png"]), ("one", ["-o", "p.png"]), ("one", ["--frames-out", "one"]),
             ("one", ["-o", "o.mp4", "--fps", "nan"]), ("one", ["-o", "o.mp4", "--fps", "0"]),
             ("one", ["-o", "o.mp4", "--background", "nope.png"])]  # fmt: skip
    for clip, extra in cases:
        before = _digest(work)
        code, err = _video(work, capsys, clip, *extra)
        lines = err.strip().splitlines()
        assert code == 2 and len(lines) == 1 and lines[0].startswith("relight-rt: error:"), (clip, extra, err)
        assert _digest(work) == before, (clip, extra)
        assert not Path("o.mp4").exists()
