"""Issue 48: someone out of focus behind the person leaves the default matte, whole (relight_rt.person.matting._behind),
on synthetic photos with stand-in graphs (the figures the rule was measured by are in its docstrings)."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest
from test_matting import iou
from test_people_found import _Bright

from relight_rt.person import matting as M
from relight_rt.person.face_detector import Face
from relight_rt.person.matting import _behind, _matter, _segmentation

H, W = 300, 400
SUBJECT_FACE = Face((218.0, 48.0, 282.0, 112.0), 0.9)  # 64 px wide


def texture(seed: int = 0) -> np.ndarray:
    """A scene's texture: per-pixel grain and a coarser weave (H, W), zero mean."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:H, 0:W]
    return 0.08 * rng.uniform(-1, 1, (H, W)) + 0.08 * np.sin(xx / 2.0) * np.sin(yy / 2.5)


def scene(behind_width: float, blurred: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray, Face]:
    """A sharp subject (an upright ellipse on the right, face 64 px wide) in front of another person on the left
    (overlapping them, face ``behind_width`` px wide), who is out of focus when ``blurred`` (the whole layer behind the
    subject blurred, their outline too), on a dark plain backdrop: (photo (H, W, 3), subject's mask, other's mask,
    the other's face)."""
    yy, xx = np.mgrid[0:H, 0:W] + 0.5
    subject = (((xx - 250) / 80) ** 2 + ((yy - 170) / 140) ** 2) < 1
    s = behind_width / 40.0
    other = (((xx - 140) / (50 * s)) ** 2 + ((yy - (110 + 90 * s)) / (100 * s)) ** 2) < 1
    grain = texture()
    back = np.where(other, 0.7 + grain, 0.05).astype(np.float32)
    if blurred:
        back = cv2.GaussianBlur(back, (0, 0), 3.0)
    photo = np.where(subject, 0.75 + grain, back).astype(np.float32)
    cx, top = 140.0, 110.0 + 90 * s - 100 * s + 20 * s
    face = Face((cx - behind_width / 2, top, cx + behind_width / 2, top + behind_width), 0.85)
    return np.repeat(photo[..., None], 3, 2), subject, other & ~subject, face


def segmented(rgb: np.ndarray, mask: np.ndarray) -> M.Person:
    """A selfie-graph segmentation holding ``mask`` (both people: it segments everyone in its region)."""
    ys, xs = np.nonzero(mask)
    region = M.Region.around(float(xs.min()), float(ys.min()), float(xs.max() + 1), float(ys.max() + 1))
    canvas = M.crop_region(np.repeat(mask.astype(np.float32)[..., None], 3, 2), region)[..., 0]
    return M.Person(region, np.where(canvas > 0.5, 10.0, -10.0).astype(np.float32), 0.99, "roi")


@pytest.mark.parametrize(
    ("behind_width", "blurred", "dropped"),
    [(40.0, True, True), (40.0, False, False), (60.0, True, False)],
)  # fmt: skip
def test_a_blurred_smaller_face_behind_the_subject_leaves_the_matte_whole(behind_width, blurred, dropped):
    """people_masks p103 / p257: a blurred woman behind a sharp one, a blurred man's face beside a woman's hand, came
    into her matte (the selfie graph segments both). A face the matte holds that is smaller than the subject's (0.62
    x: further back) and blurred where hers is sharp is someone behind: their whole body leaves the matte. A sharp
    smaller face (a child beside their mother) or a blurred one as large as hers (standing with her, a shallow focus)
    stays."""
    rgb, subject, other, face = scene(behind_width, blurred)
    matter = M.PersonMatter(refine=False)
    matter.roi, matter.face = _Bright(), None
    both = segmented(rgb, subject | other)
    before = matter.alpha(rgb, [both])
    assert iou(before, subject | other) > 0.95  # the segmentation holds both
    people = _behind.without_behind(matter.roi, rgb, [both], [SUBJECT_FACE, face])
    alpha = matter.alpha(rgb, people)
    if dropped:
        assert iou(alpha, subject) > 0.95
        assert (alpha[other] >= 0.5).mean() < 0.02  # whole: not a piece of them left
    else:
        assert people[0] is both
        assert iou(alpha, subject | other) > 0.95


def test_behind_faces_compares_size_and_sharpness_with_the_subjects_face():
    """The subject's face is the largest one the matte holds; a face outside the matte, or the only face, is no one
    behind."""
    rgb, subject, other, face = scene(40.0, True)
    both = segmented(rgb, subject | other)
    found = _behind.behind_faces(rgb, [both], [face, SUBJECT_FACE])
    assert found is not None
    assert found.subject is SUBJECT_FACE and found.faces == [face]
    assert _behind.behind_faces(rgb, [both], [SUBJECT_FACE]) is None
    assert _behind.behind_faces(rgb, [segmented(rgb, subject)], [SUBJECT_FACE, face]) is None


def test_a_photo_enlarged_is_read_where_the_subjects_face_is_face_px_wide():
    """A web photo enlarged reads as blurred everywhere at full size (p103 and p257 enlarged 5x to 2.5 MP: no face
    behind found); read reduced until the subject's face is FACE_PX wide, the face behind is still found, and the
    person behind leaves the matte as at the photo's own size."""
    rgb, subject, other, face = scene(40.0, True)
    z = 5  # enlarged so (bicubic): at full size the face behind measures 0.90 x the subject's fine detail
    big = np.clip(cv2.resize(rgb, (z * W, z * H), interpolation=cv2.INTER_CUBIC), 0.0, 1.0)
    grow = [Face(tuple(z * v for v in f.box), f.score) for f in (SUBJECT_FACE, face)]
    matter = M.PersonMatter(refine=False)
    matter.roi, matter.face = _Bright(), None
    big_subject = cv2.resize(subject.astype(np.uint8), (z * W, z * H), interpolation=cv2.INTER_NEAREST) > 0
    big_other = cv2.resize(other.astype(np.uint8), (z * W, z * H), interpolation=cv2.INTER_NEAREST) > 0
    both = segmented(big, big_subject | big_other)
    found = _behind.behind_faces(big, [both], grow)
    assert found is not None and found.faces == [grow[1]]
    alpha = matter.alpha(big, _behind.without_behind(matter.roi, big, [both], grow))
    assert iou(alpha, big_subject) > 0.95
    # the part, read on the reduced photo's pixels (cv2.resize's centres), lands back where the matte is: its left and
    # top outline within 0.6 px of the matte's (0.16 / 0.32; a grid half a reduced pixel off: 1.3 / 2.2 px)
    gray = cv2.cvtColor(big, cv2.COLOR_RGB2GRAY)
    share = _behind._part_of(matter.roi, big, gray, [both], [grow[0]], grow[0], grow[1]) >= 0.5
    matte = matter.alpha(big, [both]) >= 0.5
    rows, cols = slice(z * 150, z * 250), slice(z * 110, z * 150)
    assert abs((np.argmax(share[rows], 1) - np.argmax(matte[rows], 1)).mean()) < 0.6
    assert abs((np.argmax(share[:, cols], 0) - np.argmax(matte[:, cols], 0)).mean()) < 0.6


def test_fine_detail_falls_with_blur_and_not_with_contrast():
    """fine_detail: a ratio of fine over mid-scale detail, lower on a blurred copy, the same at half the contrast."""
    grain = texture().astype(np.float32)
    box = (100.0, 100.0, 200.0, 200.0)
    sharp = _behind.fine_detail(0.5 + grain, box)
    assert _behind.fine_detail(0.5 + cv2.GaussianBlur(grain, (0, 0), 2.0), box) < 0.6 * sharp
    assert _behind.fine_detail(0.5 + 0.5 * grain, box) == pytest.approx(sharp, rel=1e-4)


def test_the_default_matte_leaves_out_the_person_behind_and_everyones_keeps_them(monkeypatch):
    """PersonMatter.people, person="largest", drops the blurred person behind (the call site); person="all" never
    asks (it takes everyone)."""
    rgb, subject, other, face = scene(40.0, True)
    both = segmented(rgb, subject | other)
    asked = []

    def spy(roi, rgb_, people, faces):
        asked.append(len(faces))
        return _behind.without_behind(roi, rgb_, people, faces)

    monkeypatch.setattr(_matter, "without_behind", spy)
    for person in ("largest", "all"):
        matter = M.PersonMatter(refine=False, person=person)
        matter.roi, matter.face = _Bright(), None
        monkeypatch.setattr(matter, "find_faces", lambda rgb_, every=False: [SUBJECT_FACE, face])
        monkeypatch.setattr(_matter, "largest", lambda matter_, rgb_: ([both], []))
        monkeypatch.setattr(_matter, "everyone", lambda matter_, rgb_, tall=0.0: [both])
        monkeypatch.setattr(_matter, "peers", lambda *a: [])
        monkeypatch.setattr(_matter, "joined", lambda *a: [])
        monkeypatch.setattr(_matter, "own_and_turned", lambda *a: [])
        alpha = matter.alpha(rgb, matter.people(rgb))
        assert iou(alpha, subject if person == "largest" else subject | other) > 0.95
    assert asked == [2]


def _stand_in() -> M.PersonMatter:
    matter = M.PersonMatter(refine=False)
    matter.roi, matter.face = _Bright(), None
    return matter


@pytest.mark.parametrize("side", [44.0, 34.0])
def test_a_second_smaller_box_on_the_subjects_own_face_removes_nothing(side):
    """The face graph can answer a second, smaller box over a smooth part of the subject's own face (an IoU of 0.28
    with it passes its non-maximum suppression): read as someone behind, the matte was emptied. A face whose middle
    lies inside a larger one's box is that face's (_behind._own)."""
    rgb, subject, _, _ = scene(40.0, False)
    img = rgb.copy()
    img[70:110, 220:260] = cv2.GaussianBlur(rgb, (0, 0), 1.5)[70:110, 220:260]  # smooth skin
    second = Face((220.0, 70.0, 220.0 + side, 70.0 + side), 0.6)
    matter = _stand_in()
    both = segmented(img, subject)
    people = _behind.without_behind(matter.roi, img, [both], [SUBJECT_FACE, second])
    assert people[0] is both


def test_a_blurred_print_on_the_subjects_plain_shirt_removes_nothing():
    """A face printed on a plain shirt (the face graph finds prints and badges) and blurred: the shirt's texture-less
    pixels took the print's side, and the shirt left the matte (0.15 of it kept)."""
    yy, xx = np.mgrid[0:H, 0:W] + 0.5
    subject = (((xx - 250) / 80) ** 2 + ((yy - 170) / 140) ** 2) < 1
    grain = texture()
    photo = np.where(subject, np.where(yy < 125, 0.75 + grain, 0.75), 0.05).astype(np.float32)
    photo[180:214, 233:267] = cv2.GaussianBlur(0.6 + grain, (0, 0), 2.0)[180:214, 233:267]
    rgb = np.repeat(photo[..., None], 3, 2)
    matter = _stand_in()
    both = segmented(rgb, subject)
    people = _behind.without_behind(matter.roi, rgb, [both], [SUBJECT_FACE, Face((233.0, 180.0, 267.0, 214.0), 0.6)])
    alpha = matter.alpha(rgb, people)
    assert (alpha[subject] >= 0.5).mean() > 0.98


def test_the_subjects_sharp_hand_before_the_person_behind_stays():
    """p257's hand: the subject's sharp hand over the blurred person behind, cut off from her by their part, stays
    with her (a cut-off piece leaves only when it reads blurred; the selfie graph framed on the person behind claims
    everyone, the hand too); the person behind still leaves."""
    rgb, subject, other, face = scene(40.0, True)
    yy, xx = np.mgrid[0:H, 0:W] + 0.5
    hand = (((xx - 140) ** 2 + (yy - 215) ** 2) < 14**2) & ~subject
    img = rgb.copy()
    img[hand] = (0.8 + texture(1)[hand])[:, None]
    matter = _stand_in()
    both = segmented(img, subject | hand | other)
    alpha = matter.alpha(img, _behind.without_behind(matter.roi, img, [both], [SUBJECT_FACE, face]))
    assert (alpha[hand] >= 0.5).mean() > 0.9
    assert (alpha[other & ~hand] >= 0.5).mean() < 0.05


_YY, _XX = np.mgrid[0:H, 0:W] + 0.5
_SUBJECT = (((_XX - 250) / 80) ** 2 + ((_YY - 170) / 140) ** 2) < 1  # scene's
_BEHIND = (((_XX - 140) / 50) ** 2 + ((_YY - 200) / 100) ** 2) < 1  # their face 40 px wide: behind
_BEHIND_FACE = Face((120.0, 120.0, 160.0, 160.0), 0.85)


def _layered(layers: list[np.ndarray]) -> np.ndarray:
    """The sharp subject of :func:`scene` in front of ``layers`` (masks of people out of focus, blurred together with
    their outline) on the dark backdrop: (H, W, 3)."""
    grain = texture()
    back = cv2.GaussianBlur(np.where(np.any(layers, 0), 0.7 + grain, 0.05).astype(np.float32), (0, 0), 3.0)
    return np.repeat(np.where(_SUBJECT, 0.75 + grain, back).astype(np.float32)[..., None], 3, 2)


@pytest.mark.parametrize("half_width", [50.0, 40.0])
def test_the_person_behind_leaves_whole_below_the_subjects_sharp_arm(half_width):
    """The subject's sharp forearm across the person behind cuts their body below it off their part; that piece is
    joined to the subject through the arm, reads mostly sharp as one piece, and stayed (0.99 of it, both when it
    touches the subject and when the arm alone joins them). Their large blurred parts of a piece that stays leave; the
    arm stays."""
    other = (((_XX - 140) / half_width) ** 2 + ((_YY - 200) / 100) ** 2) < 1
    arm = (_YY > 235) & (_YY < 250) & (_XX > 80) & (_XX < 250)
    img = _layered([other])
    img[arm] = (0.8 + texture(2)[arm])[:, None]
    matter = _stand_in()
    both = segmented(img, _SUBJECT | other | arm)
    alpha = matter.alpha(img, _behind.without_behind(matter.roi, img, [both], [SUBJECT_FACE, _BEHIND_FACE]))
    rest = other & ~_SUBJECT & ~arm
    assert (alpha[rest & (_YY > 250)] >= 0.5).mean() < 0.05
    assert (alpha[rest & (_YY < 235)] >= 0.5).mean() < 0.05
    assert (alpha[arm & ~_SUBJECT] >= 0.5).mean() > 0.9
    assert (alpha[_SUBJECT] >= 0.5).mean() > 0.98


def _friend(hole: bool) -> tuple[np.ndarray, np.ndarray, Face]:
    """A blurred friend standing with the subject on the left (face 60 px: too large to be behind), their hand on the
    person behind's shoulder (a bridge 15 px tall); ``hole``: the segmentation misses a few pixels at their face's
    middle. (friend's mask, segmentation's mask, friend's face)."""
    friend = ((((_XX - 35) / 45) ** 2 + ((_YY - 170) / 140) ** 2) < 1) | (
        (_YY > 190) & (_YY < 205) & (_XX > 60) & (_XX < 100)
    )
    mask = _SUBJECT | _BEHIND | friend
    if hole:
        mask &= ~((np.abs(_XX - 35) < 4) & (np.abs(_YY - 80) < 4))
    return friend, mask, Face((5.0, 50.0, 65.0, 110.0), 0.9)


@pytest.mark.parametrize("hole", [False, True])
def test_a_blurred_friend_touching_the_person_behind_stays(hole):
    """A blurred person as large as the subject (standing with her, a shallow focus) whose hand touches the person
    behind: their pixels joined that person's part and left with them (0.08 of them kept). They are parted at the
    neck between them (the blurred matte opened until the cores under the two faces are apart) before the person
    behind's part is taken; the friend's face counts by its middle half, which the matte holds though its middle
    pixel falls in a hole."""
    friend, mask, friend_face = _friend(hole)
    img = _layered([_BEHIND, friend])
    matter = _stand_in()
    both = segmented(img, mask)
    people = _behind.without_behind(matter.roi, img, [both], [SUBJECT_FACE, _BEHIND_FACE, friend_face])
    alpha = matter.alpha(img, people)
    assert (alpha[friend & ~_BEHIND & mask] >= 0.5).mean() > 0.95
    assert (alpha[_BEHIND & ~_SUBJECT & ~friend] >= 0.5).mean() < 0.05
    assert (alpha[_SUBJECT] >= 0.5).mean() > 0.98


def test_a_blurred_friend_who_cannot_be_told_from_the_person_behind_keeps_both():
    """Touching the person behind over more than their face's width (no opening up to that parts the two), the
    friend cannot be told from them: the person behind stays whole rather than take the friend with them."""
    friend = (((_XX - 45) / 45) ** 2 + ((_YY - 170) / 140) ** 2) < 1
    img = _layered([_BEHIND, friend])
    matter = _stand_in()
    both = segmented(img, _SUBJECT | _BEHIND | friend)
    people = _behind.without_behind(
        matter.roi, img, [both], [SUBJECT_FACE, _BEHIND_FACE, Face((15.0, 50.0, 75.0, 110.0), 0.9)]
    )
    assert people[0] is both


def _outside_where(gap) -> M.Person:
    """A segmentation holding the whole photo but where ``gap(xs, ys)`` (image coordinates) is True."""
    region = M.Region(W / 2, H / 2, float(W))
    xs, ys = _segmentation.canvas_points(region)
    return M.Person(region, np.where(gap(xs, ys), -10.0, 10.0).astype(np.float32), 0.9, "roi")


@pytest.mark.parametrize(
    ("gap", "reaches"),
    [
        (lambda x, y: np.zeros_like(x, bool), False),
        (lambda x, y: (y > 76) & (y < 84), True),  # outside on the band's rim, 20 px out
        (lambda x, y: (y > 86) & (y < 94) & (x > 185) & (x < 215), True),  # a pocket 8 px above the box
        (lambda x, y: (x > 186) & (x < 189) & (y < 100), True),  # a 3-px slit through the band
        (lambda x, y: (y > 108) & (y < 132) & (x > 188) & (x < 212), False),  # inside the box: a print's own
        (lambda x, y: y < 76, False),  # past the band
    ],
)  # fmt: skip
def test_reaches_outside_reads_the_whole_band_around_the_face(gap, reaches):
    """A face 40 px wide: the matte's outside anywhere within 20 px of its box counts; the ring of 68 points at 20 px
    out missed a pocket between it and the box and a slit narrower than their spacing."""
    face = Face((180.0, 100.0, 220.0, 140.0), 0.8)
    assert _behind.reaches_outside([_outside_where(gap)], face, (H, W)) is reaches


def test_a_face_box_that_is_not_finite_is_no_ones():
    """A NaN box beside the face behind crashed _box_mask through the staying faces; it is ignored."""
    rgb, subject, other, face = scene(40.0, True)
    matter = _stand_in()
    both = segmented(rgb, subject | other)
    nan = Face((np.nan, np.nan, np.nan, np.nan), 0.5)
    alpha = matter.alpha(rgb, _behind.without_behind(matter.roi, rgb, [both], [SUBJECT_FACE, face, nan]))
    assert (alpha[other] >= 0.5).mean() < 0.02
    assert _behind.without_behind(matter.roi, rgb, [both], [SUBJECT_FACE, nan])[0] is both


def test_logits_are_held_only_where_someone_leaves():
    """Each segmentation's logits are held under the logit of 1 - the leaving share only where something leaves: a
    sure pixel elsewhere (logit 25, past that of a share of 0: 16.1) keeps its logit."""
    rgb, subject, other, face = scene(40.0, True)
    both = segmented(rgb, subject | other)
    sure = replace(both, logits=2.5 * both.logits)
    out = _behind.without_behind(_stand_in().roi, rgb, [sure], [SUBJECT_FACE, face])[0]
    assert (out.logits < sure.logits).any()  # someone left
    untouched = (out.logits == sure.logits) & (sure.logits > 0)
    assert untouched.sum() > 0.5 * (sure.logits > 0).sum()  # the subject, most of the matte


def test_a_person_split_from_one_segmentation_is_read_as_its_whole():
    """The parts split from one segmentation (_parts.split_by_faces) leave a seam between them where each part's
    edge is upsampled; read part by part, a seam across the person behind below their face cut their body off their
    part, and it stayed. They are read as the whole they were split from."""
    rgb, subject, other, face = scene(40.0, True)
    both = segmented(rgb, subject | other)
    _, ys = _segmentation.canvas_points(both.region)
    cut = face.box[3] + 15.0  # below their face
    top = np.where(ys < cut - 3, both.logits, -30.0).astype(np.float32)
    bottom = np.where(ys > cut + 3, both.logits, -30.0).astype(np.float32)
    parts = [replace(both, logits=top, whole=both.logits), replace(both, logits=bottom, whole=both.logits)]
    matter = _stand_in()
    alpha = matter.alpha(rgb, _behind.without_behind(matter.roi, rgb, parts, [SUBJECT_FACE, face]))
    assert (alpha[other] >= 0.5).mean() < 0.02
    assert iou(alpha, subject) > 0.95


def test_a_staying_faces_blurred_part_in_a_piece_that_stays_is_kept():
    """behind_part on drawn masks: where a staying face overlaps the face behind's box (p257: the subject's face
    beside the man's), its middle half there may read blurred, and that blurred part of a piece that stays is not the
    person behind's body (as below the subject's arm, test above): it stays."""
    matte = np.zeros((200, 200), bool)
    matte[50:, 40:200] = True  # the person behind (x < 120) and the subject (x >= 120), touching
    blurred = np.zeros_like(matte)
    blurred[50:, 40:120] = True
    blurred[60:100, 128:160] = True  # the subject's, under her face's middle half, 8 px of sharp from them
    claim = matte.copy()
    face, staying = Face((90.0, 60.0, 130.0, 100.0), 0.8), Face((112.0, 62.0, 136.0, 98.0), 0.9)
    part = _behind.behind_part(matte, blurred, claim, face, [staying])
    assert part[50:, 40:120].all()
    assert not part[60:100, 128:160].any()


def test_the_subjects_outline_is_no_part_of_the_person_behind():
    """The person behind raised so their region's segmentation claims the top of the subject's head: the subject's
    outline against the plain backdrop reads blurred there, a thin strip of her piece (which stays) as large as half
    the face behind's width square; only parts that survive an opening by the window leave (IoU with her 0.973 ->
    0.991)."""
    shift = 60.0
    other = (((_XX - 140) / 50) ** 2 + ((_YY - (200 - shift)) / 100) ** 2) < 1
    img = _layered([other])
    face = Face((120.0, 120.0 - shift, 160.0, 160.0 - shift), 0.85)
    matter = _stand_in()
    both = segmented(img, _SUBJECT | other)
    alpha = matter.alpha(img, _behind.without_behind(matter.roi, img, [both], [SUBJECT_FACE, face]))
    assert (alpha[other & ~_SUBJECT] >= 0.5).mean() < 0.02
    assert iou(alpha, _SUBJECT) > 0.985


@pytest.mark.parametrize("box, count", [((2, -20, 5, -5), 0), ((-20, 2, -5, 5), 0), ((2, 12, 5, 15), 0),
                                        ((-3, -3, 2.5, 1.2), 6), ((8.5, 8.5, 30, 30), 4)])
def test_a_box_off_the_photo_holds_only_its_pixels_inside(box, count):
    """A box wholly above or left of the photo marked pixels from the far side (a negative slice end)."""
    assert int(_behind._box_mask((10, 10), box).sum()) == count
