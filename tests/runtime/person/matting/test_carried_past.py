"""_selfie.carried_past: a portrait's shoulder past a side of its region that cuts it inside the photo is taken from
the whole photo's answer (people_masks p177-like: the region framed on the face stopped short of the shoulder at the
photo's bottom right corner, and the matte ended in the region's straight side)."""

from __future__ import annotations

import numpy as np
import pytest
from test_matting import iou

from relight_rt.person import matting as M
from relight_rt.person.matting import _segmentation, _selfie

H, W = 300, 400
FACE_REGION = M.Region(170.0, 170.0, 300.0)  # x 20..320, y 20..320: cuts the shoulder at x 320, inside the photo


def portrait(xx: np.ndarray, yy: np.ndarray) -> np.ndarray:
    """A head on shoulders that run off the photo's bottom and right border."""
    head = ((xx - 170) / 60) ** 2 + ((yy - 110) / 80) ** 2 < 1
    return head | ((yy >= 190) & (xx >= 40) & (xx < W) & (yy < H))


def graph(whole: float, apart: float = 0.0):
    """A stand-in for the selfie graph (roi_prob): sure of the person (1.0) on a region framed on them, ``whole`` sure
    of them on the whole photo's square, where it also sees a blob apart from them (a sign at the top right, past the
    region's side) at ``apart``."""

    def prob(roi, rgb, region):
        xs, ys = _segmentation.canvas_points(region)
        inside = (xs >= 0) & (xs < W) & (ys >= 0) & (ys < H)
        on_photo = region.side >= W
        blob = (xs >= 350) & (ys >= 20) & (ys < 90) & inside
        out = np.where(portrait(xs, ys) & inside, whole if on_photo else 1.0, 0.0)
        return np.where(blob & on_photo, apart, out).astype(np.float32)

    return prob


def matted(monkeypatch, whole: float, apart: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray, list]:
    """(the person's mask, the matte of the face's region alone, the matte with what carried_past adds, its parts)."""
    monkeypatch.setattr(_selfie, "roi_prob", graph(whole, apart))
    yy, xx = np.mgrid[0:H, 0:W] + 0.5
    body = portrait(xx, yy)
    rgb = np.repeat(body[..., None], 3, 2).astype(np.float32)
    matter = M.PersonMatter(edges=False)  # the guided filter, as the default matte; no selfie-graph runs of its own
    person = _selfie.roi_person(None, rgb, FACE_REGION, 0.9)
    assert M.person_box(person, (H, W))[2] == pytest.approx(320.0, abs=2.0)  # cut by the region's right side
    more = _selfie.carried_past(None, rgb, person)
    return body, matter.alpha(rgb, [person]), matter.alpha(rgb, [person, *more]), more


def test_the_shoulder_past_the_regions_cut_side_is_taken_from_the_whole_photos_answer(monkeypatch):
    body, alone, carried, more = matted(monkeypatch, whole=0.8)  # PAST_SURE <= 0.8 < SURE_PART: widened refuses it
    assert [p.source for p in more] == ["own"]  # part of the matte, no one's share of it
    shoulder = body.copy()
    shoulder[:, :330] = False
    assert (alone[shoulder] < 0.5).all()  # without it the matte ends in the region's straight side
    assert iou(alone, body) < 0.9
    assert (carried[shoulder] >= 0.5).mean() > 0.98 and iou(carried, body) > 0.97
    seam = body.copy()
    seam[:, :300] = False
    seam[:, 340:] = False
    seam[H - 4 :] = False  # (the guided filter's window at the photo's last rows)
    seam[:196] = False  # (the shoulder's own top edge)
    assert carried[seam].min() > 0.9  # the two alphas meet at the region's side without a seam


@pytest.mark.parametrize(("whole", "apart"), [(0.6, 0.0), (0.8, 0.95)])
def test_only_what_the_whole_photo_is_sure_of_and_goes_on_from_the_cut_is_taken(monkeypatch, whole, apart):
    """Under PAST_SURE (0.6) nothing past the cut is taken (a red wall's glow beside a man at 0.56, people_masks
    p064); a sure blob past the side that does not go on from the person is never taken (someone or something else)."""
    body, alone, carried, more = matted(monkeypatch, whole, apart)
    yy, xx = np.mgrid[0:H, 0:W] + 0.5
    blob = (xx >= 350) & (yy >= 20) & (yy < 90)
    assert (carried[blob] < 0.5).all()
    if whole < _selfie.PAST_SURE:
        assert more == [] and np.array_equal(carried, alone)
    else:
        assert iou(carried, body) > 0.97


def test_a_person_clear_of_their_regions_sides_adds_nothing(monkeypatch):
    monkeypatch.setattr(_selfie, "roi_prob", graph(0.8))
    rgb = np.zeros((H, W, 3), np.float32)
    person = _selfie.roi_person(None, rgb, M.Region(200.0, 150.0, 400.0), 0.9)  # the whole photo: no cut inside it
    assert _selfie.carried_past(None, rgb, person) == []
