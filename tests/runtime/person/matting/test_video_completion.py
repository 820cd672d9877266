"""Issue 48 (video16): the default ``VideoMatter`` completes a frame as a photo (``PersonMatter.completed``) where the
followed matte drops part of what the flow carries over from the last frame, and only there."""

from __future__ import annotations

import numpy as np
import pytest

from relight_rt import RelightError
from relight_rt.person import matting as M
from relight_rt.person.matting import _video


class _LosesLegs:
    """A stand-in for the pose graph: sure of the bright body (logit 10); sure of the grey legs too until ``lost`` is
    set, then it half-sees them (probability 0.2), as the real one loses the parkour runner's dark trousers for a
    frame or two."""

    def __init__(self):
        self.lost = False

    def run(self, feeds):
        grey = feeds["image"][0].mean(0)
        legs = np.log(0.2 / 0.8) if self.lost else 10.0
        seg = np.where(grey > 0.6, 10.0, np.where(grey > 0.2, legs, -10.0)).astype(np.float32)
        return {"segmentation": seg[None, None], "presence": np.array([[0.95]], np.float32)}


class _Seen:
    """A stand-in for the selfie graph: a person wherever the canvas is not black."""

    def run(self, feeds):
        return {"segmentation": (feeds["image"][0].mean(0) > 0.2).astype(np.float32)[None, None]}


def _runner() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A bright torso over grey legs on black, (300, 400, 3) float32; the torso's and the legs' masks."""
    h, w = 300, 400
    yy, xx = np.mgrid[0:h, 0:w] + 0.5
    torso = (((xx - 200) / 50) ** 2 + ((yy - 100) / 70) ** 2) < 1
    legs = (np.abs(xx - 200) < 35) & (yy > 172) & (yy < 200)
    rgb = np.zeros((h, w, 3), np.float32)
    rgb[(np.abs(xx - 200) < 35) & (yy > 150) & (yy < 205)] = 0.4  # within the region the torso alone gives
    rgb[torso] = 1.0
    return rgb, torso, legs


def _video_of(frames_seen: int, frames_lost: int, smoothing: float = 0.7, **options):
    """The alphas of a still picture of the runner, the legs seen for ``frames_seen`` frames and lost by the pose
    graph for ``frames_lost`` more, and the VideoMatter."""
    rgb, _, _ = _runner()
    matter = M.PersonMatter(refine=False)
    pose = _LosesLegs()
    matter.roi, matter.pose, matter.face = _Seen(), pose, None
    vm = M.VideoMatter(matter, refine=False, smoothing=smoothing, **options)
    alphas = []
    for i in range(frames_seen + frames_lost):
        pose.lost = i >= frames_seen
        alphas.append(vm(rgb))
    return alphas, vm


@pytest.mark.parametrize("smoothing", [0.7, 0.0])
def test_a_leg_the_followed_matte_drops_is_found_again_by_the_completion(smoothing):
    """The legs held in the last frames and dropped by the pose graph now are the person's by default (the frame is
    completed: the selfie graph sees what the pose graph half-sees); without the completion they fade out (the
    history's weight 0.7 keeps them two frames) or, unsmoothed, go at once."""
    _, torso, legs = _runner()
    alphas, vm = _video_of(2, 4, smoothing)
    never, _ = _video_of(2, 4, smoothing, complete_on_drop=None)
    for a, b in zip(alphas, never, strict=True):
        assert (a[torso] >= 0.5).mean() > 0.95 and (b[torso] >= 0.5).mean() > 0.95
    assert all((a[legs] >= 0.5).mean() > 0.95 for a in alphas)
    assert (never[-1][legs] >= 0.5).mean() < 0.05
    assert vm.completions == 4  # each frame that dropped them, none of the two that held them


def test_a_steady_matte_is_not_completed():
    """While the followed matte keeps what the last frame held, no frame is completed (no extra graph runs), and the
    mattes are those without the rule."""
    alphas, vm = _video_of(5, 0)
    never, _ = _video_of(5, 0, complete_on_drop=None)
    assert vm.completions == 0
    for a, b in zip(alphas, never, strict=True):
        assert np.array_equal(a, b)


def test_complete_completes_every_frame_and_none_without_the_rule():
    """``complete=True`` completes every frame (the first too, nothing dropped); ``complete_on_drop=None`` none."""
    _, vm = _video_of(3, 0, complete=True)
    assert vm.completions == 3
    _, vm = _video_of(2, 2, complete_on_drop=None)
    assert vm.completions == 0
    _, vm = _video_of(2, 2)
    assert vm.completions == 2
    vm.reset()
    assert vm.completions == 0


def test_dropped_share_counts_only_where_the_flow_explains_the_picture():
    carried = np.zeros((10, 10), np.float32)
    carried[:, :5] = 1.0  # 50 pixels held
    prob = carried.copy()
    prob[:, 4] = 0.0  # 10 of them dropped
    agree = np.ones((10, 10), np.float32)
    assert _video.dropped_share(prob, carried, agree) == pytest.approx(0.2)
    agree[:5] = 0.0  # half of the dropped pixels where the flow is lost
    assert _video.dropped_share(prob, carried, agree) == pytest.approx(0.1)
    assert _video.dropped_share(prob, np.zeros_like(carried), agree) == 0.0
    assert _video.dropped_share(carried, carried, agree) == 0.0


@pytest.mark.parametrize("bad", [0.0, -0.1, 1.5, float("nan")])
def test_complete_on_drop_refuses_a_share_outside_0_1(bad):
    with pytest.raises(RelightError, match=r"complete_on_drop: expected a share in \(0, 1\] or None, got"):
        M.VideoMatter(M.PersonMatter(refine=False), complete_on_drop=bad)
