"""The face's colouring in the renderer (export.render.subjects._colour_face): where it reddens and darkens."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("torch")  # export.render imports anny lazily, but the package needs the export extra

from export.render import subjects  # noqa: E402

EYE_L, EYE_R = np.array([0.117, 0.031, 1.455]), np.array([0.117, -0.031, 1.455])
TONE = np.array([0.7, 0.55, 0.47])


def _face(**kw) -> subjects._Face:
    base = dict(eye_l=EYE_L, eye_r=EYE_R, flush=1.0, under_eye=1.0, stubble=0.0,
                stubble_colour=np.array([0.1, 0.08, 0.07]), freckles=0.0, lip_tint=np.array([0.85, 0.52, 0.55]))
    base.update(kw)
    return subjects._Face(**base)


def _points(offsets) -> np.ndarray:
    """Points on the face's front plane at (y, z) offsets from the eyes' midpoint."""
    mid = 0.5 * (EYE_L + EYE_R)
    return np.array([[mid[0] + 0.005, mid[1] + y, mid[2] + z] for y, z in offsets])


SPOTS = {"forehead": (0.0, 0.05), "cheek": (0.04, -0.04), "under_eye": (0.032, -0.016), "chin": (0.0, -0.11),
         "upper_lip": (0.0, -0.062), "far": (0.0, -0.6)}


def _colour(face) -> dict[str, np.ndarray]:
    pts = _points(SPOTS.values())
    col = np.repeat(TONE[None], len(pts), 0)
    out = subjects._colour_face(col, pts, TONE, seed=3, detail={}, face=face)
    return dict(zip(SPOTS, out, strict=True))


def test_cheeks_are_redder_than_the_forehead():
    c = _colour(_face())
    ratio = lambda rgb: rgb[1] / rgb[0]  # noqa: E731 - green over red: lower is redder
    assert ratio(c["cheek"]) < ratio(c["forehead"]) - 0.05
    assert c["cheek"][0] == pytest.approx(c["forehead"][0], rel=0.05)  # redness takes green and blue, not red


def test_below_the_eyes_is_darker_and_flush_zero_leaves_cheeks_alone():
    c = _colour(_face())
    assert c["under_eye"].sum() < 0.95 * c["forehead"].sum()
    plain = _colour(_face(flush=0.0, under_eye=0.0))
    np.testing.assert_allclose(plain["cheek"], plain["forehead"], rtol=0.06)  # only pore grain differs


def test_stubble_darkens_jaw_and_upper_lip_only():
    bare, bearded = _colour(_face()), _colour(_face(stubble=1.0))
    for spot in ("chin", "upper_lip"):
        assert bearded[spot].sum() < 0.9 * bare[spot].sum()
    np.testing.assert_array_equal(bearded["forehead"], bare["forehead"])
    np.testing.assert_array_equal(bearded["far"], TONE)  # off the head: untouched


def test_sampled_faces_are_in_range_and_women_get_no_stubble():
    rng = np.random.default_rng(7)
    a = subjects._sample_face(rng, {"eye.L": EYE_L, "eye.R": EYE_R}, masculine=1.0, hair=None)
    assert 0.2 <= a.flush <= 1.0 and 0.0 <= a.stubble <= 1.0
    women = [subjects._sample_face(np.random.default_rng(s), {"eye.L": EYE_L, "eye.R": EYE_R}, 0.0, None)
             for s in range(50)]
    assert all(f.stubble == 0.0 for f in women)
