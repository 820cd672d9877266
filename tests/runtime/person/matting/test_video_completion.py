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


@pytest.mark.parametrize("bad", [0.0, -0.1, 1.5, float("nan"), True, False, "0.05", "abc", [0.05]])
def test_complete_on_drop_refuses_a_share_outside_0_1(bad):
    """A number in (0, 1] or None; a bool or a string is refused with the same error (True was read as 1.0, "0.05"
    as 0.05, and "abc" raised a bare ValueError)."""
    with pytest.raises(RelightError, match=r"complete_on_drop: expected a share in \(0, 1\] or None, got"):
        M.VideoMatter(M.PersonMatter(refine=False), complete_on_drop=bad)


def _stubbed(pose, smoothing: float = 0.7, **options) -> M.VideoMatter:
    matter = M.PersonMatter(refine=False)
    matter.roi, matter.pose, matter.face = _Seen(), pose, None
    return M.VideoMatter(matter, refine=False, smoothing=smoothing, **options)


class _HalfSeesTheBag(_LosesLegs):
    """As :class:`_LosesLegs`, and it half-sees (probability 0.2) a dark grey bag beside the torso in every frame,
    which the selfie graph sees: only the completion adds it."""

    def run(self, feeds):
        out = super().run(feeds)
        grey = feeds["image"][0].mean(0)
        bag = (grey > 0.2) & (grey < 0.37)
        out["segmentation"][0, 0][bag] = np.log(0.2 / 0.8)
        return out


@pytest.mark.parametrize("smoothing", [0.7, 0.0])
def test_a_run_of_completions_ends_when_the_followed_matte_holds_again(smoothing):
    """The legs lost for frames 2-3 and seen again from frame 4: those two frames are completed, and the one after
    (compared with the last matte as completed, where the bag counts as dropped), and no other; the bag that only the
    completion adds leaves the matte again. Before, the rule compared the followed matte with the last frame's
    COMPLETED matte in every frame, so the bag, once carried, counted as dropped in every later frame: frames 2-9 were
    all completed and the bag faded in (alpha 0.22 -> 0.9)."""
    rgb, torso, legs = _runner()
    h, w = rgb.shape[:2]
    yy, xx = np.mgrid[0:h, 0:w] + 0.5
    bag = (xx > 245) & (xx < 275) & (yy > 110) & (yy < 180) & ~torso
    rgb[bag] = 0.3
    pose = _HalfSeesTheBag()
    vm = _stubbed(pose, smoothing)
    alphas, done = [], []
    for i in range(10):
        pose.lost = i in (2, 3)
        before = vm.completions
        alphas.append(vm(rgb))
        done.append(vm.completions > before)
    assert [i for i, d in enumerate(done) if d] == [2, 3, 4]
    assert all((a[legs] >= 0.5).mean() > 0.95 for a in alphas)
    bags = [float(a[bag].mean()) for a in alphas]
    assert max(bags[6:]) < 0.5 and bags[-1] < 0.3, bags


def test_a_change_of_exposure_does_not_hide_a_drop():
    """The legs (about 7 % of the matte) lost for good from frame 2 while the exposure swings by +-0.02 on the person
    every frame: the rule fires in every frame and the legs stay. Before, the flow's agreement read the change of
    exposure as the flow being lost (exp(-0.04 / 0.05) = 0.45 over the whole person): the dropped share 0.048 in
    frame 2 missed the rule and the legs left for good."""
    rgb, _, _ = _runner()
    yy = np.mgrid[0 : rgb.shape[0], 0 : rgb.shape[1]][0] + 0.5
    rgb[yy > 182] = 0.0  # short legs
    person = rgb.max(axis=2) > 0
    legs = person & (rgb.max(axis=2) < 0.6) & (yy > 174) & (yy < 180)
    pose = _LosesLegs()
    vm = _stubbed(pose)
    alphas, done = [], []
    for i in range(8):
        pose.lost = i >= 2
        before = vm.completions
        frame = rgb + np.float32(0.02 if i % 2 else -0.02) * person[..., None]
        alphas.append(vm(np.clip(frame, 0, 1).astype(np.float32)))
        done.append(vm.completions > before)
    assert done == [False, False] + [True] * 6
    assert all((a[legs] >= 0.5).mean() > 0.9 for a in alphas), [(a[legs] >= 0.5).mean() for a in alphas]


def _moving(step: int, n: int) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """The runner, textured so that the flow can lock on, moving ``step`` px a frame to the right; the legs' masks."""
    rgb, _, legs = _runner()
    texture = np.random.default_rng(1).normal(0.0, 0.05, rgb.shape[:2] + (1,)).astype(np.float32)
    rgb = np.clip(rgb + texture * (rgb > 0), 0, 1)
    shift = [step * t - 30 for t in range(n)]
    return [np.roll(rgb, s, axis=1) for s in shift], [np.roll(legs, s, axis=1) for s in shift]


@pytest.mark.parametrize("step", [2, 12])
def test_a_moving_runner_is_completed_only_where_the_legs_are_lost(step):
    """The runner moving 2 or 12 px a frame: never completed while the pose graph sees the legs; completed in every
    frame from the one where it loses them, and the legs kept (the flow carries the last matte onto where the legs
    are now; warped the wrong way or not at all, the moving outline reads as dropped or the drop is missed)."""
    frames, legs = _moving(step, 8)
    for lost_from, expected in ((99, [False] * 8), (4, [False] * 4 + [True] * 4)):
        pose = _LosesLegs()
        vm = _stubbed(pose, 0.0)
        done, alphas = [], []
        for i, frame in enumerate(frames):
            pose.lost = i >= lost_from
            before = vm.completions
            alphas.append(vm(frame))
            done.append(vm.completions > before)
        assert done == expected
        assert all((a[m] >= 0.5).mean() > 0.9 for a, m in zip(alphas, legs, strict=True))


def test_a_limb_moving_faster_than_the_flow_follows_is_no_drop():
    """An arm beside the torso that jumps to the torso's other side in one frame (seen by the pose graph throughout):
    where it was, the flow cannot explain the picture (agreement ~0), so what the matte no longer holds there is no
    drop and no frame is completed (read without the agreement, 15 % of the matte would count as dropped)."""
    rgb, _, _ = _runner()
    h, w = rgb.shape[:2]
    yy, xx = np.mgrid[0:h, 0:w] + 0.5
    left = (xx > 105) & (xx < 145) & (yy > 60) & (yy < 120)
    right = (xx > 255) & (xx < 295) & (yy > 60) & (yy < 120)
    vm = _stubbed(_LosesLegs())
    for i in range(6):
        frame = rgb.copy()
        frame[left if i < 3 else right] = 0.45
        alpha = vm(frame)
        assert (alpha[left if i < 3 else right] >= 0.5).mean() > 0.9
    assert vm.completions == 0


class _SeesTheBagIn(_LosesLegs):
    """As :class:`_LosesLegs`, and it sees a bag of grey ``level`` beside the torso (probability 0.8) in the frames of
    ``seen``, half-sees it (0.2) in the others."""

    def __init__(self, level: float, seen: set[int]):
        super().__init__()
        self.level, self.seen, self.frame = level, seen, 0

    def run(self, feeds):
        out = super().run(feeds)
        grey = feeds["image"][0].mean(0)
        p = 0.8 if self.frame in self.seen else 0.2
        out["segmentation"][0, 0][np.abs(grey - self.level) < 0.02] = np.log(p / (1 - p))
        return out


def _bag_video(level: float, seen: set[int], smoothing: float, n: int = 12) -> tuple[list[int], list[float]]:
    """A still runner with a bag of grey ``level`` (the selfie graph sees it over 0.2, not under), the pose graph
    sure of it in the frames of ``seen`` only: the frames completed and the bag's mean alpha in each."""
    rgb, torso, _ = _runner()
    h, w = rgb.shape[:2]
    yy, xx = np.mgrid[0:h, 0:w] + 0.5
    bag = (xx > 245) & (xx < 275) & (yy > 110) & (yy < 180) & ~torso
    rgb[bag] = level
    pose = _SeesTheBagIn(level, seen)
    vm = _stubbed(pose, smoothing)
    done, bags = [], []
    for i in range(n):
        pose.frame = i
        before = vm.completions
        bags.append(float(vm(rgb)[bag].mean()))
        if vm.completions > before:
            done.append(i)
    return done, bags


@pytest.mark.parametrize("smoothing", [0.7, 0.0])
def test_a_one_frame_spike_of_the_pose_graph_does_not_latch_the_rule(smoothing):
    """The pose graph sure of the half-seen bag in frame 3 alone: no frame is completed and the bag leaves the matte
    again as without the rule. Before, the history took the spike (the unsmoothed followed matte), frame 4 counted
    the bag as dropped and was completed, the completion (the selfie graph sees the bag) recorded it as found again,
    and every later frame dropped it again: frames 4-11 completed, the bag's alpha 0.22 -> 0.86 at smoothing 0.7."""
    done, bags = _bag_video(0.3, {3}, smoothing)
    assert done == []
    assert bags[-1] < 0.3 and max(bags[5:]) < 0.5, bags


def test_what_the_completion_does_not_see_leaves_the_history():
    """The pose graph sure of a bag the selfie graph does not see (too dark) in frames 0-1, then half-seeing it: the
    frame that drops it is completed, and the one after (compared with the last matte as completed), no other; the
    completion does not find the bag again, so it leaves the history (the history keeps only what the completion sees
    of it: min(completed, history)). Kept as it was (max(followed, history)), frames 2-11 were all completed."""
    done, bags = _bag_video(0.15, {0, 1}, 0.7)
    assert done == [2, 3]
    assert bags[-1] < 0.3, bags


@pytest.mark.parametrize("smoothing", [0.7, 0.0])
def test_a_run_of_completions_is_capped(smoothing):
    """The pose graph sure of the bag in frames 3-4 (held two frames in a row, as the legs of the first test are):
    the frame that drops it is completed, and the next ones while the completion finds it again, but only
    COMPLETED_RUN in a row; then what only the completions held leaves the history, one frame more compares with the
    last matte as completed, and the bag leaves the matte. Without the cap, every frame from 5 on was completed and the
    bag stayed (alpha 0.89)."""
    done, bags = _bag_video(0.3, {3, 4}, smoothing, n=_video.COMPLETED_RUN + 16)
    assert done == list(range(5, 5 + _video.COMPLETED_RUN + 1))
    assert bags[-1] < 0.3, bags


@pytest.mark.parametrize("smoothing", [0.7, 0.0])
def test_a_plain_frame_ends_a_run_and_the_next_run_counts_from_one(smoothing):
    """The pose graph sure of the bag in frames 3-4 and again in 8-9: frames 5-7 are completed (a run of three), 8 and
    9 are plain (the followed matte holds the bag), and the run from frame 10 counts from one again: COMPLETED_RUN
    frames and the one after, as a first run. A counter that a plain frame does not reset would cap the second run
    three frames early (frames 10-19)."""
    run = _video.COMPLETED_RUN
    done, bags = _bag_video(0.3, {3, 4, 8, 9}, smoothing, n=run + 20)
    assert done == [5, 6, 7] + list(range(10, 10 + run + 1))
    assert bags[-1] < 0.3, bags


@pytest.mark.parametrize("smoothing", [0.7, 0.0])
def test_a_one_frame_spike_on_the_second_frame_does_not_latch_the_rule(smoothing):
    """The pose graph sure of the half-seen bag in frame 1 alone (the first frame with a last frame, and no history
    yet): the bag does not enter the history, no frame is completed and the bag leaves the matte. A history that took
    frame 1's followed matte whole (there is no history to compare with yet) latched: frame 2 dropped the bag, its
    completion found it again, and so on."""
    done, bags = _bag_video(0.3, {1}, smoothing)
    assert done == []
    assert bags[-1] < 0.3 and max(bags[3:]) < 0.5, bags
