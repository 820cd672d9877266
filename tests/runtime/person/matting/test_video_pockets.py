"""Issue 48 (video14): the default ``VideoMatter`` settles a gap between arm and body that the segmentation half-holds,
as the photo matte does (``matte_edges.open_pockets``): open where the frame shows the backdrop, opaque where it shows
the person. A stand-in matter answers fixed logits, so the test sees the video path alone."""

from __future__ import annotations

import numpy as np
import pytest

from relight_rt.person import matting as M

H, W = 700, 700
GAP_COLS = slice(240, 250)  # 10 px between the dress and the arm, about 3.7 canvas pixels of REGION
GAP_ROWS = slice(150, 400)
REGION = M.Region(350.0, 350.0, 700.0)  # the whole frame, 2.7 frame px a canvas pixel


def dress_and_arm(backdrop_in_gap: bool) -> np.ndarray:
    """A grey dress and a paler arm on a white backdrop, joined at the shoulder and the hand, 10 px apart in between:
    the backdrop shows there, or (``backdrop_in_gap`` False) the dress's own colour does."""
    rgb = np.ones((H, W, 3), np.float32)
    rgb[100:500, 150:240] = 0.3  # the dress
    rgb[150:400, 250:272] = 0.55  # the arm
    rgb[100:150, 240:272] = 0.3  # the shoulder ...
    rgb[400:430, 240:272] = 0.55  # ... and the hand on the hip
    if not backdrop_in_gap:
        rgb[GAP_ROWS, GAP_COLS] = 0.3
    return rgb


class _HalfSeenGap:
    """A stand-in for :class:`M.PersonMatter`: the person found in REGION, sure of the dress and the arm (logit +8),
    half-seeing the gap between them (logit +1: probability 0.73), as the graphs see the reference video's arms."""

    def __init__(self, gap_logit: float = 1.0):
        label = np.full((H, W, 3), -8.0, np.float32)
        label[100:500, 150:272] = 8.0
        label[GAP_ROWS, GAP_COLS] = gap_logit
        self.logits = M.crop_region(label, REGION)[..., 0].copy()

    def find_people(self, rgb):
        return [(1.0, (150.0, 100.0, 272.0, 500.0))]

    def segment(self, rgb, region):
        return M.Person(REGION, self.logits, 0.95)

    def vouched(self, rgb, person):
        return True


def video_alpha(rgb: np.ndarray, gap_logit: float = 1.0, **options) -> np.ndarray:
    return M.VideoMatter(_HalfSeenGap(gap_logit), smoothing=0.0, **options)(rgb)


def test_without_the_pocket_decision_the_gap_stays_half_held():
    """The stand-in's premise: the guided filter leaves the gap at 0.5-0.9 (relit part person, part backdrop)."""
    gap = video_alpha(dress_and_arm(True), pockets=False)[170:380, 243:247]
    assert 0.5 < np.median(gap) < 0.9


@pytest.mark.parametrize("backdrop", [True, False])
def test_the_default_video_matter_decides_a_half_held_gap_by_the_frames_colour(backdrop):
    """Default options: the backdrop-coloured gap opens (the backdrop is kept as it is, not relit as the person); a
    gap in the dress's colour is the person's, opaque. Before video14 the default left both at ~0.7."""
    alpha = video_alpha(dress_and_arm(backdrop))
    gap = alpha[170:380, 243:247]
    if backdrop:
        assert gap.max() < 0.5 and np.median(gap) < 0.1
    else:
        assert gap.min() >= 0.95
    assert alpha[200:350, 165:225].min() >= 0.95 and alpha[200:350, 257:265].min() >= 0.95  # dress and arm
    assert alpha[:, :110].max() < 0.05 and alpha[:, 320:].max() < 0.05  # the backdrop beside


def test_pockets_is_a_plain_switch():
    vm = M.VideoMatter(_HalfSeenGap())
    assert vm.pockets and not M.VideoMatter(_HalfSeenGap(), pockets=False).pockets


def test_a_frame_with_no_half_held_pocket_is_left_as_it_was():
    """The graphs sure of the gap's pixels (the dress's colour there): nothing is half-held inside the person, and the
    default alpha is the one without the decision, to the bit."""
    rgb = dress_and_arm(False)
    assert np.array_equal(video_alpha(rgb, gap_logit=8.0), video_alpha(rgb, gap_logit=8.0, pockets=False))
