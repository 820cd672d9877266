"""Things out of focus behind the person, taken out of the default matte (relight_rt.person.matting._things_behind,
issue 48), on synthetic photos: a portrait (a head and a torso cut by the bottom border, a sharp fine texture) before
a smooth backdrop, with a blurred textured thing beside the shoulder that the selfie graph's matte holds and the pose
graph does not see (a guitar leaning behind a girl). The pose graph's outline lies 2 px inside the matte's, as the
graph's does on photos."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from relight_rt.image.regions import Region, crop_region
from relight_rt.person.face_detector import Face
from relight_rt.person.matting import _things_behind as tb
from relight_rt.person.matting._segmentation import Person, as_logits, logits_on_grid

H, W = 240, 200
LEAN = (54, 100)
FACE = (88.0, 48.0, 132.0, 96.0)  # the subject's face box (x0, y0, x1, y1) on the head
SECOND = (156.0, 48.0, 180.0, 72.0)  # the small second person's ("person")


def _erode(mask: np.ndarray, px: int) -> np.ndarray:
    return cv2.erode(mask.astype(np.uint8), np.ones((2 * px + 1, 2 * px + 1), np.uint8)).astype(bool)


def scene(thing: str = "beside", sharp_thing: bool = False, skin: float = 0.12, blur: float = 2.5
          ) -> tuple[np.ndarray, dict[str, np.ndarray]]:  # fmt: skip
    """(rgb (H, W, 3) float32, parts): parts "body" (head and torso, the pose graph sees it) and "thing" (the matte
    holds it, the pose graph does not). ``thing``: "beside" (left of the head, against the torso's top corner only:
    sticking out), "leaning" (further down, against the torso's side: the cut runs through the matte), "front" (over
    the middle of the torso: the body all around it), "bottom" (apart from the torso, left of it, cut by the photo's
    bottom border: an elbow the frame cuts), "side" (left of the head, cut by the photo's left border), "far" (a small
    disc apart from the torso, further from it than twice its size), "person" (a
    small second head and shoulders, right of the subject's head). ``sharp_thing``: its texture as sharp as the
    body's (in focus: a held object), else blurred by a Gaussian of ``blur`` px. ``skin``: the contrast of the body's
    fine texture."""
    rng = np.random.default_rng(7)
    yy, xx = np.mgrid[0:H, 0:W] + 0.5
    backdrop = cv2.GaussianBlur(rng.standard_normal((H, W)).astype(np.float32), (0, 0), 4.0)
    rgb = np.repeat((0.45 + 0.5 * backdrop)[..., None], 3, axis=2) * np.array([0.8, 1.0, 0.8], np.float32)
    body = ((xx - 110) ** 2 + (yy - 70) ** 2 < 30**2) | ((xx > 60) & (xx < 160) & (yy > 95))
    if thing == "beside":
        part = ((xx - 42) / 22) ** 2 + ((yy - 80) / 28) ** 2 < 1.0
    elif thing == "leaning":
        part = ((xx - LEAN[0]) / 22) ** 2 + ((yy - LEAN[1]) / 28) ** 2 < 1.0
    elif thing == "front":
        part = (xx > 90) & (xx < 130) & (yy > 150) & (yy < 200)
    elif thing == "bottom":
        part = (xx > 10) & (xx < 50) & (yy > 190)
    elif thing == "side":
        part = (xx < 40) & (np.abs(yy - 80) < 25)
    elif thing == "far":
        part = (xx - 20) ** 2 + (yy - 200) ** 2 < 9**2
    else:
        part = ((xx - 168) ** 2 + (yy - 60) ** 2 < 16**2) | ((xx > 150) & (xx < 190) & (yy > 74) & (yy < 100))
    part &= ~body if thing != "front" else True
    fine = rng.standard_normal((H, W)).astype(np.float32)
    tone = 0.55 + skin * fine
    rgb[body] = (tone[body, None] * np.array([1.0, 0.8, 0.7], np.float32)).astype(np.float32)
    texture = fine if sharp_thing else cv2.GaussianBlur(fine, (0, 0), blur) * 4.0
    rgb[part] = ((0.5 + 0.12 * texture[part, None]) * np.array([0.9, 0.35, 0.3], np.float32)).astype(np.float32)
    return np.clip(rgb, 0.0, 1.0).astype(np.float32), {"body": body & ~part, "thing": part}


def maps(parts: dict[str, np.ndarray], held_thing: float = 0.99, seen_thing: float = 0.01
         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """(matte, held, pose) on the photo's grid: the matte holds both parts, the people's segmentations hold them at
    0.99 (the thing at ``held_thing``), the pose graph sees the body (0.99, its outline 2 px inside the matte's) and
    the thing at ``seen_thing``."""
    matte = parts["body"] | parts["thing"]
    held = np.where(parts["thing"], held_thing, np.where(matte, 0.99, 0.01)).astype(np.float32)
    pose = np.where(_erode(parts["body"], 2), 0.99, np.where(parts["thing"], seen_thing, 0.01)).astype(np.float32)
    return matte, held, pose


def taken(rgb: np.ndarray, parts: dict[str, np.ndarray], held_thing: float = 0.99, seen_thing: float = 0.01,
          faces: list[tuple[float, float, float, float]] = ()) -> np.ndarray:  # fmt: skip
    """What the rule takes out of the hard matte of ``parts`` (the photo's pixels), through
    tb.without_things_behind, one selfie-graph person holding ``maps``' segmentation: (H, W) bool, alpha >= 0.5
    before and < 0.5 after."""
    alpha = (parts["body"] | parts["thing"]).astype(np.float32)
    people, pose = _people(parts, 1, held_thing=held_thing, seen_thing=seen_thing)
    out = tb.without_things_behind(rgb, alpha, people, pose, lambda: [Face(f, 0.9) for f in faces])
    return (alpha >= 0.5) & (out < 0.5)


def test_blurred_thing_beside_the_shoulder_leaves():
    rgb, parts = scene()
    things = taken(rgb, parts, faces=[FACE])
    assert things[parts["thing"]].mean() > 0.9
    to_thing = cv2.distanceTransform((~parts["thing"]).astype(np.uint8), cv2.DIST_L2, 5)
    assert not things[parts["body"] & (to_thing > 3)].any()  # (the opening leaves a corner of the join)


def test_the_thing_is_found_beside_the_strip_the_pose_graph_leaves_along_the_outline():
    rgb, parts = scene()
    matte, held, pose = maps(parts)
    things = taken(rgb, parts)
    strip = matte & (pose < 0.5) & ~parts["thing"]  # the body's outline the pose graph does not see
    assert strip.sum() > 500 and things[parts["thing"]].mean() > 0.9
    assert things[strip].mean() < 0.05  # (a corner of it at the join, which the opening leaves)


@pytest.mark.parametrize(
    ("case", "kwargs", "held_thing", "seen_thing"),
    [
        ("in focus (a held object)", {"sharp_thing": True}, 0.99, 0.01),
        ("before the body (all around it)", {"thing": "front"}, 0.99, 0.01),
        ("cut by the bottom border (a body cut by the frame goes on)", {"thing": "bottom"}, 0.99, 0.01),
        ("an own-colours part (the people's segmentations hardly hold it)", {}, 0.1, 0.01),
        ("half seen by the pose graph (a sleeve it is unsure of)", {}, 0.99, 0.3),
    ],
)
def test_left_alone(case, kwargs, held_thing, seen_thing):
    rgb, parts = scene(**kwargs)
    assert parts["thing"].sum() > 12, case
    assert not taken(rgb, parts, held_thing, seen_thing).any(), case


def test_a_smooth_body_is_read_by_its_own_texture():
    rgb, parts = scene(skin=0.003, blur=1.3)  # a smooth face, sharp, beside a slightly blurred thing of more contrast
    things = taken(rgb, parts)  # 0.50 x as sharp as the body (0.69 x the whole matte)
    assert things[parts["thing"]].mean() > 0.9


def test_a_side_border_is_no_sign_of_a_body():
    rgb, parts = scene("side")  # a stage light cut by the frame's side (p016, p064's top): it leaves
    things = taken(rgb, parts)
    assert things[parts["thing"]].mean() > 0.9 and not things[parts["body"]].any()


def bust() -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """A bust that the frame does not cut (a full-length figure's upper part): the pose graph sees only the sharp
    face ("body"), the torso in a plain, barely textured cloth ("thing") ends 40 px above the bottom border."""
    rng = np.random.default_rng(3)
    yy, xx = np.mgrid[0:H, 0:W] + 0.5
    noise = cv2.GaussianBlur(rng.standard_normal((H, W)).astype(np.float32), (0, 0), 4)
    rgb = np.full((H, W, 3), 0.45, np.float32) + 0.2 * noise[..., None]
    head = (xx - 100) ** 2 + (yy - 50) ** 2 < 25**2
    torso = (xx > 60) & (xx < 140) & (yy > 72) & (yy < 200)
    fine = rng.standard_normal((H, W)).astype(np.float32)
    rgb[head] = (0.55 + 0.12 * fine[head])[:, None]
    cloth = cv2.GaussianBlur(fine, (0, 0), 1.2) * 2.0
    rgb[torso] = (0.3 + 0.08 * cloth[torso])[:, None] * np.array([0.4, 0.5, 0.9], np.float32)
    return np.clip(rgb, 0, 1).astype(np.float32), {"body": head, "thing": torso & ~head}


def test_a_bust_not_cut_by_the_border_keeps_its_torso():
    rgb, parts = bust()  # the torso reads blurred and sticks out; it is most of the matte: a body, not a thing
    assert not taken(rgb, parts).any()
    assert not taken(rgb, parts, faces=[(82.0, 30.0, 118.0, 72.0)]).any()


def test_a_part_with_a_face_is_someone():
    rgb, parts = scene("person")  # a small blurred person beside the subject: _behind's to judge, whole
    assert parts["thing"].sum() < tb._MAX_PART * (parts["body"] | parts["thing"]).sum()
    assert taken(rgb, parts)[parts["thing"]].mean() > 0.9  # a thing, without the face
    assert not taken(rgb, parts, faces=[FACE, SECOND]).any()


def test_bodily():
    part = np.zeros((100, 100), bool)
    face = (40.0, 20.0, 60.0, 40.0)
    part[30:34, 48:52] = True  # in the face's middle half
    assert tb.bodily(part, [face])
    part[:] = False
    part[45:60, 45:55] = True  # under the chin, within _NECK x its width
    assert tb.bodily(part, [face])
    part[:] = False
    part[20:40, 57:80] = True  # beside the head, over the face box's edge (p064's stage light)
    assert not tb.bodily(part, [face])
    part[:] = False
    part[55:70, 45:55] = True  # further down than a neck
    assert not tb.bodily(part, [face]) and not tb.bodily(part, [])


def test_no_detail_on_the_body_decides_nothing():
    rgb, parts = scene()
    flat = rgb.copy()
    flat[parts["body"]] = 0.5  # no texture where the pose graph sees the person: no sharpness to compare with
    assert not taken(flat, parts).any()


def test_detail_ratio():
    rng = np.random.default_rng(0)
    noise = rng.standard_normal((64, 64)).astype(np.float32)
    fine = np.abs(noise - cv2.GaussianBlur(noise, (0, 0), 1.0))
    mid = np.abs(noise - cv2.GaussianBlur(noise, (0, 0), 3.0))
    everywhere = np.ones(noise.shape, bool)
    sharp = tb.detail_ratio(fine, mid, everywhere)
    soft = cv2.GaussianBlur(noise, (0, 0), 2.0)
    blurred = tb.detail_ratio(np.abs(soft - cv2.GaussianBlur(soft, (0, 0), 1.0)),
                              np.abs(soft - cv2.GaussianBlur(soft, (0, 0), 3.0)), everywhere)  # fmt: skip
    assert 0.0 < blurred < 0.5 * sharp < 1.0
    assert np.isnan(tb.detail_ratio(np.zeros((4, 4)), np.zeros((4, 4)), np.ones((4, 4), bool)))


def _people(parts: dict[str, np.ndarray], scale: int, source: str = "roi", held_thing: float = 0.99, pad: int = 0,
            seen_thing: float = 0.01):  # fmt: skip
    """A person (``source``) whose region covers the photo at ``scale`` (with ``pad`` rows added below), holding
    ``maps``' segmentation, and the pose graph's logits for them."""
    matte, held, pose = maps(parts, held_thing, seen_thing)
    h, w = matte.shape
    big = (h * scale, w * scale)
    region = Region(big[1] / 2, big[0] / 2, float(max(big)))

    def canvas(m: np.ndarray) -> np.ndarray:
        up = cv2.resize(m, (big[1], big[0]), interpolation=cv2.INTER_LINEAR)
        up = np.pad(up, ((0, pad), (0, 0)), constant_values=0.01)
        return as_logits(np.clip(crop_region(up, region), 0.01, 0.99))

    return [Person(region, canvas(held), 0.9, source)], (lambda p: canvas(pose))


def _up(a: np.ndarray, scale: int) -> np.ndarray:
    return a if scale == 1 else cv2.resize(a, (a.shape[1] * scale, a.shape[0] * scale), interpolation=cv2.INTER_NEAREST)


def _faces(scale: int = 1):
    return lambda: [Face(tuple(v * scale for v in FACE), 0.9)]


@pytest.mark.parametrize("scale", [1, 3])  # 3: the matte's side past _SIDE, read on a reduced grid
def test_without_things_behind_on_the_photo(scale):
    rgb, parts = scene()
    people, pose = _people(parts, scale)
    alpha = _up((parts["body"] | parts["thing"]).astype(np.float32), scale)
    asked = []
    out = tb.without_things_behind(_up(rgb, scale), alpha, people, lambda p: asked.append(p) or pose(p), _faces(scale))
    thing, body = _up(parts["thing"].astype(np.uint8), scale) > 0, _up(parts["body"].astype(np.uint8), scale) > 0
    assert (out[_erode(thing, 1)] == 0).all()  # the whole part, up to its outline (the grid's pixel centres)
    inner_body = _erode(body, 3 * scale)
    np.testing.assert_array_equal(out[inner_body], alpha[inner_body])
    assert (out >= 0.5).sum() > 0.95 * body.sum()
    assert len(asked) == 1  # one pose-graph view for the region
    assert out is not alpha and alpha[thing].min() == 1.0  # a new array; the input untouched


def test_a_soft_matte_loses_the_part_softly_and_whole():
    scale = 5  # read on a grid of _SIDE px: a grid pixel is 2.2 px of the photo
    rgb, parts = scene("leaning")  # against the torso's side: the cut runs through the matte
    people, pose = _people(parts, scale)
    thing, body = (_up(parts[k].astype(np.uint8), scale) > 0 for k in ("thing", "body"))
    alpha = np.clip(cv2.GaussianBlur((thing | body).astype(np.float32), (0, 0), 2.0), 0.0, 1.0)
    out = tb.without_things_behind(_up(rgb, scale), alpha, people, pose, _faces(scale))
    assert (out[thing] < 0.5).mean() > 0.99
    n, _ = cv2.connectedComponents((out >= 0.5).astype(np.uint8), connectivity=8)
    assert n == 2  # the body, and no sliver along the part's outline
    to_thing = cv2.distanceTransform((~thing).astype(np.uint8), cv2.DIST_L2, 5)
    to_body = cv2.distanceTransform((~body).astype(np.uint8), cv2.DIST_L2, 5)
    body_rim = (alpha > 0.02) & (alpha < 0.98) & (to_body < to_thing) & (to_thing > 4 * scale)  # past the join
    assert body_rim.sum() > 1000
    np.testing.assert_array_equal(out[body_rim], alpha[body_rim])  # the body's own soft edge near the part stays
    thing_rim = (alpha > 0.02) & (to_thing < to_body - 6)
    assert thing_rim.sum() > 1000 and out[thing_rim].max() < 0.02  # the part's soft rim goes with it
    hard = _erode(alpha >= 0.999, 1)
    step = max(np.abs(np.diff(out, axis=0))[hard[1:] & hard[:-1]].max(),
               np.abs(np.diff(out, axis=1))[hard[:, 1:] & hard[:, :-1]].max())  # fmt: skip
    assert 0.0 < step < 0.6  # the cut through the matte is soft, not a grid pixel's staircase


def test_the_grid_reads_the_photo_where_it_lies():
    yy, xx = np.mgrid[0:700, 0:600] + 0.5
    disc = (((xx - 330) ** 2 + (yy - 370) ** 2) < 240**2).astype(np.float32)
    region = Region(300.0, 350.0, 700.0)
    person = Person(region, as_logits(np.clip(crop_region(disc, region), 0.01, 0.99)), 0.9, "roi")
    grid, (x0, y0, x1, y1), s = tb.reading_grid((disc >= 0.5).astype(np.uint8))
    assert s < 0.8
    read = cv2.resize(disc[y0:y1, x0:x1], grid[:2], interpolation=cv2.INTER_AREA) >= 0.5
    held = logits_on_grid(person, grid) > 0
    centre = [np.mean(np.nonzero(m), axis=1) for m in (read, held)]
    np.testing.assert_allclose(centre[0], centre[1], atol=0.2)  # the people's maps lie where the photo's pixels do


def test_own_colours_parts_do_not_hold_a_part():
    rgb, parts = scene()
    people, pose = _people(parts, 1, held_thing=0.05)  # the selfie graph hardly holds the thing ...
    own, _ = _people(parts, 1, source="own")  # ... the own colours' part does
    alpha = (parts["body"] | parts["thing"]).astype(np.float32)
    assert tb.without_things_behind(rgb, alpha, people + own, pose, _faces()) is alpha


def test_only_the_photos_bottom_border_keeps_a_part():
    rgb, parts = scene("bottom")
    alpha = (parts["body"] | parts["thing"]).astype(np.float32)
    people, pose = _people(parts, 1)
    assert tb.without_things_behind(rgb, alpha, people, pose, _faces()) is alpha  # cut by the frame
    pad = 30  # the same photo with rows below: the part no longer goes on past the frame, and leaves
    people, pose = _people(parts, 1, pad=pad)
    out = tb.without_things_behind(
        np.pad(rgb, ((0, pad), (0, 0), (0, 0)), mode="edge"), np.pad(alpha, ((0, pad), (0, 0))), people, pose, _faces()
    )
    assert (out[:H][_erode(parts["thing"], 1)] == 0).all()


def test_pose_graph_people_are_not_read():
    rgb, parts = scene()
    people, pose = _people(parts, 1, source="pose")
    alpha = (parts["body"] | parts["thing"]).astype(np.float32)
    asked = []
    out = tb.without_things_behind(rgb, alpha, people, lambda p: asked.append(p) or pose(p), _faces())
    assert out is alpha and not asked  # their segmentation is the pose graph's view: nothing they hold is unseen


def test_one_pose_graph_view_per_region():
    rgb, parts = scene()
    people, pose = _people(parts, 1)
    asked = []
    alpha = (parts["body"] | parts["thing"]).astype(np.float32)
    two = [people[0], Person(people[0].region, people[0].logits - 1.0, 0.9, "roi")]  # parts of one segmentation
    out = tb.without_things_behind(rgb, alpha, two, lambda p: asked.append(p) or pose(p), _faces())
    assert len(asked) == 1 and (out[_erode(parts["thing"], 1)] == 0).all()
    other = Person(Region(W / 2, H / 2 + 1.0, float(H)), people[0].logits, 0.9, "roi")
    tb.without_things_behind(rgb, alpha, [people[0], other], lambda p: asked.append(p) or pose(p), _faces())
    assert len(asked) == 3


def test_a_face_box_that_is_not_finite_is_no_ones():
    rgb, parts = scene()
    people, pose = _people(parts, 1)
    alpha = (parts["body"] | parts["thing"]).astype(np.float32)
    nan = Face((float("nan"), 10.0, 30.0, float("inf")), 0.9)
    out = tb.without_things_behind(rgb, alpha, people, pose, lambda: [nan, *_faces()()])
    assert (out[_erode(parts["thing"], 1)] == 0).all()


def test_faces_are_asked_only_when_a_part_would_leave():
    rgb, parts = scene(sharp_thing=True)
    people, pose = _people(parts, 1)
    alpha = (parts["body"] | parts["thing"]).astype(np.float32)
    asked = []
    assert tb.without_things_behind(rgb, alpha, people, pose, lambda: asked.append(1) or []) is alpha
    assert not asked


def test_own_colours_parts_and_an_empty_matte_are_not_read():
    rgb, parts = scene()
    people, pose = _people(parts, 1, source="own")
    alpha = (parts["body"] | parts["thing"]).astype(np.float32)
    assert tb.without_things_behind(rgb, alpha, people, pose, _faces()) is alpha  # no person but an own-colours part
    people, pose = _people(parts, 1)
    empty = np.zeros_like(alpha)
    assert tb.without_things_behind(rgb, empty, people, pose, _faces()) is empty


@pytest.fixture(scope="module")
def probes(shared_dir, load_benchmark):
    """benchmarks/things_behind_probes.py, which reads ../shared/realdata/people_masks (evaluation only, never copied;
    issue 48): the test is skipped when it is absent."""
    if not (shared_dir / "realdata" / "people_masks" / "photos").is_dir():
        pytest.skip("../shared/realdata/people_masks is not present")
    module = load_benchmark("things_behind_probes")
    module.PHOTOS = shared_dir / "realdata" / "people_masks" / "photos"  # where the fixture found it (a worktree's too)
    return module


def test_a_couples_blurred_partner_stays_and_the_foliage_leaves(probes):
    from relight_rt.person.matting import shared_matter

    alpha, out, gt = probes.couple(shared_matter(), 1.0)  # p089, the partner blurred, rows below: nothing guards them
    assert probes.taken(alpha, out) < 0.05  # the foliage below the joined hands (2.4 %; 46.7 % before the review)
    assert probes.E.iou(out >= 0.5, gt) > probes.E.iou(alpha >= 0.5, gt) + 0.01


class _Counted:
    """A graph that counts its runs."""

    def __init__(self, model):
        self.model, self.runs = model, 0

    def run(self, feeds):
        self.runs += 1
        return self.model.run(feeds)


def test_the_matter_runs_the_face_graph_once_where_a_part_leaves(probes):
    """The things-behind step asks for the whole photo's faces, which the people search found already: the matter
    answers it from the same photo's block (relight_rt.image.regions.reductions_shared) instead of a second run."""
    import copy

    from relight_rt.person.matting import shared_matter

    rgb, _ = probes.read("p104")  # a guitar behind the girl's shoulder leaves
    matter = copy.copy(shared_matter())  # (the shared matter is left as it is)
    matter.face = _Counted(matter.face)
    people, before = probes.before_rule(matter, rgb)  # (the rule left out: no faces asked for the matte)
    searched = matter.face.runs
    assert searched >= 1
    matter.face.runs = 0
    alpha = matter(rgb)
    assert probes.taken(before, alpha) > 0.02  # the part leaves: the faces were asked for ...
    assert matter.face.runs == searched  # ... and no run was added to the people search's (before: one more)
    np.testing.assert_array_equal(alpha, probes.rule(matter, rgb, before, people))  # the same matte


# -- the second review (mend21b) ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("thing", ["side", "far"])
def test_a_thing_apart_from_the_body_leaves_whole_on_a_reduced_grid(thing):
    scale = 5  # read on a grid of _SIDE px; the thing (cut by the left border, p016's blob) never touches the body
    rgb, parts = scene(thing)
    people, pose = _people(parts, scale)
    thing, body = (_up(parts[k].astype(np.uint8), scale) > 0 for k in ("thing", "body"))
    alpha = np.clip(cv2.GaussianBlur((thing | body).astype(np.float32), (0, 0), 1.0), 0.0, 1.0)
    out = tb.without_things_behind(_up(rgb, scale), alpha, people, pose, _faces(scale))
    n, _ = cv2.connectedComponents((out >= 0.5).astype(np.uint8), connectivity=8)
    assert n == 2  # the body alone: no outline of the thing along its inner edge
    to_body = cv2.distanceTransform((~body).astype(np.uint8), cv2.DIST_L2, 5)
    assert not (out[to_body > 6] > 0.05).any()  # nor its soft rim


@pytest.mark.parametrize("scale", [1, 3])
def test_a_thin_arm_the_opening_strips_leaves_with_the_thing(scale):
    rgb, parts = scene()
    yy, xx = np.mgrid[0:H, 0:W] + 0.5
    stick = (np.abs(xx - 30) < 1.0) & (yy > 20) & (yy < 60) & ~parts["body"]  # a guitar's neck, 2 px wide
    rgb[stick] = rgb[parts["thing"]].mean(axis=0)
    parts["thing"] = parts["thing"] | stick
    people, pose = _people(parts, scale)
    alpha = np.clip(
        cv2.GaussianBlur(_up((parts["body"] | parts["thing"]).astype(np.float32), scale), (0, 0), 1.0), 0, 1
    )
    out = tb.without_things_behind(_up(rgb, scale), alpha, people, pose, _faces(scale))
    assert (out[_up(stick.astype(np.uint8), scale) > 0] < 0.5).all()  # not a floating stick
    n, _ = cv2.connectedComponents((out >= 0.5).astype(np.uint8), connectivity=8)
    assert n == 2


def test_the_things_wide_soft_rim_leaves_and_the_bodys_stays():
    rgb, parts = scene()
    thing, body = parts["thing"], parts["body"]
    soft_thing = cv2.GaussianBlur(thing.astype(np.float32), (0, 0), 5.0) * 1.6  # the selfie graph's wide soft rim
    alpha = np.clip(np.maximum(cv2.GaussianBlur(body.astype(np.float32), (0, 0), 1.0), soft_thing), 0.0, 1.0)
    alpha[thing] = 1.0
    people, pose = _people(parts, 1)
    out = tb.without_things_behind(rgb, alpha, people, pose, _faces())
    to_thing = cv2.distanceTransform((~thing).astype(np.uint8), cv2.DIST_L2, 5)
    to_body = cv2.distanceTransform((~body).astype(np.uint8), cv2.DIST_L2, 5)
    rim = (alpha > 0.02) & ~thing & (to_thing + 3 < to_body)
    assert (rim & (to_thing > tb.band_width(alpha.shape) + 1)).sum() > 200  # past the refined band
    assert out[rim].max() < 0.02
    body_rim = (alpha > 0.02) & (alpha < 0.5) & (to_body + 3 < to_thing) & (to_thing < 12)  # its soft edge beside it
    assert body_rim.sum() > 20
    np.testing.assert_array_equal(out[body_rim], alpha[body_rim])


def _person(held: np.ndarray, region: Region, source: str = "roi") -> Person:
    return Person(region, as_logits(np.clip(crop_region(held.astype(np.float32), region), 0.01, 0.99)), 0.9, source)


def test_a_second_person_is_measured_against_their_own_segmentation():
    rgb, parts = scene("person")  # a blurred person beside the subject, segmented on their own (a group's peer)
    alpha = (parts["body"] | parts["thing"]).astype(np.float32)
    assert parts["thing"].sum() < tb._MAX_PART * alpha.sum()  # a small share of everyone's matte ...
    region = Region(W / 2, H / 2, float(H))
    people = [_person(parts["body"], region), _person(parts["thing"], region)]
    pose = maps(parts)[2]
    out = tb.without_things_behind(rgb, alpha, people, lambda p: _person(pose, region).logits, lambda: [])
    assert out is alpha  # ... but the whole of their own: no face needed to keep them
    one = [_person(parts["body"] | parts["thing"], region)]  # one segmentation holding both: a thing without a face
    out = tb.without_things_behind(rgb, alpha, one, lambda p: _person(pose, region).logits, lambda: [])
    assert (out[_erode(parts["thing"], 1)] == 0).all()


@pytest.mark.parametrize("scale", [1, 3])
def test_a_face_keeps_the_part_it_lies_on_where_the_grid_starts_inside_the_photo(scale):
    rgb, parts = scene("person")
    pad = 60  # backdrop above and left of the scene: the grid's box starts inside the photo
    rgb = np.pad(rgb, ((pad, 0), (pad, 0), (0, 0)), mode="reflect")
    parts = {k: np.pad(v, ((pad, 0), (pad, 0))) for k, v in parts.items()}
    people, pose = _people(parts, scale)
    alpha = _up((parts["body"] | parts["thing"]).astype(np.float32), scale)
    face = tuple(scale * (v + pad) for v in SECOND)
    out = tb.without_things_behind(_up(rgb, scale), alpha, people, pose, lambda: [Face(face, 0.9)])
    assert out is alpha  # the face's person stays
    out = tb.without_things_behind(_up(rgb, scale), alpha, people, pose, lambda: [])
    thing = _up(parts["thing"].astype(np.uint8), scale) > 0
    assert (out[_erode(thing, scale)] == 0).all()  # without it, a blurred thing sticking out


def test_the_largest_piece_by_the_cut_stays_only_when_the_matte_lies_wholly_in_the_window():
    yy, xx = np.mgrid[0:60, 0:60] + 0.5
    weight = (((xx - 30) ** 2 + (yy - 30) ** 2) < 10**2).astype(np.float32)  # the part
    alpha = (((xx - 30) ** 2 + (yy - 30) ** 2) < 13**2).astype(np.float32)  # a 3-px ring of the matte around it
    seen = np.zeros(alpha.shape, bool)
    gone = tb._leave(alpha, weight, seen, 5, 5.0, 1.0, False, 0.0)  # the matte goes on past the window: an outline
    assert gone.max() == 0.0
    kept = tb._leave(alpha, weight, seen, 5, 5.0, 1.0, True, 0.0)  # the whole matte: what is left of it stays
    assert (kept[(alpha == 1) & (weight == 0)] == 1).all()


@pytest.mark.parametrize(("seen", "leaves"), [(0.3, True), (0.9, False)])
def test_the_things_tail_the_pose_graph_half_sees_leaves_with_it(seen, leaves):
    rgb, parts = scene()  # below the thing, a tail of it that the pose graph half-sees (p064's stage light at 4x) ...
    yy, xx = np.mgrid[0:H, 0:W] + 0.5
    tail = (xx > 22) & (xx < 40) & (yy > 100) & (yy < 150) & ~parts["thing"] & ~parts["body"]
    alpha = np.where(tail, 0.6, (parts["body"] | parts["thing"]).astype(np.float32)).astype(np.float32)
    _, held, pose = maps(parts)
    held[tail], pose[tail] = 0.99, seen  # ... or sees: someone's hand, cut off in the matte
    region = Region(W / 2, H / 2, float(H))
    out = tb.without_things_behind(
        rgb, alpha, [_person(held, region)], lambda p: _person(pose, region).logits, _faces()
    )
    assert (out[_erode(parts["thing"], 1)] == 0).all()
    if leaves:
        assert (out[tail] < 0.5).all()  # not a piece of the matte floating where the thing was
    else:
        np.testing.assert_array_equal(out[_erode(tail, 1)], alpha[_erode(tail, 1)])
    n, _ = cv2.connectedComponents((out >= 0.5).astype(np.uint8), connectivity=8)
    assert n == (2 if leaves else 3)


# -- the third review (mend21c) ----------------------------------------------------------------------------------------


@pytest.mark.parametrize("own", [False, True])
def test_a_sharp_piece_apart_from_the_thing_is_not_its_tail(own):
    rgb, parts = scene()  # 3 px below the thing, never joined to it: a hand with a soft wrist, a small peer ...
    yy, xx = np.mgrid[0:H, 0:W] + 0.5
    to_thing = cv2.distanceTransform((~parts["thing"]).astype(np.uint8), cv2.DIST_L2, 5)
    to_body = cv2.distanceTransform((~parts["body"]).astype(np.uint8), cv2.DIST_L2, 5)
    piece = (xx > 20) & (xx < 50) & (yy > 110) & (yy < 150) & (to_thing > 2) & (to_body > 2)
    assert piece.sum() > 1000 and to_thing[piece].min() < 4  # (within the band the cut's slivers are read in)
    rgb[piece] = rgb[parts["body"]][: piece.sum()]  # ... sharp, in the body's texture
    alpha = (parts["body"] | parts["thing"] | piece).astype(np.float32)
    _, held, pose = maps(parts)
    held[piece], pose[piece] = 0.99, 0.01  # ... that the pose graph misses
    region = Region(W / 2, H / 2, float(H))
    people = ([_person(np.where(piece, 0.01, held), region), _person(np.where(piece, 0.99, 0.01), region)] if own
              else [_person(held, region)])  # fmt: skip
    out = tb.without_things_behind(rgb, alpha, people, lambda p: _person(pose, region).logits, _faces())
    assert (out[_erode(parts["thing"], 1)] == 0).all()  # the thing leaves ...
    np.testing.assert_array_equal(out[piece], alpha[piece])  # ... the piece beside it stays, whole


@pytest.mark.parametrize(("end", "leaves"), [(50, True), (60, False)])
def test_a_tail_that_runs_on_past_the_window_stays(end, leaves):
    yy, xx = np.mgrid[0:60, 0:60] + 0.5
    weight = (((xx - 30) ** 2 + (yy - 30) ** 2) < 8**2).astype(np.float32)  # the part
    body = xx < 8  # the matte that stays, apart from it
    tail = (xx > 30) & (xx < end) & (np.abs(yy - 30) < 3)  # joined to it, unseen; to the window's edge: it goes on
    alpha = (body | tail | (weight > 0)).astype(np.float32)
    out = tb._leave(alpha, weight, np.zeros(alpha.shape, bool), 2, 2.0, 1.0, False, 1000.0)
    past = tail & (xx > 42)
    assert (out[past] == 0).all() if leaves else (out[past] == 1).all()
    assert (out[body] == 1).all()


def test_the_soft_rim_is_cleared_only_up_to_the_halo():
    yy, xx = np.mgrid[0:80, 0:80] + 0.5
    weight = (((xx - 25) ** 2 + (yy - 40) ** 2) < 6**2).astype(np.float32)  # the part
    body = xx > 72  # the matte that stays, far from it
    to_part = cv2.distanceTransform((weight <= 0).astype(np.uint8), cv2.DIST_L2, 5)
    soft = (xx < 31) & (weight == 0)  # soft pixels on the part's far side, nearer it than the body
    alpha = np.where(body | (weight > 0), 1.0, np.where(soft, 0.3, 0.0)).astype(np.float32)
    out = tb._leave(alpha, weight, np.zeros(alpha.shape, bool), 2, 8.0, 1.0, False, 0.0)
    assert (out[soft & (to_part < 7)] == 0).all()  # its rim, within the halo, leaves ...
    far = soft & (to_part > 9)
    assert far.sum() > 100 and (out[far] == alpha[far]).all()  # ... what lies past it stays


@pytest.mark.parametrize("scale, gap", [(5, 1), (8, 2)])
def test_a_piece_beside_a_part_read_on_a_reduced_grid_is_not_its_tail(scale, gap):
    """A part decided on a reduced grid is scaled up bilinearly: its share reaches ~1 / (2 s) px past it, so a piece
    apart from it that close read as joined before the cut and left as its tail (final reader of mend21c: a piece 1 px
    from a part scaled up 5x, 2 px at 8x, went whole). Joined means joined to the part itself (share >= 0.5)."""
    grid = np.zeros((40, 40), np.float32)
    grid[10:20, 10:30] = 1
    weight = cv2.resize(grid, (40 * scale, 40 * scale), interpolation=cv2.INTER_LINEAR)
    yy, xx = np.mgrid[0 : 40 * scale, 0 : 40 * scale]
    part = weight >= 0.5
    bottom = int(np.nonzero(part.any(axis=1))[0].max())
    body = ((xx < 20) & (yy > 25) & (yy < 65)) | ((xx >= 20) & (xx < 32) & (yy > 35) & (yy < 50))  # joined to it
    piece = (yy >= bottom + 1 + gap) & (yy < bottom + 13 + gap) & (xx > 50) & (xx < 80)
    alpha = (part | body | piece).astype(np.float32)
    out = tb._leave(alpha, weight, np.zeros(alpha.shape, bool), 3, 3.0, 4.0, False, 5000.0)
    assert (out[piece] >= 0.5).all()  # before: none of it
    assert (out[part & (yy < bottom - 10)] < 0.5).all()  # the part itself leaves


# -- speed17: the leaving's cost at large photos -----------------------------------------------------------------------


def _dt(mask: np.ndarray) -> np.ndarray:
    return cv2.distanceTransform((~mask).astype(np.uint8), cv2.DIST_L2, 3)


@pytest.mark.parametrize("seed", range(6))
def test_near_measured_in_a_box_is_the_whole_windows_distance(seed):
    rng = np.random.default_rng(seed)
    h, w = rng.integers(60, 160, 2)
    mask = np.zeros((h, w), bool)
    y, x = rng.integers(10, h - 10), rng.integers(10, w - 10)
    mask[y - 5 : y + 5, x - 8 : x + 3] = rng.random((10, 11)) > 0.3  # a ragged part in the middle
    for reach in (1.0, 4.5, 13.0, 40.0):
        np.testing.assert_array_equal(tb._near(mask, reach), _dt(mask) <= reach)
    where = np.zeros((h, w), bool)
    where[rng.integers(0, h, 30), rng.integers(0, w, 30)] = True
    kept = rng.random((h, w)) > 0.97  # the matte that stays, scattered over the window
    for ramp in (1.0, 2.5, 6.0):
        np.testing.assert_array_equal(tb._near(kept, ramp, where), where & (_dt(kept) <= ramp))
    assert not tb._near(np.zeros((h, w), bool), 5.0).any() and not tb._near(kept, 5.0, np.zeros((h, w), bool)).any()


def test_blocks_hold_a_pixel_where_one_of_theirs_does():
    mask = np.zeros((7, 10), bool)
    mask[0, 0] = mask[4, 5] = mask[6, 9] = True  # the last block row and column are cut by the edge
    blocks = tb._blocks(mask, 3)
    assert blocks.shape == (3, 4)
    assert np.array_equal(np.argwhere(blocks), [[0, 0], [1, 1], [2, 3]])
    assert tb._blocks(mask, 1) is mask


def _soft_scene() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(alpha, weight, seen) of a window: a body (x > 110) and a part (a disc) joined by a neck, each with a wide
    soft rim that meets the other's between them."""
    yy, xx = np.mgrid[0:160, 0:200] + 0.5
    part = (xx - 60) ** 2 + (yy - 80) ** 2 < 25**2
    body = (xx > 110) | ((np.abs(yy - 80) < 6) & (xx > 80))
    alpha = 0.9 * cv2.GaussianBlur((part | body).astype(np.float32), (0, 0), 6.0)  # (< 0.5 outside them)
    alpha[part | body] = 1.0
    weight = cv2.GaussianBlur(part.astype(np.float32), (0, 0), 1.0)
    weight[weight < 0.02] = 0.0
    return alpha.astype(np.float32), weight.astype(np.float32), np.zeros(alpha.shape, bool)


def test_the_soft_rim_read_on_blocks_moves_only_soft_pixels_by_the_cut():
    alpha, weight, seen = _soft_scene()
    exact = tb._leave(alpha, weight, seen, 4, 30.0, 2.0, True, 5000.0)
    rim = (alpha > 0) & (alpha < 0.5) & (exact == 0)
    assert rim.sum() > 1000  # the part's soft rim leaves ...
    assert (exact[(alpha > 0) & (alpha < 0.5) & (np.mgrid[0:160, 0:200][1] > 120)] > 0).all()  # ... the body's stays
    for step in (2, 3, 5):
        blocks = tb._leave(alpha, weight, seen, 4, 30.0, 2.0, True, 5000.0, step)
        moved = blocks != exact
        np.testing.assert_array_equal(blocks >= 0.5, exact >= 0.5)  # the hard matte as it was
        assert moved.sum() < 0.05 * rim.sum() and (alpha[moved] < 0.5).all()
        # each moved pixel lies within a block of the split between the part and the body, or of the halo's end
        part_px = (exact == 0) & (alpha >= 0.5)
        to_part, to_kept, to_weight = _dt(part_px), _dt(exact >= 0.5), _dt(weight > 0)
        assert (np.minimum(np.abs(to_part - to_kept), np.abs(to_weight - 30.0))[moved] <= 2 * step).all()


@pytest.mark.parametrize("pad", [(0, 0, 0, 0), (7, 0, 12, 3), (20, 15, 9, 11)])
def test_a_window_cut_to_the_box_of_what_changes_gives_the_same_matte(pad):
    alpha, weight, seen = _soft_scene()
    yy, xx = np.mgrid[0:160, 0:200] + 0.5
    tail = (xx > 35) & (xx < 55) & (yy > 95)  # joined to the part, unseen: its tail, down to the box's bottom
    alpha[tail] = np.maximum(alpha[tail], 0.8)
    tail &= weight == 0
    top, bottom, left, right = pad  # the window before the cut reached this far past the box (nothing of the matte)
    big = [np.pad(a, ((top, bottom), (left, right))) for a in (alpha, weight, seen)]
    whole = tb._leave(*big, 4, 30.0, 2.0, False, 5000.0)
    sides = (top == 0, bottom == 0, left == 0, right == 0)
    cut = tb._leave(alpha, weight, seen, 4, 30.0, 2.0, False, 5000.0, 1, sides)
    np.testing.assert_array_equal(whole[top : top + 160, left : left + 200], cut)
    assert (cut[tail] < 0.5).all() == (bottom > 0)  # at the window's bottom edge the tail may go on: it stays


def test_many_pieces_are_read_as_joined_alike_in_one_look_up(monkeypatch):
    """Past _FEW_PIECES the pieces' joining is read in one window-wide look-up (a loop per piece took 7x longer on a
    window of specks): the same matte as the loop's."""
    alpha, weight, seen = _soft_scene()
    yy, xx = np.mgrid[0:160, 0:200] + 0.5
    alpha[(yy % 3 < 1) & (xx % 3 < 1) & (yy < 40)] = 1.0  # hundreds of one-pixel pieces
    tail = (xx > 35) & (xx < 55) & (yy > 95)  # joined to the part, unseen: its tail
    alpha[tail] = np.maximum(alpha[tail], 0.8)
    tail &= weight == 0
    sides = (True, False, True, True)  # (the window's bottom is no edge: the part's tail there leaves)
    monkeypatch.setattr(tb, "_FEW_PIECES", 10**9)
    loop = tb._leave(alpha, weight, seen, 4, 30.0, 2.0, False, 5000.0, 1, sides)
    monkeypatch.setattr(tb, "_FEW_PIECES", 0)
    one = tb._leave(alpha, weight, seen, 4, 30.0, 2.0, False, 5000.0, 1, sides)
    assert cv2.connectedComponents((alpha >= 0.5).astype(np.uint8))[0] > 300
    np.testing.assert_array_equal(loop, one)
    assert (loop[tail] < 0.5).all()  # the joined tail went (read as joined both ways)
