"""A person's own cast shadow at their feet, taken out of the matte (relight_rt.person.matting._shadow, issue 48), on
synthetic photos: sunlit paving with grain, a standing person in grey trousers, the shadow on the paving beside the
feet (the ground's colour at half its luminance, a little bluer: the sky's fill) taken into the matte."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from relight_rt.person.matting import _shadow

PAVING = np.array([0.62, 0.60, 0.56], np.float32)  # sunlit, a little warm
SKY_FILL = np.array([0.47, 0.50, 0.56], np.float32) / 0.5  # the shadow's light against the sun's, per channel


def standing(h: int = 320, w: int = 260, trousers=(0.30, 0.30, 0.30)) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """A person 200 px tall standing on paving (rows 60-260), a shoe at the bottom, their shadow beside the feet
    (rows 245-262, reaching 50 px right of the leg). Returns (rgb, parts) with parts "body" (shirt and trousers),
    "shoe" and "shadow" (what the matte wrongly holds)."""
    rng = np.random.default_rng(3)
    yy, xx = np.mgrid[0:h, 0:w] + 0.5
    rgb = PAVING * (1.0 + 0.06 * rng.standard_normal((h, w, 1))).astype(np.float32)
    parts = {
        "body": (xx > 100) & (xx < 150) & (yy > 60) & (yy < 250),
        "shoe": (xx > 96) & (xx < 146) & (yy >= 250) & (yy < 260),
        "shadow": (xx >= 146) & (xx < 200) & (yy > 245) & (yy < 262) & ~((xx < 150) & (yy < 250)),
    }
    rgb[parts["shadow"]] *= 0.5 * SKY_FILL
    rgb[parts["body"] & (yy < 150)] = (0.25, 0.35, 0.70)  # a blue shirt
    rgb[parts["body"] & (yy >= 150)] = trousers
    rgb[parts["shoe"]] = 0.08
    return np.clip(rgb, 0.0, 1.0).astype(np.float32), parts


def matte(parts: dict[str, np.ndarray]) -> np.ndarray:
    """The graphs' matte: the person and their shadow, hard."""
    return (parts["body"] | parts["shoe"] | parts["shadow"]).astype(np.float32)


def kept(out: np.ndarray, mask: np.ndarray) -> bool:
    """Whether ``out`` keeps all of ``mask`` 2 px inside its outline (its mixed rim against the shadow may go) and
    97 % of it in all."""
    core = cv2.erode(mask.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    return bool(np.all(out[core] == 1.0) and (out[mask] == 1.0).mean() >= 0.97)


def sure_of(mask: np.ndarray):
    def sure(box: tuple[int, int, int, int], matte_box: tuple[int, int, int, int]) -> np.ndarray:
        x0, y0, x1, y1 = box
        return mask[y0:y1, x0:x1]

    return sure


def test_shadow_beside_the_feet_is_dropped():
    rgb, parts = standing()
    alpha = matte(parts)
    out = _shadow.without_cast_shadow(rgb, alpha, sure_of(parts["body"]))
    assert out is not alpha and np.all(alpha == matte(parts))  # a new array; the input untouched
    assert (out[parts["shadow"]] < 0.5).mean() > 0.9
    assert np.all(out[parts["body"]] == 1.0) and kept(out, parts["shoe"])


def test_grey_trousers_on_grey_paving_are_kept_without_a_sure_body():
    """Grey cloth has the paving's chromaticity and a shadow's luminance; it is not bluer than the sunlit ground, so
    it stays even where no graph vouches for it; the shadow beside it still goes."""
    rgb, parts = standing(trousers=tuple(0.5 * PAVING))
    out = _shadow.without_cast_shadow(rgb, matte(parts))
    assert kept(out, parts["body"]) and kept(out, parts["shoe"])
    assert (out[parts["shadow"]] < 0.5).mean() > 0.9


def test_neutral_shadow_is_kept():
    """A dark patch of the ground's very colour (no sky's fill: indoors, or a dark mat) is not taken for a shadow."""
    rgb, parts = standing()
    rgb[parts["shadow"]] = PAVING * 0.5
    alpha = matte(parts)
    assert _shadow.without_cast_shadow(rgb, alpha) is alpha


@pytest.mark.parametrize("case", ["cut_by_border", "lying", "sure"])
def test_left_alone(case):
    rgb, parts = standing()
    alpha = matte(parts)
    sure = None
    if case == "cut_by_border":  # the photo ends at the feet: no ground below them shows
        rgb, alpha = rgb[:258], alpha[:258]
    elif case == "lying":  # a matte wider than tall: nobody standing on the ground
        alpha = alpha.copy()
        alpha[60:150, 20:240] = 1.0
    else:  # the selfie graph sure of it all
        sure = sure_of(alpha >= 0.5)
    assert _shadow.without_cast_shadow(rgb, alpha, sure) is alpha


class _Box:
    """A stand-in for the selfie graph: sure (0.9) of the canvas's blue-shirted or black pixels, 0.1 elsewhere."""

    def run(self, feeds):
        img = feeds["image"][0]
        person = ((img[2] - img[0] > 0.2) | (img.max(0) < 0.2)) & (img.max(0) > 0.0)
        return {"segmentation": np.where(person, 0.9, 0.1).astype(np.float32)[None, None]}


def test_selfie_sure_reads_the_graph_over_the_box():
    """The selfie graph's answer on the matte's region, carried back to the photo's pixels (black trousers here: the
    stand-in tells no grey cloth from the shadow by colour, the graph does by shape)."""
    rgb, parts = standing(trousers=(0.08, 0.08, 0.08))
    alpha = matte(parts)
    ys, xs = np.nonzero(alpha >= 0.5)
    sure = _shadow.selfie_sure(_Box(), rgb)((90, 140, 210, 265), (xs.min(), ys.min(), xs.max() + 1, ys.max() + 1))
    assert sure.shape == (125, 120)
    shirt = parts["body"][140:265, 90:210] & (np.mgrid[140:265, 90:210][0] < 150)
    assert sure[parts["shoe"][140:265, 90:210]].mean() > 0.8  # (its rim: the canvas is coarser than the photo)
    assert sure[parts["shadow"][140:265, 90:210]].mean() < 0.1
    assert sure[shirt].mean() > 0.9
    out = _shadow.without_cast_shadow(rgb, alpha, _shadow.selfie_sure(_Box(), rgb))
    assert (out[parts["shadow"]] < 0.5).mean() > 0.9 and np.all(out[parts["body"]] == 1.0)
