"""Issue 48, the matte on photos nobody here chose (benchmarks/people_masks_eval.py): the rules it added, each on
a synthetic image with stand-in graphs (the figures they were measured by are in their docstrings)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from test_matting import iou
from test_people_found import _Bright, head_and_shoulders

from relight_rt import RelightError
from relight_rt.person import matting as M
from relight_rt.person.face_detector import Face
from relight_rt.person.matting import _candidate, _colours, _company, _completion, _layout, _segmentation, _selfie


class _Unsure:
    """A stand-in for the pose graph: segments the bright part of the canvas, but its presence flag says nobody
    (as the real one does for a runner in mid-air)."""

    def run(self, feeds):
        seg = np.where(feeds["image"][0].mean(0) > 0.5, 10.0, -10.0).astype(np.float32)
        return {"segmentation": seg[None, None], "presence": np.array([[0.01]], np.float32)}


class _Blind:
    """A stand-in for the selfie graph that sees nobody."""

    def run(self, feeds):
        return {"segmentation": np.zeros((1, 1, 256, 256), np.float32)}


class _Left:
    """A stand-in for the selfie graph that sees only the left half of what is bright."""

    def run(self, feeds):
        prob = feeds["image"][0].mean(0)
        prob[:, 128:] = 0.0
        return {"segmentation": prob[None, None]}


def crouching(h: int = 300, w: int = 400) -> np.ndarray:
    """A bright blob (a body curled up) on a dark photo."""
    yy, xx = np.mgrid[0:h, 0:w] + 0.5
    return ((((xx - 200) / 80) ** 2 + ((yy - 140) / 60) ** 2) < 1).astype(np.float32)


def test_the_selfie_graph_vouches_for_a_body_the_presence_flag_misses():
    """Where the pose graph's presence flag says nobody but the selfie graph segments the same shape on the same
    region, a person is there: the parkour clip's runner in mid-air (10 frames of 100 were empty mattes)."""
    body = crouching()
    rgb = np.repeat(body[..., None], 3, 2)
    matter = M.PersonMatter(refine=False)
    matter.roi, matter.pose, matter.face = _Bright(), _Unsure(), None
    person = matter.segment(rgb, M.Region.around(120.0, 80.0, 280.0, 200.0))
    assert person.presence < _candidate.PRESENCE_MIN
    assert matter.vouched(rgb, person)
    assert iou(matter(rgb), body) > 0.95  # was "no person found"
    matter.roi = _Left()  # the selfie graph sees another shape there: no one vouches
    assert not matter.vouched(rgb, person)
    matter.roi = _Blind()
    assert not matter.vouched(rgb, person)
    with pytest.raises(RelightError, match="no person found"):
        matter(rgb)


def test_the_video_matter_keeps_a_body_the_selfie_graph_vouches_for():
    body = crouching()
    rgb = np.repeat(body[..., None], 3, 2)
    matter = M.PersonMatter(refine=False)
    matter.roi, matter.pose, matter.face = _Bright(), _Unsure(), None
    video = M.VideoMatter(matter, refine=False)
    for _ in range(2):  # found, then followed
        assert iou(video(rgb), body) > 0.95


class _AnyColour:
    """A stand-in for the selfie graph: person probability = the canvas's brightest channel."""

    def run(self, feeds):
        return {"segmentation": feeds["image"][0].max(0)[None, None]}


class _HeadOnly:
    """A stand-in for the pose graph: sure of a person, but it segments only the red part of the canvas (the
    head: it loses a close portrait's shoulders, as the real one does before an orange wall)."""

    def run(self, feeds):
        image = feeds["image"][0]
        seg = np.where((image[0] > 0.5) & (image[1] < 0.5), 10.0, -10.0).astype(np.float32)
        return {"segmentation": seg[None, None], "presence": np.array([[0.9]], np.float32)}


def red_headed_portrait() -> tuple[np.ndarray, np.ndarray]:
    person = head_and_shoulders()
    rgb = np.repeat(person[..., None], 3, 2)
    head = (person > 0) & (np.arange(person.shape[0])[:, None] < 260)
    rgb[head, 1:] = 0.0  # a red head and collar on a white chest
    return rgb, person


@pytest.mark.parametrize(("face_width", "portrait"), [(140.0, True), (30.0, False)])
def test_a_portrait_whose_pose_region_stops_above_the_bottom_is_checked(face_width, portrait):
    """The pose graph sees only the head and collar; its region, framed on them, stops above the bottom. With a
    face half the head's width inside, the selfie graph on a region reaching the bottom gives the chest too (a portrait
    before an orange wall: IoU 0.46 -> 0.98); a face a tenth of the person's width (a body crouching at the
    bottom of the frame) keeps the pose graph's answer."""
    rgb, person = red_headed_portrait()
    matter = M.PersonMatter(refine=False)
    matter.roi, matter.pose = _AnyColour(), _HeadOnly()
    cx = 150.0
    matter.find_faces = lambda rgb, every=False: [Face((cx - face_width / 2, 60.0, cx + face_width / 2, 160.0), 0.9)]
    found = matter.segment(rgb, M.Region.around(20.0, 10.0, 280.0, 260.0))
    alpha = matter.alpha(rgb, [found])
    if portrait:
        assert found.source == "roi"
        assert iou(alpha, person) > 0.95
    else:
        assert found.source == "pose"
        assert (alpha[270:] >= 0.5).sum() == 0  # the chest stays out: no portrait
    matter.find_faces = lambda rgb, every=False: []
    assert matter.segment(rgb, M.Region.around(20.0, 10.0, 280.0, 260.0)).source == "pose"  # no face: no check


def test_a_portrait_region_is_looked_for_only_near_the_bottom():
    rgb, _ = red_headed_portrait()
    matter = M.PersonMatter(refine=False)
    matter.find_faces = lambda rgb, every=False: [Face((80.0, 60.0, 220.0, 160.0), 0.9)]
    person = M.Person(M.Region(150.0, 140.0, 240.0), np.full((256, 256), 10.0, np.float32), 0.9)
    region = _candidate.portrait_region(rgb, person, matter.find_faces)  # ends at row 260 of 360: near the bottom
    assert region is not None and region.box()[3] >= 360
    high = M.Person(M.Region(150.0, 60.0, 100.0), np.full((256, 256), 10.0, np.float32), 0.9)  # ends at row 110
    assert _candidate.portrait_region(rgb, high, matter.find_faces) is None


@pytest.mark.parametrize("anywhere", [True, False])
def test_a_portrait_whose_pose_person_ends_high_is_checked_last(monkeypatch, anywhere):
    """The pose graph sees only the top of the head, its person ending over a third of the height above the bottom
    (on one photo's mirror image: 0.33, the chest cut off); the portrait check is asked last wherever the person
    ends when it holds a large face (gate44: PORTRAIT_ANYWHERE), and the selfie graph gives the chest too."""
    monkeypatch.setattr(_candidate, "PORTRAIT_ANYWHERE", anywhere)
    person = head_and_shoulders()
    rgb = np.repeat(person[..., None], 3, 2)
    top = (person > 0) & (np.arange(person.shape[0])[:, None] < 200)
    rgb[top, 1:] = 0.0  # red down to row 200 of 360: the pose graph's person ends 0.44 of the height up
    matter = M.PersonMatter(refine=False)
    matter.roi, matter.pose = _AnyColour(), _HeadOnly()
    matter.find_faces = lambda rgb, every=False: [Face((80.0, 60.0, 220.0, 160.0), 0.9)]
    found = matter.segment(rgb, M.Region.around(20.0, 10.0, 280.0, 200.0))
    alpha = matter.alpha(rgb, [found])
    if anywhere:
        assert found.source == "roi"
        assert iou(alpha, person) > 0.95
    else:  # the bar near the bottom alone: no check, the chest left out
        assert found.source == "pose"
        assert (alpha[250:] >= 0.5).sum() == 0
    matter.find_faces = lambda rgb, every=False: [Face((140.0, 60.0, 160.0, 80.0), 0.9)]  # a small face: no check
    assert matter.segment(rgb, M.Region.around(20.0, 10.0, 280.0, 200.0)).source == "pose"


class _Nobody:
    """A stand-in for the pose graph that sees nobody."""

    def run(self, feeds):
        return {"segmentation": np.full((1, 1, 256, 256), -10.0, np.float32),
                "presence": np.array([[0.0]], np.float32)}  # fmt: skip


@pytest.mark.parametrize(("score", "sure", "kept"), [(0.7, 0.0, True), (0.7, 0.8, False), (0.9, 0.8, True)])
def test_a_face_with_no_body_under_it_needs_a_sure_score_when_asked(score, sure, kept):
    """person="all" asks a face beside someone found already for a sure score where the pose graph sees no body
    under it (faces found in a red bench and a treadmill's console scored 0.66-0.73); the first face of a photo
    (a close portrait, 0.71) is taken as before."""
    body = crouching()
    rgb = np.repeat(body[..., None], 3, 2)
    matter = M.PersonMatter(refine=False)
    matter.roi, matter.pose, matter.face = _Bright(), _Nobody(), None
    face = Face((170.0, 100.0, 230.0, 160.0), score)
    p = _candidate.person_at(matter, rgb, face.body_box(rgb.shape[:2]), face, sure_face=sure)
    assert (p is not None) == kept


class _DimLegs:
    """A stand-in for the pose graph: sure of the bright body (logit 10), half-sees the grey legs (probability
    0.2), as the real one half-sees dark trousers."""

    def run(self, feeds):
        grey = feeds["image"][0].mean(0)
        seg = np.where(grey > 0.6, 10.0, np.where(grey > 0.2, np.log(0.2 / 0.8), -10.0)).astype(np.float32)
        return {"segmentation": seg[None, None], "presence": np.array([[0.95]], np.float32)}


class _Seen:
    """A stand-in for the selfie graph: a person wherever the canvas is not black."""

    def run(self, feeds):
        return {"segmentation": (feeds["image"][0].mean(0) > 0.2).astype(np.float32)[None, None]}


@pytest.mark.parametrize(("selfie", "legs"), [(_Seen, True), (_Blind, False)])
def test_what_the_pose_graph_half_sees_is_the_persons_where_the_selfie_graph_agrees(selfie, legs):
    h, w = 300, 400
    yy, xx = np.mgrid[0:h, 0:w] + 0.5
    torso = (((xx - 200) / 50) ** 2 + ((yy - 100) / 70) ** 2) < 1
    trousers = (np.abs(xx - 200) < 35) & (yy > 150) & (yy < 260)
    rgb = np.zeros((h, w, 3), np.float32)
    rgb[trousers] = 0.4
    rgb[torso] = 1.0
    matter = M.PersonMatter(refine=False)
    matter.roi, matter.pose, matter.face = selfie(), _DimLegs(), None
    seen = matter.segment(rgb, M.Region.around(150.0, 30.0, 250.0, 260.0), passes=1)
    person = _completion.backed(matter.roi, rgb, seen)
    alpha = matter.alpha(rgb, [person])
    assert (alpha[torso] >= 0.5).mean() > 0.95
    below = trousers & (yy > 175)
    assert ((alpha[below] >= 0.5).mean() > 0.9) == legs


class _HalfSeen:
    """A stand-in for the pose graph: sure it sees a person (presence 0.95), but only half-sees the whole body
    (probability 0.3 over it), as the real one half-sees an embracing couple's shirts and faces."""

    def run(self, feeds):
        seg = np.where(feeds["image"][0].mean(0) > 0.5, np.log(0.3 / 0.7), -10.0).astype(np.float32)
        return {"segmentation": seg[None, None], "presence": np.array([[0.95]], np.float32)}


def test_a_body_both_graphs_see_is_opaque_inside_and_soft_only_at_its_outline():
    """What the pose graph half-sees and the selfie graph sees is the person's (_backed): sure inside
    (_layout.BACKED_INSIDE), soft only within BACKED_DEPTH canvas pixels of the outline. At the outline's logit
    everywhere, the body stayed translucent inside (alpha 0.73: relit, the old photo showed through)."""
    body = crouching()
    rgb = np.repeat(body[..., None], 3, 2)
    matter = M.PersonMatter(refine=False)
    matter.roi, matter.pose, matter.face = _Seen(), _HalfSeen(), None
    seen = matter.segment(rgb, M.Region.around(120.0, 80.0, 280.0, 200.0), passes=1)
    person = _completion.backed(matter.roi, rgb, seen)
    alpha = matter.alpha(rgb, [person])
    yy, xx = np.mgrid[0:300, 0:400] + 0.5
    inside = (((xx - 200) / 70) ** 2 + ((yy - 140) / 50) ** 2) < 1  # 10 px (3 canvas px) in from the outline
    assert alpha[inside].min() >= 0.94  # was 0.73
    assert iou(alpha, body) > 0.95
    lift = np.zeros((15, 15), bool)
    lift[3:12, 3:12] = True
    logits = _layout.backed_logits(np.full((15, 15), -10.0, np.float32), lift)
    assert logits[7, 7] == _layout.BACKED_INSIDE and logits[3, 7] == logits[7, 11] == _layout.BACKED_EDGE
    assert logits[0, 0] == -10.0


@pytest.mark.parametrize(("brightness", "found"), [(1.0, True), (0.7, False)])
def test_a_blob_the_selfie_graph_is_sure_of_is_the_person_when_nothing_else_vouches(brightness, found):
    """person="largest": when neither the pose graph nor a face vouches for anyone, the selfie graph's own
    segmentation of its largest blob is the person if it is sure of it (mean probability >= _SURE_BLOB over it: a
    couple taking a selfie, a woman seen from behind were empty mattes)."""
    body = crouching()
    rgb = np.repeat(body[..., None] * brightness, 3, 2)
    matter = M.PersonMatter(refine=False)
    matter.roi, matter.pose, matter.face = _Bright(), _Nobody(), None
    if found:
        assert iou(matter(rgb), body) > 0.95
    else:
        with pytest.raises(RelightError, match="no person found"):
            matter(rgb)


def test_a_blob_needs_the_pose_graphs_flag_when_vouching_is_off():
    """person="all" once someone is found: a blob both graphs segment alike but the pose graph's flag calls nobody
    (a pile of clothes on a chair beside a man at a desk) is no second person."""
    body = crouching()
    rgb = np.repeat(body[..., None], 3, 2)
    matter = M.PersonMatter(refine=False)
    matter.roi, matter.pose, matter.face = _Bright(), _Unsure(), None
    box = (120.0, 80.0, 280.0, 200.0)
    assert _candidate.person_at(matter, rgb, box, None) is not None
    assert _candidate.person_at(matter, rgb, box, None, vouch=False) is None


def test_the_part_of_a_segmentation_outside_another_person():
    """person_outside: a segmentation holding two people side by side (as the pose graph gives a couple) less the one
    matted already keeps the other one whole, and nothing of the first."""
    region = M.Region.around(0.0, 0.0, 200.0, 200.0)
    cols = np.arange(256)[None, :].repeat(256, 0)
    both = np.where((cols > 40) & (cols < 216), 8.0, -8.0).astype(np.float32)
    left = M.Person(region, np.where((cols > 40) & (cols < 128), 8.0, -8.0).astype(np.float32), 1.0)
    rest = _layout.person_outside(M.Person(region, both, 1.0), left)
    assert not (rest.logits[:, 44:124] > 0).any()  # none of the person matted already
    assert (rest.logits[:, 132:212] > 0).all()  # all of the other one
    assert rest.whole is None


def test_someone_beside_from_blobs_and_faces():
    """_someone_beside: the peers are looked for where a selfie-graph blob as tall reaches past the person's box by
    _BESIDE x their width (a couple one behind the other), or a face lies outside them; a blob within the person's
    box, or a short one beside them, is nobody."""
    box = (100.0, 50.0, 200.0, 350.0)  # 100 wide, 300 tall
    assert not _layout.someone_beside(box, [(1.0, (97.0, 50.0, 203.0, 350.0))], [])  # 6 px past
    assert _layout.someone_beside(box, [(1.0, (80.0, 50.0, 205.0, 350.0))], [])  # 20 px past: 0.2 x the width
    assert not _layout.someone_beside(box, [(1.0, (300.0, 200.0, 360.0, 330.0))], [])  # 130 tall: a child far off
    assert _layout.someone_beside(box, [(1.0, (300.0, 60.0, 380.0, 340.0))], [])
    assert _layout.someone_beside(box, [], [Face((300.0, 60.0, 320.0, 80.0), 0.9)])


def two_bodies(gap: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A bright body on the left and another on the right ``gap`` px apart (negative: overlapping), on black: the
    photo (H, W, 3) and the two bodies' masks."""
    h, w = 300, 400
    yy, xx = np.mgrid[0:h, 0:w] + 0.5
    left = (((xx - 130) / 60) ** 2 + ((yy - 150) / 120) ** 2) < 1
    right = (((xx - (250 + gap)) / 60) ** 2 + ((yy - 160) / 110) ** 2) < 1
    right &= ~left
    rgb = np.repeat((left | right).astype(np.float32)[..., None], 3, 2)
    return rgb, left, right


def matted(rgb: np.ndarray, mask: np.ndarray) -> M.Person:
    """The pose graph's segmentation of ``mask`` alone (a person found), on a region around it."""
    ys, xs = np.nonzero(mask)
    region = M.Region.around(float(xs.min()), float(ys.min()), float(xs.max() + 1), float(ys.max() + 1))
    canvas = M.crop_region(np.repeat(mask.astype(np.float32)[..., None], 3, 2), region)[..., 0]
    return M.Person(region, np.where(canvas > 0.5, 10.0, -10.0).astype(np.float32), 0.99)


@pytest.mark.parametrize(
    ("gap", "score", "where", "joined"),
    [(-20.0, 0.9, "right", True), (40.0, 0.9, "right", False), (-20.0, 0.6, "right", False),
     (-20.0, 0.9, "left", False)],
)  # fmt: skip
def test_someone_joined_to_the_person_with_a_face_of_their_own_is_taken(gap, score, where, joined):
    """person="largest": a face outside the matte (score >= _JOINED_FACE) lying in a part of the selfie graph's
    segmentation that touches the matte brings that part in (a couple embracing, a boy sitting against his mother:
    people_masks photos half B 0.863 -> 0.870); a face apart from the person (a passer-by), an unsure one, or one the
    matte holds already brings nothing."""
    rgb, left, right = two_bodies(gap)
    matter = M.PersonMatter(refine=False)
    matter.roi, matter.face = _Bright(), None
    main = matted(rgb, left)
    cx = 250.0 + gap if where == "right" else 130.0
    face = Face((cx - 20.0, 70.0, cx + 20.0, 110.0), score)
    extra = _company.joined(matter.roi, rgb, [main], [face])
    assert len(extra) == int(joined)
    alpha = matter.alpha(rgb, [main, *extra])
    assert iou(alpha, left | right if joined else left) > 0.95


@pytest.mark.parametrize(
    ("held", "faces", "whole"),
    [("upper", 2, True), ("band", 2, True), ("upper", 1, False)],
)  # fmt: skip
def test_a_second_person_the_matte_holds_in_part_is_completed(held, faces, whole):
    """person="largest": two sure faces at the matte (held by it or joined to it) are two people, and the one the
    matte holds in part is completed as the selfie graph sees them: two women posing arm in arm, the pose graph
    taking the second without her legs ("upper": both faces in the matte); a couple embracing, his head and legs
    outside the matte, which holds his chest ("band": :func:`_layout.joined_part` alone brought his head back,
    stopping where the matte cuts him). With one face the second body is no one's: nothing is added."""
    rgb, left, right = two_bodies(-20.0)
    yy = np.mgrid[0 : left.shape[0], 0 : left.shape[1]][0]
    part = right & (yy < 200) if held == "upper" else right & (yy >= 130) & (yy < 200)
    matter = M.PersonMatter(refine=False)
    matter.roi, matter.face = _Bright(), None
    main = matted(rgb, left | part)
    found = [Face((110.0, 50.0, 150.0, 90.0), 0.9), Face((210.0, 70.0, 250.0, 110.0), 0.9)][:faces]
    alpha = matter.alpha(rgb, [main, *_company.joined(matter.roi, rgb, [main], found)])
    assert iou(alpha, left | right if whole else left | part) > 0.95


def test_a_selfie_graph_person_cut_by_its_regions_side_is_taken_whole():
    """_selfie.widened: where the selfie graph's segmentation runs into its region's left or right side inside the
    photo, it is run again on a region reaching past that side, so whoever stands there comes whole, not cut down
    the middle (an old man's friend in profile halved: people_masks p277-like 0.66 -> 0.96); a segmentation clear of
    its region's sides is kept as it is."""
    rgb, left, right = two_bodies(-20.0)
    both = left | right
    matter = M.PersonMatter(refine=False)
    matter.roi, matter.face = _Bright(), None
    # reaches x 0..250, the bodies 70..290
    cut = _selfie.roi_person(matter.roi, rgb, M.Region(125.0, 150.0, 250.0), 0.9)
    box = M.person_box(cut, rgb.shape[:2])
    assert box[2] == pytest.approx(250.0, abs=3.0)  # cut by the region's right side
    whole = _selfie.widened(matter.roi, rgb, cut)
    assert M.person_box(whole, rgb.shape[:2])[2] == pytest.approx(290.0, abs=3.0)
    assert iou(matter.alpha(rgb, [whole]), both) > 0.95
    clear = _selfie.roi_person(matter.roi, rgb, M.Region(190.0, 150.0, 400.0), 0.9)
    assert _selfie.widened(matter.roi, rgb, clear) is clear
    rgb[right & (rgb[..., 0] > 0) & ~left] = 0.7  # the graph unsure (0.7) of what lies past the cut: not taken
    dim = _selfie.roi_person(matter.roi, rgb, M.Region(125.0, 150.0, 250.0), 0.9)
    assert _selfie.widened(matter.roi, rgb, dim) is dim


@pytest.mark.parametrize(("ground", "dropped"), [(0.7, True), (0.99, False)])
def test_what_runs_into_a_cut_side_unseen_framed_wider_is_dropped(ground, dropped, monkeypatch):
    """_selfie.widened / _layout.unconfirmed_cut: the selfie graph framed tight takes in the ground its region cuts
    (grass around a woman lying in it, matted in two blocks ending in the region's straight sides: people_masks
    p101-like); framed wider it does not. What runs into a cut side that the wider run does not see and the first run is
    not sure of (< SURE_PART) is dropped; a part it is sure of stays (framed larger, the graph can lose half a face)."""
    h, w = 300, 400

    def framed(roi, rgb, region):
        xs, ys = _segmentation.canvas_points(region)
        body = (((xs - 200) / 60) ** 2 + ((ys - 150) / 120) ** 2) < 1
        inside = (xs >= 0) & (xs < w) & (ys >= 0) & (ys < h)
        tight = inside & (ys >= 230) & (region.side < 300)  # the ground, taken in only when framed tight
        return np.where(body, 1.0, np.where(tight, ground, 0.0)).astype(np.float32)

    monkeypatch.setattr(_selfie, "roi_prob", framed)
    rgb = np.zeros((h, w, 3), np.float32)
    first = _selfie.roi_person(None, rgb, M.Region(200.0, 150.0, 280.0), 0.9)  # x 60..340: the ground runs into both
    out = _selfie.widened(None, rgb, first)
    yy, xx = np.mgrid[0:h, 0:w] + 0.5
    body = (((xx - 200) / 60) ** 2 + ((yy - 150) / 120) ** 2) < 1
    seen = _segmentation.prob_at(out, xx, yy) > 0.5
    assert (seen & body).sum() >= 0.99 * body.sum()
    ground_seen = (yy >= 230) & (yy < 290) & (xx >= 60) & (xx < 340) & ~body  # in the first region
    if dropped:
        assert (seen & ~body).sum() < 0.005 * body.sum()  # (the canvas's staircase at the outline)
    else:
        assert (seen & ground_seen).sum() > 0.95 * ground_seen.sum()


def test_a_continuation_takes_from_the_wider_answer_only_what_goes_on_from_the_cut():
    """continued: over the first region the first answer stays (framed larger, the graph can lose half a face); past
    the cut side only the wider answer's parts joined to the cut are added, not a blob apart from it."""
    first = M.Person(M.Region(100.0, 100.0, 200.0), np.full((256, 256), -10.0, np.float32), 0.9, "roi")
    first.logits[64:192, 128:] = 10.0  # a person running into the region's right side (x 200) at rows 50..150
    wide = M.Person(M.Region(200.0, 100.0, 400.0), np.full((256, 256), -10.0, np.float32), 0.9, "roi")
    # on wide's canvas (x 0..400, 0.64 px a pixel): nothing over first's region, the person going on to x 300, and
    # a blob apart at x 340..380
    wide.logits[96:160, 128:192] = 10.0
    wide.logits[96:160, 218:243] = 10.0
    out = _layout.continued(wide, first, (False, False, True, False))
    xs = np.array([150.0, 250.0, 360.0])
    assert (_segmentation.prob_at(out, xs, np.full(3, 100.0)) > 0.5).tolist() == [True, True, False]
    assert _layout.continued(wide, first, (True, False, False, False)) is first  # the left side was not cut


class _NotGround:
    """A stand-in for the selfie graph: a person wherever the canvas is not the mid-grey ground (nor black padding),
    so it sees a runner's shadow as much as his trousers."""

    def run(self, feeds):
        img = feeds["image"][0]
        seen = (np.abs(img - 0.5).max(0) > 0.05) & (img.max(0) > 0.0) | (img.max(0) < 0.08) & (img.max(0) > 0.0)
        return {"segmentation": seen.astype(np.float32)[None, None]}


def runner(h: int = 300, w: int = 400) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """A blue shirt and black trousers (two legs) on mid-grey ground, a dark grey shadow on the ground at the feet."""
    yy, xx = np.mgrid[0:h, 0:w] + 0.5
    parts = {
        "shirt": (np.abs(xx - 200) < 40) & (yy > 60) & (yy < 150),
        "leg1": (np.abs(xx - 180) < 12) & (yy >= 150) & (yy < 250),
        "leg2": (np.abs(xx - 220) < 12) & (yy >= 150) & (yy < 250),
        "shadow": (xx > 232) & (xx < 330) & (yy > 235) & (yy < 250),
    }
    rgb = np.full((h, w, 3), 0.5, np.float32)
    rgb[parts["shirt"]] = (0.2, 0.3, 0.8)
    rgb[parts["leg1"] | parts["leg2"]] = 0.03
    rgb[parts["shadow"]] = 0.3
    return rgb, parts


@pytest.mark.parametrize("ratio", [_colours.OWN_RATIO, 0.0])
def test_a_part_the_selfie_graph_sees_in_the_persons_own_colours_is_theirs(ratio, monkeypatch):
    """_own_colours: what the selfie graph sees joined to the matte is the person's where its colour is theirs (the
    runner's other black trouser leg, which the pose graph missed: the parkour clip's worst frames 0.60 -> 0.94), not
    where it is the ground's (his shadow); with the colour test made to refuse everything, nothing is added."""
    monkeypatch.setattr(_colours, "OWN_RATIO", ratio)
    rgb, parts = runner()
    matter = M.PersonMatter(refine=False)
    matter.roi, matter.face = _NotGround(), None
    found = matted(rgb, parts["shirt"] | parts["leg1"])
    extra = _completion.own_colours(matter.roi, rgb, [found])
    alpha = matter.alpha(rgb, [found, *extra])
    leg2 = (alpha[parts["leg2"]] >= 0.5).mean()
    assert (alpha[parts["shadow"]] >= 0.5).mean() < 0.1
    if ratio:
        assert leg2 > 0.9
        monkeypatch.setattr(matter, "people", lambda rgb, name="image": [found, *extra])
        whole, parts = matter.parts(rgb)  # the leg is part of the runner, not a person of its own
        assert len(parts) == 1 and np.array_equal(parts[0], whole)
    else:
        assert extra == [] and leg2 < 0.1


def test_colour_centres_find_each_cluster_and_give_the_same_answer_each_call():
    rng = np.random.default_rng(1)
    a = rng.normal((10.0, 0.0, 0.0), 1.0, (600, 3))
    b = rng.normal((80.0, 20.0, -20.0), 1.0, (900, 3))
    x = np.concatenate([a, b]).astype(np.float32)
    c = _colours.centres(x, 2)
    assert np.allclose(np.sort(c[:, 0]), [10.0, 80.0], atol=0.5)
    assert np.array_equal(c, _colours.centres(x, 2))
    d, label = _colours.nearest(np.array([[11.0, 0.0, 0.0]], np.float32), c)
    assert d[0] < 2.0 and c[label[0], 0] < 20.0


def test_the_video_matter_adds_what_the_photo_matte_adds_to_the_person_when_asked():
    """VideoMatter(complete=True) goes through :meth:`PersonMatter.completed` (issue 48, matte4): the grey legs the
    pose graph half-sees and the selfie graph sees are the person's in video as in a photo (_backed); with the
    photo's rules taken out (``completed`` giving the person alone), or by default on a first frame (completed only
    where the matte drops what the last frame held: test_video_completion.py), they are lost."""
    h, w = 300, 400
    yy, xx = np.mgrid[0:h, 0:w] + 0.5
    torso = (((xx - 200) / 50) ** 2 + ((yy - 100) / 70) ** 2) < 1
    legs = (np.abs(xx - 200) < 35) & (yy > 170) & (yy < 190)
    rgb = np.zeros((h, w, 3), np.float32)
    rgb[(np.abs(xx - 200) < 35) & (yy > 150) & (yy < 190)] = 0.4
    rgb[torso] = 1.0
    for asked, rules in ((True, True), (True, False), (False, True)):
        matter = M.PersonMatter(refine=False)
        matter.roi, matter.pose, matter.face = _Seen(), _DimLegs(), None
        if not rules:
            matter.completed = lambda rgb, person: [person]
        video = M.VideoMatter(matter, refine=False, smoothing=0.0, complete=True) if asked else M.VideoMatter(
            matter, refine=False, smoothing=0.0)
        alpha = video(rgb)
        assert (alpha[torso] >= 0.5).mean() > 0.95
        assert ((alpha[legs] >= 0.5).mean() > 0.9) == (asked and rules)


def test_the_video_matter_searches_again_in_the_frame_where_the_followed_person_is_lost():
    """A person who leaves the region followed from the last frame (a jump, a cut) is searched for again in the same
    frame, not one frame later (the parkour clip's frame 66 was an empty matte: video 0.913 -> 0.922)."""
    body = crouching(w=800)
    rgb = np.repeat(body[..., None], 3, 2)
    moved = np.roll(rgb, 400, axis=1)  # the body, now far to the right, out of the region followed
    matter = M.PersonMatter(refine=False)
    matter.roi, matter.pose, matter.face = _Bright(), _Unsure(), None
    video = M.VideoMatter(matter, refine=False, smoothing=0.0)
    assert iou(video(rgb), body) > 0.95
    assert iou(video(moved), moved[..., 0] > 0.5) > 0.9


class _FarOnly:
    """A stand-in for the selfie graph that sees what is bright only on a canvas where little is (a person seen on
    the whole photo), nothing where the bright part fills the canvas (the real one on a dim arcade's man, region)."""

    def run(self, feeds):
        bright = (feeds["image"][0].mean(0) > 0.5).astype(np.float32)
        return {"segmentation": (bright * (bright.mean() < 0.15))[None, None]}


class _Presence:
    """A stand-in for the pose graph: segments the bright part of the canvas with a given presence flag."""

    def __init__(self, presence: float):
        self.presence = presence

    def run(self, feeds):
        seg = np.where(feeds["image"][0].mean(0) > 0.5, 10.0, -10.0).astype(np.float32)
        return {"segmentation": seg[None, None], "presence": np.array([[self.presence]], np.float32)}


@pytest.mark.parametrize(("presence", "found"), [(0.3, True), (0.05, False)])
def test_a_pose_person_the_whole_photo_vouches_for_is_taken_when_nothing_else_is(presence, found):
    """person="largest", nobody found otherwise: the pose graph's segmentation of the largest blob is the person when
    its flag shows a trace of one (>= _TRACE) and the selfie graph on the whole photo sees that very shape, though on
    the person's own region it sees nothing (people_masks p195, a man in dark clothes in a dim arcade: 0.00 -> 0.89)."""
    body = crouching()
    rgb = np.repeat(body[..., None], 3, 2)
    matter = M.PersonMatter(refine=False)
    matter.roi, matter.pose, matter.face = _FarOnly(), _Presence(presence), None
    if found:
        assert iou(matter(rgb), body) > 0.95
    else:
        with pytest.raises(RelightError, match="no person found"):
            matter(rgb)


def test_seen_whole_asks_for_the_shape_inside_and_most_of_the_view():
    mine = np.zeros((20, 20), bool)
    mine[5:15, 5:10] = True
    seen = mine.copy()
    assert _layout.seen_whole(mine, seen)
    seen[5:15, 10:14] = True  # the view is much larger than the person: IoU 50/90
    assert not _layout.seen_whole(mine, seen)
    assert not _layout.seen_whole(mine, np.roll(mine, 3, axis=1))  # partly outside the view
    assert not _layout.seen_whole(mine, np.zeros_like(mine))


def test_a_selfie_graph_person_is_averaged_with_the_whole_photos_answer_only_where_the_two_agree():
    """_layout.blended: framed on the person, the selfie graph takes a rim of what stands behind them (grass, a blurred
    guitar) that it leaves out on the whole photo; the two answers averaged lose that rim (people_masks photos A 0.910
    -> 0.913, B 0.8835 -> 0.8851), but only when they agree: a whole-photo answer that is another shape is not used."""
    yy, xx = np.mgrid[0:256, 0:256] + 0.5
    body = (((xx - 128) / 60) ** 2 + ((yy - 140) / 90) ** 2) < 1
    rim = ((((xx - 128) / 65) ** 2 + ((yy - 140) / 97) ** 2) < 1) & ~body
    region = M.Region(128.0, 128.0, 256.0)
    framed = _segmentation.Person(region, np.where(body, 6.0, np.where(rim, 0.5, -6.0)).astype(np.float32), 0.9, "roi")
    whole = np.where(body, 0.95, 0.02).astype(np.float32)  # the whole photo's answer: the body, not the rim
    out = _layout.blended(framed, whole, 256.0)  # the whole photo's canvas as fine as the region's
    assert (out.logits[body] > 0).all() and (out.logits[rim] < 0).all()  # the rim is gone, the body kept
    other = np.where(xx < 100, 0.95, 0.02).astype(np.float32)  # the whole photo's answer is someone else
    assert _layout.blended(framed, other, 256.0) is framed


def test_the_average_with_the_whole_photos_answer_brings_back_nothing_a_rule_dropped():
    """_layout.blended after _layout.unconfirmed_cut: the ground the selfie graph framed tight takes in where its
    region cuts it is dropped whole (logit -LOGIT_CLIP), and the whole photo's answer, half sure of that ground
    (0.6), agrees with the rest of the person. Averaged there as well, the ground came back as a veil at alpha 0.3
    (people_masks p101: the grass block at 0.3-0.45, pasted into every composite). The average may take from the
    region's answer, never add to what it leaves out; inside the person it is the average still."""
    yy, xx = np.mgrid[0:256, 0:256] + 0.5
    body = (((xx - 128) / 50) ** 2 + ((yy - 120) / 90) ** 2) < 1
    grass = (yy > 215) & (xx > 40) & (xx < 216) & ~body  # runs into the canvas's bottom row: the region's cut side
    region = M.Region(128.0, 128.0, 256.0)
    first = _segmentation.Person(region, np.where(body | grass, 4.0, -6.0).astype(np.float32), 0.9, "roi")
    first = replace(first, logits=np.where(grass, np.float32(1.0), first.logits))  # unsure of the grass (0.73)
    wide = _segmentation.Person(M.Region(128.0, 192.0, 384.0), np.full((256, 256), -6.0, np.float32), 0.9, "roi")
    wide.logits[_layout.resampled(first, wide.region)[0] > 3.0] = 6.0  # the wider run: the body, no grass
    cut = _layout.unconfirmed_cut(wide, first, (False, False, False, True))
    assert (_segmentation.sigmoid(cut.logits[grass]) < 0.01).all()  # dropped whole
    seen = np.where(body, 0.97, np.where(grass, 0.6, 0.02)).astype(np.float32)
    out = _segmentation.sigmoid(_layout.blended(cut, seen, 256.0).logits)
    assert out[grass].max() < 0.01  # no veil where the rule dropped the grass
    inside = 0.5 * (cut.logits[body] + _segmentation.as_logits(np.float32(0.97)))  # canvases alike: equal weights
    assert np.allclose(out[body], _segmentation.sigmoid(inside), atol=1e-3)  # the person is still the average


def test_what_the_whole_photo_is_sure_of_beside_the_person_is_taken_whole_not_half():
    """_layout.blended: a shoulder the region's answer leaves out (0.02) and the whole photo's answer is sure of
    (0.97) came out at their mean, 0.5: a veil over the person (people_masks p285: a jacket's shoulder at alpha
    0.44). Joined to the person and at least BLEND_TAKE sure, it is the whole photo's answer; a sure blob apart from
    the person (someone else) and a part the whole photo is unsure of (0.6) stay as the region's answer had them."""
    yy, xx = np.mgrid[0:256, 0:256] + 0.5
    body = (((xx - 128) / 50) ** 2 + ((yy - 120) / 90) ** 2) < 1
    shoulder = (yy > 190) & (xx > 40) & (xx < 128) & ~body  # beside the body, against it
    unsure = (yy > 220) & (xx >= 128) & (xx < 216) & ~body
    apart = (xx < 20) & (yy < 20)  # far from the body
    region = M.Region(128.0, 128.0, 256.0)
    framed = _segmentation.Person(region, np.where(body, 4.0, -4.0).astype(np.float32), 0.9, "roi")
    seen = np.where(body | shoulder | apart, 0.97, np.where(unsure, 0.6, 0.02)).astype(np.float32)
    out = _segmentation.sigmoid(_layout.blended(framed, seen, 256.0).logits)
    assert np.allclose(out[shoulder], 0.97, atol=1e-3)  # taken whole: no pixel at the half mix
    assert np.allclose(out[unsure | apart], _segmentation.sigmoid(np.float32(-4.0)), atol=1e-3)


def test_a_thin_part_the_coarser_whole_photo_blurs_away_stays_the_persons():
    """_layout.blended: a raised arm 3 canvas pixels wide that the region's answer sees (0.9) is 1.5 pixels wide on
    the whole photo's canvas, twice as coarse, whose answer blurs it to 0.05. The mean of the two probabilities
    (0.475) took it away (people_masks p109: strips of both raised arms, 0.884 against 0.921 unaveraged); the mean of
    the logits weighted by each canvas's resolution keeps it, and still takes away a broad rim of grass the whole
    photo sees as background (0.02). The same two answers on canvases alike weigh the same, and the arm goes."""
    yy, xx = np.mgrid[0:256, 0:256] + 0.5
    body = (((xx - 128) / 50) ** 2 + ((yy - 150) / 90) ** 2) < 1
    arm = (np.abs(xx - 100) < 1.5) & (yy > 20) & ~body  # 3 canvas px wide, raised above the head
    rim = ((((xx - 128) / 58) ** 2 + ((yy - 150) / 98) ** 2) < 1) & ~body & ~arm  # grass either side
    region = M.Region(128.0, 128.0, 256.0)
    logits = np.where(body, 4.0, np.where(arm, 2.2, np.where(rim, 0.85, -6.0))).astype(np.float32)  # 0.9, 0.7
    framed = _segmentation.Person(region, logits, 0.9, "roi")
    seen = np.where(body, 0.97, np.where(arm, 0.05, 0.02)).astype(np.float32)
    coarse = _layout.blended(framed, seen, 512.0)  # the whole photo spans twice the region: its canvas 2x coarser
    assert (coarse.logits[arm] > 0).all()  # the arm stays
    assert (coarse.logits[rim] < 0).all() and (coarse.logits[body] > 0).all()  # the grass goes, the body stays
    alike = _layout.blended(framed, seen, 256.0)
    assert (alike.logits[arm] < 0).all() and (alike.logits[rim] < 0).all()
    body_seen = seen.copy()
    body_seen[body] = 0.6  # the whole photo half-sees the body the region's answer is sure of (0.98)
    inside = _segmentation.sigmoid(_layout.blended(framed, body_seen, 256.0).logits[body])
    assert inside.min() > 0.88  # nearly opaque (0.90): the mean of the probabilities left it translucent (0.79)


def test_portrait_region_is_no_wider_than_the_photo():
    """A portrait's region framed on a pose-graph box as wide as the photo (800 px for a 640 x 480 poster of a
    man) showed the selfie graph the photo smaller than the photo itself, with empty margins: it took the halo
    and the print behind him (p183: IoU 0.67, 0.86 framed on the photo). Such a region is the photo's own
    square; a region within the photo's longer side is kept as it is."""
    rgb = np.zeros((480, 640, 3), np.float32)
    matter = M.PersonMatter(refine=False)
    logits = np.zeros((256, 256), np.float32)
    wide = M.Person(M.Region(320.0, 260.0, 800.0), logits, 0.99, "pose")  # reaches past the bottom
    assert _candidate.portrait_region(rgb, wide, matter.find_faces) == M.Region(320.0, 240.0, 640.0)
    close = M.Person(M.Region(300.0, 300.0, 500.0), logits, 0.99, "pose")
    assert _candidate.portrait_region(rgb, close, matter.find_faces) == close.region
    assert _layout.within_photo(M.Region(100.0, 50.0, 700.0), (480, 640)) == M.Region(320.0, 240.0, 640.0)


def test_what_runs_into_a_cut_side_is_never_the_whole_person():
    """_layout.unconfirmed_cut drops ground the tight frame took in, not the person: where the wider run sees nobody
    (it can lose half a face against a bright sky) and the whole person runs into the cut side unsure (< SURE_PART),
    the first answer stays (it had emptied the person; the review of matte14)."""
    first = M.Person(M.Region(100.0, 100.0, 200.0), np.full((256, 256), -10.0, np.float32), 0.9, "roi")
    first.logits[40:200, :90] = np.log(0.9 / 0.1)  # a person at 0.9 running into the canvas's left side
    wide = M.Person(M.Region(60.0, 100.0, 300.0), np.full((256, 256), -10.0, np.float32), 0.9, "roi")
    assert _layout.unconfirmed_cut(wide, first, (True, False, False, False)) is first
    # with a part the wider run sees, the unseen ground joined to the cut still goes
    wide.logits[:, :] = -10.0
    seen = _segmentation.prob_at(first, *_segmentation.canvas_points(wide.region)) > 0.5
    wide.logits[seen] = 10.0
    first.logits[200:256, :90] = np.log(0.7 / 0.3)  # ground below, touching the cut side and the bottom
    out = _layout.unconfirmed_cut(wide, first, (True, False, False, False))
    assert (out.logits[40:200, :90] > 0).all() and (out.logits[200:256, :90] <= 0).all()
