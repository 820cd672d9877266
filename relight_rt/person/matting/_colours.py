"""The person's own colours: what the selfie graph sees joined to the matte, kept where its colour is the person's.

The pose graph does not see dark trousers on a runner (probability < 0.01 over them on the parkour clip's worst
frames), nor the selfie graph a patch of them; the selfie graph on the whole photo sees most of them, and the
shadow on the ground beside them too. Colour tells them apart: the trousers are the colour of the person's other
leg, the shadow is the ground's. On one square region's canvas (the person's), the colours of the person's sure
interior and of a ring of background around them are each summarised by a few k-means centres (CIELAB); a pixel the
selfie graph sees (>= OWN_SURE) outside the matte, joined to it, is the person's where its colour lies nearer to
the person's nearest centre than OWN_RATIO x its distance to the background's nearest centre (and what is kept
stays joined to the matte). Measured in relight_rt.person.matting._completion.own_colours.

A candidate must also be seen (>= 0.5) by the graph framed on the people's own region: on the whole photo the graph,
seeing the person small, takes in the dark post or wall block the feet stand on, the very colour of black trousers,
which framed on the person it leaves out (parkour clip frames 85-88: 0.815 -> 0.92 for frame 85). Measured with
_turned (benchmarks/people_masks_eval.py --methods ours): clip 0.9296 -> 0.9319 (with _turned's OWN_MIN bound, +0.0004
alone; frames 85, 87, 7, 93, 88 +0.02-0.11;
frame 49 -0.14: a trailing leg the graph sees only on the whole photo), photos half A 0.9186 -> 0.9196, half B 0.8929
-> 0.8931 (checked). Both answers >= OWN_SURE instead (their smaller one): clip 0.9321, A 0.9194, but the skater's
beige sleeve left out, her raised hand apart from her arm (tests/runtime/person/matting/test_people_found.py).
"""

from __future__ import annotations

import cv2
import numpy as np

OWN_SURE = 0.7  # the selfie graph's probability over a pixel that may be the person's own colour
OWN_RATIO = 0.4  # ... nearer to the person's colours than this x its distance to the background's
OWN_CENTRES = 6  # k-means centres per side
OWN_SAMPLES = 1500  # pixels sampled per side for the centres (every n-th: the same answer each call)
OWN_MIN = 0.01  # candidates, or a part kept, of fewer than this x the matte's pixels are its rim: not looked at
OWN_RING = 0.1  # the background ring reaches this x the person's extent past them (canvas pixels, at least 2)
_ITERATIONS = 6

Colours = tuple[np.ndarray, np.ndarray, np.ndarray]  # a canvas's L*a*b*, the person's centres, the backdrop's


def centres(samples: np.ndarray, k: int = OWN_CENTRES) -> np.ndarray:
    """(k', 3) k-means centres of (N, 3) float32 ``samples`` (k' = min(k, N)), deterministic: started from the
    samples at evenly spaced ranks of their first channel (lightness), _ITERATIONS Lloyd steps."""
    x = samples[:: max(1, len(samples) // OWN_SAMPLES)].astype(np.float32)
    k = min(k, len(x))
    order = np.argsort(x[:, 0], kind="stable")
    c = x[order[((np.arange(k) + 0.5) * len(x) / k).astype(int)]].copy()
    for _ in range(_ITERATIONS):
        label = nearest(x, c)[1]
        for i in range(k):
            mine = x[label == i]
            if len(mine):
                c[i] = mine.mean(0)
    return c


def nearest(x: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance from each of (N, 3) ``x`` to its nearest centre of ``c``, and that centre's index."""
    d = (x * x).sum(1)[:, None] - 2.0 * (x @ c.T) + (c * c).sum(1)[None, :]
    label = d.argmin(1)
    return np.sqrt(np.maximum(d[np.arange(len(x)), label], 0.0)), label


def joined(part: np.ndarray, mine: np.ndarray) -> np.ndarray:
    """The 8-connected components of ``part`` | ``mine`` that hold some of ``mine``, less ``mine``."""
    _, labels = cv2.connectedComponents((part | mine).astype(np.uint8), connectivity=8)
    keep = np.unique(labels[mine])
    return np.isin(labels, keep[keep > 0]) & part


def backdrop_ring(inside: np.ndarray, mine: np.ndarray, around: np.ndarray) -> np.ndarray:
    """(S, S) bool: the ring ``OWN_RING`` x the matte ``mine``'s size wide (at least 2 canvas pixels) round
    ``around`` (the matte and what is asked about), a pixel off it, inside the photo (``inside``)."""
    ys, xs = np.nonzero(mine)
    r = max(2, int(OWN_RING * max(np.ptp(ys), np.ptp(xs))))
    base = around.astype(np.uint8)
    ring = cv2.dilate(base, np.ones((2 * r + 1, 2 * r + 1), np.uint8)).astype(bool)
    return ring & ~cv2.dilate(base, np.ones((3, 3), np.uint8)).astype(bool) & inside


def colour_model(canvas: np.ndarray, inside: np.ndarray, mine: np.ndarray, around: np.ndarray,
                 apart: np.ndarray | None = None) -> Colours | None:  # fmt: skip
    """The person's and the backdrop's colours on a canvas: (its L*a*b*, the k-means centres of the matte ``mine``'s
    interior, those of :func:`backdrop_ring` round ``around``, less ``apart``), or None when either holds under 20
    pixels inside the photo (``inside``)."""
    interior = cv2.erode(mine.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool) & inside
    ring = backdrop_ring(inside, mine, around)
    if apart is not None:
        ring &= ~apart
    if interior.sum() < 20 or ring.sum() < 20:
        return None
    lab = cv2.cvtColor(np.ascontiguousarray(canvas, dtype=np.float32), cv2.COLOR_RGB2Lab)  # L 0-100
    return lab, centres(lab[interior]), centres(lab[ring])


def backdrop_less(model: Colours, inside: np.ndarray, mine: np.ndarray, around: np.ndarray,
                  apart: np.ndarray) -> Colours | None:  # fmt: skip
    """``model`` (:func:`colour_model` of the same canvas, matte ``mine`` and ``around``) with its backdrop's centres
    drawn again from the ring less ``apart``: its L*a*b* and the person's centres as they are; None when that ring
    holds under 20 pixels."""
    lab, person, _ = model
    ring = backdrop_ring(inside, mine, around) & ~apart
    return (lab, person, centres(lab[ring])) if ring.sum() >= 20 else None


def candidates(inside: np.ndarray, mine: np.ndarray, seen: np.ndarray, framed: np.ndarray) -> np.ndarray:
    """The own colours' candidates on a canvas: the pixels inside the photo (``inside``) outside the matte ``mine``,
    joined to it, that the selfie graph sees both on the whole photo (``seen`` >= OWN_SURE) and framed on the people's
    region (``framed`` >= 0.5; module docstring). (S, S) bool. :func:`own_part` decides on them with the
    :func:`colour_model` of the ring round the matte and them; relight_rt.person.matting._cut_body adds, for a body the
    photo's bottom border cuts, what the framed graph alone is sure of."""
    return joined((framed >= 0.5) & (seen >= OWN_SURE) & ~mine & inside, mine)


def own_part(mine: np.ndarray, cand: np.ndarray, model: Colours) -> np.ndarray | None:
    """The candidates ``cand`` (:func:`candidates`) that are the person's own colour (module docstring); None when
    none are (or fewer than OWN_MIN x the matte ``mine``'s pixels). (S, S) bool."""
    lab, person, backdrop = model
    x = lab[cand]
    ok = nearest(x, person)[0] < OWN_RATIO * nearest(x, backdrop)[0]
    part = np.zeros(mine.shape, bool)
    part[cand] = ok
    part = joined(part, mine)
    return part if part.sum() >= max(1.0, OWN_MIN * mine.sum()) else None
