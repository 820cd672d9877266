"""How strongly a new light changes the photo: the directional bands of stage 1's transport, restored.

Stage 1 regresses the transport from a photo, and a regression shrinks what it is unsure of toward the mean:
measured against the true transport of held-out renders (``benchmarks/heldout_change.py``'s people, five
framings, DESIGN.md §3 normalisation), the per-pixel ratio of the degree-1 band's magnitude to the degree-0
coefficient is 1.06-1.08 in the network's transport against 1.18-1.20 in the truth (x0.89-0.92), and the degree-2
band's 0.46-0.50 against 0.61-0.66 (x0.73-0.82); the band-1 directions differ by 16-20 degrees on average. A
transport whose directional bands are too small makes every new light look like a softer version of itself: the
relit change of a single lamp had 0.31-0.47x the contrast of the truth.

The runtime scales the degree-1 and degree-2 bands of the transport by fixed gains that undo that shrinkage on
average (``BAND_GAIN``), before computing both sides of the relighting factor (relight_rt.relighter ``_gain``).
Band 0 (the pixel's overall visibility, which sets the exposure) is kept. Because the numerator (new light) and
denominator (the photo's own light) use the same restored transport, the photo's own light still gives the photo
back. A per-pixel renormalisation of the bands to a unit normal's ratio was measured too and does not help (it
also shrinks the pixels the network got strong); a uniform gain does.
"""

from __future__ import annotations

import numpy as np

from ._errors import RelightError

BAND_GAIN = (1.0, 1.1, 1.3)  # degree 0, 1, 2: the inverse of the measured shrinkage (module docstring)


def restore_bands(transport: np.ndarray, gains: tuple[float, float, float] | None = None) -> np.ndarray:
    """A copy of an (..., 9) transport (DESIGN.md §3 order) with each degree's coefficients times its gain.

    Args:
        transport: (..., 9) SH transport, any leading shape.
        gains: the factors for degree 0, 1 and 2 (default ``BAND_GAIN``).

    Returns:
        float32 array of the same shape.
    """
    t = np.asarray(transport)
    if t.shape[-1] != 9:
        raise RelightError(f"transport must end in 9 SH coefficients, got shape {t.shape}")
    if gains is None:
        gains = BAND_GAIN
    scale = np.array([gains[0]] + [gains[1]] * 3 + [gains[2]] * 5, np.float32)
    return (t * scale).astype(np.float32, copy=False)
