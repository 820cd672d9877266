"""A group's person whose share of the matte never reaches half (relight_rt.relight.people ``folded``): stage 1 takes
a person where their mask is >= 0.5, and such a share failed the whole photo as an empty mask (people_masks p229,
one of 30 group photos). It is folded into the person it overlaps most; the shares still sum to the matte."""

from __future__ import annotations

import numpy as np
from _graphs import models_dir
from test_group_shown_edge import _group, _GroupMatter

from relight_rt import Relighter, RuntimeConfig
from relight_rt.relight import people

__all__ = ["models_dir"]  # fixture


def _crop(box, value):
    y0, y1, x0, x1 = box
    return box, np.full((y1 - y0, x1 - x0), value, np.float32)


def _whole(crops, shape=(40, 40)) -> np.ndarray:
    out = np.zeros(shape, np.float32)
    for (y0, y1, x0, x1), share in crops:
        out[y0:y1, x0:x1] += share
    return out


def test_a_faint_share_goes_to_the_person_it_overlaps_most():
    a, b = _crop((0, 20, 0, 20), 0.6), _crop((10, 40, 10, 40), 0.6)  # b the larger
    faint = _crop((5, 15, 5, 15), 0.3)  # overlaps a by 100 pixels, b by 25: a's, not the largest's
    out = people.folded([a, faint, b])
    assert len(out) == 2
    assert out[1] is b  # b untouched
    assert out[0][0] == (0, 20, 0, 20) and out[0][1].max() == np.float32(0.6) + np.float32(0.3)
    np.testing.assert_array_equal(_whole(out), _whole([a, faint, b]))  # the shares still sum to the matte


def test_a_faint_share_overlapping_no_one_goes_to_the_largest_in_a_box_holding_both():
    a, b = _crop((0, 10, 0, 10), 0.6), _crop((0, 30, 20, 40), 0.6)
    faint = _crop((32, 40, 0, 8), 0.3)
    out = people.folded([a, b, faint])
    assert [box for box, _ in out] == [(0, 10, 0, 10), (0, 40, 0, 40)]
    np.testing.assert_array_equal(_whole(out), _whole([a, b, faint]))


def test_only_faint_shares_make_one_and_strong_ones_are_kept_as_they_are():
    weak = [_crop((0, 10, 0, 10), 0.3), _crop((5, 20, 5, 20), 0.4)]
    out = people.folded(weak)
    assert len(out) == 1
    np.testing.assert_array_equal(_whole(out), _whole(weak))
    strong = [_crop((0, 10, 0, 10), 0.5), _crop((5, 20, 5, 20), 1.0)]
    assert people.folded(strong) is strong


def test_a_group_with_a_faint_person_is_relit_not_refused(models_dir):
    """Before: RelightError 'mask is empty' from the faint person's stage-1 pass."""
    img, soft, (sa, sb) = _group()
    faint = np.zeros_like(sb)
    faint[60:100, 70:105] = 0.4 * sb[60:100, 70:105]  # 40 % of the right person's share, over part of them
    rl = Relighter(RuntimeConfig(models=str(models_dir), device="cpu", matting="all"),
                   matter=_GroupMatter(soft, [sa, sb - faint, faint]))
    dec = rl.decompose(img)
    assert len(dec.people) == 2
    out = np.asarray(rl.relight(dec, dec))
    assert 255 * np.abs(out - img).max() < 0.5
