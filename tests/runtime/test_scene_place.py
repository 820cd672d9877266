"""relight_rt.scene_place: how a photo framed its person and where they go in another scene (synthetic mattes)."""

import numpy as np
import pytest

from relight_rt import RelightError
from relight_rt.scene_place import (
    CAMERA_M,
    DEFAULT_FEET,
    PERSON_M,
    check_camera_height,
    framing,
    place,
)


def figure(h=200, w=120, top=20, bottom=180, arm=False):
    """A straight-alpha RGBA stick figure: a body at columns 50-70, legs 48-56 and 64-72 below row 120 (feet
    centred at column 60); ``arm``: a long arm out to the right, columns 70-118, rows 60-70."""
    rgba = np.zeros((h, w, 4), np.float32)
    rgba[..., :3] = (0.5, 0.4, 0.3)
    rgba[top:min(bottom, 120), 50:70, 3] = 1
    rgba[120:bottom, 48:56, 3] = 1
    rgba[120:bottom, 64:72, 3] = 1
    if arm:
        rgba[60:70, 70:118, 3] = 1
    return rgba


def legs_x(placed):
    """The frame column of the centre of the placed person's bottom rows (their feet), from their pixels."""
    sole = placed.premult[-3:, :, 3].sum(axis=0)
    return placed.left + float(sole @ (np.arange(sole.size) + 0.5) / sole.sum())


def test_framing_finds_the_borders_that_cut_the_person():
    a = figure()[..., 3]
    assert framing(a).cut == frozenset() and framing(a).full_body
    half = figure(bottom=200)[..., 3]  # the legs run off the bottom
    assert framing(half).cut == {"bottom"} and not framing(half).full_body
    side = half.copy()
    side[60:200, 0:60] = 1  # and off the left border
    assert framing(side).cut == {"bottom", "left"}
    wisp = a.copy()
    wisp[199, 30] = 1  # one stray pixel on the bottom row, and a faint haze along it
    wisp[199, :] = np.maximum(wisp[199, :], 0.3)
    assert framing(wisp).full_body


def test_the_feet_are_under_the_legs_not_the_box():
    fr = framing(figure(arm=True)[..., 3])
    y0, y1, x0, x1 = fr.box
    assert (x0 + x1) / 2 == pytest.approx(83)  # the arm pulls the box's centre to the right
    assert fr.feet_x == pytest.approx(60, abs=0.5) and fr.feet_width == pytest.approx(24, abs=1)


def test_a_full_body_stands_its_feet_where_asked_and_scales_with_the_camera_height():
    rgba = figure(arm=True)
    placed = place(rgba, (300, 400, 3), (0.25, 0.9), None, 0.5)
    assert placed.full_body and placed.feet_y == 270
    assert legs_x(placed) == pytest.approx(100, abs=1)  # the legs, not the box's centre, stand at x = 0.25
    assert placed.feet_x == pytest.approx(100, abs=0.5)
    assert placed.height == round((0.9 - 0.5) * 300 * PERSON_M / CAMERA_M)
    low = place(rgba, (300, 400, 3), (0.25, 0.9), None, 0.5, camera_height=2 * CAMERA_M)
    assert low.height == pytest.approx(placed.height / 2, abs=1)  # twice as high a camera: the feet twice as far
    default = place(figure(), (300, 400, 3), None, None, 0.5)
    assert default.feet_y == round(DEFAULT_FEET * 300) and default.feet_x == pytest.approx(60 / 120 * 400, abs=0.5)


@pytest.mark.parametrize("bg", [(300, 400), (400, 300), (200, 600)])
def test_a_half_body_is_cut_by_the_same_borders(bg):
    hb, wb = bg
    rgba = figure(bottom=200)
    rgba[60:200, 0:60, 3] = 1  # cut by the bottom and the left border of its 200 x 120 photo
    placed = place(rgba, (hb, wb, 3))
    assert not placed.full_body
    assert placed.top + placed.height == hb and placed.left == 0  # the cut edges on the same borders
    assert placed.height == round(180 * hb / 200)  # its relative height kept
    right = place(rgba[:, ::-1], (hb, wb, 3))
    assert right.left + right.width == wb and right.top + right.height == hb


@pytest.mark.parametrize("bg, reach", [((300, 400), True), ((400, 300), True), ((150, 600), False)])
def test_a_portrait_cut_at_both_sides_reaches_both_borders_if_its_face_stays(bg, reach):
    from relight_rt.scene_place import HEAD_ROOM

    hb, wb = bg
    rgba = np.zeros((200, 200, 4), np.float32)
    rgba[40:, :, 3] = 1  # shoulders through both side borders and the bottom: a portrait
    rgba[10:40, 75:125, 3] = 1  # the head, whole, 10 rows below the top
    placed = place(rgba, (hb, wb, 3))
    assert placed.top + placed.height == hb  # on the bottom border
    assert (placed.left <= 0 and placed.left + placed.width >= wb) == reach  # the cut sides on both borders
    assert placed.top >= -HEAD_ROOM * placed.height - 1  # the face kept
    assert abs(placed.left + placed.width / 2 - wb / 2) <= 1  # centred, as its photo framed it
    if not reach:  # a tall portrait in a wide strip: as large as the head room allows, not smaller
        assert placed.top == pytest.approx(-HEAD_ROOM * placed.height, abs=1)


def test_a_person_not_cut_at_a_side_stays_whole_in_the_picture():
    rgba = figure(bottom=200)  # cut by the bottom only, near its photo's right
    rgba = np.roll(rgba, 45, axis=1)
    placed = place(rgba, (300, 200, 3))
    assert placed.left >= 0 and placed.left + placed.width <= 200


def test_bad_camera_heights():
    assert check_camera_height("1.2") == 1.2
    for bad in ("low", "nan", 0, -1, 1e4):
        with pytest.raises(RelightError, match="camera height"):
            check_camera_height(bad)


def test_the_contact_shadow_lies_under_the_feet_and_is_foreshortened():
    from relight_rt.scene import SceneLighting, shade, shadows

    placed = place(figure(arm=True), (300, 400, 3), (0.5, 0.9), 0.5, 0.5)
    none = SceneLighting(np.zeros((9, 3), np.float32), np.zeros((9, 3), np.float32), None, 0.0)
    cast = shadows(placed, (300, 400, 3), 0.5, 60.0, none)
    assert cast.foot[0] == pytest.approx(legs_x(placed), abs=1) == 200  # under the legs, not the arm-wide box
    lin = np.ones((300, 400, 3), np.float32)
    shade(lin, (0, 0), cast)
    row = lin[int(cast.foot[1]), :, 0]
    dark = np.flatnonzero(row < 0.9)
    assert abs((dark[0] + dark[-1]) / 2 - 200) <= 2  # centred under the feet
    cols = np.flatnonzero(lin[:, 200, 0] < 0.9)
    assert cols.size < dark.size / 2  # flatter than wide: ground seen at a slant
    near = place(figure(), (300, 400, 3), (0.5, 0.98), 0.5, 0.5)
    far = place(figure(), (300, 400, 3), (0.5, 0.7), 0.5, 0.5)
    (w0, h0), (w1, h1) = (shadows(p, (300, 400, 3), 0.5, 60.0, none).size for p in (near, far))
    assert h0 / w0 == pytest.approx(2.4 * h1 / w1, rel=0.05)  # the ground 2.4x as far below the horizon
