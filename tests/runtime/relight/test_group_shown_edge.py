"""A group photo relit person by person (relight_rt.relight.people ``with_shown_edge``) takes the soft edge the photo
shows, as one person does (relight.compose.shown_edge): the automatic matte's feather past a sharp outline no
longer carries the people's change onto the wall beside them, and where two people meet nothing is cut."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from _graphs import models_dir

from relight_rt import Relighter, RuntimeConfig, lights
from relight_rt.image.compositing import Background
from relight_rt.relight import people

__all__ = ["models_dir"]  # fixture

H, W = 150, 130
A, B = (20, 140, 20, 65), (20, 140, 65, 110)  # the two people's boxes: side by side, touching at x = 65
WALL = (0.85, 0.85, 0.8)


def _group() -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """Two people with sharp outlines before a plain pale wall, an automatic-style matte feathered 4 px past the
    outlines, and each person's share of it (summing to it)."""
    img = np.empty((H, W, 3), np.float32)
    img[...] = WALL
    hards = []
    for (y0, y1, x0, x1), colour in ((A, (0.35, 0.25, 0.2)), (B, (0.25, 0.3, 0.45))):
        img[y0:y1, x0:x1] = colour
        hard = np.zeros((H, W), np.float32)
        hard[y0:y1, x0:x1] = 1
        hards.append(hard)
    soft = np.clip(cv2.GaussianBlur(hards[0] + hards[1], (0, 0), 4.0), 0, 1)
    near = [cv2.GaussianBlur(h, (0, 0), 4.0) for h in hards]
    total = np.maximum(near[0] + near[1], 1e-6)
    return img, soft, [soft * n / total for n in near]


class _GroupMatter:
    """An automatic matter that finds the two people (``parts``, as relight_rt's matter gives them)."""

    def __init__(self, soft, shares):
        self.soft, self.shares = soft, shares

    def __call__(self, rgb, name="image"):
        return self.soft

    def parts(self, rgb, name="image"):
        return self.soft, list(self.shares)


@pytest.fixture(scope="module")
def decomposed(models_dir):
    """The group decomposed with the shown edge, and as before it (the group's matte's own edge)."""
    img, soft, shares = _group()
    rl = Relighter(RuntimeConfig(models=str(models_dir), device="cpu", matting="all"),
                   matter=_GroupMatter(soft, shares))
    shown = rl.decompose(img)
    with pytest.MonkeyPatch.context() as m:
        m.setattr(people, "with_shown_edge", lambda factor, dec, parts: factor.derive(dec, people=tuple(
            factor.derive(part, foreground=people.colours_in_group(part, dec.mask)) for part in parts)))
        before = rl.decompose(img)
    return rl, img, soft, shown, before


def test_the_wall_beside_a_group_keeps_its_colour(decomposed):
    rl, img, soft, shown, before = decomposed
    assert len(shown.people) == 2 and shown.edge is not None and before.edge is None
    np.testing.assert_array_equal(shown.mask, before.mask)  # the matte itself is not changed
    wall = np.zeros((H, W), bool)  # the wall the matte feathers onto, 2-7 px outside the outline
    wall[24:136, 13:18] = wall[24:136, 112:117] = wall[13:18, 24:106] = True
    assert soft[wall].min() > 0.03
    light = lights.preset("campfire")
    change = {k: 255 * np.abs(np.asarray(rl.relight(d, light)) - img).max(axis=2)[wall]
              for k, d in (("shown", shown), ("before", before))}
    assert change["before"].max() > 5  # the feather carries the people's change onto the wall ...
    assert change["shown"].max() < 0.3 * change["before"].max()  # ... which the shown edge leaves as it was
    assert change["shown"].mean() < 0.2 * change["before"].mean()


def test_nothing_is_cut_where_the_two_people_meet(decomposed):
    rl, img, soft, shown, before = decomposed
    y0, _, x0, _ = shown.geometry.box
    seam = (slice(40 - y0, 120 - y0), slice(55 - x0, 76 - x0))  # 10 px either side of where they meet
    np.testing.assert_array_equal(shown.edge[seam], shown.geometry.crop(shown.mask)[seam])
    light = lights.preset("campfire")
    a, b = np.asarray(rl.relight(shown, light)), np.asarray(rl.relight(before, light))
    np.testing.assert_allclose(a[40:120, 55:76], b[40:120, 55:76], atol=1e-5)  # the seam relit as before


@pytest.mark.parametrize("background", ["original", Background.original(grade=True)])
def test_the_groups_own_light_gives_the_photo_back(decomposed, background):
    rl, img, soft, shown, before = decomposed
    out = np.asarray(rl.relight(shown, shown, background=background))
    assert 255 * np.abs(out - img).max() < 0.5


@pytest.mark.parametrize("background", ["transparent", "white"])
def test_a_new_backdrop_keeps_the_groups_matte(decomposed, background):
    """The shown edge is for the photo's own background: RGBA and a new backdrop go under the matte as before."""
    rl, img, soft, shown, before = decomposed
    light = lights.preset("studio")
    np.testing.assert_array_equal(rl.relight(shown, light, background=background),
                                  rl.relight(before, light, background=background))
