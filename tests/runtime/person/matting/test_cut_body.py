"""The body the photo's bottom border cuts (relight_rt.person.matting._cut_body, issue 48: a trouser leg and the bottom
of a top the pose graph missed down to the bottom border), on a synthetic photo with a stand-in selfie graph."""

from __future__ import annotations

import numpy as np
import pytest
from test_broad_set_rules import matted

from relight_rt.person import matting as M
from relight_rt.person.matting import _colours, _cut_body, _layout
from relight_rt.person.matting._detect import around_people, roi_prob
from relight_rt.person.matting._segmentation import canvas_points

WALL = 0.6  # the backdrop's grey
GAP = 0.61  # light between the legs: the wall's colour, which the stand-in graph sees as a person
GREY = 0.33  # the missed trouser leg: about as near the wall's grey as the other leg's dark one


class _NotWall:
    """A stand-in for the selfie graph: a person wherever the canvas is not the wall's grey (nor black padding), the
    light between the legs included."""

    def run(self, feeds):
        img = feeds["image"][0]
        seen = (np.abs(img - WALL).max(0) > 0.005) & (img.max(0) > 0.0)
        return {"segmentation": seen.astype(np.float32)[None, None]}


def standing(bottom: int, h: int = 300, w: int = 400) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """A blue top and two trouser legs (one dark, one grey) down to row ``bottom`` before a grey wall, light between
    the legs in the wall's colour, and a bench in the grey leg's colour beside the dark leg."""
    yy, xx = np.mgrid[0:h, 0:w] + 0.5
    parts = {
        "top": (np.abs(xx - 200) < 45) & (yy > 40) & (yy < 160),
        "leg1": (xx >= 160) & (xx < 190) & (yy >= 160) & (yy < bottom),
        "leg2": (xx >= 210) & (xx < 240) & (yy >= 160) & (yy < bottom),
        "gap": (xx >= 190) & (xx < 210) & (yy >= 190) & (yy < bottom),
        "bench": (xx >= 100) & (xx < 160) & (yy >= 230) & (yy < bottom),
        "crotch": (xx >= 190) & (xx < 210) & (yy >= 160) & (yy < 190),
    }
    rgb = np.full((h, w, 3), WALL, np.float32)
    rgb[parts["top"]] = (0.2, 0.3, 0.8)
    rgb[parts["leg1"]] = 0.08
    rgb[parts["leg2"] | parts["bench"]] = GREY
    rgb[parts["gap"]] = GAP
    rgb[parts["crotch"]] = 0.08
    return rgb, parts


@pytest.mark.parametrize(("bottom", "rule", "taken"), [(300, True, True), (300, False, False), (270, True, False)])
def test_what_the_selfie_graph_sees_under_a_person_cut_by_the_bottom_border_is_theirs(bottom, rule, taken, monkeypatch):
    """Cut by the bottom border (the legs run off the photo), the grey trouser leg the pose graph missed is the
    person's though its colour lies as near the wall's as the person's (the own colours' test refuses it); without the
    rule it is left out, and so it is when the legs end above the bottom (what lies under a person's feet is the own
    colours' to decide: ground, a shadow). Never taken: the bench beside the person in the leg's very colour (not
    under the matte)."""
    if not rule:
        monkeypatch.setattr(_cut_body, "CUT_UNDER", 2.0)  # no part can lie this much under the matte: the rule off
    rgb, parts = standing(bottom)
    matter = M.PersonMatter(refine=False)
    matter.roi, matter.face = _NotWall(), None
    found = matted(rgb, parts["top"] | parts["leg1"] | parts["crotch"])
    extra = matter._own_colours(rgb, [found])
    alpha = matter.alpha(rgb, [found, *extra])
    assert ((alpha[parts["leg2"]] >= 0.5).mean() > 0.9) == taken
    assert (alpha[parts["bench"]] >= 0.5).mean() < 0.1
    if taken:  # down to the border
        assert (alpha[bottom - 1, 212:238] >= 0.5).all()


def test_the_light_between_two_legs_cut_by_the_bottom_border_is_not_theirs():
    """Both legs matted, run off the photo: what the graph sees between them in the wall's colour stays out."""
    rgb, parts = standing(300)
    matter = M.PersonMatter(refine=False)
    matter.roi, matter.face = _NotWall(), None
    found = matted(rgb, parts["top"] | parts["leg1"] | parts["leg2"] | parts["crotch"])
    extra = matter._own_colours(rgb, [found])
    alpha = matter.alpha(rgb, [found, *extra])
    assert (alpha[parts["gap"]] >= 0.5).mean() < 0.1
    assert (alpha[parts["leg2"]] >= 0.5).mean() > 0.9


def test_the_own_colours_test_alone_refuses_the_grey_leg():
    """The case the rule is for: the own colours' per-pixel test (OWN_RATIO) leaves the grey leg out."""
    rgb, parts = standing(300)
    matter = M.PersonMatter(refine=False)
    matter.roi, matter.face = _NotWall(), None
    found = matted(rgb, parts["top"] | parts["leg1"] | parts["crotch"])
    region, seen, inside, mine = around_people(matter.roi, rgb, [found])
    prob = np.where(roi_prob(matter.roi, rgb, region) >= 0.5, seen, 0.0).astype(np.float32)
    canvas = M.crop_region(rgb, region)
    own = _colours.own_part(canvas, inside, mine, prob)
    cut = _cut_body.cut_part(canvas, inside, mine, prob)
    xs, ys = canvas_points(region)
    leg2 = parts["leg2"][np.clip(ys.astype(int), 0, 299), np.clip(xs.astype(int), 0, 399)] & inside
    assert own is None or (own & leg2).sum() < 0.1 * leg2.sum()
    assert cut is not None and (cut & leg2).sum() > 0.9 * leg2.sum()


def test_the_photos_bottom_rows_on_a_canvas():
    """The photo's last row and the JOIN_GAP rows above it, inside the photo; none where the photo goes on past the
    canvas."""
    inside = np.zeros((9, 4), bool)
    inside[1:7, 1:3] = True
    rows, cols = np.nonzero(_cut_body.photo_bottom(inside))
    assert set(rows) == set(range(7 - 1 - _layout.JOIN_GAP, 7)) and set(cols) == {1, 2}
    assert not _cut_body.photo_bottom(np.ones((6, 4), bool)).any()
