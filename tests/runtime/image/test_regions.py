"""image.regions: Pyramid.answer (what a graph answered on a region of one photo, kept inside reductions_shared);
a Region's own check."""

import gc

import numpy as np
import pytest

from relight_rt import RelightError
from relight_rt.image.regions import Region, crop_region, pyramid_of, reductions_shared


class _Graph:
    """A stand-in graph whose answer is its own tag; counts how often it is asked."""

    def __init__(self, tag: float) -> None:
        self.tag, self.runs = tag, 0

    def ask(self) -> float:
        self.runs += 1
        return self.tag


def test_a_graph_freed_inside_the_block_never_lends_its_answers_to_the_next_one():
    """A graph's answers are kept under its id: the Pyramid holds the graph, so a new graph made after the old one
    was dropped cannot take its address and read its answers."""
    rgb = np.zeros((64, 64, 3), np.float32)
    region = Region(32.0, 32.0, 64.0)
    with reductions_shared(rgb):
        for i in range(40):
            g = _Graph(float(i))
            assert pyramid_of(rgb).answer(g, "selfie", region, g.ask, 8) == float(i)
            del g
            gc.collect()


def test_one_graph_asked_two_kinds_of_question_on_a_region_keeps_both_answers_apart():
    rgb = np.zeros((64, 64, 3), np.float32)
    region = Region(32.0, 32.0, 64.0)
    g = _Graph(1.0)
    with reductions_shared(rgb):
        pyr = pyramid_of(rgb)
        assert pyr.answer(g, "selfie", region, lambda: "probability", 8) == "probability"
        assert pyr.answer(g, "face", region, lambda: "boxes", 8) == "boxes"
        assert pyr.answer(g, "selfie", region, g.ask, 8) == "probability"  # kept: not asked again
    assert g.runs == 0
    assert pyramid_of(rgb).answer(g, "selfie", region, g.ask, 8) == 1.0  # outside the block: asked every time


@pytest.mark.parametrize("values", [(0.0, 0.0, 0.0), (32.0, 32.0, -10.0), (float("nan"), 0.0, 10.0),
                                    (0.0, float("inf"), 10.0), (0.0, 0.0, float("inf"))])
def test_a_region_without_a_finite_centre_and_side_is_one_clear_error(values):
    """fuzz8: a side of 0 failed in grid_of_region (ZeroDivisionError), a NaN or Inf centre or side converting to int
    (ValueError, OverflowError), from crop_region and PersonMatter.segment alike; a region far past the image is
    still a canvas of zeros."""
    with pytest.raises(RelightError, match="region"):
        Region(*values)
    img = np.ones((4, 500, 3), np.float32)
    assert not crop_region(img, Region(-1e9, 5.0, 10.0)).any()
    assert crop_region(img, Region(250.0, 2.0, 1e-6)).shape == (256, 256, 3)
