"""The person seen turned (relight_rt.person.matting._turned, issue 48): limbs the upright graphs miss, found by the
selfie graph on the person's region turned a quarter each way, on a synthetic photo with a stand-in graph."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from test_matting import iou

from relight_rt.person import matting as M
from relight_rt.person.matting import _turned

GROUND, FENCE = 0.5, 0.85


class _Upright:
    """A stand-in for the selfie graph, made for upright people: it sees whatever is not the mid-grey ground (nor
    black padding), surely (1.0) where the thing is tall, half (0.6) where it is lying (a run of it shorter than 41
    canvas rows): a leg stretched out sideways is half-seen, turned a quarter it stands and is seen."""

    def run(self, feeds):
        img = feeds["image"][0]
        fg = ((np.abs(img - GROUND).max(0) > 0.05) & (img.max(0) > 0.0)).astype(np.uint8)
        tall = cv2.morphologyEx(fg, cv2.MORPH_OPEN, np.ones((41, 1), np.uint8))
        return {"segmentation": (0.6 * fg + 0.4 * tall).astype(np.float32)[None, None]}


class _Red:
    """A stand-in for the selfie graph that answers with the canvas's red channel."""

    def run(self, feeds):
        return {"segmentation": feeds["image"][:, :1].copy()}


def lying(h: int = 300, w: int = 400) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """A runner lying back on a wall: a blue shirt and black hips upright, one black leg stretched out to the left; on
    the right, a pale bar of backdrop between his arm and body (the colour of the fence posts around him)."""
    yy, xx = np.mgrid[0:h, 0:w] + 0.5
    parts = {
        "shirt": (xx > 180) & (xx < 260) & (yy > 40) & (yy < 150),
        "hips": (xx > 180) & (xx < 260) & (yy >= 150) & (yy < 190),
        "leg": (xx > 135) & (xx <= 180) & (yy > 168) & (yy < 186),
        "gap": (xx >= 260) & (xx < 320) & (yy > 70) & (yy < 88),
        "fence": ((np.abs(xx - 169) < 1.5) | (np.abs(xx - 271) < 1.5)) & (yy > 95) & (yy < 160),
    }
    rgb = np.full((h, w, 3), GROUND, np.float32)
    rgb[parts["shirt"]] = (0.2, 0.3, 0.8)
    rgb[parts["hips"] | parts["leg"]] = 0.03
    rgb[parts["gap"] | parts["fence"]] = FENCE
    return rgb, parts


def matted(mask: np.ndarray) -> M.Person:
    """The pose graph's segmentation of ``mask`` alone (a person found), on a region around it."""
    ys, xs = np.nonzero(mask)
    region = M.Region.around(float(xs.min()), float(ys.min()), float(xs.max() + 1), float(ys.max() + 1))
    canvas = M.crop_region(np.repeat(mask.astype(np.float32)[..., None], 3, 2), region)[..., 0]
    return M.Person(region, np.where(canvas > 0.5, 10.0, -10.0).astype(np.float32), 0.99)


def test_each_turned_view_is_turned_back():
    canvas = np.zeros((256, 256, 3), np.float32)
    canvas[20:60, 30:200, 0] = 1.0  # a bar along the top, off centre: any view left turned would move it
    canvas[100:110, 10:20, 0] = 0.5
    assert np.array_equal(_turned.turned_views(_Red(), canvas), canvas[..., 0])


@pytest.mark.parametrize(
    ("sure", "colour", "leg", "gap"),
    [(_turned.TURNED_SURE, _turned.TURNED_COLOUR, True, False),  # the rule: the leg, not the backdrop between
     (1.01, _turned.TURNED_COLOUR, False, False),  # no turned view sure enough: nothing (the matte as before)
     (_turned.TURNED_SURE, 1e9, True, True)],  # no colour test: the backdrop the turned views see comes too
)  # fmt: skip
def test_a_limb_seen_only_turned_is_the_persons_in_their_colours(sure, colour, leg, gap, monkeypatch):
    """The parkour clip's runner lying on the wall (frame 31): the pose graph misses his legs and the selfie graph
    half-sees them upright; turned a quarter either way it sees them. A part the turned views see in the backdrop's
    colours (the gap between an arm and the body, a car behind) stays out."""
    monkeypatch.setattr(_turned, "TURNED_SURE", sure)
    monkeypatch.setattr(_turned, "TURNED_COLOUR", colour)
    rgb, parts = lying()
    body = parts["shirt"] | parts["hips"]
    matter = M.PersonMatter(refine=False)
    matter.roi, matter.face = _Upright(), None
    found = matted(body)
    extra = _turned.turned_people(matter.roi, rgb, [found])
    assert all(p.source == "own" for p in extra)  # part of the person, no one's share of it
    alpha = matter.alpha(rgb, [found, *extra])
    assert ((alpha[parts["leg"]] >= 0.5).mean() > 0.9) == leg
    assert ((alpha[parts["gap"]] >= 0.5).mean() > 0.5) == gap
    assert (alpha[parts["fence"]] >= 0.5).mean() < 0.1  # thin posts: no part reaching past the matte
    assert iou(alpha, body) > 0.95 if not (leg or gap) else extra


def test_the_turned_views_add_nothing_where_the_upright_ones_see_nothing():
    """A part only a turned view sees (the upright selfie graph below UPRIGHT_SEEN there, on the region and on the whole
    photo) stays out: turned, the graph also takes sky and lawn for a body."""
    mine = np.zeros((256, 256), bool)
    mine[60:200, 100:160] = True
    turned = np.zeros((256, 256), np.float32)
    turned[60:200, 100:160] = 1.0
    turned[170:190, 20:100] = 1.0  # a leg to the left, seen surely turned
    canvas = np.full((256, 256, 3), GROUND, np.float32)
    canvas[mine] = 0.03
    canvas[170:190, 20:100] = 0.03  # in the person's colour
    inside = np.ones((256, 256), bool)
    for seen, added in ((0.4, False), (0.6, True)):
        upright = np.where(mine, 1.0, 0.0).astype(np.float32)
        upright[170:190, 20:100] = seen
        part = _turned.turned_part(canvas, inside, mine, upright, turned)
        assert (part is not None and part[175:185, 30:90].all()) == added


class _UprightBody:
    """A stand-in for the pose graph: segments the largest thing on the canvas that is tall (as _Upright sees it
    surely), and is sure a person is there."""

    def run(self, feeds):
        tall = _Upright().run(feeds)["segmentation"][0, 0] > 0.9
        n, labels, stats, _ = cv2.connectedComponentsWithStats(tall.astype(np.uint8), connectivity=8)
        body = labels == 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA])) if n > 1 else tall
        seg = np.where(body, 10.0, -10.0).astype(np.float32)
        return {"segmentation": seg[None, None], "presence": np.array([[0.99]], np.float32)}


@pytest.mark.parametrize("sure", [_turned.TURNED_SURE, 1.01])
def test_the_default_matte_takes_the_limb_seen_turned(sure, monkeypatch):
    """PersonMatter() asks the turned views after the other rules (people()): the lying leg is in the matte; with no
    turned view sure enough, it is not (the matte as before the rule)."""
    monkeypatch.setattr(_turned, "TURNED_SURE", sure)
    rgb, parts = lying()
    matter = M.PersonMatter(refine=False)
    matter.roi, matter.pose, matter.face = _Upright(), _UprightBody(), None
    alpha = matter(rgb)
    assert iou(alpha, parts["shirt"] | parts["hips"]) > 0.85
    assert ((alpha[parts["leg"]] >= 0.5).mean() > 0.9) == (sure <= 1.0)
    assert (alpha[parts["gap"]] >= 0.5).mean() < 0.1


@pytest.mark.parametrize("turned", [True, False])
def test_the_video_matters_completion_takes_a_limb_seen_only_turned(turned, monkeypatch):
    """``PersonMatter.completed`` (what ``VideoMatter(complete=True)`` adds to the person it follows) runs the turned
    views as the photo matte does (matte13): the parkour clip's frames 19 and 50, whose back leg only the turned
    views see, were 0.67 / 0.78 in video against 0.94 / 0.96 per frame. Without them the stretched leg is lost."""
    from relight_rt.person.matting import _completion

    if not turned:
        monkeypatch.setattr(_completion, "turned_people", lambda *args, **kw: [])
    rgb, parts = lying()
    body = parts["shirt"] | parts["hips"]
    matter = M.PersonMatter(refine=False)
    matter.roi, matter.face = _Upright(), None
    found = matted(body)
    alpha = matter.alpha(rgb, matter.completed(rgb, found))
    assert (alpha[body] >= 0.5).mean() > 0.95
    assert ((alpha[parts["leg"]] >= 0.5).mean() > 0.9) == turned
    assert (alpha[parts["gap"]] >= 0.5).mean() < 0.5
