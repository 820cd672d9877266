"""_selfie.carried_past: a portrait's shoulder past a side of its region that cuts it inside the photo is taken from
the whole photo's answer (people_masks p177-like: the region framed on the face stopped short of the shoulder at the
photo's bottom right corner, and the matte ended in the region's straight side)."""

from __future__ import annotations

import numpy as np
import pytest
from test_matting import iou

from relight_rt.person import matting as M
from relight_rt.person.face_detector import Face
from relight_rt.person.matting import _matter, _parts, _segmentation, _selfie

H, W = 300, 400
FACE_REGION = M.Region(170.0, 170.0, 300.0)  # x 20..320, y 20..320: cuts the shoulder at x 320, inside the photo


def portrait(xx: np.ndarray, yy: np.ndarray) -> np.ndarray:
    """A head on shoulders that run off the photo's bottom and right border."""
    head = ((xx - 170) / 60) ** 2 + ((yy - 110) / 80) ** 2 < 1
    return head | ((yy >= 190) & (xx >= 40) & (xx < W) & (yy < H))


def graph(whole: float, apart: float = 0.0, more=None, person=portrait):
    """A stand-in for the selfie graph (roi_prob): sure of ``person`` (1.0) on a region framed on them, ``whole`` sure
    of them on the whole photo's square, where it also sees a blob apart from them (a sign at the top right, past the
    region's side) at ``apart`` and, as sure as of them, what ``more`` (xs, ys -> bool) holds."""

    def prob(roi, rgb, region):
        xs, ys = _segmentation.canvas_points(region)
        inside = (xs >= 0) & (xs < W) & (ys >= 0) & (ys < H)
        on_photo = region.side >= W
        blob = (xs >= 350) & (ys >= 20) & (ys < 90) & inside
        out = np.where(person(xs, ys) & inside, whole if on_photo else 1.0, 0.0)
        out = np.where(blob & on_photo, apart, out)
        if more is not None:
            out = np.where(more(xs, ys) & inside & on_photo, whole, out)
        return out.astype(np.float32)

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
    xs, ys = np.meshgrid(np.arange(307.0, 314.0), np.arange(200.0, 290.0))  # past the seam, inside the region
    assert (_segmentation.prob_at(more[0], xs.ravel(), ys.ravel()) < 0.5).all()  # the region's own answer decides there


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


def test_nothing_past_a_side_that_does_not_cut_the_person_is_taken(monkeypatch):
    """The region's top does not cut the head (clear of it): what the whole photo's answer holds above it stays out,
    even joined to what goes on past the cut right side (a raised arm past the side, bent over the head)."""

    def arm(xs, ys):
        return ((xs >= 325) & (xs < 345) & (ys >= 5) & (ys < 200)) | ((xs >= 200) & (xs < 345) & (ys >= 5) & (ys < 15))

    monkeypatch.setattr(_selfie, "roi_prob", graph(0.9, more=arm))
    rgb = np.zeros((H, W, 3), np.float32)
    person = _selfie.roi_person(None, rgb, FACE_REGION, 0.9)
    more = _selfie.carried_past(None, rgb, person)
    xs, ys = np.meshgrid(np.arange(328.0, 342.0), np.arange(10.0, 180.0))  # the arm past the right side: taken
    assert len(more) == 1 and (_segmentation.prob_at(more[0], xs.ravel(), ys.ravel()) > 0.5).all()
    xs, ys = np.meshgrid(np.arange(210.0, 300.0), np.arange(7.0, 14.0))  # above the top, left of the right side
    assert (_segmentation.prob_at(more[0], xs.ravel(), ys.ravel()) < 0.5).all()


def passer_by(xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """Someone cut by the photo's right border whose body touches the portrait's shoulder (people_masks-like: a
    passer-by behind a shoulder), their head at x 355-405, y 28-92."""
    return (((xs - 380) / 25) ** 2 + ((ys - 60) / 32) ** 2 < 1) | ((ys >= 90) & (xs >= 345))


def short_portrait(xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """:func:`portrait` whose shoulder ends at x 345, past the region's side (x 320)."""
    return portrait(xs, ys) & (xs < 345)


THEIR_FACE = Face((357.0, 30.0, 400.0, 90.0), 0.9)
OWN_FACE = Face((125.0, 60.0, 215.0, 160.0), 0.9)


@pytest.mark.parametrize("faces", [[THEIR_FACE], [OWN_FACE, THEIR_FACE]])
def test_a_passer_by_joined_at_the_shoulder_is_never_taken(monkeypatch, faces):
    """The whole photo's answer holds a passer-by joined to the shoulder past the cut, sure (0.95): a part holding the
    middle of a face the person does not hold is someone else, left out whole (person="largest": others only whole,
    and only when seen whole, _company.peers); the person's own face is no reason to leave anything out."""
    monkeypatch.setattr(_selfie, "roi_prob", graph(0.95, more=passer_by, person=short_portrait))
    yy, xx = np.mgrid[0:H, 0:W] + 0.5
    rgb = np.zeros((H, W, 3), np.float32)
    person = _selfie.roi_person(None, rgb, FACE_REGION, 0.9)
    assert len(_selfie.carried_past(None, rgb, person)) == 1  # no face known: the passer-by comes in with it
    more = _selfie.carried_past(None, rgb, person, faces)
    alpha = M.PersonMatter(refine=False).alpha(rgb, [person, *more])
    assert more == [] and (alpha[passer_by(xx, yy) & ~short_portrait(xx, yy)] < 0.5).all()


def test_the_same_shoulder_without_a_passer_by_is_still_carried(monkeypatch):
    monkeypatch.setattr(_selfie, "roi_prob", graph(0.95, person=short_portrait))
    rgb = np.zeros((H, W, 3), np.float32)
    person = _selfie.roi_person(None, rgb, FACE_REGION, 0.9)
    more = _selfie.carried_past(None, rgb, person, [OWN_FACE, THEIR_FACE])  # a face where no one is: nothing held
    xs, ys = np.meshgrid(np.arange(325.0, 340.0), np.arange(200.0, 290.0))
    assert len(more) == 1 and (_segmentation.prob_at(more[0], xs.ravel(), ys.ravel()) > 0.5).all()


def test_a_face_box_with_nan_holds_nothing(monkeypatch):
    """A face box the detector could not place (NaN) is no one's face: the shoulder is carried as without it."""
    monkeypatch.setattr(_selfie, "roi_prob", graph(0.95, person=short_portrait))
    rgb = np.zeros((H, W, 3), np.float32)
    person = _selfie.roi_person(None, rgb, FACE_REGION, 0.9)
    nan = Face((float("nan"), 30.0, 400.0, float("nan")), 0.9)
    assert len(_selfie.carried_past(None, rgb, person, [nan])) == 1


@pytest.fixture
def matter_of(monkeypatch):
    """A PersonMatter whose people() starts from ``found`` (the region finder's answer) and whose other steps keep
    them as they are: what people() does with carried_past alone (``faces``: the face graph's boxes)."""

    def make(found: list, faces: list) -> M.PersonMatter:
        matter = M.PersonMatter(refine=False)
        monkeypatch.setattr(_matter, "largest", lambda matter_, rgb: (list(found), []))
        monkeypatch.setattr(matter, "find_faces", lambda rgb, every=False: list(faces))
        for name in ("peers", "joined", "own_and_turned"):
            monkeypatch.setattr(_matter, name, lambda *a: [])
        monkeypatch.setattr(_matter, "widened", lambda roi, rgb, p: p)
        monkeypatch.setattr(_matter, "uncut", lambda roi, rgb, p: (p, None))
        monkeypatch.setattr(_matter, "blended", lambda p, seen, side: p)
        monkeypatch.setattr(_matter, "seen_on", lambda roi, rgb, region: None)
        monkeypatch.setattr(_matter, "without_behind", lambda roi, rgb, people, faces: people)
        return matter

    return make


def test_people_carries_the_shoulder_on_with_the_faces_it_has(monkeypatch, matter_of):
    monkeypatch.setattr(_selfie, "roi_prob", graph(0.95, more=passer_by, person=short_portrait))
    rgb = np.zeros((H, W, 3), np.float32)
    person = _selfie.roi_person(None, rgb, FACE_REGION, 0.9)
    found = matter_of([person], []).people(rgb)
    assert [(p.source, p.of) for p in found] == [("roi", None), ("own", FACE_REGION)]  # no face: the part is added
    assert matter_of([person], [OWN_FACE, THEIR_FACE]).people(rgb) == [person]  # the passer-by's face: not theirs
    xs, ys = _segmentation.canvas_points(M.Region(380.0, 150.0, 300.0))  # found with them (a peer, whole): joined
    peer = M.Person(M.Region(380.0, 150.0, 300.0), np.where(passer_by(xs, ys), 8.0, -8.0).astype(np.float32), 0.9)
    found = matter_of([person, peer], [OWN_FACE, THEIR_FACE]).people(rgb)
    assert [(p.source, p.of) for p in found] == [("roi", None), ("pose", None), ("own", FACE_REGION)]


def test_a_split_segmentation_is_carried_on_once(monkeypatch, matter_of):
    """Two people side by side in one selfie-graph segmentation (split by their faces, Person.whole) whose bodies run
    on below the region's bottom as one blob: that blob is one part, not one per person."""

    def pair(xs, ys):
        heads = [((xs - cx) / 35) ** 2 + ((ys - 120) / 45) ** 2 < 1 for cx in (150, 250)]
        return heads[0] | heads[1] | ((ys > 170) & (xs > 100) & (xs < 300))

    monkeypatch.setattr(_selfie, "roi_prob", graph(0.9, person=pair))
    rgb = np.zeros((H, W, 3), np.float32)
    both = _selfie.roi_person(None, rgb, M.Region(200.0, 150.0, 250.0), 0.9)  # y 25..275: cut at the bottom
    faces = [Face((115.0, 75.0, 185.0, 165.0), 0.9), Face((215.0, 75.0, 285.0, 165.0), 0.9)]
    split = _parts.split_by_faces(both, faces)
    found = matter_of(split, faces).people(rgb)
    assert [p.source for p in found] == ["roi", "roi", "own"]
    yy, xx = np.mgrid[0:H, 0:W] + 0.5
    below = pair(xx, yy) & (yy > 280)
    assert (_segmentation.prob_at(found[2], xx[below], yy[below]) > 0.5).all()  # both bodies, in the one part


def test_the_carried_shoulder_is_its_persons_share(monkeypatch):
    """PersonMatter.parts: the shoulder carried past the region's side lies outside the person's region, where their
    own logits do not reach; it is theirs, not the share of someone beside whose region reaches it (their logits
    there merged into the person's, :func:`_selfie.owning`)."""
    w = 600
    yy, xx = np.mgrid[0:H, 0:w] + 0.5

    def long_portrait(xs, ys):  # the shoulder runs to x 400, past the region's side (x 320)
        return (((xs - 170) / 60) ** 2 + ((ys - 110) / 80) ** 2 < 1) | ((ys >= 190) & (xs >= 40) & (xs < 400))

    def peer(xs, ys):  # someone standing apart, whole (x 455-545)
        return ((xs - 500) / 45) ** 2 + ((ys - 150) / 130) ** 2 < 1

    def prob(roi, rgb, region):
        xs, ys = _segmentation.canvas_points(region)
        on_photo = region.side >= w
        seen = long_portrait(xs, ys) | (peer(xs, ys) & on_photo)
        return np.where(seen & (xs >= 0) & (xs < w) & (ys >= 0) & (ys < H), 0.9 if on_photo else 1.0, 0.0)

    monkeypatch.setattr(_selfie, "roi_prob", lambda roi, rgb, region: prob(roi, rgb, region).astype(np.float32))
    rgb = np.zeros((H, w, 3), np.float32)
    me = _selfie.roi_person(None, rgb, FACE_REGION, 0.9)
    more = _selfie.carried_past(None, rgb, me)
    xs, ys = _segmentation.canvas_points(M.Region(500.0, 150.0, 340.0))  # the peer's region reaches x 330
    other = M.Person(M.Region(500.0, 150.0, 340.0), np.where(peer(xs, ys), 8.0, -8.0).astype(np.float32), 0.95)
    matter = M.PersonMatter(refine=False)
    monkeypatch.setattr(matter, "people", lambda rgb, name="image": [me, *more, other])
    alpha, (mine, theirs) = matter.parts(rgb)
    shoulder = long_portrait(xx, yy) & (xx > 335) & (xx < 390) & (yy > 200) & (yy < H - 4)
    assert len(more) == 1 and (alpha[shoulder] >= 0.5).all()
    assert (mine[shoulder] >= 0.9 * alpha[shoulder]).all()  # before: all of it the peer's
    body = peer(xx, yy) & (alpha >= 0.5)
    assert body.sum() > 10000 and (theirs[body] >= 0.9 * alpha[body]).mean() > 0.99  # the peer keeps theirs
