"""A face's albedo with the photo's own shading that stage 1 took into it taken out (relight_rt.relight.factor
``Factor.own``: on a photo with a face mesh, before the relighting factor divides by the pipeline's own image)."""

from __future__ import annotations

import numpy as np

UNSHADE_MIN_SKIN = 50  # unshaded_albedo: the fewest face-skin pixels (network frame) its fit is made on


def unshaded_albedo(albedo: np.ndarray, shading: np.ndarray, skin: np.ndarray, inner: np.ndarray) -> np.ndarray:
    """Stage 1's albedo luminance with the part of the photo's own shading it took in taken out.

    A face's skin is one material, so its albedo does not follow the light: the slope b of log albedo on log
    shading over ``skin`` (the least-squares fit, kept in [0, 1]) is the share of the photo's own shading that
    stage 1 put into the albedo (on side-lit Extended Yale B faces the shaded half's albedo came out 15-30 % darker
    than the lit half's: the ratio then kept that much of the photo's shadow, benchmarks/yale_eval.py). Over the
    person (``inner``) the albedo becomes albedo x (shading / its median over the skin) ** -b, the shading held
    within the 2-98 % range the fit saw (stage 1 does this to every material; only skin shows how much); outside
    it stays. With fewer than ``UNSHADE_MIN_SKIN`` skin pixels (no face mesh) nothing changes.

    Args:
        albedo, shading: (r, r') float32 luminance of stage 1's albedo and of the shading under the photo's own
            light (both > 0 where they mean anything).
        skin, inner: (r, r') bool, the face's skin (a mesh's) and the person's pixels.

    Returns:
        (r, r') float32, a new array (``albedo`` itself when nothing is taken out).
    """
    ok = skin & (shading > 1e-3) & (albedo > 1e-3)
    if int(ok.sum()) < UNSHADE_MIN_SKIN:
        return albedo
    x, y = np.log(shading[ok]), np.log(albedo[ok])
    x = x - x.mean()
    b = float(np.clip((x * (y - y.mean())).sum() / max(float((x * x).sum()), 1e-9), 0, 1))
    if b == 0:
        return albedo
    # within the shading the fit saw: a profile's hair turned away in deep shade came out 3x brighter without
    lo, level, hi = np.percentile(shading[ok], [2, 50, 98])
    gain = np.where(inner, (np.clip(shading, lo, hi) / level) ** -b, 1)
    return (albedo * gain).astype(np.float32)
