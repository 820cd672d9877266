"""matte38: the matte's steps decide alike on a photo and its mirror image where the graphs' answers mirror (each
test fails on matte37, where the step looked at the pixels in row order)."""

from __future__ import annotations

import numpy as np

from relight_rt.person.matting import _colours


def _two_colours(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A (256, 256) L*a*b* canvas whose left part is one colour and right part another (noisy), and a mask over
    most of it: the own colours' samples in row order differ from their mirror's."""
    lab = np.empty((256, 256, 3), np.float32)
    lab[:, :90] = (20.0, 10.0, -5.0)
    lab[:, 90:] = (70.0, -15.0, 25.0)
    lab += rng.normal(0.0, 6.0, lab.shape).astype(np.float32)
    mask = np.zeros((256, 256), bool)
    mask[30:230, 17:241] = True
    mask[100:140, 3:17] = True  # (not symmetric itself)
    return lab, mask


def test_colour_centres_do_not_depend_on_the_samples_order():
    rng = np.random.default_rng(38)
    lab, mask = _two_colours(rng)
    x = lab[mask]
    assert len(x) > 4 * _colours.OWN_SAMPLES
    c = _colours.centres(x)
    for order in (rng.permutation(len(x)), np.arange(len(x))[::-1]):
        assert np.array_equal(_colours.centres(x[order]), c)


def test_own_colour_samples_and_centres_of_a_canvas_and_its_mirror_are_the_same():
    lab, mask = _two_colours(np.random.default_rng(7))
    flip_lab, flip_mask = np.ascontiguousarray(lab[:, ::-1]), np.ascontiguousarray(mask[:, ::-1])
    a, b = _colours.sampled(lab, mask), _colours.sampled(flip_lab, flip_mask)
    assert _colours.OWN_SAMPLES <= len(a) <= 3 * _colours.OWN_SAMPLES
    assert np.array_equal(np.sort(a.view(np.void(12)).ravel()), np.sort(b.view(np.void(12)).ravel()))
    assert np.array_equal(_colours.centres(a), _colours.centres(b))
    # the whole model, as PersonMatter._own_colours builds it from the canvas (RGB in [0, 1])
    rgb = np.clip(np.random.default_rng(3).random((256, 256, 3)), 0, 1).astype(np.float32)
    rgb[:, :120] *= 0.3
    inside = np.ones((256, 256), bool)
    mine = np.zeros((256, 256), bool)
    mine[60:200, 70:160] = True
    m1 = _colours.colour_model(rgb, inside, mine, mine)
    m2 = _colours.colour_model(np.ascontiguousarray(rgb[:, ::-1]), inside, mine[:, ::-1].copy(), mine[:, ::-1].copy())
    assert m1 is not None and m2 is not None
    assert np.allclose(m1[1], m2[1], atol=1e-4) and np.allclose(m1[2], m2[2], atol=1e-4)


def test_a_thin_mask_the_grid_misses_keeps_all_its_pixels():
    lab = np.random.default_rng(1).normal(50.0, 10.0, (256, 256, 3)).astype(np.float32)
    mask = np.zeros((256, 256), bool)
    mask[:, 100] = True  # one column: 256 pixels, under twice OWN_SAMPLES
    assert len(_colours.sampled(lab, mask)) == 256
    wide = np.zeros((256, 256), bool)
    wide[:, 1:255:3] = True  # columns the grid may step over: never fewer than OWN_SAMPLES / 4 kept
    assert len(_colours.sampled(lab, wide)) >= _colours.OWN_SAMPLES // 4
