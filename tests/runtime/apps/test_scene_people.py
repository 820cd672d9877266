"""relight_rt.apps.scene_people: the horizon from the people standing in a background, and room beside them
(synthetic people: boxes drawn from the perspective rule, a stand-in for the person graphs, stick figures)."""

import logging

import numpy as np
import pytest
from _graphs import diffuse_models_dir

from relight_rt import RelightError
from relight_rt.apps import scene_people
from relight_rt.apps.scene_people import (
    Someone,
    combine_horizons,
    find_people,
    make_room,
    people_horizon,
    place_among_people,
)
from relight_rt.apps.scene_place import CAMERA_M, PERSON_M, place
from relight_rt.person.face_detector import FACE_SIZE, GRID
from relight_rt.person.matting import PersonMatter, Region, _detect

__all__ = ["diffuse_models_dir"]  # fixtures


def standing(feet, horizon, x=0.5, metres=PERSON_M, camera=CAMERA_M, full=True):
    """A person ``metres`` tall whose feet are at row ``feet`` under a level camera ``camera`` metres up with its
    horizon at ``horizon`` (fractions), 1/4 as wide as tall, centred on column ``x``."""
    tall = (feet - horizon) * metres / camera
    return Someone((x - tall / 8, feet - tall, x + tall / 8, feet), 0.99, full)


def figure(h=200, w=120):
    """A straight-alpha RGBA stick figure, whole (feet at row 180, centred on column 60)."""
    rgba = np.zeros((h, w, 4), np.float32)
    rgba[..., :3] = 0.5
    rgba[20:120, 50:70, 3] = 1
    rgba[120:180, 48:56, 3] = 1
    rgba[120:180, 64:72, 3] = 1
    return rgba


def test_one_person_gives_the_horizon_through_the_standing_camera():
    for hz in (0.3, 0.45, 0.6):
        got, se = people_horizon([standing(0.9, hz)])
        assert got == pytest.approx(hz, abs=1e-9)  # the prior's own camera: exact
        assert 0.05 < se < 0.25  # ... but only as sure as the camera's height is


def test_people_at_several_depths_find_the_horizon_whatever_the_camera():
    # the heads' line and the feet's line meet at the horizon: a camera 2.5 m up, not the assumed 1.5 m
    people = [standing(f, 0.4, camera=2.5) for f in (0.55, 0.7, 0.95)]
    got, se = people_horizon(people)
    alone, _ = people_horizon(people[-1:])
    assert abs(got - 0.4) < 0.35 * abs(alone - 0.4)  # one person alone errs by the camera's height
    assert abs(got - 0.4) < 2 * se
    assert se < people_horizon(people[-1:])[1]


def test_cut_or_lying_people_and_a_child_do_not_count():
    assert people_horizon([standing(0.9, 0.4, full=False)]) is None
    assert people_horizon([]) is None
    people = [standing(f, 0.4) for f in (0.6, 0.75, 0.95)] + [standing(0.8, 0.4, metres=0.9)]  # a child
    got, _ = people_horizon(people)
    assert got == pytest.approx(0.4, abs=0.01)


def test_the_people_win_where_the_verticals_disagree_strongly():
    assert combine_horizons((0.6, 0.01), None) is None  # nobody: the verticals' rule stands
    assert combine_horizons(None, (0.35, 0.04)) == (0.35, "people")
    assert combine_horizons((0.61, 0.008), (0.33, 0.03)) == (0.33, "people")  # the bus: 0.28 apart
    both, which = combine_horizons((0.50, 0.01), (0.46, 0.05))
    assert which == "both" and 0.46 < both < 0.50  # agreeing: the mean weighted by their errors
    assert abs(both - 0.50) < abs(both - 0.46)  # the surer one nearer


class FakeMatter:
    """The person graphs' two calls as relight_rt.apps.scene_people uses them, answering from known boxes (pixels
    of the copy it is given)."""

    def __init__(self, boxes, presence=0.99):
        self.boxes, self.presence, self.shapes = boxes, presence, []

    def find_people(self, rgb):
        self.shapes.append(rgb.shape)
        return [(1.0, b) for b in self.boxes]

    def segment(self, rgb, region, give_up=0.0, passes=None):
        from relight_rt.image.regions import grid_of_region
        from relight_rt.person.matting import Person

        box = next(b for b in self.boxes if Region.around(*b) == region)
        k, bx, by = grid_of_region(region)  # image (x, y) -> canvas (k x + bx, k y + by)
        x0, x1 = (round(k * v + bx) for v in box[0::2])
        y0, y1 = (round(k * v + by) for v in box[1::2])
        logits = np.full((256, 256), -5.0, np.float32)
        logits[y0:y1, x0:x1] = 5.0
        return Person(region, logits, self.presence)


def test_find_people_keeps_upright_whole_people_as_full_bodies():
    photo = np.zeros((300, 400, 3), np.uint8)
    boxes = [(100, 60, 140, 220), (300, 100, 360, 299.5), (10, 200, 120, 260)]  # whole; cut at the bottom; lying
    found = find_people(photo, FakeMatter(boxes))
    assert len(found) == 3
    assert [p.full_body for p in found] == [True, False, False]
    x0, y0, x1, y1 = found[0].box
    assert (x0 * 400, y0 * 300, x1 * 400, y1 * 300) == pytest.approx((100, 60, 140, 220), abs=2)
    assert find_people(photo, FakeMatter(boxes, presence=0.1)) == []  # the pose graph sees nobody


class NoFaceGraph:
    """A stand-in for the face graph that finds no face and counts its runs."""

    def __init__(self):
        self.runs = 0

    def run(self, feeds):
        self.runs += 1
        assert feeds["image"].shape == (1, 3, FACE_SIZE, FACE_SIZE)
        return {"boxes": np.zeros((1, 16, GRID, GRID), np.float32), "scores": np.full((1, 1, GRID, GRID), -50.0)}


class FacedMatter(FakeMatter):
    """FakeMatter whose segment asks for the whole photo's faces, as PersonMatter.segment's portrait check does
    (PersonMatter.find_faces itself, on a face graph that counts its runs)."""

    find_faces = PersonMatter.find_faces

    def __init__(self, boxes):
        super().__init__(boxes)
        self.face = NoFaceGraph()

    def segment(self, rgb, region, give_up=0.0, passes=None):
        self.find_faces(rgb)
        return super().segment(rgb, region, give_up, passes)


def test_the_face_graph_runs_once_per_background_not_once_per_blob():
    photo = np.zeros((300, 400, 3), np.uint8)
    boxes = [(100, 60, 140, 220), (300, 100, 360, 299.5), (10, 200, 120, 260)]
    matter = FacedMatter(boxes)
    found = find_people(photo, matter)
    ways = 2 if _detect.FACE_BOTH_WAYS else 1  # the whole photo: as it comes and mirrored
    assert matter.face.runs == ways  # three blobs, each checking for a portrait, one photo: one run (its answer kept)
    assert found == find_people(photo, FakeMatter(boxes))  # the same people
    find_people(photo, matter)
    assert matter.face.runs == 2 * ways  # a new call, a new photo: asked again


def test_find_people_looks_on_a_small_copy():
    matter = FakeMatter([(200, 100, 260, 340)])
    found = find_people(np.zeros((900, 1600, 3), np.float32), matter)
    assert matter.shapes == [(360, 640, 3)]
    assert found[0].box == pytest.approx((200 / 640, 100 / 360, 260 / 640, 340 / 360), abs=0.01)
    with pytest.raises(RelightError, match="RGB"):
        find_people(np.zeros((90, 160), np.uint8), matter)


def test_a_photo_one_pixel_tall_or_wide_has_nobody_in_it_and_an_empty_one_is_an_error():
    """fuzz8: a 1 x 1, 1 x N or N x 1 photo was refused as "expected an (H, W, 3) RGB photo, got (1, 50, 3)" (it is
    one) where a 2 x 2 or a 15 x 900 one finds nobody; now all of them find nobody, and only an empty array is an
    error."""
    for shape in ((1, 1, 3), (1, 50, 3), (50, 1, 3), (1, 5000, 3), (5000, 1, 3), (2, 2, 3)):
        assert find_people(np.zeros(shape, np.uint8), FakeMatter([(0, 0, 1, 1)])) == []
    for shape in ((0, 5, 3), (5, 0, 3), (0, 0, 3)):
        with pytest.raises(RelightError, match="RGB photo"):
            find_people(np.zeros(shape, np.uint8), FakeMatter([]))


def test_a_default_place_moves_along_its_row_off_a_person_there():
    bg_shape = (400, 600, 3)
    rgba = figure()
    placed = place(rgba, bg_shape, None, None, 0.5)
    # someone stands right where the new person would (their box around the new one's feet)
    cx, feet = (placed.left + placed.width / 2) / 600, placed.feet_y / 400
    there = [standing(feet + 0.02, 0.5, x=cx)]
    moved = make_room(placed, there, bg_shape)
    assert (moved.top, moved.height, moved.width) == (placed.top, placed.height, placed.width)  # same row, size
    x0, _, x1, _ = there[0].box
    assert moved.left >= x1 * 600 - 0.1 * moved.width or moved.left + moved.width <= x0 * 600 + 0.1 * moved.width
    assert moved.feet_x - placed.feet_x == moved.left - placed.left
    assert 0 <= moved.left and moved.left + moved.width <= 600
    # a person elsewhere: nothing moves
    assert make_room(placed, [standing(0.9, 0.5, x=0.05 if cx > 0.5 else 0.95)], bg_shape) == placed


def test_no_free_ground_or_a_given_position_stays_with_a_warning(caplog):
    bg_shape = (400, 600, 3)
    placed = place(figure(), bg_shape, None, None, 0.5)
    wall = [Someone((0.0, 0.2, 1.0, 0.99), 0.99, False)]  # people across the whole row
    with caplog.at_level(logging.WARNING, logger=scene_people.__name__):
        assert make_room(placed, wall, bg_shape) == placed
        assert "no free ground" in caplog.text
        given = place(figure(), bg_shape, (0.5, 0.9), None, 0.5)
        assert make_room(given, [standing(0.92, 0.5)], bg_shape, moved=False) == given
        assert "given position" in caplog.text


def test_place_among_people_takes_the_horizon_from_the_people():
    bg = np.full((400, 600, 3), 128, np.uint8)  # no verticals: the verticals say nothing
    people = [standing(0.9, 0.35, x=0.15), standing(0.7, 0.35, x=0.85)]
    placed, hz = place_among_people(figure(), bg, None, None, None, CAMERA_M, 60.0, lambda photo: people)
    assert hz == pytest.approx(0.35, abs=0.01)
    assert placed.height == pytest.approx((placed.feet_y / 400 - hz) * PERSON_M / CAMERA_M * 400, rel=0.02)
    # nobody there, or nobody looked for: the level camera's 0.5
    assert place_among_people(figure(), bg, None, None, None, CAMERA_M, 60.0, lambda photo: [])[1] == 0.5
    assert place_among_people(figure(), bg, None, None, None, CAMERA_M, 60.0, None)[1] == 0.5
    # a given horizon wins; a cut-off person is not looked around for
    assert place_among_people(figure(), bg, None, None, 0.42, CAMERA_M, 60.0, lambda photo: people)[1] == 0.42
    cut = figure()[:150]

    def no_call(photo):
        raise AssertionError("looked for people for a cut-off person")

    assert place_among_people(cut, bg, None, None, None, CAMERA_M, 60.0, no_call)[1] == 0.5


def test_place_among_people_reads_the_framing_once(monkeypatch):
    from relight_rt.apps import scene_place

    calls, framing = [], scene_place.framing

    def counted(alpha):
        calls.append(alpha.shape)
        return framing(alpha)

    bg = np.full((300, 400, 3), 90, np.uint8)
    alone = place(figure(), bg.shape, None, None, 0.5)
    monkeypatch.setattr(scene_people, "framing", counted)
    monkeypatch.setattr(scene_place, "framing", counted)
    placed, _ = place_among_people(figure(), bg, None, None, 0.5, CAMERA_M, 60.0, None)
    assert len(calls) == 1  # the full-body check and the placement share one reading
    assert (placed.top, placed.left, placed.height, placed.width) == (alone.top, alone.left, alone.height, alone.width)
    assert np.array_equal(placed.premult, alone.premult)


def test_people_are_not_looked_for_with_matting_off():
    from types import SimpleNamespace

    from relight_rt.apps.scene_people import people_finder

    assert people_finder(SimpleNamespace(config=SimpleNamespace(matting="off", device="cpu"))) is None
    finder = people_finder(SimpleNamespace(config=SimpleNamespace(matting="auto", device="cpu")))
    assert callable(finder)
    assert finder(np.full((240, 320, 3), 0.5, np.float32)) == []  # the bundled graphs: nobody in an even grey


def test_only_people_standing_on_the_ground_in_view_count():
    high = standing(0.34, 0.06)  # feet above the verticals' horizon: a balcony, or a pattern taken for a person
    low = standing(0.9, 0.45)
    assert people_horizon([high, low], below=0.5)[0] == pytest.approx(0.45, abs=1e-9)
    assert people_horizon([high], below=0.5) is None
    # no verticals (an even grey): feet above FEET_LEVEL do not stand on the ground a level camera sees
    bg = np.full((400, 600, 3), 128, np.uint8)
    placed, hz = place_among_people(figure(), bg, None, None, None, CAMERA_M, 60.0, lambda photo: [high])
    assert hz == 0.5


def test_composite_stands_a_full_body_off_the_people_found_and_by_their_horizon(diffuse_models_dir, monkeypatch):
    from relight_rt import Relighter, RuntimeConfig
    from relight_rt.apps import scene

    relighter = Relighter(RuntimeConfig(models=diffuse_models_dir, device="cpu", detail=False))
    img = np.zeros((150, 100, 3), np.uint8)
    img[:] = (150, 110, 90)
    mask = np.zeros((150, 100), np.float32)
    mask[20:140, 30:70] = 1.0  # a whole body, feet in frame
    bg = np.full((200, 300, 3), 90, np.uint8)  # no verticals
    kw = {"mask": mask, "meter": "background", "shadow": False, "match_camera": False, "light_wrap": False}

    def person_box(out):
        rows = np.flatnonzero((np.abs(out - 90 / 255).max(2) > 0.02).any(1))
        cols = np.flatnonzero((np.abs(out - 90 / 255).max(2) > 0.02).any(0))
        return rows[0], rows[-1] + 1, cols[0], cols[-1] + 1

    monkeypatch.setattr(scene, "people_finder", lambda r: None)
    y0, y1, x0, x1 = person_box(scene.composite(relighter, img, bg, **kw))  # a level camera's 0.5
    # someone stands where the person would, and with another further back puts the horizon at 0.3
    here = standing(y1 / 200, 0.3, x=(x0 + x1) / 600)
    there = standing(0.6, 0.3, x=0.9)
    monkeypatch.setattr(scene, "people_finder", lambda r: (lambda photo: [here, there]))
    z0, z1, u0, u1 = person_box(scene.composite(relighter, img, bg, **kw))
    assert z1 == pytest.approx(y1, abs=1)  # the same feet row
    assert (z1 - z0) == pytest.approx((y1 - y0) * (y1 / 200 - 0.3) / (y1 / 200 - 0.5), abs=3)  # taller: horizon 0.3
    hx0, _, hx1, _ = here.box
    assert u0 >= hx1 * 300 or u1 <= hx0 * 300  # clear of the person there
