"""The second stage-1 pass on a face seen small (relight_rt.relight.face_pass and the Relighter's use of it)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

import relight_rt
from relight_rt import Relighter, RuntimeConfig, lights
from relight_rt.image.crop import CropGeometry
from relight_rt.relight.decomposition import Decomposition
from relight_rt.relight.face_pass import (
    MIN_HEAD_INPUT,
    SHADOW_LIFTS,
    SMALL_FACE,
    FacePass,
    feather,
    head_box,
    seen_head_box,
)


def _person(r: int, face: int, face_y: int, face_x: int):
    """A standing person in the network square with a skin blob of ``face`` pixels for a face."""
    mask = np.zeros((r, r), np.float32)
    mask[20 : r - 4, r // 2 - 30 : r // 2 + 30] = 1
    skin = np.zeros((r, r), np.float32)
    skin[face_y : face_y + face, face_x : face_x + face] = 1
    skin[r - 40 : r - 30, r // 2 + 20 : r // 2 + 28] = 1  # a hand, lower down and larger than nothing
    return skin * mask, mask


def test_head_box_is_found_around_a_small_face_in_input_pixels():
    r = 128
    skin, mask = _person(r, face=12, face_y=26, face_x=58)
    photo_mask = np.zeros((1000, 600), np.float32)
    photo_mask[40:960, 100:500] = 1
    geom = CropGeometry.from_mask(photo_mask, r)  # side 930 px for 128 network px
    box = head_box(skin, mask, geom)
    assert box is not None
    y0, y1, x0, x1 = box
    # the face's centre (network x 63.5, y 31.5: the blob's centroid) in input pixels, by the geometry's mapping
    k = geom.scale
    cy = (31.5 + 0.5) * k - 0.5 - geom.offset[0] + geom.box[0]
    cx = (63.5 + 0.5) * k - 0.5 - geom.offset[1] + geom.box[2]
    assert abs((y0 + y1) / 2 - cy) < 2 and abs((x0 + x1) / 2 - cx) < 2
    assert y1 - y0 == pytest.approx(3 * 12 * k, abs=2) and x1 - x0 == pytest.approx(3 * 12 * k, abs=2)


def test_a_raised_forearm_larger_than_the_face_is_not_taken_for_it():
    """An arm's skin in the upper part, larger than the face but long and thin (4 x 40 network px against 12 x 12),
    is not the face: the head pass still finds the face (the reference clip's raised forearm outweighed its face)."""
    r = 128
    skin, mask = _person(r, face=12, face_y=26, face_x=58)
    skin[22:62, 40:44] = mask[22:62, 40:44]  # 160 px against the face's 144
    photo_mask = np.zeros((1000, 600), np.float32)
    photo_mask[40:960, 100:500] = 1
    geom = CropGeometry.from_mask(photo_mask, r)
    box = head_box(skin, mask, geom)
    assert box is not None
    k = geom.scale
    cx = (63.5 + 0.5) * k - 0.5 - geom.offset[1] + geom.box[2]
    assert abs((box[2] + box[3]) / 2 - cx) < 2


def test_no_head_pass_for_a_large_face_no_face_or_too_few_pixels():
    r = 128
    photo_mask = np.zeros((1000, 600), np.float32)
    photo_mask[40:960, 100:500] = 1
    geom = CropGeometry.from_mask(photo_mask, r)
    big = int(SMALL_FACE * r) + 4
    skin, mask = _person(r, face=big, face_y=24, face_x=64 - big // 2)
    assert head_box(skin, mask, geom) is None  # already seen large
    skin, mask = _person(r, face=12, face_y=26, face_x=58)
    skin[:70] = 0  # a person seen from behind: skin only lower down (a hand)
    assert head_box(skin, mask, geom) is None
    small = np.zeros((120, 80), np.float32)
    small[5:115, 10:70] = 1
    tiny_geom = CropGeometry.from_mask(small, r)  # 115 input px for 128 network px: nothing more to see
    skin, mask = _person(r, face=12, face_y=26, face_x=58)
    assert 3 * 12 * tiny_geom.scale < MIN_HEAD_INPUT and head_box(skin, mask, tiny_geom) is None


def test_no_head_pass_on_a_temple_beside_a_large_face_lower_down():
    """A portrait framed from the chest up: the face fills the square and its centre lies below the upper part,
    so the largest skin blob there was a patch of temple (DPR's portrait: a 7x9 blob) and the second pass ran on a
    96-px square of it (a red patch under neon). A large face whose top is in the upper part means no second pass."""
    r = 128
    photo_mask = np.zeros((1000, 600), np.float32)
    photo_mask[40:960, 100:500] = 1
    geom = CropGeometry.from_mask(photo_mask, r)
    mask = np.ones((r, r), np.float32)
    skin = np.zeros((r, r), np.float32)
    skin[20:120, 30:80] = 1  # the face: 50 x 100 network pixels, centre at 0.55 of the person's height
    skin[24:32, 86:94] = 1  # a patch of temple beyond the hair
    assert head_box(skin, mask, geom) is None


def _seen(views: list[np.ndarray], mask: np.ndarray) -> Decomposition:
    """A Decomposition of a standing person (a 1000 x 600 photo, its matte left-right symmetric) whose stage 1 gave
    the skin maps ``views`` (the picture's, the mirror's mapped back); the rest zeros."""
    r = mask.shape[0]
    photo_mask = np.zeros((1000, 600), np.float32)
    photo_mask[40:960, 100:500] = 1
    skin = np.mean(views, axis=0)
    return Decomposition(albedo_chw=np.zeros((3, r, r)), skin=skin, transport_chw=np.zeros((9, r, r)),
                         light=np.zeros((9, 3)), network_mask=mask, network_image=np.zeros((r, r, 3)),
                         mask=photo_mask, image=np.zeros((1000, 600, 3)),
                         geometry=CropGeometry.from_mask(photo_mask, r), skin_views=np.stack(views))


def test_the_head_is_looked_for_on_each_skin_map_not_on_their_mean():
    """p272's kind: a small face whose skin map joins its neck on neither map alone, but on their mean (0.45 and 0.7
    on each: 0.575 on the mean), which is then too tall for a small face; each map alone finds it."""
    r = 128
    face, mask = _person(r, face=12, face_y=26, face_x=58)
    bridge, neck = np.zeros_like(face), np.zeros_like(face)
    bridge[38:41, 58:70] = 1
    neck[41:56, 60:68] = 1
    a = face + 0.45 * bridge + 0.7 * neck
    b = face + 0.7 * bridge + 0.45 * neck
    assert 15 + 15 > SMALL_FACE * r  # face, bridge and neck joined: seen large
    assert head_box((a + b) / 2, mask, _seen([a, b], mask).geometry) is None
    dec = _seen([a, b], mask)
    box = seen_head_box(dec)
    assert box is not None
    assert box == seen_head_box(_seen([b, a], mask))  # whichever map is the photo's
    single = head_box(a, mask, dec.geometry)
    assert abs((box[2] + box[3]) / 2 - (single[2] + single[3]) / 2) < 1  # the face's column, not moved


def test_a_face_one_map_misses_keeps_its_head_pass():
    """p238's kind: the mirror's map misses a small face (zeros): the photo's map alone gives its box."""
    r = 128
    face, mask = _person(r, face=12, face_y=26, face_x=58)
    dec = _seen([face, np.zeros_like(face)], mask)
    assert seen_head_box(dec) == head_box(face, mask, dec.geometry)
    assert seen_head_box(_seen([np.zeros_like(face)] * 2, mask)) is None


def test_the_head_box_of_a_photo_and_of_its_mirror_image_are_mirrored():
    """Two maps a little apart (their boxes overlapping): the mean map's box; the mirror image's maps are the photo's
    mirrored and swapped, and its box is the photo's mirrored, within the pixel ``head_box`` itself is off by (it
    rounds a box around a pixel's centre, and a mirror's centre W - 1 - c rounds the other way: one map alone)."""
    r = 128
    a, mask = _person(r, face=12, face_y=26, face_x=40)
    b, _ = _person(r, face=12, face_y=27, face_x=42)
    box = seen_head_box(_seen([a, b], mask))
    y0, y1, x0, x1 = box
    mirrored = seen_head_box(_seen([b[:, ::-1], a[:, ::-1]], mask[:, ::-1]))
    assert mirrored[:2] == (y0, y1) and np.abs(np.subtract(mirrored[2:], (600 - x1, 600 - x0))).max() <= 1
    assert box == head_box((a + b) / 2, mask, _seen([a], mask).geometry)


def test_where_the_mean_map_finds_no_small_face_the_two_boxes_are_averaged():
    """Two maps whose mean finds no face (their blobs apart by a few pixels, each 0.9: the mean 0.45 off their
    overlap, too small a blob): the mean of the two maps' boxes, the start rounded down and the end up."""
    r = 128
    a, mask = _person(r, face=12, face_y=26, face_x=40)
    b, _ = _person(r, face=12, face_y=26, face_x=49)
    a, b = 0.9 * a, 0.9 * b
    geom = _seen([a], mask).geometry
    assert head_box((a + b) / 2, mask, geom) is None
    ya, yb = head_box(a, mask, geom), head_box(b, mask, geom)
    box = seen_head_box(_seen([a, b], mask))
    assert box == ((ya[0] + yb[0]) // 2, -((-ya[1] - yb[1]) // 2), (ya[2] + yb[2]) // 2, -((-ya[3] - yb[3]) // 2))


def test_a_face_one_map_sees_large_gets_no_head_pass():
    """p080's kind: one map sees the face large (a hand over its mouth splits the other's blob into a small one):
    the face is seen well enough, whichever map is the photo's."""
    r = 128
    big = int(SMALL_FACE * r) + 4
    large, mask = _person(r, face=big, face_y=24, face_x=64 - big // 2)
    small, _ = _person(r, face=12, face_y=26, face_x=58)
    assert head_box(small, mask, _seen([small], mask).geometry) is not None
    assert seen_head_box(_seen([large, small], mask)) is None
    assert seen_head_box(_seen([small, large], mask)) is None


def test_two_maps_finding_different_faces_take_the_larger_blob_or_none():
    r = 128
    small, mask = _person(r, face=10, face_y=26, face_x=34)
    large, _ = _person(r, face=12, face_y=26, face_x=80)
    dec = _seen([small, large], mask)
    assert seen_head_box(dec) == head_box(large, mask, dec.geometry)
    other, _ = _person(r, face=10, face_y=26, face_x=80)
    assert seen_head_box(_seen([small, other], mask)) is None  # equal blobs apart: neither is the head


def test_feather_fades_to_zero_at_open_sides_and_keeps_cut_sides():
    w = feather(40, 30)
    assert w[20, 15] == pytest.approx(1) and w.max() <= 1 and w.min() >= 0
    assert w[0].max() < 0.05 and w[:, 0].max() < 0.05 and w[-1].max() < 0.05
    cut = feather(40, 30, (True, False, False, False))  # the box ends at the photo's top
    assert cut[0, 15] == pytest.approx(1) and cut[-1, 15] < 0.05


def test_full_body_photo_gets_a_head_pass_that_changes_only_the_head(reference_dir):
    r = Relighter(RuntimeConfig(device="cpu"))
    photo = reference_dir / "photo" / "sample.jpg"
    mask = reference_dir / "photo" / "sample_mask.png"
    dec = r.decompose(photo, mask)
    assert dec.head is not None
    y0, y1, x0, x1 = dec.head_box
    light = lights.directional((0.4, 1, 0.3)) + lights.ambient(0.08)
    with_head = r.relight(dec, light)
    r.face_pass = False
    plain = r.relight(r.decompose(photo, mask), light)
    diff = np.abs(with_head - plain).max(axis=2)
    outside = np.ones(diff.shape, bool)
    outside[y0:y1, x0:x1] = False
    assert diff[outside].max() < 1e-6 and diff[y0:y1, x0:x1].mean() > 0.003
    # the light from the image's right: the face's right half is brighter than its left
    face = with_head[y0 + (y1 - y0) // 3 : y1 - (y1 - y0) // 3, x0 + (x1 - x0) // 3 : x1 - (x1 - x0) // 3]
    lum = face @ np.array([0.2126, 0.7152, 0.0722])
    half = lum.shape[1] // 2
    assert lum[:, half:].mean() > 1.2 * lum[:, :half].mean()


def test_the_photos_own_light_gives_the_photo_back_with_head_pass_and_soft_matte(reference_dir):
    """A real frame with its automatic (soft) matte: the head pass, the foreground colours of the soft edge and
    the background behind it all cancel under the photo's own light."""
    r = relight_rt.open(RuntimeConfig(device="cpu"))
    dec = r.decompose(reference_dir / "video" / "frame_001.png")  # no mask: the automatic matte
    alpha = np.asarray(dec.mask)
    assert ((alpha > 0.05) & (alpha < 0.95)).sum() > 1000 and dec.head is not None
    out = r.relight(dec, dec)
    assert np.abs(out - dec.image).max() < 0.01


class _DarkShySearch:
    """A face mesh stand-in that finds a face only where the box's mean level is at least ``need`` (a detector
    that misses a face half in deep shadow); it records the mean level of each image it was shown."""

    available = True

    def __init__(self, need: float) -> None:
        self.need, self.seen = need, []

    def faces(self, rgb: np.ndarray, box: tuple[int, int, int, int], lift: float = 1.0) -> list[np.ndarray]:
        y0, y1, x0, x1 = box
        level = float((rgb[y0:y1, x0:x1] ** lift).mean())
        self.seen.append(level)
        return [np.full((468, 3), level)] if level >= self.need else []


def _face_pass_with(search: _DarkShySearch) -> FacePass:
    faces = FacePass(Path("/nonexistent"))
    faces._mesh = search
    return faces


def test_a_face_missed_in_deep_shadow_is_looked_for_again_with_the_shadows_lifted():
    photo = np.full((64, 64, 3), 0.1, np.float32)  # mean 0.1: lifted by gamma 0.5 to 0.32
    search = _DarkShySearch(need=0.3)
    found = _face_pass_with(search).find(photo, (0, 64, 0, 64))
    assert len(found) == 1
    assert search.seen[0] == pytest.approx(0.1) and search.seen[-1] == pytest.approx(0.1 ** SHADOW_LIFTS[0], rel=1e-5)
    assert (np.asarray(photo) == np.float32(0.1)).all()  # the photo itself untouched


def test_a_face_found_as_the_photo_is_gets_no_second_look_and_none_is_made_up():
    photo = np.full((64, 64, 3), 0.5, np.float32)
    search = _DarkShySearch(need=0.3)
    assert len(_face_pass_with(search).find(photo, (0, 64, 0, 64))) == 1 and len(search.seen) == 1
    search = _DarkShySearch(need=0.99)  # no face however lifted: nothing, after one look per lift
    assert _face_pass_with(search).find(photo, (0, 64, 0, 64)) == ()
    assert len(search.seen) == 1 + len(SHADOW_LIFTS)


def test_the_face_mesh_shows_its_graphs_the_lifted_crops_not_a_lifted_photo(monkeypatch):
    from relight_rt.person import face_mesh

    shown = []

    class Graph:
        def run(self, feeds):
            shown.append(float(feeds["image"].mean()))
            return {"boxes": np.zeros((1, 16, 48, 48), np.float32), "scores": np.full((1, 1, 48, 48), -20, np.float32)}

    mesh = face_mesh.FaceMesh(Path("/nonexistent"))
    mesh.detector = Graph()
    photo = np.full((80, 80, 3), 0.25, np.float32)
    assert mesh.faces(photo, (10, 70, 10, 70), lift=0.5) == []
    assert shown[0] == pytest.approx(0.25 ** 0.5, rel=1e-4)  # the first look lies inside the photo
    assert (photo == np.float32(0.25)).all()


def test_stage1_keeps_both_skin_maps_whose_mean_is_the_skin():
    """The head pass's search reads the skin map stage 1 gave on the picture and on its mirror (mapped back): their
    mean is the Decomposition's skin, the mirror's is the picture's own mirror image's answer, and both travel with
    it (pickled, the head pass is decided alike)."""
    import pickle

    from relight_rt.relight import network

    rgba = cv2.imread(str(Path(relight_rt.__file__).parent / "data" / "example.png"), cv2.IMREAD_UNCHANGED)
    rgb = cv2.cvtColor(rgba[..., :3], cv2.COLOR_BGR2RGB).astype(np.float32) / 255
    mask = rgba[..., 3].astype(np.float32) / 255
    r = relight_rt.open(RuntimeConfig(device="cpu"))
    dec = r.decompose(rgb, mask)
    views = dec.skin_views
    assert network.STAGE1_MIRROR and views.shape == (2,) + dec.skin.shape and not views.flags.writeable
    np.testing.assert_allclose(views.mean(axis=0), dec.skin, atol=1e-6)
    mirrored = r.decompose(np.ascontiguousarray(rgb[:, ::-1]), np.ascontiguousarray(mask[:, ::-1]))
    np.testing.assert_allclose(mirrored.skin_views[0][:, ::-1], views[1], atol=1e-4)  # the mirror's own answer
    back = pickle.loads(pickle.dumps(dec))
    np.testing.assert_array_equal(back.skin_views, views)
    assert seen_head_box(back) == seen_head_box(dec)
