"""Colour decontamination: the foreground colour of a matte's soft edge, so a cut-out carries none of
its old background.

An edge pixel of a photo mixes the person and what lay behind them: ``I = alpha F + (1 - alpha) B``.
Compositing the photo's own pixels over a new backdrop keeps the old ``B`` in every soft pixel (the
grey-blue or white fringe around hair and limbs); compositing ``F`` does not. :func:`estimate_foreground`
recovers ``F`` (and ``B``) by the multilevel method of Germer, Uelwer, Conrad & Harmeling, "Fast
Multi-Level Foreground Estimation" (ICPR 2020): per pixel, minimise

    (alpha F + (1 - alpha) B - I)^2 + sum over the 4 neighbours j of
        (eps + omega |alpha_i - alpha_j|) ((F_i - F_j)^2 + (B_i - B_j)^2)

with the neighbours held fixed (a 2x2 linear system per pixel and channel), sweeping the image in
red-black order, coarse to fine: the coarse levels carry colours far into the edge, the fine levels
sharpen them. Written here in numpy (the paper's code, pymatting, needs numba). At the fine levels only
the pixels near the soft edge are solved (elsewhere F = I where alpha = 1, B = I where alpha = 0, and
the coarser level's answer otherwise), so the cost grows with the length of the outline, not the photo.
"""

from __future__ import annotations

import cv2
import numpy as np

from ..engine.errors import RelightError

_EPS_R = 1e-5  # regulariser: smoothness of F and B where alpha is flat (the paper's and pymatting's value)
_OMEGA = 1.0  # extra smoothness weight per unit of alpha change between neighbours
_SMALL = 32  # levels whose sides are both <= this get _ITER_SMALL sweeps, the others _ITER_BIG
_ITER_SMALL = 10
_ITER_BIG = 2
_SOLID = 1.0 / 255  # alpha within this of 0 or 1 counts as background / foreground at the fine levels
_DENSE_MAX = 1 << 16  # levels with at most this many pixels are solved everywhere
_MARGIN = 16  # pixels of background kept around the person's box (at least; 1/8 of the box's side)


def _check(rgb: np.ndarray, alpha: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    if not isinstance(rgb, np.ndarray) or rgb.ndim != 3 or rgb.shape[2] != 3:
        got = f"{tuple(rgb.shape)} {rgb.dtype}" if isinstance(rgb, np.ndarray) else type(rgb).__name__
        raise RelightError(f"estimate_foreground: expected an (H, W, 3) RGB image, got {got}")
    if not isinstance(alpha, np.ndarray) or alpha.ndim not in (2, 3) or (alpha.ndim == 3 and alpha.shape[2] != 1):
        got = f"{tuple(alpha.shape)} {alpha.dtype}" if isinstance(alpha, np.ndarray) else type(alpha).__name__
        raise RelightError(f"estimate_foreground: expected an (H, W) alpha, got {got}")
    if alpha.shape[:2] != rgb.shape[:2]:
        raise RelightError(f"estimate_foreground: alpha is {alpha.shape[:2]}, the image {rgb.shape[:2]} (H, W)")
    out = []
    for name, a in (("image", rgb), ("alpha", alpha.reshape(alpha.shape[:2]))):
        if a.dtype == np.uint8:
            out.append(a.astype(np.float32) * np.float32(1 / 255))
            continue
        if a.dtype.kind != "f":
            raise RelightError(f"estimate_foreground: {name}: expected uint8 or float in [0, 1], got {a.dtype}")
        a = np.asarray(a, np.float32)
        if not np.isfinite(a).all():
            raise RelightError(f"estimate_foreground: {name}: expected finite values, got NaN or Inf")
        out.append(np.clip(a, 0.0, 1.0))
    return out[0], out[1]


def _level_sizes(h: int, w: int) -> list[tuple[int, int]]:
    """(h, w) per level, from 1x1 up to the full size, each about twice the previous."""
    n = max(int(np.ceil(np.log2(max(h, w)))), 1)
    sizes = []
    for i in range(n + 1):
        s = i / n
        size = (max(int(round(h**s)), 1), max(int(round(w**s)), 1))
        if not sizes or size != sizes[-1]:
            sizes.append(size)
    return sizes


def _neighbours(idx: np.ndarray, h: int, w: int, alpha_flat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(4, n) neighbour indices (self where outside the image) and weights (0 there) of flat pixels ``idx``."""
    y, x = np.divmod(idx, w)
    nbr = np.stack([idx - w, idx + w, idx - 1, idx + 1])
    ok = np.stack([y > 0, y < h - 1, x > 0, x < w - 1])
    nbr = np.where(ok, nbr, idx[None])
    a = alpha_flat[idx]
    wgt = (_EPS_R + _OMEGA * np.abs(a[None] - alpha_flat[nbr])) * ok
    return nbr, wgt.astype(np.float32)


def _prepare(idx: np.ndarray, h: int, w: int, img: np.ndarray, alpha: np.ndarray) -> tuple:
    """What one Gauss-Seidel update of pixels ``idx`` needs that stays fixed over the sweeps of a level: the
    neighbours and their weights, and the 2x2 system's inverse applied to the data terms."""
    nbr, wgt = _neighbours(idx, h, w, alpha)
    a = alpha[idx][:, None]
    wsum = wgt.sum(0)[:, None]
    inv = 1.0 / (wsum * (a * a + (1 - a) * (1 - a) + wsum))  # = 1 / det, without the cancellation
    i = img[idx]
    coef = (((1 - a) * (1 - a) + wsum) * inv, a * (1 - a) * inv, (a * a + wsum) * inv)
    flat = (idx[:, None] * 3 + np.arange(3)).reshape(-1)  # the pixels' values in the flat (n * 3,) F and B
    return flat, nbr, wgt, coef, a * i, (1 - a) * i


def _sweep(f: np.ndarray, b: np.ndarray, prepared: tuple) -> None:
    """One Gauss-Seidel update of the flat (n, 3) F and B at the prepared pixels (in place: the solver's state, both
    C-contiguous, so that their flat views are them).

    Per pixel and channel, with the neighbours' F and B held fixed:
    [a^2 + W, a(1-a); a(1-a), (1-a)^2 + W] [F; B] = [a I + sum w F_j; (1-a) I + sum w B_j], W = sum w.
    The gathers by ``np.take`` and the writes through the flat indices are the same values as ``f[nbr]`` and
    ``f[idx] = ...``, several times faster."""
    flat, nbr, wgt, (c22, c12, c11), ai, bi = prepared
    r1 = np.einsum("kn,knc->nc", wgt, np.take(f, nbr, axis=0))
    r1 += ai
    r2 = np.einsum("kn,knc->nc", wgt, np.take(b, nbr, axis=0))
    r2 += bi
    f.reshape(-1)[flat] = np.clip(c22 * r1 - c12 * r2, 0.0, 1.0).reshape(-1)
    b.reshape(-1)[flat] = np.clip(c11 * r2 - c12 * r1, 0.0, 1.0).reshape(-1)


def estimate_foreground(rgb: np.ndarray, alpha: np.ndarray, *, return_background: bool = False):
    """The foreground colour F of every pixel, given the photo and its soft matte (module docstring).

    Args:
        rgb: (H, W, 3) RGB, float in [0, 1] or uint8.
        alpha: (H, W) or (H, W, 1) matte, float in [0, 1] or uint8; 1 = person.
        return_background: also return the estimated background colour B.

    Returns:
        New float32 (H, W, 3) F in [0, 1] (equal to the photo where alpha is 1); with
        ``return_background``, the pair (F, B). Composite with ``alpha F + (1 - alpha) backdrop``.

    Raises:
        RelightError: shapes that do not match, a dtype other than uint8 or float, NaN or Inf.
    """
    img, a = _check(rgb, alpha)
    # only the person's box (plus a margin for the background's colours) needs solving: F = I elsewhere
    ys = np.nonzero(cv2.reduce(a, 1, cv2.REDUCE_MAX)[:, 0] > _SOLID)
    xs = np.nonzero(cv2.reduce(a, 0, cv2.REDUCE_MAX)[0] > _SOLID)
    if ys[0].size == 0 or bool((a >= 1 - _SOLID).all()):
        f = img.copy()
        return (f, img.copy()) if return_background else f
    y0, y1, x0, x1 = int(ys[0][0]), int(ys[0][-1]) + 1, int(xs[0][0]), int(xs[0][-1]) + 1
    m = max(_MARGIN, (max(y1 - y0, x1 - x0) + 7) // 8)
    y0, y1, x0, x1 = max(y0 - m, 0), min(y1 + m, a.shape[0]), max(x0 - m, 0), min(x1 + m, a.shape[1])
    f_box, b_box = _solve(np.ascontiguousarray(img[y0:y1, x0:x1]), np.ascontiguousarray(a[y0:y1, x0:x1]))
    f = img.copy()
    f[y0:y1, x0:x1] = f_box
    if not return_background:
        return f
    b = img.copy()
    b[y0:y1, x0:x1] = b_box
    return f, b


def _solve(img: np.ndarray, a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The multilevel solve on one (h, w, 3) image and its (h, w) alpha: (F, B), float32."""
    h, w = a.shape
    sizes = [s for s in _level_sizes(h, w) if s[0] * s[1] > 1 or h * w == 1]  # 1x1 has no neighbours
    pyramid = [(img, a)]  # finest first; each level reduced from the next finer one (cheap, no aliasing)
    for lh, lw in reversed(sizes[:-1]):
        pi, pa = pyramid[-1]
        pyramid.append((cv2.resize(pi, (lw, lh), interpolation=cv2.INTER_AREA),
                        cv2.resize(pa, (lw, lh), interpolation=cv2.INTER_AREA)))  # fmt: skip
    f = b = None
    for li, la in reversed(pyramid):
        lh, lw = la.shape
        li = li.reshape(-1, 3)
        la = la.reshape(-1)
        if f is None:
            f = li.copy()
            b = li.copy()
        else:
            f = cv2.resize(f, (lw, lh), interpolation=cv2.INTER_LINEAR).reshape(-1, 3)
            b = cv2.resize(b, (lw, lh), interpolation=cv2.INTER_LINEAR).reshape(-1, 3)
        if lh * lw <= _DENSE_MAX:
            active = np.arange(lh * lw)
        else:
            solid_fg = la >= 1 - _SOLID
            solid_bg = la <= _SOLID
            np.copyto(f, li, where=solid_fg[:, None])
            np.copyto(b, li, where=solid_bg[:, None])
            soft = (~(solid_fg | solid_bg)).reshape(lh, lw).astype(np.uint8)
            active = np.flatnonzero(cv2.dilate(soft, np.ones((3, 3), np.uint8)))
        if active.size and lh * lw > 1:  # (a single pixel has no neighbours: F = B = I)
            y, x = np.divmod(active, lw)
            odd = ((y + x) & 1).astype(bool)
            parts = [active[~odd], active[odd]]  # red-black: neighbours differ in colour
            prepared = [_prepare(p, lh, lw, li, la) for p in parts if p.size]
            for _ in range(_ITER_SMALL if lh <= _SMALL and lw <= _SMALL else _ITER_BIG):
                for prep in prepared:
                    _sweep(f, b, prep)
        f = f.reshape(lh, lw, 3)
        b = b.reshape(lh, lw, 3)
    np.copyto(f, img, where=(a >= 1 - _SOLID)[..., None])  # an opaque pixel keeps its colour exactly
    return f, b


def nearest_colours(rgb: np.ndarray, alpha: np.ndarray, radius: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """(F, B) of a thin soft edge from the solid pixels beside it: a cheap :func:`estimate_foreground`.

    A matte whose soft edge is a pixel or two wide (anti-aliasing, a video frame's feathered mask) mixes the
    person and the background over so short a stretch that the colours on either side are the edge's own. Each
    soft pixel takes the mean colour of the solid pixels of each kind within ``radius`` (twice, then four
    times that where there are none) for the side it mixes less of, and the compositing equation
    ``I = alpha F + (1 - alpha) B`` gives the other (dividing by at least 1/2): F where alpha >= 1/2, B below.
    Where that leaves [0, 1], the first side is solved back from the clipped second, so the pair always
    composes into the photo. Solid pixels keep the photo's colour in both. Costs a few box filters over the
    soft pixels' box.

    Args:
        rgb: (H, W, 3) float32 RGB in [0, 1].
        alpha: (H, W) float32 matte in [0, 1].
        radius: half-width of the window the solid neighbours are taken from.

    Returns:
        New float32 (H, W, 3) F and B.
    """
    f, b = rgb.copy(), rgb.copy()
    soft = (alpha > _SOLID) & (alpha < 1 - _SOLID)
    rows, cols = np.flatnonzero(soft.any(axis=1)), np.flatnonzero(soft.any(axis=0))
    if rows.size == 0:
        return f, b
    reach = 4 * radius + 1
    y0, y1 = max(int(rows[0]) - reach, 0), min(int(rows[-1]) + 1 + reach, alpha.shape[0])
    x0, x1 = max(int(cols[0]) - reach, 0), min(int(cols[-1]) + 1 + reach, alpha.shape[1])
    img, a, edge = rgb[y0:y1, x0:x1], alpha[y0:y1, x0:x1], soft[y0:y1, x0:x1]
    ey, ex = np.nonzero(edge)
    i, av = img[ey, ex], a[ey, ex][:, None]
    sides = []
    for solid in (a >= 1 - _SOLID, a <= _SOLID):
        weight = solid.astype(np.float32)
        weighted = img * weight[..., None]
        mean = i.copy()  # no solid pixel of that kind within reach: the photo
        todo = np.arange(len(i))
        for r in (radius, 2 * radius, 4 * radius):
            # the window sums only over the box of the pixels still without a mean (the wider windows are
            # for a few pixels: where the outline meets the border, a thin limb)
            py, px = ey[todo], ex[todo]
            by0, bx0 = max(int(py.min()) - r, 0), max(int(px.min()) - r, 0)
            by1, bx1 = min(int(py.max()) + r + 1, a.shape[0]), min(int(px.max()) + r + 1, a.shape[1])
            k = (2 * r + 1, 2 * r + 1)
            n = cv2.boxFilter(weighted[by0:by1, bx0:bx1], -1, k, normalize=False, borderType=cv2.BORDER_CONSTANT)
            d = cv2.boxFilter(weight[by0:by1, bx0:bx1], -1, k, normalize=False, borderType=cv2.BORDER_CONSTANT)
            n, d = n[py - by0, px - bx0], d[py - by0, px - bx0]
            found = d > 0.5
            mean[todo[found]] = n[found] / d[found, None]
            todo = todo[~found]
            if not todo.size:
                break
        sides.append(mean)
    near_f, near_b = sides
    mostly_f = av >= 0.5
    known = np.where(mostly_f, near_b, near_f)  # the side the pixel mixes less of, from its neighbours
    share = np.where(mostly_f, 1 - av, av)
    solved = np.clip((i - share * known) / (1 - share), 0, 1)  # the other side from the equation
    known = np.clip((i - (1 - share) * solved) / share, 0, 1)  # where that clipped: the pair composes back
    f[y0 + ey, x0 + ex] = np.where(mostly_f, solved, known)
    b[y0 + ey, x0 + ex] = np.where(mostly_f, known, solved)
    return f, b
