"""A finer alpha on a band round a matte's outline: closed-form matting's local colour-line model (Levin, Lischinski
& Weiss, "A Closed-Form Solution to Natural Image Matting", 2008), its Laplacian applied with large-kernel box
filters (He, Sun & Tang, "Fast Matting Using Large Kernel Matting Laplacian Matrices", 2010) and solved by conjugate
gradients.

In every (2r + 1)^2 window k alpha is taken as an affine function of the colour, ``alpha_i ~ a_k . I_i + b_k``; the
matting Laplacian L sums each window's error of that fit (with ``eps`` holding a_k small) as a quadratic form in
alpha. ``L p`` needs no matrix: per window, ``a_k = (Sigma_k + eps / n_k U)^-1 (mean_k(I p) - mu_k mean_k(p))`` and
``b_k = mean_k(p) - a_k . mu_k``, and ``(L p)_i = N_i p_i - (sum_k a_k) . I_i - sum_k b_k`` over the N_i windows
that hold pixel i: box sums, O(1) a pixel whatever r (He et al.'s eq. 8-10; windows are clipped at the border, n_k
their pixels, which keeps L symmetric).

On the unknown pixels U the solution minimises ``alpha' L alpha + lam sum_U (alpha_i - prior_i)^2`` with the other
pixels held at their values: ``(L_UU + lam I) alpha_U = lam prior_U - L_UK alpha_K``, symmetric positive definite, so
conjugate gradients converge; they start from the prior (the coarse matte). The prior term keeps alpha where colour
says nothing (a white shirt before a white wall: there L only smooths).
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["colour_line_alpha", "held_background"]


def _box(x: np.ndarray, r: int) -> np.ndarray:
    """Sums of ``x`` (h, w) or (h, w, c) float32 over the (2r + 1)^2 window round each pixel, clipped at the border."""
    k = 2 * r + 1
    return cv2.boxFilter(x, -1, (k, k), normalize=False, borderType=cv2.BORDER_CONSTANT)


class _Laplacian:
    """The matting Laplacian of ``image`` (h, w, 3) float32 with windows of radius ``r``, applied as ``L @ p``.

    Kept as planes (one (h, w) array a channel): OpenCV's box filter and arithmetic on contiguous planes cost a
    fraction of numpy's on strided channel slices."""

    def __init__(self, image: np.ndarray, r: int, eps: float) -> None:
        self.r = r
        self.planes = [np.ascontiguousarray(image[..., c]) for c in range(3)]
        self.n = _box(np.ones(image.shape[:2], np.float32), r)  # pixels per window = windows per pixel (clipped)
        self.inv_n = 1 / self.n
        # the window statistics in float64: a flat window's variance is a small difference of large sums
        wide = [c.astype(np.float64) for c in self.planes]
        inv_n = self.inv_n.astype(np.float64)
        mu = [_box(c, r) * inv_n for c in wide]
        self.mu = [m.astype(np.float32) for m in mu]
        # the window's colour covariance plus eps / n on its diagonal, inverted by cofactors (six distinct entries)
        pair = lambda c, d: _box(wide[c] * wide[d], r) * inv_n - mu[c] * mu[d]  # noqa: E731
        reg = eps * inv_n
        rr, gg, bb = pair(0, 0) + reg, pair(1, 1) + reg, pair(2, 2) + reg
        rg, rb, gb = pair(0, 1), pair(0, 2), pair(1, 2)
        c00, c01, c02 = gg * bb - gb * gb, gb * rb - rg * bb, rg * gb - gg * rb
        c11, c12, c22 = rr * bb - rb * rb, rg * rb - rr * gb, rr * gg - rg * rg
        det = rr * c00 + rg * c01 + rb * c02
        self.inv = [(c / det).astype(np.float32) for c in (c00, c01, c02, c11, c12, c22)]

    def __matmul__(self, p: np.ndarray) -> np.ndarray:
        """(h, w) float32 ``L p`` for ``p`` (h, w) float32."""
        r, inv_n, mu = self.r, self.inv_n, self.mu
        pbar = cv2.multiply(_box(p, r), inv_n)
        x, y, z = (cv2.subtract(cv2.multiply(_box(cv2.multiply(c, p), r), inv_n), cv2.multiply(m, pbar))
                   for c, m in zip(self.planes, mu, strict=True))
        i00, i01, i02, i11, i12, i22 = self.inv
        a = [cv2.add(cv2.add(cv2.multiply(u, x), cv2.multiply(v, y)), cv2.multiply(w, z))
             for u, v, w in ((i00, i01, i02), (i01, i11, i12), (i02, i12, i22))]
        b = pbar
        for ac, m in zip(a, mu, strict=True):
            b = cv2.subtract(b, cv2.multiply(ac, m))
        out = cv2.subtract(cv2.multiply(self.n, p), _box(b, r))
        for ac, c in zip(a, self.planes, strict=True):
            out = cv2.subtract(out, cv2.multiply(_box(ac, r), c))
        return out


def colour_line_alpha(image: np.ndarray, prior: np.ndarray, unknown: np.ndarray, radius: int, eps: float,
                      lam: float | np.ndarray, iterations: int) -> np.ndarray:
    """The closed-form matte on the ``unknown`` pixels, the others held at ``prior``'s values.

    Args:
        image: (h, w, 3) float32 RGB in [0, 1].
        prior: (h, w) float32 in [0, 1]: the coarse matte (held where not ``unknown``; pulled toward on it).
        unknown: (h, w) bool, the pixels solved for.
        radius: the windows' radius r in pixels.
        eps: the colour-line fit's regulariser (on the colour's variance, as in Levin et al.).
        lam: the pull toward ``prior`` on the unknown pixels, per window that holds a pixel ((2r + 1)^2 of them): a
            number, or (h, w) float32 per pixel (held harder where colour says less).
        iterations: conjugate-gradient steps at most (it stops sooner once the residual falls 1000-fold).

    Returns:
        (h, w) float32 in [0, 1], new: ``prior`` with its unknown pixels solved.
    """
    lap = _Laplacian(np.ascontiguousarray(image, np.float32), radius, eps)
    u = unknown.astype(np.float32)
    weight = (np.asarray(lam, np.float32) * np.float32((2 * radius + 1) ** 2)).astype(np.float32)
    x = np.array(prior, np.float32)
    # A v = (L v + weight v) on U for v zero off U; the start x = prior everywhere makes the residual -(L x) on U
    res = -(lap @ x) * u
    d = res.copy()
    rho = float((res * res).sum())
    stop = rho * 1e-6
    for _ in range(iterations):
        if rho <= stop or not np.isfinite(rho):
            break
        q = ((lap @ d) + weight * d) * u
        curve = float((d * q).sum())
        if not curve > 0:  # rounding has spent the system's positive definiteness: keep what was reached
            break
        step = rho / curve
        x += step * d
        res -= step * q
        rho, old = float((res * res).sum()), rho
        d = res + (rho / old) * d
    return np.clip(x, 0, 1)


_WORK_PIXELS = 120_000  # held_background: the crop box is solved at most this many pixels (reduced as needed)
_RADIUS = 6  # ... the colour-line windows' radius, in working pixels
_EPS = 1e-4  # ... the fit's regulariser
_LAM = 1e-3  # ... the pull toward the coarse matte on the band
_ITERATIONS = 20  # ... conjugate-gradient steps at most
_BAND = 6  # the band: the soft pixels within this many pixels of the photo inside the 0.5 line ...
_BAND_SOFT = 1.0  # ... or this x the soft edge's mean width, if more, up to ...
_BAND_MAX = 12  # ... this many; and the solid matte within this many of the line:
_SOLID = 3
_BAND_TEXTURE = 2.0  # ... both times this where the photo shows fine texture (hair: its colour gradient's window ...
_TEXTURE = 0.08  # ... mean at least this)
_TAU = 0.02  # a lowering counts as far as colour tells the sides apart: |F - B|^2 / (|F - B|^2 + this) ...
_SURE = 0.3  # ... and as far as the solve is sure of background: whole at alpha 0, none from this alpha up


def _side(image: np.ndarray, where: np.ndarray, r: int) -> tuple[np.ndarray, np.ndarray]:
    """The mean colour (h, w, 3) of ``image`` over ``where`` within ``r`` px, and where any such pixel lies (h, w)."""
    w = where.astype(np.float32)
    n = _box(w, r)
    return _box(image * w[..., None], r) / np.maximum(n, 1e-6)[..., None], n > 0.5


def held_background(image: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """(h, w) float32, new: ``alpha`` lowered where the closed-form matte on a band round its outline is sure of
    background the matte holds (the sky between strands of hair at alpha 0.5-1, a sliver beside a shoulder).

    The band (unknown): the soft pixels (0.02 < alpha < 0.98) within ``_BAND`` px (or ``_BAND_SOFT`` x the soft
    edge's mean width, at most ``_BAND_MAX``) inside the 0.5 line and all of them outside it, and the matte within
    ``_SOLID`` px inside the line; both ``_BAND_TEXTURE`` x as deep where the photo shows fine texture (hair). The
    rest is held: the coarse matte's own values, 1 from 0.98 up and 0 from 0.02 down. The crop box is solved at
    reduced resolution (at most ``_WORK_PIXELS``) with windows of ``_RADIUS`` working pixels and a pull ``_LAM``
    toward the coarse matte, and the lowering is brought back to full size bilinearly. A solved pixel is lowered
    only as far as the solve is sure of background (whole where it solves to 0, none from ``_SURE`` up: a partial
    answer on the person's own edge, a pale cheek before a pale wall, is the colour-line model's doubt, which on
    people_masks' half A took more from the person than from background) and as far as colour tells the solid
    person and background nearby apart (|F - B|^2 / (|F - B|^2 + ``_TAU``): a white shirt on a white wall moves
    nothing). Never raised: a raise needs a colour behind the person that the photo may not allow.

    Args:
        image: (h, w, 3) float32 RGB in [0, 1], the photo in the crop box.
        alpha: (h, w) float32 in [0, 1], the matte there.
    """
    h, w = alpha.shape
    scale = min(1.0, float(np.sqrt(_WORK_PIXELS / (h * w))))
    size = (max(1, round(w * scale)), max(1, round(h * scale)))
    small = scale < 1.0
    img = cv2.resize(image, size, interpolation=cv2.INTER_AREA) if small else np.ascontiguousarray(image, np.float32)
    a = cv2.resize(alpha, size, interpolation=cv2.INTER_AREA) if small else np.asarray(alpha, np.float32)
    inside = (a >= 0.5).astype(np.uint8)
    soft = (a > 0.02) & (a < 0.98)
    if not inside.any() or not soft.any():
        return np.array(alpha, np.float32)
    depth = cv2.distanceTransform(np.pad(inside, 1, constant_values=1), cv2.DIST_L2, 3)[1:-1, 1:-1]
    outline = max(int(np.count_nonzero(inside - cv2.erode(inside, np.ones((3, 3), np.uint8)))), 1)
    band = scale * min(max(_BAND, _BAND_SOFT * np.count_nonzero(soft) / outline / scale), _BAND_MAX)
    gx, gy = cv2.Sobel(img, cv2.CV_32F, 1, 0, ksize=3), cv2.Sobel(img, cv2.CV_32F, 0, 1, ksize=3)
    gradient = np.sqrt((gx * gx + gy * gy).sum(axis=2)) / 8  # Sobel's weights sum to 8
    r = _RADIUS
    deeper = np.where(cv2.blur(gradient, (2 * r + 1,) * 2) >= _TEXTURE, _BAND_TEXTURE, 1.0)
    reach = deeper * band
    unknown = (soft & (depth <= reach)) | ((inside > 0) & (depth <= deeper * (_SOLID * scale)))
    prior = np.where(a >= 0.98, 1, np.where(a <= 0.02, 0, a)).astype(np.float32)
    solved = colour_line_alpha(img, prior, unknown, r, _EPS, _LAM, _ITERATIONS)
    # how far colour tells the solid person (deeper than the band) from the solid background near each pixel
    far = int(np.ceil(2 * _BAND_TEXTURE * band)) + r
    b, has_b = _side(img, a <= 0.02, far)
    f, has_f = _side(img, (a >= 0.98) & (depth > reach), far)
    apart = ((f - b) ** 2).sum(axis=2)
    trust = has_b * has_f * apart / (apart + _TAU)
    sure = np.clip(1 - solved / _SURE, 0, 1)
    drop = np.where(unknown, trust * sure * np.maximum(a - solved, 0), 0).astype(np.float32)
    if small:
        drop = cv2.resize(drop, (w, h), interpolation=cv2.INTER_LINEAR)
    return np.clip(alpha - drop, 0, 1).astype(np.float32)
