"""The body the photo's bottom border cuts (relight_rt.person.matting._cut_body, issue 48: a trouser leg and the bottom
of a top the pose graph missed down to the bottom border), on a synthetic photo with a stand-in selfie graph."""

from __future__ import annotations

import cv2
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


def run_own(rgb: np.ndarray, matte: np.ndarray | list[np.ndarray]) -> np.ndarray:
    """The default matte's alpha with the own colours' parts (and what the bottom border cuts) of the people matted
    as ``matte`` (one mask or several), the selfie graph a :class:`_NotWall`."""
    matter = M.PersonMatter(refine=False)
    matter.roi, matter.face = _NotWall(), None
    found = [matted(rgb, m) for m in (matte if isinstance(matte, list) else [matte])]
    return matter.alpha(rgb, [*found, *matter._own_colours(rgb, found)])


def inset(mask: np.ndarray, px: int) -> np.ndarray:
    """``mask`` eroded by ``px`` pixels (the pose graph's outline inside the selfie graph's), still running into the
    photo's bottom border where it did."""
    if not px:
        return mask
    out = cv2.erode(mask.astype(np.uint8), np.ones((2 * px + 1, 2 * px + 1), np.uint8)).astype(bool)
    out[-px - 1 :] |= mask[-px - 1 :]
    return out


@pytest.mark.parametrize(
    ("bottom", "rule", "px", "taken"),
    [(300, True, 0, True), (300, True, 1, True), (300, True, 2, True), (300, False, 0, False), (270, True, 0, False)],
)  # fmt: skip
def test_what_the_selfie_graph_sees_under_a_person_cut_by_the_bottom_border_is_theirs(
    bottom, rule, px, taken, monkeypatch
):
    """Cut by the bottom border (the legs run off the photo), the grey trouser leg the pose graph missed is the
    person's though its colour lies as near the wall's as the person's (the own colours' test refuses it); without the
    rule it is left out, and so it is when the legs end above the bottom (what lies under a person's feet is the own
    colours' to decide: ground, a shadow). Never taken: the bench beside the person in the leg's very colour (not
    under the matte), though the selfie graph's outline, a pixel or two outside a matte drawn ``px`` pixels inside
    it, joins the bench to the leg; nor the light between the legs in the wall's colour, joined to the grey leg."""
    if not rule:
        monkeypatch.setattr(_cut_body, "CUT_UNDER", 2.0)  # no part can lie this much under the matte: the rule off
    rgb, parts = standing(bottom)
    alpha = run_own(rgb, inset(parts["top"] | parts["leg1"] | parts["crotch"], px))
    assert ((alpha[parts["leg2"]] >= 0.5).mean() > 0.9) == taken
    assert (alpha[parts["bench"]] >= 0.5).mean() < 0.1
    middle = parts["gap"] & (np.abs(np.arange(400) - 200) < 7)  # the own colours' rim round the matted leg aside
    assert (alpha[middle] >= 0.5).mean() < 0.05
    if taken:  # down to the border
        assert (alpha[bottom - 1, 212:238] >= 0.5).all()


@pytest.mark.parametrize("scale", [0.5, 0.25])
def test_the_cut_leg_on_a_photo_smaller_than_the_canvas(scale):
    """The same scene at half and a quarter size, the canvas finer than the photo (1.6 and 3.2 canvas pixels a photo
    pixel: the selfie graph's outline, read on the canvas, lies a canvas pixel past the matte's and joins the bench to
    the leg): the grey leg is still taken, down to the border."""
    rgb, parts = standing(300)
    h, w = int(300 * scale), int(400 * scale)
    rgb = cv2.resize(rgb, (w, h), interpolation=cv2.INTER_NEAREST)
    parts = {k: cv2.resize(v.astype(np.uint8), (w, h), interpolation=cv2.INTER_NEAREST) > 0 for k, v in parts.items()}
    alpha = run_own(rgb, parts["top"] | parts["leg1"] | parts["crotch"])
    assert (alpha[parts["leg2"]] >= 0.5).mean() > 0.9
    assert (alpha[h - 1][parts["leg2"][h - 1]] >= 0.5).all()
    assert (alpha[parts["gap"] | parts["bench"]] >= 0.5).mean() < 0.1


class _FaintOnTheWhole(_NotWall):
    """The stand-in seeing the grey of the missed leg (and of the bench) at ``whole`` on the whole photo (letterboxed:
    black bars at the top) and at ``framed`` framed on the people (no bars): the real graph, shown a couple small on the
    whole photo, is unsure of the man's trousers at the bottom border that it is sure of framed on them."""

    def __init__(self, whole: float, framed: float):
        self.whole, self.framed = whole, framed

    def run(self, feeds):
        img = feeds["image"][0]
        seen = super().run(feeds)["segmentation"][0, 0]
        grey = np.abs(img - GREY).max(0) < 0.005
        seen = np.where(grey, self.whole if img[:, :4].max() == 0.0 else self.framed, seen)
        return {"segmentation": seen.astype(np.float32)[None, None]}


@pytest.mark.parametrize(("whole", "framed", "taken"), [(0.5, 0.95, True), (0.2, 0.8, True), (0.5, 0.6, False)])
def test_under_a_body_cut_by_the_bottom_border_the_graph_framed_on_the_people_alone_decides(whole, framed, taken):
    """The grey leg the selfie graph is sure of framed on the people (>= OWN_SURE) comes though the graph on the whole
    photo is unsure of it (before the rule both had to see it, the whole photo's >= OWN_SURE, and it stayed out), with
    its alpha from the framed answer, down to the border; sure of it on neither, it stays out. The bench in its colour
    (not under the matte) and the light between the legs stay out either way."""
    rgb, parts = standing(300)
    matter = M.PersonMatter(refine=False)
    matter.roi, matter.face = _FaintOnTheWhole(whole, framed), None
    found = [matted(rgb, parts["top"] | parts["leg1"] | parts["crotch"])]
    alpha = matter.alpha(rgb, [*found, *matter._own_colours(rgb, found)])
    assert ((alpha[parts["leg2"]] >= 0.5).mean() > 0.9) == taken
    if taken:
        assert (alpha[299, 212:238] >= 0.5).all()
    assert (alpha[parts["bench"]] >= 0.5).mean() < 0.1
    assert (alpha[parts["gap"] & (np.abs(np.arange(400) - 200) < 7)] >= 0.5).mean() < 0.05


@pytest.mark.parametrize("framed", [0.95, 0.5])
def test_under_the_feet_of_a_standing_person_the_framed_answer_alone_takes_nothing(framed):
    """Feet above the bottom border: the dark ground the graph framed on the person is sure of, the whole photo's not
    (0.2), stays out (the bottom border's step is for bodies it cuts; the own colours' asks the whole photo too)."""
    rgb, people, ground = feet_above_the_border(False)
    rgb[ground] = GREY
    matter = M.PersonMatter(refine=False)
    matter.roi, matter.face = _FaintOnTheWhole(0.2, framed), None
    found = [matted(rgb, m) for m in people]
    alpha = matter.alpha(rgb, [*found, *matter._own_colours(rgb, found)])
    assert (alpha[ground] >= 0.5).mean() < 0.1


def feet_above_the_border(other: bool) -> tuple[np.ndarray, list[np.ndarray], np.ndarray]:
    """A person standing before the wall, feet 20 px above the bottom border, on a dark ground the selfie graph sees
    as theirs down to the border (a shadow); with ``other``, someone else beside them, cut by the bottom border."""
    h, w = 300, 400
    yy, xx = np.mgrid[0:h, 0:w] + 0.5
    top = (np.abs(xx - 200) < 45) & (yy > 40) & (yy < 160)
    legs = (((xx >= 160) & (xx < 190)) | ((xx >= 210) & (xx < 240))) & (yy >= 160) & (yy < 280)
    crotch = (xx >= 190) & (xx < 210) & (yy >= 160) & (yy < 190)
    ground = (xx >= 158) & (xx < 242) & (yy >= 280)
    someone = (xx >= 320) & (xx < 380) & (yy >= 120)
    rgb = np.full((h, w, 3), WALL, np.float32)
    rgb[top] = (0.2, 0.3, 0.8)
    rgb[legs | crotch] = 0.08
    rgb[ground] = 0.25
    rgb[someone] = (0.8, 0.3, 0.2)
    return rgb, [top | legs | crotch] + ([someone] if other else []), ground


@pytest.mark.parametrize("other", [False, True])
def test_what_lies_under_the_feet_of_a_standing_person_stays_out(other):
    """The rule holds only under a matte that itself runs into the bottom border: under a standing person's feet the
    ground is the own colours' to decide (they refuse it), also where someone else beside them is cut by the border."""
    rgb, people, ground = feet_above_the_border(other)
    alpha = run_own(rgb, people)
    assert (alpha[ground] >= 0.5).mean() < 0.1
    if other:
        assert (alpha[people[1]] >= 0.5).mean() > 0.9


def test_the_light_between_two_legs_cut_by_the_bottom_border_is_not_theirs():
    """Both legs matted, run off the photo: what the graph sees between them in the wall's colour stays out."""
    rgb, parts = standing(300)
    alpha = run_own(rgb, parts["top"] | parts["leg1"] | parts["leg2"] | parts["crotch"])
    assert (alpha[parts["gap"]] >= 0.5).mean() < 0.1
    assert (alpha[parts["leg2"]] >= 0.5).mean() > 0.9


def test_the_own_colours_test_alone_refuses_the_grey_leg(monkeypatch):
    """The case the rule is for: the own colours' per-pixel test (OWN_RATIO) leaves the grey leg out. Where the matte
    does not reach the bottom border, both steps decide on one set of candidates and one colour model, made once."""
    rgb, parts = standing(300)
    roi = _NotWall()
    region, seen, inside, mine = around_people(roi, rgb, [matted(rgb, parts["top"] | parts["leg1"] | parts["crotch"])])
    bottom = _cut_body.photo_bottom(region, rgb.shape[:2])
    (cand, model), (below, below_model) = _colours.candidates(M.crop_region(rgb, region), inside, mine, seen,
                                                               roi_prob(roi, rgb, region), bottom)  # fmt: skip
    own = _colours.own_part(mine, cand, model)
    cut = _cut_body.cut_part(mine, below, below_model, bottom)
    xs, ys = canvas_points(region)
    leg2 = parts["leg2"][np.clip(ys.astype(int), 0, 299), np.clip(xs.astype(int), 0, 399)] & inside
    assert own is None or (own & leg2).sum() < 0.1 * leg2.sum()
    assert cut is not None and (cut & leg2).sum() > 0.9 * leg2.sum()
    made = []
    monkeypatch.setattr(_colours, "colour_model", lambda *a, **k: made.append(1) or model)
    matter = M.PersonMatter(refine=False)
    matter.roi, matter.face = roi, None
    rgb, people, _ = feet_above_the_border(False)
    matter._own_colours(rgb, [matted(rgb, people[0])])
    assert len(made) == 1


@pytest.mark.parametrize(
    ("cx", "cy", "rows", "cols"),
    [(-50.0, 172.0, range(253, 256), range(178, 256)), (200.0, 172.5, range(252, 255), range(256)),
     (200.0, 100.0, range(0), range(0))],
)  # fmt: skip
def test_the_photos_bottom_rows_on_a_canvas(cx, cy, rows, cols):
    """The photo's last row and the JOIN_GAP rows above it on a region's canvas (a 300 x 400 photo, a 256-pixel
    region: a canvas pixel a photo pixel), in the columns inside the photo: the canvas's own last row where the photo
    ends there too (row centres 44.5 .. 299.5), the row above where the canvas goes a row past the photo; none where
    the photo goes on past the canvas."""
    assert _layout.JOIN_GAP == 2
    r, c = np.nonzero(_cut_body.photo_bottom(M.Region(cx, cy, 256.0), (300, 400)))
    assert set(r) == set(rows) and set(c) == set(cols)
