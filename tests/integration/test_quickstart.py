"""README's first block, as a new user runs it: a photo with no mask and no alpha relights through the
automatic matte, and the background outside the person stays as it was."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from relight_rt import cli

REPO = Path(__file__).resolve().parents[2]
SCENE = REPO / "relight_rt" / "data" / "example_scene.jpg"
TRUTH = REPO / "tests" / "data" / "example_scene_truth.png"  # the alpha the person was composited with


def test_readme_relights_a_photo_with_no_mask(tmp_path, monkeypatch, capsys):
    monkeypatch.delenv("RELIGHT_RT_MODELS", raising=False)
    readme = (REPO / "README.md").read_text()
    assert "relight-rt relight relight_rt/data/example_scene.jpg" in readme  # the command CI runs is this one
    src = cv2.imread(str(SCENE))
    assert src.ndim == 3 and src.shape[2] == 3  # no alpha, and no NAME_mask file beside it
    assert not list(SCENE.parent.glob("example_scene_mask.*"))
    out = tmp_path / "relit_scene.png"
    code = cli.main(["relight", str(SCENE), "--preset", "golden-hour", "--device", "cpu", "-o", str(out)])
    assert code == 0, capsys.readouterr().err
    relit = cv2.imread(str(out))
    truth = cv2.imread(str(TRUTH), cv2.IMREAD_GRAYSCALE) / 255.0
    assert relit.shape == src.shape
    far = cv2.dilate((truth > 0.02).astype(np.uint8), np.ones((25, 25), np.uint8)) == 0
    np.testing.assert_array_equal(relit[far], src[far])  # the street is untouched
    core = cv2.erode((truth > 0.98).astype(np.uint8), np.ones((9, 9), np.uint8)) > 0
    change = np.abs(relit[core].astype(np.int16) - src[core]).mean()
    assert change > 5  # the person is relit


def test_the_automatic_matte_finds_the_person(monkeypatch):
    import relight_rt
    from relight_rt import RuntimeConfig

    monkeypatch.delenv("RELIGHT_RT_MODELS", raising=False)
    r = relight_rt.open(RuntimeConfig(device="cpu"))
    dec = r.decompose(SCENE)  # no mask: the matte
    truth = cv2.imread(str(TRUTH), cv2.IMREAD_GRAYSCALE) / 255.0
    a, b = dec.mask > 0.5, truth > 0.5
    iou = (a & b).sum() / (a | b).sum()
    assert iou > 0.95, iou  # measured 0.988
    assert ((dec.mask > 0.05) & (dec.mask < 0.95)).any()  # soft at the outline


def test_video_frames_without_masks_get_the_automatic_matte(tmp_path, monkeypatch, capsys):
    monkeypatch.delenv("RELIGHT_RT_MODELS", raising=False)
    scene = cv2.imread(str(SCENE))
    truth = cv2.imread(str(TRUTH), cv2.IMREAD_GRAYSCALE) / 255.0
    frames = tmp_path / "frames"
    frames.mkdir()
    for t in range(3):  # the camera pans a little
        cv2.imwrite(str(frames / f"f{t}.png"), np.roll(scene, 3 * t, axis=1))
    out = tmp_path / "out"
    code = cli.main(["video", str(frames), "--preset", "window-left", "--device", "cpu", "--frames-out", str(out)])
    assert code == 0, capsys.readouterr().err
    far = cv2.dilate((truth > 0.02).astype(np.uint8), np.ones((31, 31), np.uint8)) == 0
    core = cv2.erode((truth > 0.98).astype(np.uint8), np.ones((15, 15), np.uint8)) > 0
    for t in range(3):
        src = cv2.imread(str(frames / f"f{t}.png"))
        got = cv2.imread(str(out / f"f{t}.png"))
        shift = lambda a, t=t: np.roll(a, 3 * t, axis=1)  # noqa: E731
        np.testing.assert_array_equal(got[shift(far)], src[shift(far)])
        assert np.abs(got[shift(core)].astype(np.int16) - src[shift(core)]).mean() > 5
    # --masks auto: the matte even where a mask file exists (here an empty one, which would relight nothing)
    cv2.imwrite(str(frames / "f0_mask.png"), np.zeros(scene.shape[:2], np.uint8))
    plain, forced = tmp_path / "plain", tmp_path / "forced"
    for folder, extra in ((plain, []), (forced, ["--masks", "auto"])):
        code = cli.main(["video", str(frames), "--preset", "window-left", "--device", "cpu", "--no-stabilize",
                         "--frames-out", str(folder), *extra])
        assert code == 0, capsys.readouterr().err
    src0 = cv2.imread(str(frames / "f0.png"))
    np.testing.assert_array_equal(cv2.imread(str(plain / "f0.png")), src0)  # the (empty) mask file was used
    assert np.abs(cv2.imread(str(forced / "f0.png")).astype(np.int16) - src0).max() > 20
