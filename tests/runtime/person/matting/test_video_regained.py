"""Issue 48 (video23): a frame whose followed matte drops part of the person leaves a box, and so a region for the next
frame, that has lost that part too; the next frame starts where the region finder sees the person whole (the parkour
clip's frame 19 took frame 18's region, built on a box without the legs, and the pose graph framed there lost a leg).
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from relight_rt.engine.errors import RelightError
from relight_rt.person import matting as M
from relight_rt.person.matting import _video


class _WholeLegs:
    """A stand-in for the pose graph: sure of the bright body (grey > 0.6); of the grey legs (0.2-0.6) sure only while
    the canvas shows them whole (cut by the canvas's edge they read as nobody's, as the real graph, framed on a body
    the crop cuts, loses the cut limb), and half-sure of them (0.2) while ``lost``."""

    def __init__(self):
        self.lost = False

    def run(self, feeds):
        grey = feeds["image"][0].mean(0)
        legs = (grey > 0.2) & (grey <= 0.6)
        cut = bool(legs[-2:].any() or legs[:2].any() or legs[:, :2].any() or legs[:, -2:].any())
        level = np.log(0.2 / 0.8) if self.lost else (-10.0 if cut else 10.0)
        seg = np.where(grey > 0.6, 10.0, np.where(legs, level, -10.0)).astype(np.float32)
        return {"segmentation": seg[None, None], "presence": np.array([[0.95]], np.float32)}


class _Seen:
    """A stand-in for the selfie graph: a person wherever the canvas is not black."""

    def run(self, feeds):
        return {"segmentation": (feeds["image"][0].mean(0) > 0.2).astype(np.float32)[None, None]}


def _frame(other: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(300, 640, 3) float32 on black: a runner (a bright torso over grey legs that reach 30 px below it) and, with
    ``other``, a taller bright figure apart on the right; the runner's torso and legs and the figure's masks."""
    h, w = 300, 640
    yy, xx = np.mgrid[0:h, 0:w] + 0.5
    torso = (((xx - 200) / 50) ** 2 + ((yy - 100) / 70) ** 2) < 1
    block = (np.abs(xx - 200) < 35) & (yy > 150) & (yy < 205)
    figure = (((xx - 530) / 60) ** 2 + ((yy - 150) / 120) ** 2) < 1
    rgb = np.zeros((h, w, 3), np.float32)
    rgb[block] = 0.4
    rgb[torso] = 1.0
    if other:
        rgb[figure] = 0.9
    return rgb, torso, block & ~torso & (yy > 174) & (yy < 200), figure


def _matted(complete: bool, other_from: int = 99, n: int = 6, **options) -> tuple[list[np.ndarray], M.VideoMatter]:
    """The alphas of a still runner whose legs the pose graph half-sees in frame 2 only (the frame after sees them
    again wherever they are framed whole), the taller figure beside from frame ``other_from``; and the VideoMatter."""
    matter = M.PersonMatter(refine=False)
    pose = _WholeLegs()
    matter.roi, matter.pose, matter.face = _Seen(), pose, None
    vm = M.VideoMatter(matter, refine=False, complete=complete, **options)
    alphas = []
    for i in range(n):
        pose.lost = i == 2
        alphas.append(vm(_frame(other=i >= other_from)[0]))
    return alphas, vm


@pytest.mark.parametrize("complete", [False, True])
def test_a_region_that_lost_the_legs_gets_them_back_in_the_next_frame(complete):
    """Frame 2's matte holds the legs only through the completion; its box, the torso's, gives a region that cuts
    them, where the pose graph sees none of them. The frame after starts from the region finder's view of the whole
    person: the pose graph sees the legs whole and no later frame is completed (by default). Before, the region
    stayed on the torso's and the legs left the matte from frame 4 on, in both modes (the completion cannot find
    what the canvas cuts)."""
    _, torso, legs, _ = _frame()
    alphas, vm = _matted(complete)
    assert all((a[torso] >= 0.5).mean() > 0.95 for a in alphas)
    assert all((a[legs] >= 0.5).mean() > 0.95 for a in alphas), [float((a[legs] >= 0.5).mean()) for a in alphas]
    if not complete:
        assert vm.completions == 1  # frame 2 alone


def test_without_the_rule_the_region_is_not_searched_again():
    """``complete_on_drop=None`` keeps the matter as it was before video16: no drop is read, the region built on
    frame 2's box is followed, and the legs the canvas cuts fade out of the matte (the history's weight holds half of
    them in frame 3) and are gone from frame 4 on."""
    _, _, legs, _ = _frame()
    alphas, vm = _matted(False, complete_on_drop=None)
    assert vm.completions == 0
    assert all((a[legs] >= 0.5).mean() > 0.95 for a in alphas[:2])
    assert all((a[legs] >= 0.5).mean() < 0.05 for a in alphas[4:])


@pytest.mark.parametrize("complete", [False, True])
def test_the_search_after_a_drop_keeps_to_the_person_followed(complete):
    """A taller figure apart from the runner enters in the frame where the legs are lost: the search in the next frame
    takes the region finder's blob that holds the runner's last box, not its largest (the figure's), so the runner
    stays matted, legs and all, and the figure is not."""
    _, torso, legs, figure = _frame()
    alphas, _ = _matted(complete, other_from=2)
    for a in alphas[3:]:
        assert (a[torso] >= 0.5).mean() > 0.95 and (a[legs] >= 0.5).mean() > 0.95
        assert (a[figure] >= 0.5).mean() < 0.05


def test_held_share():
    assert _video._held_share((0.0, 0.0, 10.0, 10.0), (5.0, 5.0, 15.0, 15.0)) == pytest.approx(0.25)
    assert _video._held_share((0.0, 0.0, 10.0, 10.0), (2.0, 2.0, 8.0, 8.0)) == pytest.approx(1.0)
    assert _video._held_share((0.0, 0.0, 10.0, 10.0), (20.0, 0.0, 30.0, 10.0)) == 0.0
    assert _video._held_share((0.0, 0.0, 10.0, 10.0), (5.0, 5.0, 5.0, 9.0)) == 0.0  # an empty box


class _Largest(_WholeLegs):
    """The pose stand-in above, segmenting only the largest figure in its canvas (as a single-person graph does), and
    reading the runner's legs as cut only where the canvas's bottom cuts them mid-width."""

    def run(self, feeds):
        grey = feeds["image"][0].mean(0)
        legs = (grey > 0.2) & (grey <= 0.6)
        n = grey.shape[1]
        cut = bool(legs[-2:, n // 4 : 3 * n // 4].any())
        level = np.log(0.2 / 0.8) if self.lost else (-10.0 if cut else 10.0)
        seg = np.where(grey > 0.6, 10.0, np.where(legs, level, -10.0)).astype(np.float32)
        count, label, stats, _ = cv2.connectedComponentsWithStats((grey > 0.2).astype(np.uint8), connectivity=8)
        if count > 1:
            seg[label != 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))] = -10.0
        return {"segmentation": seg[None, None], "presence": np.array([[0.95]], np.float32)}


def _close_by(rgb: np.ndarray, x: float = 345.0) -> tuple[np.ndarray, np.ndarray]:
    """``rgb`` with a taller bright figure centred at ``x``, ~35 px right of the runner's torso (within the gap the
    region finder merges boxes over, outside the runner's region); the frame and the figure's mask."""
    h, w = rgb.shape[:2]
    yy, xx = np.mgrid[0:h, 0:w] + 0.5
    figure = (((xx - x) / 60) ** 2 + ((yy - 150) / 120) ** 2) < 1
    rgb = rgb.copy()
    rgb[figure] = 0.9
    return rgb, figure


@pytest.mark.parametrize("complete", [False, True])
def test_the_search_after_a_drop_does_not_switch_to_someone_close_beside(complete):
    """A taller figure stands close to the runner from frame 1: the region finder merges the two into one blob, which
    holds all of the runner's last box, and the region around it is centred between them, where the pose graph takes
    the taller figure. That person does not hold the runner's last box, so the region followed is segmented instead:
    the runner stays matted and the figure never is (without the check on the person found, frames 4-5 matted the
    figure and dropped the runner)."""
    rgb0, torso, _, _ = _frame()
    matter = M.PersonMatter(refine=False)
    pose = _Largest()
    matter.roi, matter.pose, matter.face = _Seen(), pose, None
    blobs = matter.find_people(_close_by(rgb0)[0])
    assert len(blobs) == 1 and _video._held_share(blobs[0][1], (150.0, 30.0, 250.0, 170.0)) == 1.0  # the premise
    vm = M.VideoMatter(matter, refine=False, complete=complete)
    for i in range(6):
        pose.lost = i == 2
        rgb, figure = _close_by(rgb0)
        rgb = rgb if i >= 1 else rgb0
        alpha = vm(rgb)
        assert (alpha[torso] >= 0.5).mean() > 0.95, i
        assert (alpha[figure] >= 0.5).mean() < 0.05, i


class _Blobs:
    """A stand-in matter for :meth:`VideoMatter._regained`: the region finder's blobs; the levels it was asked for."""

    def __init__(self, blobs):
        self.blobs, self.levels = blobs, []

    def find_people(self, rgb, *, max_level=None):
        self.levels.append(max_level)
        return [(1.0, b) for b in self.blobs]


def test_the_search_after_a_drop_takes_no_blob_that_holds_under_half_the_box():
    """The region finder's blob is taken only where it holds at least _REGAINED of the last box (else the region
    followed is segmented, as before); the most held wins, not the largest; the finder runs on the whole frame alone."""
    rgb = np.zeros((300, 640, 3), np.float32)
    box = (100.0, 50.0, 200.0, 250.0)
    beside = (170.0, 40.0, 400.0, 280.0)  # holds 30 % of the box
    matter = _Blobs([beside])
    vm = M.VideoMatter(matter, refine=False)
    vm._box = box
    assert _video._held_share(beside, box) == pytest.approx(0.3)
    assert vm._regained(rgb) is None
    matter.blobs = [beside, (90.0, 45.0, 190.0, 255.0)]  # the second holds 90 %
    region = vm._regained(rgb)
    assert region is not None and region.cx == pytest.approx(140.0) and region.cy == pytest.approx(150.0)
    assert matter.levels == [1, 1]
    vm._box = None  # nobody followed: nothing to regain
    assert vm._regained(rgb) is None


class _Counting:
    """A selfie-graph stand-in that sees nobody, counting its runs."""

    def __init__(self):
        self.runs = 0

    def run(self, feeds):
        self.runs += 1
        return {"segmentation": np.zeros_like(feeds["image"][0, :1])[None]}


def test_find_people_max_level_keeps_to_the_whole_image():
    """Where the whole image shows nobody the finder goes on to its tiles (1 + 4 + 9 windows at 720p and more);
    ``max_level=1`` stops after the one whole-image run. A bad level is refused."""
    matter = M.PersonMatter(refine=False)
    matter.roi = _Counting()
    rgb = np.zeros((720, 1280, 3), np.float32)
    assert matter.find_people(rgb) == [] and matter.roi.runs > 1
    matter.roi.runs = 0
    assert matter.find_people(rgb, max_level=1) == [] and matter.roi.runs == 1
    for bad in (0, True, 1.0, "1"):
        with pytest.raises(RelightError, match="max_level"):
            matter.find_people(rgb, max_level=bad)
