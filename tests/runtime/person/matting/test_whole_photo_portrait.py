"""A portrait the selfie graph segments framed on the whole photo (_selfie.confirmed, _layout.unconfirmed): what it
takes in unsure there, joined to the person, must be seen framed on the face too (people_masks p063: the pale rocks
left of a woman's shoulder, 0.6 on the whole photo's square, matted with her; framed on her face, left out)."""

from __future__ import annotations

import numpy as np
import pytest

from relight_rt.person import matting as M
from relight_rt.person.face_detector import Face
from relight_rt.person.matting import _detect, _layout, _segmentation, _selfie

H, W = 300, 400
FACE = Face((160.0, 40.0, 240.0, 120.0), 0.9)
WHOLE = M.Region(200.0, 200.0, 500.0)  # a pose region reaching past the photo's bottom, wider than the photo
TIGHTER = M.Region(200.0, 200.0, 260.0)  # one within the photo: head to chest, cut at the bottom


def _shapes(xs: np.ndarray, ys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A head on shoulders running off the bottom of a H x W photo, and ground left of the shoulders touching them."""
    head = ((xs - 200) / 45) ** 2 + ((ys - 90) / 60) ** 2 < 1
    body = head | ((ys >= 150) & (ys < H) & (xs >= 100) & (xs < 310))
    ground = (ys >= 180) & (ys < H) & (xs >= 5) & (xs < 100)
    return body, ground


class _Pose:
    """A stand-in for the pose graph: sure of a person over the bright part of its canvas."""

    def run(self, feeds):
        seg = np.where(feeds["image"][0].mean(0) > 0.5, 10.0, -10.0).astype(np.float32)
        return {"segmentation": seg[None, None], "presence": np.array([[0.99]], np.float32)}


class _NoFaceGraph:
    """A stand-in for the face graph that finds no face, its runs noted in ``runs``."""

    def __init__(self, runs: list):
        self.runs = runs

    def run(self, feeds):
        self.runs.append(1)
        return {"boxes": np.zeros((1, 16, 48, 48), np.float32), "scores": np.full((1, 1, 48, 48), -80.0, np.float32)}


def _framed(ground: float, sees_ground=lambda region: region.side >= max(H, W)):
    """A stand-in for the selfie graph's answer on a region (roi_prob): the person, and the ground at ``ground`` on
    the regions ``sees_ground`` names (by default the whole photo's square: it sees the background small there)."""

    def prob(roi, rgb, region):
        xs, ys = _segmentation.canvas_points(region)
        body, near = _shapes(xs, ys)
        there = sees_ground(region)
        return np.where(body, 0.99, np.where(near & there, ground, 0.01)).astype(np.float32).reshape(256, 256)

    return prob


def _photo() -> np.ndarray:
    yy, xx = np.mgrid[0:H, 0:W] + 0.5
    return np.repeat(_shapes(xx, yy)[0][..., None], 3, 2).astype(np.float32)


def _matter(faces: list[Face] | None, calls: list) -> M.PersonMatter:
    """A person matter on the stand-ins. ``faces``: what its find_faces answers, each call noted in ``calls``;
    None: its own find_faces on a face graph that finds nobody (:class:`_NoFaceGraph`), each run noted."""
    matter = M.PersonMatter(refine=False)
    matter.pose = _Pose()
    if faces is None:
        matter.face = _NoFaceGraph(calls)
    else:
        matter.find_faces = lambda image, every=False: calls.append(1) or list(faces)
    return matter


def _portrait(monkeypatch, ground: float, faces: list[Face]) -> M.Person:
    """PersonMatter.segment on WHOLE: a portrait framed on the whole photo's square (_layout.within_photo)."""
    monkeypatch.setattr(_selfie, "roi_prob", _framed(ground))
    calls = []
    person = _matter(faces, calls).segment(_photo(), WHOLE, passes=1)
    assert person.source == "roi" and person.region == M.Region(W / 2, H / 2, float(W))  # the whole photo's square
    assert len(calls) == 1
    return person


def _seen(person: M.Person) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    yy, xx = np.mgrid[0:H, 0:W] + 0.5
    body, ground = _shapes(xx, yy)
    return _segmentation.prob_at(person, xx, yy) > 0.5, body, ground


@pytest.mark.parametrize(("ground", "kept"), [(0.6, False), (0.9, True)])
def test_what_a_portrait_on_the_whole_photo_takes_in_unsure_must_be_seen_framed_on_the_face(ground, kept, monkeypatch):
    """Ground joined to the person that the graph framed on the whole photo sees at 0.6 and framed on the face's body
    not at all is dropped, whole (its left end lies outside the face's framing: dropped with it); a part it is sure
    of (>= DOUBTED_PART: the lit star a man stands beside, 0.83, which the service's mask holds) stays. The person
    stays whole either way."""
    seen, body, near = _seen(_portrait(monkeypatch, ground, [FACE]))
    assert (seen & body).sum() >= 0.99 * body.sum()
    if kept:
        assert (seen & near).sum() >= 0.95 * near.sum()
    else:
        assert (seen & near).sum() <= 0.01 * near.sum()


def test_without_a_face_in_the_person_the_whole_photos_answer_stays(monkeypatch):
    """Nothing confirms or denies without a face inside the person (one beside them frames someone else)."""
    beside = Face((20.0, 20.0, 60.0, 60.0), 0.9)
    seen, _, near = _seen(_portrait(monkeypatch, 0.6, [beside]))
    assert (seen & near).sum() >= 0.95 * near.sum()


def test_a_portrait_framed_on_less_than_the_whole_photo_is_not_asked_again(monkeypatch):
    """The rule is for the whole photo's framing only: on a region within it the selfie graph's answer stays as it
    is, unsure ground and all, though the face's framing does not see that ground; the faces are not asked for."""
    face_region = M.Region.around(*FACE.body_box((H, W)))
    monkeypatch.setattr(_selfie, "roi_prob", _framed(0.6, lambda region: region != face_region))
    calls = []
    person = _matter([FACE], calls).segment(_photo(), TIGHTER, passes=1)
    assert person.source == "roi" and person.region.side < max(H, W)
    seen, _, near = _seen(person)
    inside = near & (np.mgrid[0:H, 0:W][1] + 0.5 >= TIGHTER.box()[0])  # the ground the region holds
    assert inside.any() and (seen & inside).sum() >= 0.95 * inside.sum()
    assert calls == []


@pytest.mark.parametrize(("region", "runs"), [(TIGHTER, 0), (WHOLE, 1)], ids=["tighter", "whole-photo"])
def test_the_face_graph_runs_for_a_portrait_only_on_the_whole_photos_framing(region, runs, monkeypatch):
    """A portrait framed tighter than the whole photo runs no face graph for the rule (VideoMatter's followed
    portrait frames: one run more each, about 10 ms at 720p, where the rule cannot act); on the whole photo, one
    (each way: faceflip44)."""
    monkeypatch.setattr(_selfie, "roi_prob", _framed(0.6))
    runs_seen = []
    person = _matter(None, runs_seen).segment(_photo(), region, passes=1)
    assert person.source == "roi" and (person.region.side >= max(H, W)) == (runs > 0)
    assert len(runs_seen) == runs * (2 if _detect.FACE_BOTH_WAYS else 1)  # (the whole photo: as it comes, mirrored)


_YY, _XX = np.mgrid[0:256, 0:256] + 0.5
_BODY = (_XX - 128) ** 2 + (_YY - 150) ** 2 < 70**2


def _canvas(mask: np.ndarray, sure: float = 0.99, rest: float = 0.01) -> M.Person:
    prob = np.where(mask, sure, rest).astype(np.float32)
    return M.Person(M.Region(128.0, 128.0, 256.0), _segmentation.as_logits(prob), 0.9, "roi")


def test_an_outline_a_little_apart_stays_and_an_unsure_part_the_other_does_not_see_goes():
    """_layout.unconfirmed: where the two framings draw one outline within JOIN_GAP canvas pixels of each other, the
    photo decides at full resolution (nothing is cut there); a part joined to the person that the other framing does
    not see and the first is unsure of goes, whole."""
    disk = (_XX - 128) ** 2 + (_YY - 128) ** 2 < 60**2
    ring = (_XX - 128) ** 2 + (_YY - 128) ** 2 < (60 + _layout.JOIN_GAP) ** 2
    first = _canvas(disk | ring, sure=0.7)
    first = M.Person(first.region, np.where(disk, _canvas(disk).logits, first.logits), 0.9, "roi")
    assert _layout.unconfirmed(first, _canvas(disk)) is first
    blob = (_XX > 180) & (_XX < 240) & (_YY > 100) & (_YY < 160)  # joined to the disk, unsure, unseen by the other
    first = _canvas(disk | blob, sure=0.6)
    first = M.Person(first.region, np.where(disk, _canvas(disk).logits, first.logits), 0.9, "roi")
    out = _layout.unconfirmed(first, _canvas(disk))
    assert (out.logits[disk] > 0).all() and (out.logits[blob & ~disk] <= 0).all()


@pytest.mark.parametrize(
    "other",
    [np.zeros_like(_BODY), (_XX - 128) ** 2 + (_YY - 110) ** 2 < 12**2],
    ids=["other-lost-the-person", "other-sees-only-the-face"],
)
def test_an_unsure_person_the_other_framing_loses_stays_whole(other):
    """Where what would go holds most of the first answer's person (LOST_SHARE), the other framing lost the person:
    an unsure body (0.75) stays whole, beside a sure part apart from it (a lit decoration at 0.95) too."""
    star = (_XX - 20) ** 2 + (_YY - 20) ** 2 < 8**2
    first = _canvas(_BODY, sure=0.75)
    first = M.Person(first.region, np.where(star, _canvas(star, sure=0.95).logits, first.logits), 0.9, "roi")
    assert _layout.unconfirmed(first, _canvas(other)) is first


def test_what_lies_outside_the_other_framings_region_is_unknown_and_stays():
    """A second person (0.78, smaller than the first: not LOST_SHARE of the answer) beside the first, wholly outside
    the other framing's region (framed on the first's face, it does not reach them), is not "unseen" there: they
    stay, and so does the first."""
    left = (_XX - 70) ** 2 + (_YY - 150) ** 2 < 40**2
    right = (_XX - 190) ** 2 + (_YY - 150) ** 2 < 30**2
    first = _canvas(left | right, sure=0.78)
    first = M.Person(first.region, np.where(left, _canvas(left, sure=0.95).logits, first.logits), 0.9, "roi")
    region = M.Region(70.0, 150.0, 128.0)  # on first's canvas: x 6..134; the right person from x 150 on
    xs, ys = _segmentation.canvas_points(region)
    second = _canvas((xs - 70) ** 2 + (ys - 150) ** 2 < 40**2)
    second = M.Person(region, second.logits, 0.9, "roi")
    out = _layout.unconfirmed(first, second)
    assert (out.logits[right] > 0).all() and (out.logits[left] > 0).all()
