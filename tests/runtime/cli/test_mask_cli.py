"""``relight-rt mask`` (relight_rt.cli.mask) end to end on the bundled example person."""

from __future__ import annotations

import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
from _scenes import write_noise_clip

from relight_rt import cli

REPO = Path(__file__).resolve().parents[3]
EXAMPLE = REPO / "relight_rt" / "data" / "example.png"


def run(*argv) -> int:
    return cli.main(["mask", *[str(a) for a in argv]])


def truth() -> np.ndarray:
    return cv2.imread(str(EXAMPLE), cv2.IMREAD_UNCHANGED)[..., 3] >= 128


def iou(mask_u8: np.ndarray, t: np.ndarray) -> float:
    m = mask_u8 >= 128
    return float((m & t).sum() / (m | t).sum())


@pytest.fixture
def photos(tmp_path) -> Path:
    folder = tmp_path / "photos"
    folder.mkdir()
    shutil.copy(EXAMPLE, folder / "person.png")
    bgr = cv2.imread(str(EXAMPLE), cv2.IMREAD_COLOR)
    cv2.imwrite(str(folder / "person_gray.jpg"), cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY))
    yy, xx = np.mgrid[0:120, 0:160]
    cv2.imwrite(str(folder / "gradient.png"), np.dstack([xx, yy, xx + yy]).astype(np.uint8))
    (folder / "broken.jpg").write_bytes(b"not an image")
    return folder


def test_one_image_gives_an_8bit_png(tmp_path, capsys):
    out = tmp_path / "person_mask.png"
    assert run(EXAMPLE, "-o", out) == 0
    m = cv2.imread(str(out), cv2.IMREAD_UNCHANGED)
    assert m.dtype == np.uint8 and m.ndim == 2 and m.shape == truth().shape
    assert iou(m, truth()) > 0.93
    assert run(EXAMPLE, "-o", tmp_path / "b.png", "--binary") == 0
    assert set(np.unique(cv2.imread(str(tmp_path / "b.png"), cv2.IMREAD_UNCHANGED))) <= {0, 255}
    assert run(EXAMPLE, "-o", tmp_path / "m.jpg") == 2
    assert "error: output" in capsys.readouterr().err


def test_folder_goes_on_past_bad_files(photos, tmp_path, capsys):
    out = tmp_path / "masks"
    assert run(photos, "-o", out) == 2
    err = capsys.readouterr().err
    assert "broken.jpg" in err and "no person found in" in err and "gradient.png" in err
    assert "2 failed, 2 written" in err
    assert sorted(p.name for p in out.iterdir()) == ["person_gray_mask.png", "person_mask.png"]
    assert iou(cv2.imread(str(out / "person_gray_mask.png"), cv2.IMREAD_GRAYSCALE), truth()) > 0.9


def test_never_writes_over_an_input(photos, capsys):
    src = photos / "person.png"
    before = src.read_bytes()
    assert run(src, "-o", src) == 2
    assert "refusing to overwrite" in capsys.readouterr().err
    (photos / "person_mask.png").write_bytes(b"a hand-made mask")
    assert run(photos, "-o", photos) == 2  # writing beside the photos must not replace the user's mask
    assert (photos / "person_mask.png").read_bytes() == b"a hand-made mask"
    assert src.read_bytes() == before
    assert not list(photos.glob(".*tmp*"))


def test_video_gives_a_mask_video_and_frames(tmp_path):
    rgb = cv2.imread(str(EXAMPLE), cv2.IMREAD_COLOR)[:, :288]  # even size for the codec
    clip = tmp_path / "clip.avi"
    writer = cv2.VideoWriter(str(clip), cv2.VideoWriter_fourcc(*"MJPG"), 10, (rgb.shape[1], rgb.shape[0]))
    for t in range(3):
        writer.write(np.roll(rgb, 2 * t, axis=1))
    writer.release()
    assert run(clip, "-o", tmp_path / "clip_mask.avi") == 0
    cap = cv2.VideoCapture(str(tmp_path / "clip_mask.avi"))
    frames = []
    while True:
        ok, f = cap.read()
        if not ok:
            break
        frames.append(f[..., 0])
    cap.release()
    assert len(frames) == 3 and iou(frames[0], truth()[:, :288]) > 0.9
    assert run(clip, "-o", tmp_path / "frames") == 0
    assert sorted(p.name for p in (tmp_path / "frames").iterdir()) == [f"frame_{i:06d}_mask.png" for i in range(3)]


def test_help_lists_the_command(capsys):
    assert cli.main(["mask", "--help"]) == 0
    assert "NAME_mask.png" in capsys.readouterr().out


def test_frame_folder_as_a_sequence(tmp_path):
    frames = tmp_path / "frames"
    frames.mkdir()
    rgb = cv2.imread(str(EXAMPLE), cv2.IMREAD_COLOR)
    for t in range(3):
        cv2.imwrite(str(frames / f"f{t}.png"), np.roll(rgb, 2 * t, axis=1))
    assert run(frames, "--sequence", "--smoothing", "0.5", "-o", tmp_path / "masks") == 0
    names = sorted(p.name for p in (tmp_path / "masks").iterdir())
    assert names == ["f0_mask.png", "f1_mask.png", "f2_mask.png"]
    assert iou(cv2.imread(str(tmp_path / "masks" / "f2_mask.png"), cv2.IMREAD_GRAYSCALE), np.roll(truth(), 4, 1)) > 0.9
    assert run(frames, "--sequence", "--smoothing", "1.5", "-o", tmp_path / "m2") == 2


def test_video_frames_are_held_to_max_pixels(tmp_path, capsys):
    """issue 35 item 8: a video's frames are held to --max-pixels (from its header, before decoding)."""
    clip = write_noise_clip(tmp_path / "clip.mp4", 2)
    assert run(clip, "-o", tmp_path / "m.avi", "--max-pixels", "3000") == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "64x48" in err[0] and "--max-pixels" in err[0], err
    assert not (tmp_path / "m.avi").exists() and not list(tmp_path.glob(".*"))


def test_damaged_video_writes_every_frame_or_nothing(tmp_path, capsys):
    """issue 35 item 9: a damaged clip gave a mask video of 3 of its 24 frames and exit 0; as ``video``, the
    frames written must be the frames the clip has, else one error line and no mask video."""
    clip = write_noise_clip(tmp_path / "clip.mp4", 24)
    data = bytearray(clip.read_bytes())
    n = len(data)
    data[n // 3 : n // 2] = np.random.default_rng(1).integers(0, 255, n // 2 - n // 3, dtype=np.uint8).tobytes()
    clip.write_bytes(bytes(data))
    code = run(clip, "-o", tmp_path / "m.avi")
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and err[0].startswith("relight-rt: error: ") and "clip.mp4" in err[0], err
    assert not (tmp_path / "m.avi").exists() and not list(tmp_path.glob(".*"))
def test_foreground_over_an_input_writes_nothing(tmp_path, capsys):
    """Issue 50 bug 9: the mask was written, then the cut-out refused (it named the input): a partial output. Both
    targets are checked before any work, and the two files are written as one."""
    shutil.copy(EXAMPLE, tmp_path / "a.png")
    before = (tmp_path / "a.png").read_bytes()
    assert run(tmp_path / "a.png", "-o", tmp_path / "a_m.png", "--foreground", tmp_path / "a.png") == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "refusing to overwrite the input" in err[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.png"] and (tmp_path / "a.png").read_bytes() == before


def test_foreground_cutout(tmp_path, capsys):
    """Issue 33: ``--foreground`` writes the decontaminated RGBA cut-out beside the mask."""
    bgra = cv2.imread(str(EXAMPLE), cv2.IMREAD_UNCHANGED)
    person = bgra[..., :3].astype(np.float32) / 255
    a = bgra[..., 3:].astype(np.float32) / 255
    photo = tmp_path / "over_red.png"  # the example person over pure red (BGR)
    cv2.imwrite(str(photo), np.round((person * a + (1 - a) * np.array([0, 0, 1.0])) * 255).astype(np.uint8))
    out, cut = tmp_path / "m.png", tmp_path / "cut.png"
    assert run(photo, "-o", out, "--foreground", cut) == 0
    rgba = cv2.imread(str(cut), cv2.IMREAD_UNCHANGED)
    assert rgba.shape == bgra.shape and rgba.dtype == np.uint8
    np.testing.assert_array_equal(rgba[..., 3], cv2.imread(str(out), cv2.IMREAD_UNCHANGED))
    soft = (rgba[..., 3] > 25) & (rgba[..., 3] < 230)
    assert soft.sum() > 100
    redness = lambda img: img[soft][:, 2].astype(float) - img[soft][:, :2].astype(float).mean(1)  # noqa: E731
    photo_px = cv2.imread(str(photo), cv2.IMREAD_COLOR)
    assert redness(rgba).mean() < redness(photo_px).mean() - 30  # the red fringe is taken out
    assert run(photo, "-o", tmp_path / "m2.png", "--foreground", tmp_path / "cut.jpg") == 2
    assert "--foreground" in capsys.readouterr().err


def _grey_clip(path: Path, frames: int = 3) -> Path:
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10, (64, 96))
    for _ in range(frames):
        writer.write(np.full((96, 64, 3), 128, np.uint8))
    writer.release()
    return path


def test_a_clip_of_nobody_is_an_error_like_a_photo_of_nobody(tmp_path, capsys):
    """Issue 50 bug 14: a clip with nobody in any frame gave exit 0 without a word (a photo: "no person found")."""
    clip = _grey_clip(tmp_path / "grey.avi")
    for out in (tmp_path / "m.avi", tmp_path / "frames"):
        assert run(clip, "-o", out) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "no person found in any of the 3 frames" in err[0], err
        assert not out.exists() or not list(out.iterdir())  # no mask video, no frames
    assert sorted(p.name for p in tmp_path.iterdir()) in (["grey.avi"], ["frames", "grey.avi"])
