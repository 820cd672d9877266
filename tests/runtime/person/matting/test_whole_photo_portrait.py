"""A portrait the selfie graph segments framed on the whole photo (_selfie.confirmed, _layout.unconfirmed): what it
takes in unsure there, joined to the person, must be seen framed on the face too (people_masks p063: the pale rocks
left of a woman's shoulder, 0.6 on the whole photo's square, matted with her; framed on her face, left out)."""

from __future__ import annotations

import numpy as np
import pytest

from relight_rt.person import matting as M
from relight_rt.person.face_detector import Face
from relight_rt.person.matting import _layout, _segmentation, _selfie

H, W = 300, 400
FACE = Face((160.0, 40.0, 240.0, 120.0), 0.9)


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


def _framed(ground: float):
    """A stand-in for the selfie graph's answer on a region (roi_prob): the person, and the ground at ``ground``
    only where the region is the whole photo (it sees the background small there)."""

    def prob(roi, rgb, region):
        xs, ys = _segmentation.canvas_points(region)
        body, near = _shapes(xs, ys)
        whole = region.side >= max(H, W)
        return np.where(body, 0.99, np.where(near & whole, ground, 0.01)).astype(np.float32).reshape(256, 256)

    return prob


def _portrait(monkeypatch, ground: float, faces: list[Face]) -> M.Person:
    """PersonMatter.segment on a region reaching past the photo's bottom and wider than it: a portrait, framed on the
    whole photo's square (_layout.within_photo)."""
    monkeypatch.setattr(_selfie, "roi_prob", _framed(ground))
    yy, xx = np.mgrid[0:H, 0:W] + 0.5
    rgb = np.repeat(_shapes(xx, yy)[0][..., None], 3, 2).astype(np.float32)
    matter = M.PersonMatter(refine=False)
    matter.pose = _Pose()
    matter.find_faces = lambda image, every=False: list(faces)
    person = matter.segment(rgb, M.Region(200.0, 200.0, 500.0), passes=1)
    assert person.source == "roi" and person.region == M.Region(W / 2, H / 2, float(W))  # the whole photo's square
    return person


def _seen(person: M.Person) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    yy, xx = np.mgrid[0:H, 0:W] + 0.5
    body, ground = _shapes(xx, yy)
    return _segmentation.prob_at(person, xx, yy) > 0.5, body, ground


@pytest.mark.parametrize(("ground", "kept"), [(0.6, False), (0.9, True)])
def test_what_a_portrait_on_the_whole_photo_takes_in_unsure_must_be_seen_framed_on_the_face(ground, kept, monkeypatch):
    """Ground joined to the person that the graph framed on the whole photo sees at 0.6 and framed on the face's body
    not at all is dropped, whole; a part it is sure of (>= DOUBTED_PART: the lit star a man stands beside, 0.83, which
    the service's mask holds) stays. The person stays whole either way."""
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
    """The rule is for the whole photo's framing only: a region within it is the selfie graph's answer as it is."""
    monkeypatch.setattr(_selfie, "roi_prob", _framed(0.6))
    rgb = np.zeros((H, W, 3), np.float32)
    person = _selfie.roi_person(None, rgb, M.Region(200.0, 160.0, 300.0), 0.9)
    assert _selfie.confirmed(None, rgb, person, [FACE]) is person


def _canvas(mask: np.ndarray, sure: float = 0.99, rest: float = 0.01) -> M.Person:
    return M.Person(M.Region(128.0, 128.0, 256.0), _segmentation.as_logits(np.where(mask, sure, rest)), 0.9, "roi")


def test_an_outline_a_little_apart_stays_and_the_whole_person_is_never_dropped():
    """_layout.unconfirmed: where the two framings draw one outline within JOIN_GAP canvas pixels of each other, the
    photo decides at full resolution (nothing is cut there); where the other framing sees nobody at all (it lost the
    person), the first answer stays."""
    yy, xx = np.mgrid[0:256, 0:256] + 0.5
    disk = (xx - 128) ** 2 + (yy - 128) ** 2 < 60**2
    wider = np.where((xx - 128) ** 2 + (yy - 128) ** 2 < (60 + _layout.JOIN_GAP) ** 2, 0.7, 0.01)
    first = _canvas(disk, rest=0.01)
    first = M.Person(first.region, _segmentation.as_logits(np.where(disk, 0.99, wider)), 0.9, "roi")
    assert _layout.unconfirmed(first, _canvas(disk)) is first
    assert _layout.unconfirmed(first, _canvas(np.zeros_like(disk))) is first
    blob = (xx > 180) & (xx < 240) & (yy > 100) & (yy < 160)  # joined to the disk, unsure, unseen by the other
    first = M.Person(first.region, _segmentation.as_logits(np.where(disk, 0.99, np.where(blob, 0.6, 0.01))), 0.9, "roi")
    out = _layout.unconfirmed(first, _canvas(disk))
    assert (out.logits[disk] > 0).all() and (out.logits[blob & ~disk] <= 0).all()
