"""The coarse matte at full resolution: a person's 256² segmentation carried over the photo through a working
grid and refined by the fast guided filter steered by the photo (relight_rt.image.guided_filter; He & Sun 2015), so hair
and arm outlines follow the photo's own edges. Only the person's region is processed at full resolution."""

from __future__ import annotations

import cv2
import numpy as np

from ...image.guided_filter import fast_guided_filter
from ._models import SIZE
from ._segmentation import Grid, Person, logits_on_grid, sigmoid, working_grid

GF_EPS = 1e-3  # guided-filter regulariser (guide in [0, 1]); benchmarks/matting_eval.py picked it
_GF_RADIUS = 1.0  # guided-filter window radius, in pixels of the 256² segmentation


def guide_radius(person: Person, grid: Grid) -> int:
    """The guided filter's window radius on a working grid: _GF_RADIUS canvas pixels of the person's
    segmentation, in working-grid pixels (at least 2)."""
    k_canvas = SIZE / person.region.side
    return max(2, int(round(_GF_RADIUS * grid[2] / k_canvas)))


def region_alpha(
    rgb: np.ndarray, person: Person, rect: tuple[int, int, int, int], *, refine: bool = True,
    prob: np.ndarray | None = None, guide: str = "gray",
) -> np.ndarray:  # fmt: skip
    """Soft alpha of one person over the image rectangle ``rect`` = (x0, y0, x1, y1), full resolution.

    ``prob`` (optional) replaces the person's probability on the working grid (the video matter passes
    its temporally smoothed one)."""
    rx0, ry0, rx1, ry1 = rect
    grid = working_grid(rect)
    gw, gh = grid[0], grid[1]
    if prob is None:
        prob = sigmoid(logits_on_grid(person, grid)).astype(np.float32)
    sub = rgb[ry0:ry1, rx0:rx1]
    if not refine:
        if (gw, gh) == (rx1 - rx0, ry1 - ry0):
            return prob
        return cv2.resize(prob, (rx1 - rx0, ry1 - ry0), interpolation=cv2.INTER_LINEAR)
    radius = guide_radius(person, grid)
    if guide == "color":
        sub = np.ascontiguousarray(sub)
        small = sub if (gw, gh) == (rx1 - rx0, ry1 - ry0) else cv2.resize(sub, (gw, gh), interpolation=cv2.INTER_AREA)
        return fast_guided_filter(prob, small, sub, radius, GF_EPS)
    gray_full = cv2.cvtColor(sub, cv2.COLOR_RGB2GRAY)  # reads the view (no copy of the region: ~1 ms saved)
    if (gw, gh) == (rx1 - rx0, ry1 - ry0):
        gray_small = gray_full
    else:
        gray_small = cv2.resize(gray_full, (gw, gh), interpolation=cv2.INTER_AREA)
    return fast_guided_filter(prob, gray_small, gray_full, radius, GF_EPS)
