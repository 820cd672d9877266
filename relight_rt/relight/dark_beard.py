"""A black beard read as a dark material, not as shaded skin (relight_rt.relight.factor ``Factor.own``; issue 48).

Stage 1 reads a near-black beard as skin in shadow (p024: albedo 0.40-0.48 against the skin's 0.49-0.51), so the
deep shadow's fill (relight_rt.relight.shadow_fill) votes the lit skin's colour into it and a new light lifts it as it
would lift skin: a magenta or blue-grey beard. Where a pixel of the lower face is near black and near neutral in the
photo, dark on both halves of the face (a shadow is dark on one) and far darker than the shading of the lit pixels
around it implies, it takes their transport and the photo over their shading as its albedo (dark37's rule): the fill
sees no shadow there and a light changes it as it changes its surroundings.

The same cues fit shadowed brown hair (held-out renders: face RMSE 0.0786 -> 0.0838 with the rule anywhere), and
nothing in colour tells them apart; where they lie does. So the rule acts only in the beard's place from the face mesh
(``beard_region``): below the nose, within the jaw's width, down past the chin onto the neck, its edge soft. Long
dark hair hanging beside the jaw lies there too (beard40's broad check: about 20 of the 47 photos it acted on), but on
one side: a beard is one piece around the chin and mouth, so only pieces that reach across the chin's midline are
kept (``one_piece``, beard41).

Both cues (dark on both halves, one piece across the midline) read the face's two halves, and a turned face shows one:
its midline lies near the jaw's far edge and the region's far side is the neck or the hair behind it. There a shadow
on the neck under a lit 3/4 jaw (p092) or hair under the chin (p085) met every cue, and nothing in the photo told
them from a beard; so the rule acts only on faces turned less than ``BEARD_TURN`` (``turn``, beard42).

The module's constants are read when the functions run: benchmarks and tests set them here.
"""

from __future__ import annotations

import cv2
import numpy as np

from ..image.blur import wide_blur
from ..image.color import REC709
from ..person.face_mesh import reflection
from .look import to_lab

BEARD = True  # the rule on; False: off
BEARD_L = (25.0, 35.0)  # photo's L* below the first: near black; above the second: not
BEARD_C = (8.0, 12.0)  # photo's C* below the first: near neutral; above the second: not
BEARD_SHADING = (0.45, 0.65)  # implied shading over the lit surroundings': below the first all, above the second none
BEARD_DETAIL = (1.5, 0.03)  # fine detail: the log photo less its blur over this many px, averaged over this share ...
BEARD_TEXTURE = (0.035, 0.06)  # ... of the face's height: below the first smooth skin (none), above the second a beard
BEARD_SMOOTH = 1.0  # ... read on the photo smoothed over this many network pixels
BEARD_MIN_FACE = 48  # a face less tall than this (network px) has too few for a beard's detail: left alone
BEARD_BELOW = 0.3  # the region reaches this share of the face's height (forehead to chin) below the chin
BEARD_SOFT = 0.06  # ... its edge soft over this share of the face's height
BEARD_MIRROR = (0.05, 0.25)  # around the mirror image: a Gaussian of this share of the face's height, this share dark
BEARD_MIRROR_L, BEARD_MIRROR_C = (40.0, 50.0), (12.0, 18.0)  # ... dark there: the beard's lit half is lighter
BEARD_AROUND = 0.12  # the lit surroundings: a Gaussian of this share of the face's height
BEARD_AROUND_C = (8.0, 12.0)  # ... their mean C*: below the first grey (the rule off), above the second coloured
BEARD_ACROSS = (0.1, 0.03)  # one piece across the chin's midline: pixels of weight above the first, joined over ...
# ... this share of the face's height; None: no such gate (beard40)
BEARD_TURN = (0.3, 0.45)  # a face's turn (``turn``): below the first the rule acts, above the second not; None: no
# such gate (beard41). Chosen on half A between its bettered photos' at most 0.13 and the rest's from 0.46 (p092 0.51)
NOSE, CHIN, TOP = 2, 152, 10  # landmarks: below the nose's base, the chin's lowest, the forehead's highest
JAW = (132, 58, 172, 136, 150, 149, 176, 148, 152, 377, 400, 378, 379, 365, 397, 288, 361)  # the jaw's contour


def _height(points: np.ndarray) -> float:
    """A face's height in pixels: its forehead's highest landmark to its chin's lowest."""
    p = np.asarray(points, np.float64)
    return float(np.hypot(*(p[TOP, :2] - p[CHIN, :2])))


def _ramp(x: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """Smooth step: 1 at and below ``lo``, 0 at and above ``hi``."""
    q = np.clip((hi - x) / (hi - lo), 0, 1)
    return q * q * (3 - 2 * q)


def _mean(values: np.ndarray, weight: np.ndarray, sigma: float) -> np.ndarray:
    """(h, w) float32: the ``weight``-weighted mean of ``values`` over a Gaussian of ``sigma`` px (0: no weight)."""
    den = wide_blur(weight, sigma)
    num = wide_blur(values * weight, sigma)
    return np.divide(num, den, out=np.zeros_like(num), where=den > 1e-4)


def turn(points: np.ndarray) -> float:
    """How far the face of ``points`` ((468, >= 2) landmarks) is turned from the camera, in [0, inf): the nose's base
    off the middle of the jaw's contour, across the face (its own frame, as ``beard_region``), in halves of the
    contour's width; 0 frontal, 1 the nose's base over the jaw's far end (a profile). On the 26 people_masks photos
    the rule acted on (beard41): the 9 it bettered 0.03-0.24, its 2 false beards p092 0.51 and p085 1.05."""
    p = np.asarray(points, np.float64)[:, :2]
    height = _height(p)
    if height < 1e-3:
        return float("inf")
    up = (p[TOP] - p[CHIN]) / height
    jaw = (p[list(JAW)] - p[NOSE]) @ np.array([-up[1], up[0]])
    width = float(jaw.max() - jaw.min())
    return abs(float(jaw.max() + jaw.min())) / width if width > 1e-3 else float("inf")


def beard_region(points: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """(h, w) float32 in [0, 1]: where a beard can lie on the face of ``points`` ((468, >= 2) landmarks in the
    window's pixels, centres at integers): in the face's own frame (up from the chin to the forehead), from the line
    through the nose's base down to ``BEARD_BELOW`` of the face's height past the chin, across the jaw contour's
    width, each edge a smooth step over ``BEARD_SOFT`` of the face's height (half inside, half outside)."""
    p = np.asarray(points, np.float64)[:, :2]
    up = p[TOP] - p[CHIN]
    height = _height(p)
    h, w = shape
    if height < 1e-3:
        return np.zeros(shape, np.float32)
    up /= height
    side = np.array([-up[1], up[0]])
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    down = -((xs - p[NOSE, 0]) * up[0] + (ys - p[NOSE, 1]) * up[1])  # 0 on the nose line, positive below
    across = (xs - p[NOSE, 0]) * side[0] + (ys - p[NOSE, 1]) * side[1]
    jaw = (p[list(JAW)] - p[NOSE]) @ side
    bottom = float((p[CHIN] - p[NOSE]) @ -up) + BEARD_BELOW * height
    soft = BEARD_SOFT * height

    def inside(x: np.ndarray, lo: float, hi: float) -> np.ndarray:
        return _ramp(-x, -lo - soft / 2, -lo + soft / 2) * _ramp(x, hi - soft / 2, hi + soft / 2)

    return (inside(down, 0.0, bottom) * inside(across, float(jaw.min()), float(jaw.max()))).astype(np.float32)


def one_piece(d: np.ndarray, points: tuple[np.ndarray, ...], height: float,
              regions: tuple[np.ndarray, ...] | None = None) -> np.ndarray:
    """``d`` (r, r') float32 in [0, 1] kept only on its pieces that reach across a face's midline (the line through
    the nose's base and the chin, inside that face's ``beard_region``), zero elsewhere: a beard is one piece around
    the chin and mouth, long dark hair hangs beside the jaw on one side (beard40's main false positive). A piece: the
    pixels whose weight exceeds ``BEARD_ACROSS[0]``, joined over ``BEARD_ACROSS[1]`` of the face's height (a beard is
    patchy); a kept piece keeps the weaker weight within that reach of it, so its edge stays soft. ``regions``: each
    face's ``beard_region`` on ``d``'s grid, when the caller has them."""
    reach = max(int(round(BEARD_ACROSS[1] * height)), 1)
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * reach + 1, 2 * reach + 1))
    strong = cv2.morphologyEx((d > BEARD_ACROSS[0]).astype(np.uint8), cv2.MORPH_CLOSE, kernel)
    count, labels = cv2.connectedComponents(strong, connectivity=8)
    if count < 2:
        return np.zeros_like(d)
    keep = np.zeros(count, bool)
    h, w = d.shape
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    if regions is None:
        regions = tuple(beard_region(pts, (h, w)) for pts in points)
    for pts, region in zip(points, regions, strict=True):
        p = np.asarray(pts, np.float64)[:, :2]
        down = p[CHIN] - p[NOSE]
        side = np.sign((xs - p[NOSE, 0]) * down[1] - (ys - p[NOSE, 1]) * down[0])  # -1 / +1: the face's halves
        inside = region > 0
        halves = []
        for sign in (-1, 1):
            seen = np.zeros(count, bool)
            seen[np.unique(labels[inside & (side == sign)])] = True
            halves.append(seen)
        keep |= halves[0] & halves[1]
    keep[0] = False
    kept = cv2.dilate(keep[labels].astype(np.uint8), kernel)
    return (d * kept).astype(np.float32)


def beard_weight(rgb: np.ndarray, albedo: np.ndarray, transport: np.ndarray, white: np.ndarray, solid: np.ndarray,
                 points: tuple[np.ndarray, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """(d, around, shading): d (r, r') float32 in [0, 1], how far each pixel is a black beard (module docstring),
    around (r, r', 9) the transport of the lit pixels about it and shading (r, r') theirs under ``white``; None where
    the rule is off (``BEARD``) or finds nothing. Arguments as ``dark_material``'s."""
    # each face's share: 1 facing the camera, fading to 0 (the face left out) as it turns to ``BEARD_TURN[1]``
    facing = [(p, 1.0 if BEARD_TURN is None else float(_ramp(np.float64(turn(p)), *BEARD_TURN))) for p in points]
    facing = [(p, f) for p, f in facing if f > 0 and _height(p) >= BEARD_MIN_FACE]
    if not BEARD or not facing or not solid.any():
        return None
    points = tuple(p for p, _ in facing)
    shape = albedo.shape
    regions = tuple(beard_region(pts, shape) * np.float32(f) for pts, f in facing)
    region = np.maximum.reduce(regions) * solid
    if not region.max() > 1e-3:
        return None
    # read on the photo smoothed a little: a beard's colour is shared by its pixels, a pixel's own chroma is noise
    lab = to_lab(cv2.GaussianBlur(np.clip(rgb, 0, 1).astype(np.float32), (0, 0), BEARD_SMOOTH))
    dark = _ramp(lab[..., 0], *BEARD_L) * _ramp(np.hypot(lab[..., 1], lab[..., 2]), *BEARD_C)
    dark = (dark * solid).astype(np.float32)
    height = max(_height(p) for p in points)
    # dark on both halves of the face (a shadow darkens one): around its mirror image at least ``BEARD_MIRROR[1]`` of
    # the pixels near black (a beard is patchy; its mirror pixel by pixel missed half of p024's)
    darkish = _ramp(lab[..., 0], *BEARD_MIRROR_L) * _ramp(np.hypot(lab[..., 1], lab[..., 2]), *BEARD_MIRROR_C)
    near = cv2.GaussianBlur((darkish * solid).astype(np.float32), (0, 0), max(BEARD_MIRROR[0] * height, 0.5))
    both = dark
    for pts, face_region in zip(points, regions, strict=True):
        m = reflection(pts)
        if m is not None:
            there = cv2.warpAffine(near, m.astype(np.float64), shape[::-1],
                                   flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_CONSTANT)
            both = np.where(face_region > 0, dark * np.clip(there / BEARD_MIRROR[1], 0, 1), both)
    candidate = both * region
    if not candidate.max() > 1e-3:
        return None
    white = np.asarray(white, np.float32)
    shading = transport @ white
    sigma = max(BEARD_AROUND * height, 1.0)
    implied = ((rgb @ REC709) / np.maximum(albedo, 1e-3)).astype(np.float32)  # the shading the photo implies
    # the lit surroundings: not near black, each by the square of the shading the photo implies there (the skin in a
    # shadow under the jaw is not what lights the beard: counted alike, p024's beard took the neck's transport and a
    # side lamp's ratio there was 2.5 against the cheek's 1.2; by the shading 1.57, by its square 1.33)
    lit = ((1 - dark) * solid * (shading > 1e-3) * np.clip(implied, 0, 2) ** 2).astype(np.float32)
    den = wide_blur(lit, sigma)
    ok = den > 1e-3
    around = wide_blur(transport * lit[..., None], sigma)
    around = np.divide(around, den[..., None], out=np.asarray(transport, np.float32).copy(), where=ok[..., None])
    lit_implied = wide_blur(implied * lit, sigma)
    q = np.divide(implied * den, lit_implied, out=np.ones_like(implied), where=ok & (lit_implied > 1e-3 * den))
    # and hair, not skin: the fine detail among its near-black pixels (the log photo less their mean over
    # ``BEARD_DETAIL[0]`` px, its size averaged over ``BEARD_DETAIL[1]`` of the face's height; the edge to the skin
    # around is no detail) is a beard's; a shade on smooth skin has next to none (p024's and p264's beards 0.04-0.16,
    # the held-out renders' shaded chins 0.005-0.03)
    log = np.log(rgb @ REC709 + np.float32(0.02)).astype(np.float32)
    detail = np.abs(log - _mean(log, dark, BEARD_DETAIL[0]))
    detail = _mean(detail, dark, max(BEARD_DETAIL[1] * height, BEARD_DETAIL[0]))
    hair = 1 - _ramp(detail, *BEARD_TEXTURE)
    # near neutral against coloured surroundings: in a grey photo (Extended Yale B) every pixel is neutral, and a
    # side-lit face's shaded jaw met every other cue (de-light correlation 0.9240 -> 0.9168)
    chroma = np.hypot(lab[..., 1], lab[..., 2])
    coloured = 1 - _ramp(_mean(chroma, lit, sigma), *BEARD_AROUND_C)
    d = (candidate * _ramp(q, *BEARD_SHADING) * hair * coloured * ok).astype(np.float32)
    if BEARD_ACROSS is not None:
        d = one_piece(d, points, height, regions)
    return (d, around, around @ white) if d.max() > 1e-3 else None


def dark_material(rgb: np.ndarray, albedo: np.ndarray, transport: np.ndarray, white: np.ndarray, solid: np.ndarray,
                  points: tuple[np.ndarray, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """(albedo, transport, d) with a black beard taken as a dark material (module docstring): the inputs themselves
    and None where the rule is off (``BEARD``) or finds nothing.

    Args:
        rgb: (r, r', 3) float32 RGB in [0, 1], the photo stage 1 saw in the person's window.
        albedo: (r, r') float32 albedo luminance (after relight_rt.relight.unshade).
        transport: (r, r', 9) float32, unpremultiplied.
        white: (9,) the photo's own light taken as white (a column of ``Decomposition.white_light``).
        solid: (r, r') bool, the person's own pixels (alpha > 0.9).
        points: the face meshes in the window's pixels (``FacePass.window_points``).

    Returns:
        (r, r') albedo and (r, r', 9) transport, float32: d x (the surroundings' transport, the photo's luminance
        over their shading) + (1 - d) x the input's; d (r, r') float32 in [0, 1], the beard's weight
        (``beard_weight``; relight_rt.relight.look ``with_material`` keeps its chroma too).
    """
    if not BEARD or not points:
        return albedo, transport, None
    # only around the beard's place: its region's box grown by the surroundings' reach (3 sigma), so that every blur
    # sees what it would over the whole window (p024's 256 x 256 window: 42 -> 12 ms)
    h, w = albedo.shape
    box = []
    for pts in points:
        p = np.asarray(pts)
        height = _height(p)
        reach = 3 * max(BEARD_AROUND * height, 1.0) + BEARD_SOFT * height
        below = p[CHIN, :2] + BEARD_BELOW * (p[CHIN, :2] - p[TOP, :2])  # the region's reach under the chin
        corners = np.vstack([p[list(JAW), :2], p[NOSE, :2], below, below + p[JAW[0], :2] - p[CHIN, :2],
                             below + p[JAW[-1], :2] - p[CHIN, :2]])
        box.append((corners.min(axis=0) - reach, corners.max(axis=0) + reach))
    x0, y0 = (max(int(np.floor(min(b[0][k] for b in box))), 0) for k in (0, 1))
    x1, y1 = min(int(np.ceil(max(b[1][0] for b in box))) + 1, w), min(int(np.ceil(max(b[1][1] for b in box))) + 1, h)
    if x1 <= x0 or y1 <= y0:
        return albedo, transport, None
    shift = np.array([x0, y0, 0.0])[: np.asarray(points[0]).shape[1]]
    part = (slice(y0, y1), slice(x0, x1))
    found = beard_weight(rgb[part], albedo[part], transport[part], white, solid[part],
                         tuple(np.asarray(p, np.float64) - shift for p in points))
    if found is None:
        return albedo, transport, None
    d, around, shading = found
    own = (rgb[part] @ REC709) / np.maximum(shading, 1e-3)
    new_albedo, new_transport = albedo.astype(np.float32), transport.astype(np.float32)
    new_albedo[part] = albedo[part] + d * (own - albedo[part])
    new_transport[part] = transport[part] + d[..., None] * (around - transport[part])
    weight = np.zeros((h, w), np.float32)
    weight[part] = d
    return new_albedo, new_transport, weight
