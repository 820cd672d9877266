"""Video frames with the automatic matte go over their own background with the soft edge as the frame shows it
(``compose.shown_edge``, ``compose.FRAME_EDGE``, issue 48): a matte wider than the frame's sharp edge no longer
relights the plain background beside the person; a given mask keeps its own edge (videoedge44)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from _box_clip import box_clip
from _graphs import models_dir

from relight_rt import Relighter, RuntimeConfig, lights
from relight_rt.relight import compose
from relight_rt.video.frames import FrameSource
from relight_rt.video.job import LightSchedule, RelighterEngine, relight_frames
from relight_rt.video.stabilize import Stabilizer

__all__ = ["models_dir"]  # fixture

LIGHT = lights.directional((0.3, 1.0, 0.2), (1, 1, 1), 1.0) + lights.ambient(0.01)


def _relit(source, relighter) -> list[tuple[np.ndarray, np.ndarray]]:
    """(frame, relit) per frame, as ``relight-rt video`` relights them over their own background."""
    return [(f.image, np.asarray(out)) for f, out, _ in relight_frames(
        source, LightSchedule.constant(LIGHT), fps=25.0, engine=RelighterEngine(relighter),
        stabilizer=Stabilizer(0.8), batch_size=2)]


@pytest.fixture
def clip(tmp_path, models_dir, monkeypatch):
    """The clip, the box, its automatic matte (the masks' values) and a Relighter (the frames' rim on)."""
    monkeypatch.setattr(compose, "FRAME_RIM", True)
    box = box_clip(tmp_path / "clip", grow=2)
    soft = next(iter(FrameSource(tmp_path / "clip"))).mask
    matter = lambda rgb, name="image": soft  # noqa: E731
    return tmp_path / "clip", box, matter, Relighter(RuntimeConfig(models=str(models_dir), device="cpu"))


def _beside(box: np.ndarray) -> np.ndarray:
    """The plain background within 5 px of the box (outside it by 1 px: the frame's pixels there are background)."""
    near = cv2.dilate(box.astype(np.uint8), np.ones((11, 11), np.uint8)) > 0
    return near & ~(cv2.dilate(box.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0)


def test_the_automatic_mattes_frames_leave_the_background_beside_the_person(clip, monkeypatch):
    folder, box, matter, relighter = clip
    beside = _beside(box)
    deep = cv2.erode(box.astype(np.uint8), np.ones((17, 17), np.uint8)) > 0
    on = _relit(FrameSource(folder, "auto", matter=matter), relighter)
    monkeypatch.setattr(compose, "FRAME_EDGE", False)
    off = _relit(FrameSource(folder, "auto", matter=matter), relighter)
    for (img, a), (_, o) in zip(on, off, strict=True):
        change_on = np.abs(a - img).max(axis=2)[beside]
        change_off = np.abs(o - img).max(axis=2)[beside]
        assert change_off.mean() > 2 / 255  # the wide matte relights the background beside the box ...
        assert change_on.mean() < change_off.mean() / 5  # ... the edge as the frame shows it far less
        np.testing.assert_array_equal(a[deep], o[deep])  # the person's solid inside


def test_given_masks_keep_their_own_edge(clip, monkeypatch):
    folder, _, _, relighter = clip
    on = _relit(FrameSource(folder), relighter)
    monkeypatch.setattr(compose, "FRAME_EDGE", False)
    for (_, a), (_, o) in zip(on, _relit(FrameSource(folder), relighter), strict=True):
        np.testing.assert_array_equal(a, o)


def test_only_the_automatic_mattes_frames_carry_an_edge(clip, monkeypatch):
    folder, _, matter, relighter = clip
    frames = list(FrameSource(folder, "auto", matter=matter))[:2]
    engine = RelighterEngine(relighter)
    on, off = engine.decompose([f.image for f in frames], [f.mask for f in frames], [True, False])
    assert on.state.edge is not None and off.state.edge is None and off.state.foreground is None
    alpha = on.state.geometry.crop(on.state.mask)
    assert (on.state.edge < alpha - 0.1).any()  # the outer half lowered: the frame shows a sharp edge
    monkeypatch.setattr(compose, "FRAME_EDGE", False)
    assert engine.decompose([frames[0].image], [frames[0].mask], [True])[0].state.edge is None


def test_the_rule_near_the_soft_pixels_gives_the_whole_crops_values():
    """``shown_edge_near`` (a frame's) works on the box round the soft pixels; a faint tail (under ``_SOFT``) over
    the whole crop keeps its colour behind solved as ``shown_edge`` solves it."""
    rng = np.random.default_rng(4)
    h, w = 160, 130
    hard = np.zeros((h, w), np.float32)
    hard[40:120, 50:90] = 1
    alpha = np.clip(cv2.GaussianBlur(hard, (0, 0), 3.0), 0, 1)
    alpha = np.where(alpha < compose._SOFT, rng.uniform(0, compose._SOFT, (h, w)), alpha).astype(np.float32)
    image = np.empty((h, w, 3), np.float32)
    image[:] = (0.9, 0.85, 0.6)
    image[hard > 0] = (0.4, 0.35, 0.3)
    image = np.clip(image + rng.normal(0, 0.01, image.shape), 0, 1).astype(np.float32)
    fg = np.where(alpha[..., None] > 0.5, image, (0.4, 0.35, 0.3)).astype(np.float32)
    full, near = compose.shown_edge(image, alpha, fg), compose.shown_edge_near(image, alpha, fg)
    assert (full[0] != alpha).any()
    for a, b in zip(full, near, strict=True):
        np.testing.assert_array_equal(a, b)
