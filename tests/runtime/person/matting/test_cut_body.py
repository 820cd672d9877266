"""The body the photo's bottom border cuts (relight_rt.person.matting._cut_body, issue 48: a trouser leg and the bottom
of a top the pose graph missed down to the bottom border), on a synthetic photo with a stand-in selfie graph."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from test_broad_set_rules import matted

from relight_rt.person import matting as M
from relight_rt.person.matting import _colours, _completion, _cut_body, _detect, _layout
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
    return matter.alpha(rgb, [*found, *_completion.own_colours(matter.roi, rgb, found)])


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


def graph_maps(monkeypatch, whole: np.ndarray, framed: np.ndarray) -> None:
    """The selfie graph as two maps over the photo, each (H, W) float read at the canvas pixels' centres: ``whole``
    its answer on the whole photo, ``framed`` on a region framed on the people (every other region)."""

    def answer(roi, rgb, region):
        h, w = rgb.shape[:2]
        xs, ys = canvas_points(region)
        prob = whole if region == M.Region(w / 2, h / 2, float(max(h, w))) else framed
        at = prob[np.clip(ys.astype(int), 0, h - 1), np.clip(xs.astype(int), 0, w - 1)]
        return np.where((xs >= 0) & (xs < w) & (ys >= 0) & (ys < h), at, 0.0).astype(np.float32)

    monkeypatch.setattr(_detect, "roi_prob", answer)
    monkeypatch.setattr(_completion, "roi_prob", answer)


def own_alpha(rgb: np.ndarray, matte: np.ndarray) -> np.ndarray:
    """:func:`run_own` with the selfie graph's answers as :func:`graph_maps` set them."""
    matter = M.PersonMatter(refine=False)
    matter.face = None
    found = [matted(rgb, matte)]
    return matter.alpha(rgb, [*found, *_completion.own_colours(matter.roi, rgb, found)])


FOLD = 0.3  # the lit creases of a dark trouser leg at the hip: a shade the person's matted parts lack


def framed_alone(leg: str, whole: float = 0.5, framed: float = 0.95) -> tuple[np.ndarray, dict, np.ndarray, np.ndarray]:
    """:func:`standing` with the second leg missed by the pose graph, seen at ``whole`` on the whole photo and at
    ``framed`` framed on the people: "dark", the first leg's dark with its top 40 rows (by the hip, near the matte)
    in :data:`FOLD`, or "grey" (no colour of the person's). The bench in its colour is seen by both (a candidate);
    the top, the first leg and the crotch are the matte. Returns (photo, parts, the whole photo's answer, the framed
    one's)."""
    rgb, parts = standing(300)
    if leg == "dark":
        rgb[parts["leg2"]] = 0.08
        rgb[parts["leg2"] & (np.arange(300)[:, None] < 200)] = FOLD
    seen = (parts["top"] | parts["leg1"] | parts["crotch"] | parts["bench"]).astype(np.float32)
    return rgb, parts, np.where(parts["leg2"], whole, seen), np.where(parts["leg2"], framed, seen)


@pytest.mark.parametrize(
    ("leg", "whole", "framed", "taken"),
    [("dark", 0.5, 0.95, True), ("dark", 0.2, 0.8, True), ("dark", 0.5, 0.6, False), ("grey", 0.5, 0.95, False)],
)  # fmt: skip
def test_under_a_body_cut_by_the_bottom_border_the_graph_framed_on_the_people_alone_decides(
    leg, whole, framed, taken, monkeypatch
):
    """The leg in the person's dark that the selfie graph is sure of framed on the people (>= OWN_SURE) comes though
    the graph on the whole photo is unsure of it (the own colours' step asks both), creases and all (their shade is
    no colour of the person's, nor the backdrop's: against a backdrop sampled with them in, they would be its), with
    its alpha from the framed answer, down to the border; sure of it on neither, it stays out. A grey leg the framed
    graph alone sees stays out: its colour is no colour of the person's, as a chair's would be (the grey leg both
    graphs see is taken: the first test). The bench (not under the matte) and the light between the legs stay out
    either way."""
    rgb, parts, seen, sure = framed_alone(leg, whole, framed)
    graph_maps(monkeypatch, seen, sure)
    alpha = own_alpha(rgb, parts["top"] | parts["leg1"] | parts["crotch"])
    assert ((alpha[parts["leg2"]] >= 0.5).mean() > 0.9) == taken
    if taken:
        assert (alpha[parts["leg2"] & (rgb[..., 0] == FOLD)] >= 0.5).mean() > 0.9  # the creases
        assert (alpha[299, 212:238] >= 0.5).all()
        assert abs(np.median(alpha[parts["leg2"]]) - framed) < 0.02  # (not the whole photo's)
    assert (alpha[parts["bench"]] >= 0.5).mean() < 0.1
    assert (alpha[parts["gap"] & (np.abs(np.arange(400) - 200) < 7)] >= 0.5).mean() < 0.05


CHAIR, DARK_WOOD, BEHIND = (0.45, 0.28, 0.12), (0.2, 0.12, 0.06), (0.7, 0.15, 0.15)


@pytest.mark.parametrize("colour", [CHAIR, DARK_WOOD, BEHIND])
def test_a_thing_only_the_framed_graph_sees_under_a_cut_body_stays_out(colour, monkeypatch):
    """Both legs matted and cut by the bottom border; between them a chair (brown, or dark wood nearer the trousers'
    dark than the wall) or someone behind in red, which the graph framed on the people is sure of (0.95) and the
    whole photo's is not (0.3): it stays out. The backdrop the part is judged against holds it, and its colour is
    none of the person's (a rule that sampled the backdrop without it took 99 % of the chair)."""
    rgb, parts = standing(300)
    rgb[parts["leg2"]] = 0.08
    rgb[parts["gap"]] = colour
    person = parts["top"] | parts["leg1"] | parts["leg2"] | parts["crotch"]
    seen = (person | parts["bench"]).astype(np.float32)
    graph_maps(monkeypatch, np.where(parts["gap"], 0.3, seen), np.where(parts["gap"], 0.95, seen))
    alpha = own_alpha(rgb, person)
    assert (alpha[parts["gap"]] >= 0.5).mean() < 0.05
    assert (alpha[person] >= 0.5).mean() > 0.95


@pytest.mark.parametrize("colour", [CHAIR, DARK_WOOD, BEHIND])
def test_a_thing_only_the_framed_graph_sees_beside_a_leg_it_alone_sees_stays_out(colour, monkeypatch):
    """The second leg in the trousers' dark with its lit creases (:func:`framed_alone`), which only the graph framed on
    the people is sure of, and in the gap between the legs, touching it, a chair (brown, dark wood) or someone behind
    in red that it is as sure of (0.95; the whole photo's 0.3): the leg is taken, creases and all, the chair is not.
    One part holds both; judged by its median, the leg's pixels decided for the chair, whose pixels were then tested
    against a backdrop drawn without it (99 % of the brown and the dark-wood chair taken), and someone behind took
    the leg down with them (0 % of it)."""
    rgb, parts, seen, sure = framed_alone("dark")
    rgb[parts["gap"]] = colour
    graph_maps(monkeypatch, np.where(parts["gap"], 0.3, seen), np.where(parts["gap"], 0.95, sure))
    alpha = own_alpha(rgb, parts["top"] | parts["leg1"] | parts["crotch"])
    assert (alpha[parts["leg2"]] >= 0.5).mean() > 0.9
    assert (alpha[parts["leg2"] & (rgb[..., 0] == FOLD)] >= 0.5).mean() > 0.9  # the creases
    assert (alpha[parts["gap"]] >= 0.5).mean() < 0.1  # (the matte's soft edge along the first leg aside)
    assert (alpha[parts["gap"] & (np.abs(np.arange(400) - 200) < 7)] >= 0.5).mean() == 0.0


def test_a_leg_the_framed_graph_alone_sees_is_kept_whole_where_no_backdrop_is_left_without_it(monkeypatch):
    """Where the backdrop's ring holds under 20 pixels once what the framed graph alone sees is taken out of it, the
    part is kept as judged: the leg with its creases, not a leg lost whole (its creases, tested against a backdrop
    that holds them, failed, and the rest of the leg was no longer joined to the matte: 0 % of it)."""
    rgb, parts, seen, sure = framed_alone("dark")
    graph_maps(monkeypatch, seen, sure)
    monkeypatch.setattr(_cut_body, "backdrop_less", lambda *args: None)
    alpha = own_alpha(rgb, parts["top"] | parts["leg1"] | parts["crotch"])
    assert (alpha[parts["leg2"]] >= 0.5).mean() > 0.9
    assert (alpha[parts["leg2"] & (rgb[..., 0] == FOLD)] >= 0.5).mean() > 0.9


def test_a_shade_of_the_persons_colour_is_near_it_another_hue_is_not():
    """:func:`_cut_body.shade_distances`: a colour in more or less light (linear RGB scaled) lies within a few a*b*
    units of it; against the person of :func:`standing` (black trousers, a blue top), the creases' grey is a shade of
    theirs, a chair, dark wood (its chroma: 16) and someone behind in red are not."""

    def lab(rgb):
        return cv2.cvtColor(np.array([rgb], np.float32), cv2.COLOR_RGB2Lab)[0]

    def linear(c):
        return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)

    def srgb(c):
        return np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)

    brown = np.array([0.35, 0.25, 0.18])
    lit = srgb(np.clip(linear(brown) * np.array([[0.5], [2.0], [3.0]]), 0, 1))  # the same cloth, half to 3x the light
    assert (_cut_body.shade_distances(lab(lit), lab([brown])) < 1.5).all()
    person = lab([[0.08, 0.08, 0.08], [0.2, 0.3, 0.8]])
    assert _cut_body.shade_distances(lab([[FOLD] * 3]), person)[0] < 0.1
    assert (_cut_body.shade_distances(lab([CHAIR, DARK_WOOD, BEHIND]), person) > _cut_body.CUT_SHADE).all()


def test_the_own_colours_part_is_kept_where_the_framed_graph_alone_sees_all_around(monkeypatch):
    """A body cut by the bottom border with an arm out to the side in the top's blue that the pose graph missed and
    both views see; the graph framed on the people is sure of the whole wall too (0.8), the whole photo's not (0.2).
    The arm is the own colours' (its model's backdrop ring holds the wall) and is taken; the wall stays out (the
    bottom border's step finds no part of it under the matte). A rule that made a model without the pixels the framed
    graph alone sees, found none left for it, and gave up on both, lost the arm."""
    rgb, parts = standing(300)
    rgb[parts["leg2"] | parts["gap"]] = 0.08
    rgb[parts["bench"]] = WALL
    yy, xx = np.mgrid[0:300, 0:400]
    arm = (xx >= 245) & (xx < 330) & (yy >= 60) & (yy < 85)
    rgb[arm] = (0.2, 0.3, 0.8)
    person = parts["top"] | parts["leg1"] | parts["leg2"] | parts["crotch"] | parts["gap"]
    both = (person | arm).astype(np.float32)
    graph_maps(monkeypatch, np.maximum(both, 0.2), np.maximum(both, 0.8))
    alpha = own_alpha(rgb, person)
    assert (alpha[arm] >= 0.5).mean() > 0.9
    assert (alpha[~(person | arm)] >= 0.5).mean() < 0.01


@pytest.mark.parametrize("other", [False, True])
def test_under_the_feet_of_a_standing_person_the_framed_answer_alone_takes_nothing(other, monkeypatch):
    """Feet above the bottom border on a ground of the trousers' very dark (a colour test cannot refuse it), which
    the graph framed on the people is sure of (0.95) and the whole photo's is not (0.2): it stays out, the bottom
    border's step being for bodies it cuts. With someone else beside them cut by the border (the step runs), what
    keeps it out is that it lies beside no piece of the matte that runs into the border."""
    rgb, people, ground = feet_above_the_border(other)
    rgb[ground] = 0.08
    seen = np.any(people, axis=0).astype(np.float32)
    graph_maps(monkeypatch, np.where(ground, 0.2, seen), np.where(ground, 0.95, seen))
    matter = M.PersonMatter(refine=False)
    matter.face = None
    found = [matted(rgb, m) for m in people]
    alpha = matter.alpha(rgb, [*found, *_completion.own_colours(matter.roi, rgb, found)])
    assert (alpha[ground] >= 0.5).mean() < 0.05
    assert (alpha[np.any(people, axis=0)] >= 0.5).mean() > 0.95


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


def test_the_own_colours_test_alone_refuses_the_grey_leg():
    """The case the rule is for: the own colours' per-pixel test (OWN_RATIO) leaves the grey leg out; the bottom
    border's step, on the same colour model, takes it."""
    rgb, parts = standing(300)
    roi = _NotWall()
    region, seen, inside, mine = around_people(roi, rgb, [matted(rgb, parts["top"] | parts["leg1"] | parts["crotch"])])
    framed = roi_prob(roi, rgb, region)
    cand = _colours.candidates(inside, mine, seen, framed)
    model = _colours.colour_model(M.crop_region(rgb, region), inside, mine, mine | cand)
    own = _colours.own_part(mine, cand, model)
    cut = _cut_body.cut_body(inside, mine, cand, framed, _cut_body.photo_bottom(region, rgb.shape[:2]))
    xs, ys = canvas_points(region)
    leg2 = parts["leg2"][np.clip(ys.astype(int), 0, 299), np.clip(xs.astype(int), 0, 399)] & inside
    assert own is None or (own & leg2).sum() < 0.1 * leg2.sum()
    assert cut is not None and (cut.part(model) & leg2).sum() > 0.9 * leg2.sum()


def test_a_candidate_of_the_own_colours_is_seen_by_both_views():
    """A pixel joined to the matte is an own colours' candidate where the whole photo's answer is >= OWN_SURE and the
    framed one's >= 0.5 (not the dark post the whole photo takes in under the feet: _colours' module docstring);
    under a matte that runs into the photo's bottom rows, the bottom border's step also looks at what the framed
    answer alone is sure of (>= OWN_SURE)."""
    mine = np.zeros((64, 64), bool)
    mine[6:62, 20:30] = mine[6:10, 20:45] = True  # a body and an arm over the strips, cut by the bottom rows
    inside, bottom = np.ones_like(mine), np.zeros_like(mine)
    bottom[-3:] = True
    seen, framed = np.zeros((64, 64), np.float32), np.zeros((64, 64), np.float32)
    for i, (s, f) in enumerate([(0.9, 0.6), (0.9, 0.3), (0.5, 0.9), (0.6, 0.6)]):  # both, whole, framed, neither
        seen[12 + 12 * i : 20 + 12 * i, 30:40], framed[12 + 12 * i : 20 + 12 * i, 30:40] = s, f
    seen[57:, 30:40], framed[57:, 30:40] = 0.5, 0.9  # (a part the bottom border's step keeps: it runs)
    cand = _colours.candidates(inside, mine, seen, framed)
    assert [bool(cand[16 + 12 * i, 35]) for i in range(4)] == [True, False, False, False]
    cut = _cut_body.cut_body(inside, mine, cand, framed, bottom)
    assert cut is not None and [bool(cut.below[16 + 12 * i, 35]) for i in range(4)] == [True, False, True, False]


@pytest.mark.parametrize(("scene", "runs"), [("feet", 2), ("bench", 0), ("chair", 2), ("folds", 3)])
def test_the_colours_are_looked_at_only_where_a_part_can_be_kept(scene, runs, monkeypatch):
    """The k-means runs (two a colour model: the person's, the backdrop's) of the own colours' step: one model where
    the own colours' candidates are enough for a part (the ground under the feet of a standing person); none where
    they are not and no part of what the framed graph alone sees lies where a body cut by the border goes on (a bench
    beside it); one where such a part is refused against it (a chair between the legs), and one backdrop more where
    a part holds up and its pixels are judged without what the framed graph alone sees (a leg with creases)."""
    count = []
    centres = _colours.centres
    monkeypatch.setattr(_colours, "centres", lambda *a, **k: count.append(1) or centres(*a, **k))
    matter = M.PersonMatter(refine=False)
    matter.face = None
    if scene == "feet":
        rgb, people, _ = feet_above_the_border(False)
        matter.roi, matte = _NotWall(), people[0]
    elif scene == "folds":
        rgb, parts, seen, sure = framed_alone("dark")
        graph_maps(monkeypatch, seen, sure)
        matte = parts["top"] | parts["leg1"] | parts["crotch"]
    else:
        rgb, parts = standing(300)
        thing = parts["bench"] if scene == "bench" else parts["gap"]
        matte = parts["top"] | parts["leg1"] | parts["leg2"] | parts["crotch"]
        if scene == "bench":
            matte = matte | parts["gap"]
        rgb[matte & ~parts["top"]] = 0.08
        rgb[thing] = CHAIR
        seen = inset(matte, 2)  # (the graph's outline inside the matte: no rim of candidates round it)
        graph_maps(monkeypatch, np.where(thing, 0.3, seen), np.where(thing, 0.95, seen))
    _completion.own_colours(matter.roi, rgb, [matted(rgb, matte)])
    assert len(count) == runs


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


def test_the_backdrop_ring_lies_inside_the_photo():
    """A person at the photo's left edge, a trouser leg in a dark a shade off the matted one's missed by the pose graph
    (both views see it): the own colours take it, the backdrop's ring round the matte reaching past the photo's edge
    into the canvas's black padding, which is no backdrop (counted as one, the leg lay as near it as the person's dark:
    1 % of it taken). The ring itself holds no pixel outside the photo."""
    h, w = 300, 400
    yy, xx = np.mgrid[0:h, 0:w] + 0.5
    top = (xx >= 4) & (xx < 96) & (yy > 40) & (yy < 160)
    leg1, leg2 = ((xx >= x) & (xx < x + 30) & (yy >= 160) & (yy < 280) for x in (10, 60))
    crotch = (xx >= 40) & (xx < 60) & (yy >= 160) & (yy < 190)
    rgb = np.full((h, w, 3), WALL, np.float32)
    rgb[top] = (0.2, 0.3, 0.8)
    rgb[leg1 | crotch] = 0.08
    rgb[leg2] = 0.13
    alpha = run_own(rgb, top | leg1 | crotch)
    assert (alpha[leg2] >= 0.5).mean() > 0.9
    assert (alpha[~(top | leg1 | leg2 | crotch)] >= 0.5).mean() < 0.01
    region, _, inside, mine = around_people(_NotWall(), rgb, [matted(rgb, top | leg1 | crotch)])
    ring = _colours.backdrop_ring(inside, mine, mine)
    assert region.cx - region.side / 2 < 0 and ring.any() and not (ring & ~inside).any()


@pytest.mark.parametrize("colour", [CHAIR, DARK_WOOD, BEHIND])
def test_a_chair_beside_a_leg_the_framed_graph_alone_sees_stays_out_where_no_backdrop_is_left(colour, monkeypatch):
    """As above, the chair (or someone behind) between the legs touching the second leg, where no backdrop is left
    without what the framed graph alone sees (the pixels it alone is sure of then read as the person's): the leg is
    taken, the chair stays out (it is no shade of the person's colours, so it may not be added)."""
    rgb, parts, seen, sure = framed_alone("dark")
    rgb[parts["gap"]] = colour
    graph_maps(monkeypatch, np.where(parts["gap"], 0.3, seen), np.where(parts["gap"], 0.95, sure))
    monkeypatch.setattr(_cut_body, "backdrop_less", lambda *args: None)
    alpha = own_alpha(rgb, parts["top"] | parts["leg1"] | parts["crotch"])
    assert (alpha[parts["leg2"]] >= 0.5).mean() > 0.9
    assert (alpha[parts["gap"] & (np.abs(np.arange(400) - 200) < 7)] >= 0.5).mean() == 0.0
