"""The person's own colours (_completion.own_colours, relight_rt.person.matting._colours) taken only where the selfie
graph sees them framed on the people too (issue 48: the parkour clip's dark wall block under the runner's feet)."""

from __future__ import annotations

import numpy as np
import pytest
from test_broad_set_rules import matted, runner

from relight_rt.person import matting as M
from relight_rt.person.matting._completion import own_colours

BLOCK = 0.06  # the wall block's grey: near the trousers' black (0.03)


class _FarSighted:
    """A stand-in for the selfie graph: a person wherever the canvas is not the mid-grey ground (nor black padding),
    and, shown the whole photo (letterboxed: black bars at the top), also the dark block the runner stands on; framed
    on the runner (no bars) it leaves the block out, as the real graph does on the clip's frames 85-88."""

    def run(self, feeds):
        img = feeds["image"][0]
        seen = (np.abs(img - 0.5).max(0) > 0.05) & (img.max(0) > 0.0)
        if img[:, :4].max() > 0.0:  # no letterbox bar: the block is backdrop
            seen &= np.abs(img - BLOCK).max(0) > 0.005
        return {"segmentation": seen.astype(np.float32)[None, None]}


class _Always(_FarSighted):
    """The same stand-in seeing the block however it is framed."""

    def run(self, feeds):
        img = feeds["image"][0]
        seen = (np.abs(img - 0.5).max(0) > 0.05) & (img.max(0) > 0.0)
        return {"segmentation": seen.astype(np.float32)[None, None]}


@pytest.mark.parametrize(("graph", "taken"), [(_FarSighted, False), (_Always, True)])
def test_own_colours_are_taken_where_the_graph_framed_on_the_people_sees_them_too(graph, taken):
    """Seen on the whole photo only, the block stays out (the rule; before it the whole photo's answer alone decided,
    and the block came); seen framed on the runner too, it comes: its colour is the trousers', colour cannot refuse
    it. The other trouser leg comes either way."""
    rgb, parts = runner()
    yy, xx = np.mgrid[0:300, 0:400] + 0.5
    block = (np.abs(xx - 200) < 30) & (yy >= 250) & (yy < 268)  # under the feet, joined to both legs
    rgb[block] = BLOCK
    matter = M.PersonMatter(refine=False)
    matter.roi, matter.face = graph(), None
    found = matted(rgb, parts["shirt"] | parts["leg1"])
    extra = own_colours(matter.roi, rgb, [found])
    alpha = matter.alpha(rgb, [found, *extra])
    assert (alpha[parts["leg2"]] >= 0.5).mean() > 0.9
    assert ((alpha[block] >= 0.5).mean() > 0.9) == taken
    assert (alpha[parts["shadow"]] >= 0.5).mean() < 0.1  # the ground's colour: never
