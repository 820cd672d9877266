"""How strongly a new light changes the photo: the directional bands of stage 1's transport, restored.

Stage 1 regresses the transport from a photo, and a regression shrinks what it is unsure of toward the mean:
measured against the true transport of held-out renders (``benchmarks/heldout_change.py``'s people, five
framings, DESIGN.md §3 normalisation), the per-pixel ratio of the degree-1 band's magnitude to the degree-0
coefficient is 1.06-1.08 in the network's transport against 1.18-1.20 in the truth (x0.89-0.92), and the degree-2
band's 0.46-0.50 against 0.61-0.66 (x0.73-0.82); the band-1 directions differ by 16-20 degrees on average. A
transport whose directional bands are too small makes every new light look like a softer version of itself: the
relit change of a single lamp had 0.31-0.47x the contrast of the truth.

The runtime scales the degree-1 and degree-2 bands of the transport by fixed gains that undo that shrinkage on
average (``BAND_GAIN``), before computing both sides of the relighting factor (relight_rt.relight.relighter ``_gain``).
Those figures are the sixth bundled stage 1's (gains 1.1 / 1.3). The seventh (2026-11-27, trained with losses on
the bands' magnitudes and the degree-1 direction; models/README.md) is no longer shrunk (degree-1/0 1.24-1.37
against 1.20-1.23 true, degree-2/0 0.67-0.80 against 0.69-0.75), but its light is still softer than the truth
(degree-1/0 1.20-1.36 against 1.42, degree-2/0 1.37-1.76 against 1.78): together they leave degree 1 about
0.96 x 1.13 and degree 2 about 1.0 x 1.16 short, hence 1.05 / 1.15. The averaged stage 1 shipped since
2026-11-28 (degree-1/0 1.24-1.31, degree-2/0 0.67-0.74; light 1.19-1.33 and 1.36-1.68) leaves about 0.93 and 0.85,
gains of about 1.08 / 1.18: the same gains are kept.
Band 0 (the pixel's overall visibility, which sets the exposure) is kept. Because the numerator (new light) and
denominator (the photo's own light) use the same restored transport, the photo's own light still gives the photo
back. A per-pixel renormalisation of the bands to a unit normal's ratio was measured too and does not help (it
also shrinks the pixels the network got strong); a uniform gain does.
"""

from __future__ import annotations

import cv2
import numpy as np

from ..engine.errors import RelightError
from ..image.color import REC709
from .fill_edge import soften

BAND_GAIN = (1.0, 1.05, 1.15)  # degree 0, 1, 2: what the measured transport and light leave short (module docstring)


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


# --------------------------------------------------------------------------------------- the photo's own light

REFIT_PRIOR = 0.3  # ridge weight toward stage 1's estimate, relative to the normal matrix's mean diagonal (refit_light)
FACE_PRIOR = 0.1  # face_refit: its ridge toward the refit light (scaled to the face), relative as REFIT_PRIOR
FACE_TRIM = 2.5  # ... skin pixels further than this many robust deviations from the fit are left out (eyes, brows)
FACE_PIXELS = 2000  # ... a face of n skin pixels moves the light n / (n + this) of the way to its own fit
_FACE_MIN = 50  # ... fewer skin pixels than this: no fit


def refit_light(
    light: np.ndarray, albedo: np.ndarray, transport: np.ndarray, photo: np.ndarray, prior: float | None = None
) -> np.ndarray:
    """Stage 1's estimate of the photo's light, refit so that albedo x (transport . light) explains the photo.

    Stage 1 estimates the light from the photo alone, a regression that shrinks toward a soft, ambient light;
    the runtime divides the photo by albedo x shading under that light (relight_rt.relight.relighter), so every error
    in the estimate stays in the relit picture as shading the new light did not make. Given the transport the
    runtime actually divides with (directional bands restored, the face mesh's normals blended in), the light
    that best explains the photo's luminance is a 9-unknown linear least-squares problem over the person's
    pixels: minimise |X l - y|^2 + prior * mean(diag(X'X)) * |l - l0|^2 with X = albedo x transport,
    y = the photo's luminance and l0 the luminance of stage 1's estimate. The ridge keeps the light stage 1's
    where the pixels do not pin it down (a person seen from the front says little about the light behind).
    Where the estimate already explains the photo the correction is zero. ``REFIT_PRIOR`` 0.3: with 0.01 the
    fit can overshoot into a light no sky of non-negative radiance gives (on the studio's example photo a
    degree-1 band twice the degree-0 coefficient), whose shading is near zero on part of the person; 0.3 keeps
    the held-out renders' figures within 0.01 of the weaker prior's and the DPR portraits' sides and correlation
    at or above stage 1's light's (docs/RESULTS.md, "Real photos").

    The correction is added to each colour column in proportion to the estimate's own colour (its degree-0
    coefficients over their luminance; white when that is not a colour), so the result's luminance (what
    ``Decomposition.white_light`` takes) is the fitted light and its colour is stage 1's.

    Args:
        light: (9, 3) stage 1's RGB estimate.
        albedo: (N,) albedo luminance of the person's pixels.
        transport: (N, 9) their transport, as the runtime uses it.
        photo: (N,) the photo's luminance there (the pixel values the runtime multiplies).
        prior: the ridge weight (>= 0; relative, see above; default ``REFIT_PRIOR``).

    Returns:
        (9, 3) float32 light; ``light`` itself (a float32 copy) when there are fewer than 9 pixels.
    """
    light = np.asarray(light, np.float32)
    t = np.asarray(transport, np.float64).reshape(-1, 9)
    a = np.asarray(albedo, np.float64).reshape(-1)
    y = np.asarray(photo, np.float64).reshape(-1)
    if light.shape != (9, 3):
        raise RelightError(f"light must be (9, 3), got {light.shape}")
    if not (t.shape[0] == a.shape[0] == y.shape[0]):
        raise RelightError(f"refit_light: {a.shape[0]} albedo, {t.shape[0]} transport and {y.shape[0]} photo pixels")
    if prior is None:
        prior = REFIT_PRIOR
    if not prior >= 0:
        raise RelightError(f"refit_light: prior must be >= 0, got {prior!r}")
    if t.shape[0] < 9:
        return light.copy()
    l0 = light.astype(np.float64) @ REC709
    x = t * a[:, None]
    normal = x.T @ x
    ridge = prior * max(float(np.trace(normal)) / 9, 1e-12)
    correction = np.linalg.solve(normal + ridge * np.eye(9), x.T @ (y - x @ l0))
    return _luminance_changed(light, correction)


def _luminance_changed(light: np.ndarray, change: np.ndarray) -> np.ndarray:
    """``light`` (9, 3) float32 with ``change`` (9,) added to its luminance, each colour column in proportion to
    the light's own colour (its degree-0 coefficients over their luminance; white when that is not a colour), so
    the colour stays the light's; ``light`` itself (a copy) if the sum is not finite."""
    dc = light[0].astype(np.float64)
    dc_lum = float(dc @ REC709)
    colour = dc / dc_lum if dc_lum > 1e-6 and (dc > 0).all() else np.ones(3)
    out = light + (np.asarray(change, np.float64)[:, None] * colour[None, :]).astype(np.float32)
    return out if np.isfinite(out).all() else light.copy()


def face_refit(
    light: np.ndarray, face_transport: np.ndarray, face_photo: np.ndarray, albedo: np.ndarray, transport: np.ndarray
) -> np.ndarray:
    """The photo's light turned toward what a face's own shading says, where the photo shows a face mesh.

    Stage 1 reads a soft, front-lit studio photo as lit from overhead (the degree-1 band of its estimate, as
    (toward the camera, image right, up) over degree 0: DPR's portrait (0.62, 0.03, 0.37), scikit-image's
    astronaut (0.24, 0.11, 0.67)); a surface that faces up is then taken as lit in the photo, and a light from
    below darkens it twice (campfire's dark patch beside the nose). Over a face the transport is the mesh's
    (relight_rt.person.face_mesh), a shape the photo does not have to explain, and skin is about one colour: its
    luminance is a constant times transport . light. The fit (least squares with a ridge ``FACE_PRIOR`` toward
    ``light`` scaled to the face; pixels beyond ``FACE_TRIM`` robust deviations dropped, three rounds: eyes, brows,
    lips) gives the light's shape; its degree 0 is kept, and its level is set so that the person's mean
    albedo x shading stays what ``light`` gives (the exposure and the "missing light" rule read that level). A face
    of n kept pixels moves the light n / (n + ``FACE_PIXELS``) of the way: a small face's fit is noisy. On the
    held-out renders the band-1 direction of the photo's light moves closer to the truth (mean cosine 0.963 -> 0.975
    face, 0.960 -> 0.982 head-and-shoulders, 0.929 -> 0.948 waist-up framings: docs/RESULTS.md).

    Args:
        light: (9, 3) the photo's light so far (``refit_light``'s).
        face_transport: (M, 9) the transport of the face's skin pixels, as the runtime uses it.
        face_photo: (M,) the photo's luminance there.
        albedo: (N,) albedo luminance of all the person's pixels.
        transport: (N, 9) their transport.

    Returns:
        (9, 3) float32 light; ``light`` itself (a float32 copy) when the face says nothing usable.
    """
    light = np.asarray(light, np.float32)
    if light.shape != (9, 3):
        raise RelightError(f"light must be (9, 3), got {light.shape}")
    t = np.asarray(face_transport, np.float64).reshape(-1, 9)
    y = np.asarray(face_photo, np.float64).reshape(-1)
    a = np.asarray(albedo, np.float64).reshape(-1)
    tp = np.asarray(transport, np.float64).reshape(-1, 9)
    if t.shape[0] != y.shape[0] or a.shape[0] != tp.shape[0]:
        raise RelightError(f"face_refit: {t.shape[0]} face transport and {y.shape[0]} photo pixels, "
                           f"{a.shape[0]} albedo and {tp.shape[0]} transport pixels")
    if t.shape[0] < _FACE_MIN or a.shape[0] == 0:
        return light.copy()
    l0 = light.astype(np.float64) @ REC709
    keep = np.ones(y.shape[0], bool)
    m = None
    for _ in range(3):
        tk, yk = t[keep], y[keep]
        if tk.shape[0] < _FACE_MIN:
            break
        s0 = tk @ l0
        scale = float(s0 @ yk) / max(float(s0 @ s0), 1e-12)  # the face's luminance ~ scale x (transport . l0)
        normal = tk.T @ tk
        ridge = FACE_PRIOR * max(float(np.trace(normal)) / 9, 1e-12)
        m = np.linalg.solve(normal + ridge * np.eye(9), tk.T @ yk + ridge * scale * l0)
        r = y - t @ m
        centre = float(np.median(r[keep]))
        spread = 1.4826 * float(np.median(np.abs(r[keep] - centre))) + 1e-6
        keep = np.abs(r - centre) < FACE_TRIM * spread
    if m is None or not m[0] > 0 or not l0[0] > 0:
        return light.copy()
    fitted = m * (l0[0] / m[0])
    before = float((a * np.maximum(tp @ l0, 0)).sum())
    after = float((a * np.maximum(tp @ fitted, 0)).sum())
    if not (before > 0 and after > 0):
        return light.copy()
    fitted *= before / after
    n = int(keep.sum())
    return _luminance_changed(light, (fitted - l0) * (n / (n + FACE_PIXELS)))


# ------------------------------------------------------------------------------- the photo's own shading, kept

EXPLAIN_SHARE = 0.5  # explain_photo: the share of the shading stage 1 leaves unexplained that goes into the transport
EXPLAIN_SHADOW_SHARE = 1.0  # ... where a face's skin shows less than the transport (Factor.own: a shadow, not texture)
EXPLAIN_CLIP = 1.0  # ... at most this much shading (the photo's own light's units) moved per pixel
EXPLAIN_SIGMA = 1.5  # ... the move smoothed over this many pixels: shading is smooth, a stripe the albedo missed is not
EXPLAIN_ALBEDO_MIN = 0.05  # ... the albedo luminance the photo is divided by, floored here (black cloth, hair)


def skin_shadow_share(skin: np.ndarray, spread: float) -> np.ndarray | None:
    """(h, w) float32: ``explain_photo``'s ``shadow_share`` for a face's ``skin`` (h, w) bool: ``EXPLAIN_SHADOW_SHARE``
    inside the skin, ramped down to ``EXPLAIN_SHARE`` at and past its edge over ``spread`` pixels; None without skin.

    A hard switch at the skin's edge drew a line where the skin's inset around an eye crosses a cheek's shadow
    (faces23); ramped outward instead, the hair beside a face moved 3-4 levels.
    """
    if not skin.any():
        return None
    inside = 1 - soften(~skin, spread)
    return (EXPLAIN_SHARE + inside * (EXPLAIN_SHADOW_SHARE - EXPLAIN_SHARE)).astype(np.float32)


def explain_photo(
    transport: np.ndarray, albedo: np.ndarray, photo: np.ndarray, light: np.ndarray, where: np.ndarray,
    share: float | None = None, shadow_share: float | np.ndarray | None = None,
) -> np.ndarray:  # fmt: skip
    """The transport moved, along the photo's own light, part of the way to the shading the photo shows.

    Stage 1's transport is a regression and misses what the photo shows of its own shading (a fold's shadow, a
    shaded cheek, a lit edge): albedo x transport . light falls short of or beyond the photo there. The shading
    the photo shows, photo / albedo (luminance; the albedo floored at ``EXPLAIN_ALBEDO_MIN``), differs from the
    transport's by d per pixel; the transport is moved by ``share`` x d (clipped to ``EXPLAIN_CLIP``, then smoothed
    over ``EXPLAIN_SIGMA`` pixels among ``where``'s: what is not smooth is texture the albedo missed, a shirt's
    stripes, not shading) along ``light`` / |light|^2, the least change that adds that much shading under the
    photo's own light. A new light then keeps that part of the photo's own shading as far as it resembles the
    photo's light (the component along it) and none of it where it is orthogonal; both sides of the relighting
    factor use the moved transport, so the photo's own light still gives the photo back. On the held-out renders
    (benchmarks/heldout_change.py) a share of 0.5 lowers the relight RMSE in every framing (0.0861 -> 0.0843 face
    ... 0.1235 -> 0.1216 full) and raises the change's correlation with the truth by 0.005-0.010 (docs/RESULTS.md,
    seventh session).

    Args:
        transport: (h, w, 9) the transport the relighting factor uses (unpremultiplied).
        albedo: (h, w) the albedo's luminance; photo: (h, w) the photo's luminance, both in the network frame.
        light: (9,) the photo's own light's luminance (white light: any column).
        where: (h, w) bool, the pixels to move (the person's inner pixels); the others are returned as they are.
        share: the share of the difference moved (0: the transport unchanged); None: ``EXPLAIN_SHARE``.
        shadow_share: the share where the photo shows less shading than the transport (d < 0), one for all pixels
            or (h, w) per pixel; None: ``share``.

    Returns:
        (h, w, 9) float32, a new array.
    """
    t = np.asarray(transport, np.float32)
    l = np.asarray(light, np.float32).reshape(-1)
    if t.shape[-1] != 9 or l.shape != (9,):
        raise RelightError(f"explain_photo: transport (..., 9) and a (9,) light expected, got {t.shape}, {l.shape}")
    norm = float(l @ l)
    share = EXPLAIN_SHARE if share is None else float(share)
    shadow = np.float32(share) if shadow_share is None else np.asarray(shadow_share, np.float32)
    if max(share, float(shadow.max())) <= 0 or norm <= 1e-12:
        return t.copy()
    shown = np.asarray(photo, np.float32) / np.maximum(np.asarray(albedo, np.float32), EXPLAIN_ALBEDO_MIN)
    w = np.asarray(where, np.float32)
    d = np.clip(shown - t @ l, -EXPLAIN_CLIP, EXPLAIN_CLIP)
    move = np.where(d < 0, shadow, np.float32(share)) * d * w
    if EXPLAIN_SIGMA > 0:  # shading is smooth; what is not (a stripe the albedo missed) is texture, not shading
        den = cv2.GaussianBlur(w, (0, 0), EXPLAIN_SIGMA)
        move = np.where(w > 0, cv2.GaussianBlur(move, (0, 0), EXPLAIN_SIGMA) / np.maximum(den, 1e-3), 0)
    return (t + move[..., None] * (l / norm)).astype(np.float32)
