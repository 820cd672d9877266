"""_parts.along_edges: people split from one segmentation by their faces (split_by_faces) share the matte along the
photo's own edges, not along a straight column between their faces."""

from __future__ import annotations

import numpy as np
import pytest

from relight_rt.person import matting as M
from relight_rt.person.face_detector import Face
from relight_rt.person.matting import _parts

H, W = 200, 300


def _touching_pair(top: float, slant: float):
    """Two flat-coloured figures filling the photo side by side, red left of the line x = top + slant * y, blue right
    of it (within a face's width of x 150, where their faces' distances are equal), their faces (40 px wide) at
    x 60-100 and 200-240; one segmentation holding both (as the selfie graph gives people side by side)."""
    ys, xs = np.mgrid[0:H, 0:W] + 0.5
    left = xs < top + slant * ys
    rgb = np.where(left[..., None], np.float32([0.8, 0.15, 0.1]), np.float32([0.1, 0.2, 0.8])).astype(np.float32)
    both = M.Person(M.Region.around(0, 0, W, H), np.full((256, 256), 8.0, np.float32), 1.0, "roi")
    faces = [Face((60.0, 20.0, 100.0, 60.0), 0.9), Face((200.0, 20.0, 240.0, 60.0), 0.9)]
    edge = top + slant * ys
    return rgb, _parts.split_by_faces(both, faces), xs < edge - 12, xs > edge + 12


@pytest.mark.parametrize(("top", "slant"), [(120.0, 0.3), (180.0, -0.3), (130.0, 0.0)])
def test_touching_people_are_split_along_their_colour_boundary(top, slant):
    rgb, parts, left, right = _touching_pair(top, slant)
    alpha = np.ones((H, W), np.float32)
    shares = _parts.shares(parts, alpha, rgb)
    assert len(shares) == 2
    np.testing.assert_allclose(shares[0] + shares[1], 1, atol=1e-5)
    assert shares[0][left].min() > 0.95 and shares[1][right].min() > 0.95
    # the straight cut between the faces (x 150, what shares gives without the photo) puts part of one colour in
    # the other person's share: this test tells the two apart
    columns = _parts.shares(parts, alpha)
    assert min(columns[0][left].min(), columns[1][right].min()) < 0.05
    crops = _parts.shares(parts, alpha, rgb, crops=True)
    for ((y0, y1, x0, x1), share), full in zip(crops, shares, strict=True):
        np.testing.assert_allclose(share, full[y0:y1, x0:x1], atol=1e-6)


def test_a_flat_photo_keeps_the_straight_cut():
    """Without an edge to follow, the cut stays where the faces' distances are equal (x 150)."""
    rgb = np.full((H, W, 3), 0.5, np.float32)
    _, parts, _, _ = _touching_pair(150.0, 0.0)
    shares = _parts.shares(parts, np.ones((H, W), np.float32), rgb)
    assert shares[0][:, :140].min() > 0.95 and shares[1][:, 160:].min() > 0.95


def test_the_matters_parts_and_crops_give_the_photo_to_the_split(monkeypatch):
    """PersonMatter.parts and part_crops hand the photo to shares: their people meet along its edges."""
    rgb, parts, left, right = _touching_pair(120.0, 0.3)
    alpha = np.ones((H, W), np.float32)
    matter = M.PersonMatter(person="all")
    monkeypatch.setattr(matter, "_matte", lambda image, name: (alpha, parts))
    _, whole = matter.parts(rgb)
    assert whole[0][left].min() > 0.95 and whole[1][right].min() > 0.95
    _, crops = matter.part_crops(rgb)
    for ((y0, y1, x0, x1), part), full in zip(crops, whole, strict=True):
        np.testing.assert_allclose(part, full[y0:y1, x0:x1], atol=1e-6)


@pytest.mark.parametrize("photo", [False, True])
def test_a_hidden_first_part_leaves_its_cells_to_the_rest(photo):
    """The left part of a split holding under _MIN_PART opaque pixels of the matte is dropped (hidden); the cells
    only it reached go to the nearest person kept. They went to the nearest region's person, the dropped part
    itself (the parts of a split share one region): no one's, and every share there was NaN."""
    rgb, parts, _, _ = _touching_pair(130.0, 0.0)
    alpha = np.zeros((H, W), np.float32)
    alpha[:, 150:] = 1
    alpha[:10, 140:150] = 1  # 100 opaque pixels left of the cut: the left person is hidden
    for crops in (False, True):
        got = _parts.shares(parts, alpha, rgb if photo else None, crops=crops)
        assert len(got) == 1
        (y0, y1, x0, x1), share = got[0] if crops else ((0, H, 0, W), got[0])
        assert np.isfinite(share).all()
        assert share[alpha[y0:y1, x0:x1] > 0].min() > 0.99 and not alpha[:, :x0].any() and not alpha[:, x1:].any()
