"""Video frames over their own background with the automatic matte keep the background's rim (relight.kept_rim, issue
48): a frame's matte from the clip's matter takes it, a given mask or alpha channel none (videorim44)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from _box_clip import box_clip
from _graphs import models_dir

from relight_rt import Relighter, RuntimeConfig, lights
from relight_rt.relight import compose
from relight_rt.relight import kept_rim as kr
from relight_rt.video.frames import FrameSource
from relight_rt.video.job import LightSchedule, RelighterEngine, relight_frames
from relight_rt.video.stabilize import Stabilizer

__all__ = ["models_dir"]  # fixture

LIGHT = lights.directional((0.3, 1.0, 0.2), (1, 1, 1), 1.0) + lights.ambient(0.01)


def _relit(source, relighter) -> list[np.ndarray]:
    return [np.asarray(out) for _, out, _ in relight_frames(source, LightSchedule.constant(LIGHT), fps=25.0,
                                                             engine=RelighterEngine(relighter),
                                                             stabilizer=Stabilizer(0.8), batch_size=2)]


@pytest.fixture
def clip(tmp_path, models_dir, monkeypatch):
    """The clip, its automatic matte and a Relighter, with the frames' rim switched on (``compose.FRAME_RIM``)."""
    monkeypatch.setattr(compose, "FRAME_RIM", True)
    box_clip(tmp_path / "clip")
    soft = next(iter(FrameSource(tmp_path / "clip"))).mask  # the masks as the source reads them
    matter = lambda rgb, name="image": soft  # noqa: E731  (the automatic matte: the same values as the masks)
    return tmp_path / "clip", matter, Relighter(RuntimeConfig(models=str(models_dir), device="cpu"))


def test_frames_source_says_which_masks_are_the_automatic_matte(clip):
    folder, matter, _ = clip
    assert not any(f.automatic for f in FrameSource(folder, matter=matter))  # STEM_mask files beside the frames
    assert all(f.automatic for f in FrameSource(folder, "auto", matter=matter))
    for f in folder.glob("*_mask.png"):
        f.unlink()
    assert all(f.automatic for f in FrameSource(folder, matter=matter))  # no mask: the matter's


def test_the_automatic_mattes_frames_keep_the_rim_given_masks_none(clip, monkeypatch):
    """Over the frame's own background a lamp from the side lightens the dark side's outline against the bright
    background with the automatic matte, and only on the outline; the same mask given relights as without the rule."""
    folder, matter, relighter = clip
    monkeypatch.setattr(compose, "FRAME_EDGE", False)  # the rim alone (the shown edge: test_video_edge.py)
    auto = _relit(FrameSource(folder, "auto", matter=matter), relighter)
    given = _relit(FrameSource(folder), relighter)
    monkeypatch.setattr(kr, "KEPT_SCATTER", 0.0)
    off = _relit(FrameSource(folder, "auto", matter=matter), relighter)
    mask = next(iter(FrameSource(folder))).mask
    inside = (mask >= 0.5).astype(np.uint8)
    deep = cv2.distanceTransform(np.pad(inside, 1), cv2.DIST_L2, 3)[1:-1, 1:-1] > 12
    for a, g, o in zip(auto, given, off, strict=True):
        np.testing.assert_array_equal(g, o)
        assert (a >= o - 1 / 255).all() and a.sum() > o.sum() + 1
        np.testing.assert_array_equal(a[deep], o[deep])
        np.testing.assert_array_equal(a[mask <= 0], o[mask <= 0])


def test_a_frames_decomposition_says_whether_its_matte_is_automatic(clip):
    folder, matter, relighter = clip
    frames = list(FrameSource(folder, "auto", matter=matter))
    engine = RelighterEngine(relighter)
    on, off = engine.decompose([f.image for f in frames[:2]], [f.mask for f in frames[:2]], [True, False])
    assert on.state.automatic and not off.state.automatic
    assert relighter.kept_rim(on.state) is not None and relighter.kept_rim(off.state) is None
    plain = engine.decompose([frames[0].image], [frames[0].mask])[0].state  # no word: a given mask
    assert not plain.automatic and relighter.kept_rim(plain) is None


def test_switched_off_a_frame_keeps_no_rim(clip, monkeypatch):
    """``compose.FRAME_RIM`` off (and the shown edge, ``FRAME_EDGE``, test_video_edge.py): the automatic matte's
    frames relight as given masks do."""
    folder, matter, relighter = clip
    monkeypatch.setattr(compose, "FRAME_RIM", False)
    monkeypatch.setattr(compose, "FRAME_EDGE", False)
    auto = _relit(FrameSource(folder, "auto", matter=matter), relighter)
    for a, g in zip(auto, _relit(FrameSource(folder), relighter), strict=True):
        np.testing.assert_array_equal(a, g)
