"""The person's own colours: what the selfie graph sees joined to the matte, kept where its colour is the person's.

The pose graph does not see dark trousers on a runner (probability < 0.01 over them on the parkour clip's worst
frames), nor the selfie graph a patch of them; the selfie graph on the whole photo sees most of them, and the
shadow on the ground beside them too. Colour tells them apart: the trousers are the colour of the person's other
leg, the shadow is the ground's. On one square region's canvas (the person's), the colours of the person's sure
interior and of a ring of background around them are each summarised by a few k-means centres (CIELAB); a pixel the
selfie graph sees (>= OWN_SURE) outside the matte, joined to it, is the person's where its colour lies nearer to
the person's nearest centre than OWN_RATIO x its distance to the background's nearest centre (and what is kept
stays joined to the matte). Measured in relight_rt.person.matting._matter.PersonMatter._own_colours.

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


def colour_model(canvas: np.ndarray, inside: np.ndarray, mine: np.ndarray, around: np.ndarray,
                 apart: np.ndarray | None = None, like: Colours | None = None) -> Colours | None:  # fmt: skip
    """The person's and the backdrop's colours on a canvas: (its L*a*b*, the k-means centres of the matte ``mine``'s
    interior, those of a ring ``OWN_RING`` x the matte's size wide round ``around`` (the matte and what is asked
    about), less ``apart``), or None when either holds under 20 pixels inside the photo (``inside``). With ``like``, a
    model of the same canvas and matte, its L*a*b* and person's centres are reused: only the backdrop's are made."""
    one = np.ones((3, 3), np.uint8)
    ys, xs = np.nonzero(mine)
    r = max(2, int(OWN_RING * max(np.ptp(ys), np.ptp(xs))))
    base = around.astype(np.uint8)
    ring = cv2.dilate(base, np.ones((2 * r + 1, 2 * r + 1), np.uint8)).astype(bool)
    ring &= ~cv2.dilate(base, one).astype(bool) & inside
    if apart is not None:
        ring &= ~apart
    if like is not None:
        return (like[0], like[1], centres(like[0][ring])) if ring.sum() >= 20 else None
    interior = cv2.erode(mine.astype(np.uint8), one).astype(bool) & inside
    if interior.sum() < 20 or ring.sum() < 20:
        return None
    lab = cv2.cvtColor(np.ascontiguousarray(canvas, dtype=np.float32), cv2.COLOR_RGB2Lab)  # L 0-100
    return lab, centres(lab[interior]), centres(lab[ring])


def candidates(canvas: np.ndarray, inside: np.ndarray, mine: np.ndarray, seen: np.ndarray, framed: np.ndarray,
               bottom: np.ndarray) -> tuple[tuple[np.ndarray, Colours], tuple[np.ndarray, Colours]] | None:  # fmt: skip
    """What the own colours' step and the bottom border's (relight_rt.person.matting._cut_body) look at on a canvas,
    each with its colour model (:func:`colour_model`, the ring round the matte and the first): the
    pixels outside the matte, joined to it, that the selfie graph sees (module docstring: >= OWN_SURE on the whole
    photo, >= 0.5 framed on the people), and for the bottom border's step, where the matte reaches the photo's bottom
    rows, those with the pixels the graph framed on the people alone is sure of (>= OWN_SURE), and their ring less
    these pixels (the backdrop's colours are sampled where no view sees the person); one set and one model for both
    where the matte does not reach those rows or the two are the same pixels. None when the second
    are fewer than OWN_MIN x the matte's pixels (its rim) or a model cannot be made. :func:`own_part` decides on the
    first, relight_rt.person.matting._cut_body.cut_part on the second.

    The whole photo's answer is asked so that the ground under a person's feet, which that graph, seeing the person
    small, takes in, stays out; under a body the photo's bottom border cuts, that ground is out of the frame, and there
    the framed answer alone is the surer (a man's brown trousers at the bottom border of a photo of an embracing
    couple: 0.9+ framed on the couple, 0.3-0.6 on the whole photo; measured in relight_rt.person.matting._cut_body).

    Args:
        canvas: (S, S, 3) float32 RGB in [0, 1].
        inside: (S, S) bool, the canvas pixels inside the photo.
        mine: (S, S) bool, the matte (the people found).
        seen: (S, S) float, the selfie graph's person probability on the whole photo.
        framed: (S, S) float, the selfie graph's person probability framed on the canvas's region.
        bottom: (S, S) bool, the photo's bottom rows on the canvas (relight_rt.person.matting._cut_body.photo_bottom).

    Returns:
        ((own colours' candidates, their model), (the bottom border's, theirs)), each candidates an (S, S) bool and each
        model (L*a*b* canvas, the person's centres, the backdrop's); or None.
    """
    outside = ~mine & inside
    cand = joined((framed >= 0.5) & (seen >= OWN_SURE) & outside, mine)
    below = cand | joined((framed >= OWN_SURE) & outside, mine) if (mine & bottom).any() else cand
    if below.sum() < max(1.0, OWN_MIN * mine.sum()):
        return None
    model = colour_model(canvas, inside, mine, mine | cand)
    if model is None:
        return None
    more = below & ~cand
    below_model = colour_model(canvas, inside, mine, mine | cand, more, like=model) if more.any() else model
    return None if below_model is None else ((cand, model), (below, below_model))


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
