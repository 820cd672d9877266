"""``relight_rt.image.colour_line_matte``: the matting Laplacian applied by box filters, its conjugate-gradient solve
on a band, and ``held_background`` (the background a coarse matte holds between strands, hairmat26)."""

from __future__ import annotations

import numpy as np
import pytest

from relight_rt.image.colour_line_matte import _Laplacian, colour_line_alpha, held_background
from relight_rt.relight.compose import colours_of, shown_edge

SKY, HAIR = (0.55, 0.72, 0.95), (0.12, 0.08, 0.05)


def _dense_laplacian_times(image: np.ndarray, p: np.ndarray, r: int, eps: float) -> np.ndarray:
    """L p by the definition (Levin et al. 2008, eq. 12, windows clipped at the border), window by window in float64:
    each window adds p_i - (a . I_i + b) at its pixels, (a, b) the regularised least-squares fit of p to the colour."""
    h, w = p.shape
    out = np.zeros((h, w))
    for ky in range(h):
        for kx in range(w):
            ys, xs = slice(max(ky - r, 0), min(ky + r + 1, h)), slice(max(kx - r, 0), min(kx + r + 1, w))
            colour, values = image[ys, xs].reshape(-1, 3).astype(np.float64), p[ys, xs].reshape(-1).astype(np.float64)
            n = values.size
            mu = colour.mean(axis=0)
            cov = (colour - mu).T @ (colour - mu) / n + eps / n * np.eye(3)
            a = np.linalg.solve(cov, (colour * values[:, None]).mean(axis=0) - mu * values.mean())
            out[ys, xs] += (values - (colour @ a + values.mean() - a @ mu)).reshape(out[ys, xs].shape)
    return out


@pytest.mark.parametrize(("h", "w", "r"), [(12, 17, 1), (20, 14, 2), (9, 9, 3)])
def test_the_box_filter_laplacian_is_the_definitions(h, w, r):
    rng = np.random.default_rng(h * w + r)
    image, p = rng.random((h, w, 3)).astype(np.float32), rng.random((h, w)).astype(np.float32)
    got = _Laplacian(image, r, 1e-3) @ p
    np.testing.assert_allclose(got, _dense_laplacian_times(image, p, r, 1e-3), atol=2e-4)


def test_the_laplacian_is_symmetric_and_keeps_constants_in_its_null_space():
    rng = np.random.default_rng(1)
    image = rng.random((24, 31, 3)).astype(np.float32)
    lap = _Laplacian(image, 2, 1e-4)
    p, q = rng.random((2, 24, 31)).astype(np.float32)
    assert float((q * (lap @ p)).sum()) == pytest.approx(float((p * (lap @ q)).sum()), rel=1e-4)
    assert np.abs(lap @ np.ones((24, 31), np.float32)).max() < 1e-3


def _strands(noise: float = 0.01) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sky left, a dark head of hair right (columns >= 150), loose strands 2 px wide every 6 px between (columns
    110-150) and a matte that holds the sky between the strands (at 0.8 over the loose strands, as the coarse matte
    smears them: p286's sky between strands lay at alpha 0.54-1, median 0.75; 1 over the head): image, matte,
    strands."""
    h, w = 120, 200
    image = np.empty((h, w, 3), np.float32)
    image[:] = SKY
    image[:, 150:] = HAIR
    strands = np.zeros((h, w), bool)
    for x in range(110, 150, 6):
        strands[:, x : x + 2] = True
    image[strands] = HAIR
    rng = np.random.default_rng(5)
    image = np.clip(image + noise * rng.standard_normal(image.shape), 0, 1).astype(np.float32)
    alpha = np.zeros((h, w), np.float32)
    alpha[:, 110:150] = 0.8
    alpha[:, 150:] = 1
    return image, alpha, strands


def test_the_solve_lowers_the_sky_between_strands_and_holds_the_rest():
    image, alpha, strands = _strands()
    unknown = np.zeros(alpha.shape, bool)
    unknown[:, 100:150] = True
    solved = colour_line_alpha(image, alpha, unknown, 4, 1e-4, 1e-3, 60)
    gaps = ~strands & (np.arange(200) >= 110)[None, :] & (np.arange(200) < 150)[None, :]
    assert solved[gaps].mean() < 0.2  # the matte held them at 1
    assert solved[strands].mean() > 0.75
    np.testing.assert_array_equal(solved[~unknown], alpha[~unknown])


def test_held_background_lowers_the_sky_between_strands():
    image, alpha, strands = _strands()
    before = alpha.copy()
    out = held_background(image, alpha)
    np.testing.assert_array_equal(alpha, before)  # a new array; the matte is not touched
    near = ~strands & (np.arange(200) >= 110)[None, :] & (np.arange(200) < 116)[None, :]  # gaps near the outline
    assert out[near].mean() < 0.6  # from the 0.8 the matte held
    assert out[strands].mean() > 0.7
    assert np.all(out <= alpha)  # only lowered
    assert np.all(out[:, 180:] == 1)  # the head of hair, away from the outline


@pytest.mark.parametrize("noise", [0.0, 0.01, 0.03])
def test_a_white_shirt_on_a_white_wall_moves_nothing(noise):
    """Colour cannot tell the person from the wall: the matte stays as it is, whatever the noise."""
    rng = np.random.default_rng(2)
    image = np.clip(0.94 + noise * rng.standard_normal((100, 140, 3)), 0, 1).astype(np.float32)
    alpha = np.zeros((100, 140), np.float32)
    alpha[:, 70:] = 1
    alpha[:, 66:70] = (0.1, 0.35, 0.65, 0.9)
    assert np.abs(held_background(image, alpha) - alpha).max() < 0.02


def test_the_photo_is_given_back_under_its_own_light():
    """With the held background taken (the shown edge lowered between the strands), the colour behind is solved so
    that alpha' F + (1 - alpha') behind is the photo again."""
    image, alpha, strands = _strands()
    fg, _ = colours_of(image, alpha, multilevel=True)
    shown, behind = shown_edge(image, alpha, fg)
    gaps = ~strands & (np.arange(200) >= 110)[None, :] & (np.arange(200) < 116)[None, :]
    assert shown[gaps].mean() < 0.5  # the shown edge took the sky the matte held
    again = shown[..., None] * fg + (1 - shown[..., None]) * behind
    np.testing.assert_allclose(again, image, atol=1 / 255)


def test_a_matte_without_an_inside_is_returned_as_it_is():
    image = np.full((20, 20, 3), 0.5, np.float32)
    alpha = np.full((20, 20), 0.3, np.float32)
    np.testing.assert_array_equal(held_background(image, alpha), alpha)
