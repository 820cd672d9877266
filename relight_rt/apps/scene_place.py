"""Where a person goes in another scene: ``place`` (step 4 of ``relight_rt.apps.scene``), and how their photo
framed them.

The person's photo says how it framed them (``framing``): which of its borders cut the person (the matte reaches
within ``EDGE`` of that border with alpha above 1/2 along at least ``EDGE_RUN`` of it: a few stray soft pixels
do not count), and, when the bottom border does not cut them, where their feet are (the matte's lowest rows: the
alpha-weighted centre and the width of the bottom ``SOLE`` of the box).

* A **full body** (its feet in frame) stands on the background's ground. Its feet go to ``position`` (x, y), in
  fractions of the background (default: x where its feet were in its own photo, y = ``DEFAULT_FEET``), and its
  height follows from perspective for a level camera ``camera_height`` metres above the ground (default
  ``CAMERA_M``, a standing photographer): the horizon is the row ``horizon``, and a person ``PERSON_M`` tall whose
  feet are d rows below it is d · PERSON_M / camera_height rows tall (similar triangles: the camera's eye row is
  the horizon at any distance). ``height`` (a fraction of the background's height) overrides that. By default
  the whole person is kept in the picture across, unless a side border of its photo cut it: then that side of
  the box goes to the same border of the background.
* A **cut-off** person (a half body or a portrait: the photo's bottom border cuts them) is placed as the photo
  framed them: the photo's frame is scaled by background height / photo height (their relative height kept),
  or, for a person cut by both side borders, enough to reach both when that loses at most ``HEAD_ROOM`` of a
  person the photo showed whole at the top (else the photo's framing stands: a tall portrait in a wide place keeps
  its whole head and shows its cut sides), and each border that cut them goes to the same border of the background
  (the bottom always; a left or right one too; both: the frame centred). Not cut at a side, they keep their
  relative x and stay inside the picture, made as large as fits across if they are wider than it. ``position``
  moves the bottom centre of the box (the cut edge) and ``height`` sets the box's height as for a full body.

Parts beyond the background's edges are cut off.

The horizon (``horizon``: a row fraction; ``estimate_horizon`` when it is not given). A level camera's horizon is
the picture's middle row; a camera turned up or down by a tilt t moves it by f · tan t (f the focal length in
pixels, from the horizontal field of view), and makes the world's verticals (walls, poles, door frames, towers)
converge toward a point f / tan t from the centre on the other side. ``estimate_horizon`` reads t from the
photo's near-vertical line segments (OpenCV's line segment detector): each segment's slope against where it lies
gives t by least squares, made robust by reweighting (segments that are not verticals of the world disagree);
without ``MIN_VERTICALS`` segments that agree (a landscape, a flat wall), or when those that agree fix the
horizon no better than ``MAX_HORIZON_ERROR`` of the height (one standard error: hair, a few strands near the
middle), it returns None and the level camera's 0.5 stands. The camera is assumed not to roll. A full body's
default feet are ``DEFAULT_FEET`` down, or halfway from a low horizon to the bottom edge (the ground between them
is what the camera sees of it).

The sky bounds the horizon from below (``sky_line``): flat ground reaches the horizon, and anything standing on it
hides sky only above it, so no sky is seen below the horizon. Each column's run from the top edge, down to its first
step in log luminance or chromaticity (``SKY_JUMP`` over ``SKY_STEP`` rows), is sky when it is at least
``SKY_RATIO`` times as bright as the ground (the median of the bottom ``SKY_GROUND`` rows: a ground of albedo at
most about 1/3 under that sky) or blue (log2 B/R at least ``SKY_BLUE``: a clear or twilight sky, darker than a lit
pad at dusk); a run that reaches the bottom edge is a backdrop, not a sky over ground (and when more such runs
reach it than stop above it, there is no sky line). With sky in at least ``SKY_MIN_COLUMNS`` of the columns, the
``SKY_QUANTILE`` of their lower ends is the sky line (a bound: poles, wires and branches end runs higher), and
``find_horizon`` (composite's without people) puts the horizon no higher than it where the
verticals see the camera turned up: a camera turned up at a launch pad, whose towers' convergence reads a horizon
too high (the focal length is a guess), would otherwise stand a large person in the sky above the pad's lights.
Alone, without the verticals, it is not used: a bright wall or curtain over a darker floor, a calm sea, a backdrop
behind a portrait over the sitter's dark clothes read as sky.

People standing in the background tell the horizon too (their heads and feet): ``relight_rt.apps.scene_people``
combines their reading with the verticals' (``horizon_reading``: the verticals' answer and its standard error) and
falls back on ``find_horizon`` where nobody stands whole in view.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from ..engine.errors import RelightError
from ..engine.number_pair import number_pair
from ..image.color import REC709, SRGB8_TO_LINEAR

__all__ = [
    "CAMERA_M", "DEFAULT_FEET", "HORIZON_ESTIMATE_MAX", "PERSON_M", "Framing", "Placement", "check_camera_height",
    "estimate_horizon", "find_horizon", "framing", "horizon_reading", "parse_position", "place", "sky_line",
]

ALPHA_BOX = 0.005  #: the person's box: matte above this
EDGE = 0.004  #: a border cuts the person when the matte reaches within this fraction of the side (at least 1 px)
EDGE_RUN = 0.02  #: ... with alpha > 1/2 along at least this fraction of that border (at least 2 px)
SOLE = 0.04  #: the feet: the bottom this fraction of the box's height
PERSON_M = 1.7  #: a standing person's height, metres
CAMERA_M = 1.5  #: the default camera height above the ground, metres (a standing photographer)
CAMERA_RANGE = (0.05, 100.0)  #: accepted camera heights, metres
DEFAULT_FEET = 0.92  #: default row of a full-body person's feet, fraction of the background's height
HORIZON_ESTIMATE_MAX = 0.9  #: an estimated horizon is used at most this low (the feet need ground below it)
MIN_VERTICALS = 6  #: estimate_horizon: near-vertical segments that must agree on the tilt
MAX_HORIZON_ERROR = 0.02  #: estimate_horizon: no answer when the horizon's standard error exceeds this (× height)
MAX_TILT = 35.0  #: estimate_horizon: the largest camera tilt it reports, degrees
_NEAR_VERTICAL = math.tan(math.radians(20))  # |dx / dy| of a segment that may be a vertical of the world
_MIN_SEGMENT = 0.04  # a segment's least length, fraction of the photo's height
_AGREE = 0.03  # a segment agrees with the tilt when its slope is within this of the one predicted (~1.7°)
_HORIZON_WIDTH = 640  # the segments are found on a copy at most this wide
HEAD_ROOM = 0.25  #: a person cut at both sides loses at most this share of their box off the top to reach both
SKY_STEP = 4  #: sky_line: a run from the top ends at a step over this many rows (of a copy ``_SKY_WIDTH`` wide)
SKY_JUMP = 0.25  #: ... of at least this in log2 luminance or log2 R/G, B/G (a quarter stop)
SKY_RATIO = 3.0  #: a run is sky when its median linear luminance is this many times the ground's ...
SKY_BLUE = 1.0  #: ... or its median log2 B/R is at least this
SKY_GROUND = 0.2  #: the ground: the bottom this fraction of the rows
SKY_MIN_COLUMNS = 0.2  #: a sky line needs sky in at least this fraction of the columns
SKY_QUANTILE = 0.75  #: the sky line: this quantile of the sky columns' lower ends
_SKY_WIDTH = 320


def parse_position(value) -> tuple[float, float]:
    """'X,Y' (or a pair) → (x, y), each a fraction of the background in [0, 1]."""
    x, y = number_pair(value, "position", "X,Y (fractions of the background)", "0.5,0.9")
    if not (0 <= x <= 1 and 0 <= y <= 1):  # also rejects NaN
        raise RelightError(f"position: expected X,Y each in [0, 1] (fractions of the background), got {x:g},{y:g}")
    return x, y


def check_height(height) -> float | None:
    """A person's height as a fraction of the background's height, in (0, 1], or None."""
    if height is None:
        return None
    try:
        h = float(height)
    except (TypeError, ValueError):
        raise RelightError(f"height: expected a fraction of the background height in (0, 1], got {height!r}") from None
    if not 0 < h <= 1:
        raise RelightError(f"height: expected a fraction of the background's height in (0, 1], got {height!r}")
    return h


def check_horizon(horizon) -> float:
    """The horizon's row as a fraction of the background's height, in [0, 1]."""
    message = f"horizon: expected a fraction of the background's height in [0, 1], got {horizon!r}"
    try:
        h = float(horizon)
    except (TypeError, ValueError):
        raise RelightError(message) from None
    if not 0 <= h <= 1:  # also rejects NaN
        raise RelightError(message)
    return h


def check_camera_height(value) -> float:
    """The camera's height above the ground in metres, in ``CAMERA_RANGE``."""
    lo, hi = CAMERA_RANGE
    message = f"camera height: expected metres above the ground in [{lo:g}, {hi:g}], got {value!r}"
    try:
        m = float(value)
    except (TypeError, ValueError):
        raise RelightError(message) from None
    if not lo <= m <= hi:  # also rejects NaN
        raise RelightError(message)
    return m


def box(alpha: np.ndarray) -> tuple[int, int, int, int]:
    """(y0, y1, x0, x1): the rows and columns where the matte ``alpha`` exceeds ``ALPHA_BOX``."""
    rows = np.flatnonzero((alpha > ALPHA_BOX).any(axis=1))
    cols = np.flatnonzero((alpha > ALPHA_BOX).any(axis=0))
    if rows.size == 0:
        raise RelightError("mask: the person's matte is empty")
    return int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1


@dataclass(frozen=True)
class Framing:
    """How a photo framed its person: their box (y0, y1, x0, x1) in the photo's pixels, the photo's (h, w), the
    borders that cut them (a subset of "top", "bottom", "left", "right"), and their feet's centre column and
    width in pixels (the box's bottom centre and width when cut at the bottom: no feet in frame)."""

    box: tuple[int, int, int, int]
    shape: tuple[int, int]
    cut: frozenset
    feet_x: float
    feet_width: float

    @property
    def full_body(self) -> bool:
        return "bottom" not in self.cut


def _cuts(alpha: np.ndarray, where: str) -> bool:
    h, w = alpha.shape
    side = w if where in ("top", "bottom") else h
    depth = max(1, round(EDGE * (h if where in ("top", "bottom") else w)))
    strip = {"top": alpha[:depth], "bottom": alpha[h - depth :], "left": alpha[:, :depth].T,
             "right": alpha[:, w - depth :].T}[where]  # fmt: skip
    return int(np.count_nonzero((strip > 0.5).any(axis=0))) >= max(2, EDGE_RUN * side)


def framing(alpha: np.ndarray) -> Framing:
    """How the photo whose matte is ``alpha`` ((h, w) float in [0, 1]) framed its person (module docstring).

    Raises:
        RelightError: an empty matte.
    """
    a = np.asarray(alpha, np.float32)
    y0, y1, x0, x1 = box(a)
    cut = frozenset(side for side in ("top", "bottom", "left", "right") if _cuts(a, side))
    feet_x, feet_w = (x0 + x1) / 2, float(x1 - x0)
    if "bottom" not in cut:
        sole = a[max(y0, y1 - max(1, round(SOLE * (y1 - y0)))) : y1, x0:x1]
        weight = sole.sum(axis=0)
        if weight.sum() > 0:
            cols = np.arange(x0, x1, dtype=np.float64) + 0.5
            feet_x = float(weight @ cols / weight.sum())
            solid = np.flatnonzero(weight >= 0.5 * weight.max())
            feet_w = float(solid[-1] + 1 - solid[0])
    return Framing((y0, y1, x0, x1), a.shape, cut, feet_x, feet_w)


def _as_uint8(photo) -> np.ndarray:
    """An sRGB photo as uint8 (itself when it is one; float in [0, 1] rounded, NaN as 0)."""
    img = np.asarray(photo)
    if img.dtype == np.uint8:
        return img
    return (np.clip(np.nan_to_num(img.astype(np.float32)), 0, 1) * 255 + 0.5).astype(np.uint8)


def estimate_horizon(photo: np.ndarray, fov: float = 60.0) -> float | None:
    """The horizon's row in ``photo`` as a fraction of its height, from the tilt its verticals show (module
    docstring), or None when too few near-vertical segments agree.

    Args:
        photo: (H, W, 3) RGB, uint8 or float in [0, 1].
        fov: its horizontal field of view, degrees.

    Returns:
        A fraction (below 0 or above 1 when the horizon lies outside the picture), or None.
    """
    found = horizon_reading(photo, fov)
    return None if found is None else found[0]


def horizon_reading(photo: np.ndarray, fov: float = 60.0) -> tuple[float, float] | None:
    """``estimate_horizon``'s answer with its standard error (from the agreeing segments' spread alone, both
    fractions of the height), or None."""
    grey = cv2.cvtColor(_as_uint8(photo), cv2.COLOR_RGB2GRAY)
    h, w = grey.shape
    if w > _HORIZON_WIDTH:
        grey = cv2.resize(grey, (_HORIZON_WIDTH, max(2, round(h * _HORIZON_WIDTH / w))), interpolation=cv2.INTER_AREA)
        h, w = grey.shape
    found = cv2.createLineSegmentDetector().detect(grey)[0]
    if found is None:
        return None
    x1, y1, x2, y2 = found.reshape(-1, 4).astype(np.float64).T
    dx, dy = x2 - x1, y2 - y1
    length = np.hypot(dx, dy)
    keep = (length >= _MIN_SEGMENT * h) & (np.abs(dx) <= _NEAR_VERTICAL * np.abs(dy))
    if int(keep.sum()) < MIN_VERTICALS:
        return None
    k = dx[keep] / dy[keep]  # columns per row
    mx, my, wt = ((x1 + x2) / 2)[keep], ((y1 + y2) / 2)[keep], length[keep]
    cx, cy = w / 2, h / 2
    f = (w / 2) / math.tan(math.radians(float(fov)) / 2)
    # a vertical through (mx, my) points at V = (cx, cy + 1/u): k = u · ((cx − mx) + k · (my − cy)), u = −tan t / f
    g = (cx - mx) + k * (my - cy)
    weight = wt.copy()
    u = 0.0
    for _ in range(8):  # iteratively reweighted least squares (Cauchy weights on the slope's residual)
        den = float(weight @ (g * g))
        if den <= 0:
            return None
        u = float(weight @ (k * g)) / den
        r = k - u * g
        scale = max(1.4826 * float(np.median(np.abs(r))), 0.01)
        weight = wt / (1 + (r / (2 * scale)) ** 2)
    r = k - u * g
    agree = np.abs(r) <= _AGREE
    if int(agree.sum()) < MIN_VERTICALS:
        return None
    # how precisely the agreeing segments fix the horizon: u's standard error, as rows of the picture
    ga, ra = g[agree], r[agree]
    se_u = math.sqrt(float(ra @ ra) / max(ga.size - 1, 1) / max(float(ga @ ga), 1e-12))
    se = f * f * se_u / h
    if se > MAX_HORIZON_ERROR:
        return None
    tilt = math.degrees(math.atan(-u * f))
    tilt = max(-MAX_TILT, min(MAX_TILT, tilt))
    return (cy + f * math.tan(math.radians(tilt))) / h, se


def sky_line(photo: np.ndarray) -> float | None:
    """The row above which the sky in ``photo`` lies (module docstring), a fraction of its height, or None when
    too few columns show sky over ground.

    Args:
        photo: (H, W, 3) RGB, uint8 or float in [0, 1] (sRGB), at least 2 px a side.

    Raises:
        RelightError: another shape.
    """
    img = np.asarray(photo)
    if img.ndim != 3 or img.shape[2] != 3 or min(img.shape[:2]) < 2:
        raise RelightError(f"sky line: expected an (H, W, 3) RGB photo, got {img.shape} {img.dtype}")
    img = _as_uint8(img)
    h, w = img.shape[:2]
    small = cv2.resize(img, (_SKY_WIDTH, max(2 * SKY_STEP, round(h * _SKY_WIDTH / w))), interpolation=cv2.INTER_AREA)
    lin = cv2.GaussianBlur(SRGB8_TO_LINEAR[small], (0, 0), 1.0) + np.float32(1e-3)
    lum = lin @ REC709
    rows = lum.shape[0]
    logs = np.dstack([np.log2(lum), np.log2(lin[..., 0] / lin[..., 1]), np.log2(lin[..., 2] / lin[..., 1])])
    step = (np.abs(logs[SKY_STEP:] - logs[:-SKY_STEP]) > SKY_JUMP).any(axis=2)  # (rows - SKY_STEP, W)
    ends = np.where(step.any(axis=0), step.argmax(axis=0) + SKY_STEP // 2, rows)  # each column's run: rows [0, end)
    ground = max(float(np.median(lum[int(rows * (1 - SKY_GROUND)) :])), 1e-4)
    in_run = np.arange(rows)[:, None] < ends[None, :]
    blue = np.log2(lin[..., 2] / lin[..., 0])
    # each run's medians (NaN outside it), columns with a run of at least two rows that stops above the bottom
    run_lum = np.nanmedian(np.where(in_run, lum, np.nan), axis=0)
    run_blue = np.nanmedian(np.where(in_run, blue, np.nan), axis=0)
    like = (ends >= 2) & ((run_lum >= SKY_RATIO * ground) | (run_blue >= SKY_BLUE))
    sky = like & (ends < rows)
    if int(sky.sum()) < SKY_MIN_COLUMNS * sky.size or int((like & (ends >= rows)).sum()) > int(sky.sum()):
        return None  # too little sky, or more of it runs down to the bottom edge than stops over ground
    return float(np.quantile(ends[sky], SKY_QUANTILE)) / rows


def find_horizon(photo: np.ndarray, fov: float = 60.0, reading=...) -> float:
    """The horizon ``relight_rt.apps.scene.composite`` uses when none is given: the verticals' (``estimate_horizon``;
    a level camera's 0.5 without them), where they see the camera turned up no higher than the sky line
    (``sky_line``), at most ``HORIZON_ESTIMATE_MAX``.

    The verticals tell which way the camera is turned more surely than how far (how far scales with the focal
    length squared, and ``fov`` is a guess): where they see it turned up (a horizon below the middle), the sky may
    put the horizon lower still. Where they see it level or turned down, sky below their horizon contradicts them,
    and they stand; where they say nothing, the sky line alone is not trusted (a bright wall or curtain over a
    darker floor, a calm sea under its sky, a backdrop over dark clothes read as sky). ``reading``:
    ``horizon_reading``'s answer on ``photo`` where the caller has it already."""
    if reading is ...:
        reading = horizon_reading(photo, fov)
    found = None if reading is None else reading[0]
    hz = 0.5 if found is None else found
    if found is not None and found > 0.5:
        line = sky_line(photo)
        if line is not None:
            hz = max(hz, line)
    return min(max(hz, 0.0), HORIZON_ESTIMATE_MAX)


@dataclass(frozen=True)
class Placement:
    """Where the person goes (step 4): ``premult`` (h, w, 4) premultiplied linear RGB and alpha at their size in
    the background, its top-left corner (``top``, ``left``; may lie outside), their box's size before any blur
    (``height``, ``width``), the row of their feet, whether they stand on the ground (``full_body``), and their
    feet's centre column and width in the background (pixels; the box's bottom centre and width for a cut-off
    person; None: the box's)."""

    premult: np.ndarray
    top: int
    left: int
    height: int
    width: int
    feet_y: int
    full_body: bool
    feet_x: float | None = None
    feet_width: float | None = None


def _too_large(new_w: int, new_h: int, wb: int, hb: int) -> RelightError:
    return RelightError(
        f"height: the person would be {new_w} x {new_h} px (W x H) after scaling, larger than the background "
        f"({wb} x {hb}); give a smaller --height"
    )


def place(rgba: np.ndarray, background_shape: tuple[int, ...], position=None, height=None, horizon: float = 0.5,
          camera_height: float = CAMERA_M, framed: Framing | None = None) -> Placement:  # fmt: skip
    """The relit person ``rgba`` ((h, w, 4) straight-alpha linear RGBA, their photo's size) scaled and put into a
    background of ``background_shape`` (module docstring).

    Args:
        rgba: the person.
        background_shape: (H, W[, C]) of the background.
        position: a checked (x, y) (``parse_position``) or None.
        height: a checked fraction (``check_height``) or None.
        horizon: a checked row fraction (``check_horizon``).
        camera_height: a checked height in metres (``check_camera_height``).
        framed: ``framing(rgba[..., 3])`` where the caller has it already (None: read here).

    Raises:
        RelightError: an empty matte; a full body's feet on or above the horizon without a height; a given
            height that makes the person larger than the background.
    """
    pos, frac, hz = position, height, horizon
    hb, wb = background_shape[:2]
    hp, wp = rgba.shape[:2]
    fr = framing(rgba[..., 3]) if framed is None else framed
    y0, y1, x0, x1 = fr.box
    box_h, box_w = y1 - y0, x1 - x0
    given = frac is not None
    sides = fr.cut & {"left", "right"}
    if fr.full_body:
        feet = (fr.feet_x / wp, max(DEFAULT_FEET, (hz + 1) / 2)) if pos is None else pos
        if frac is None:
            rows_below = (feet[1] - hz) * hb
            if rows_below < 0.02 * hb:
                raise RelightError(
                    f"position: the feet (y = {feet[1]:g}) are on or above the horizon (y = {hz:g}), where the "
                    "ground is not seen; give feet lower in the picture (a larger --position Y), a horizon higher in "
                    "it (a smaller --horizon), a lower --camera-height, or a --height"
                )
            frac = min(rows_below * PERSON_M / camera_height / hb, 1.0)
        scale = frac * hb / box_h
        if not given and not sides and box_w * scale > wb:  # a default size that would not fit across
            scale = wb / box_w
    else:
        feet = (fr.feet_x / wp, 1.0) if pos is None else pos
        if given:
            scale = frac * hb / box_h
        else:
            scale = hb / hp  # the photo's frame height → the background's: the relative height kept
            reach = wb / wp  # the scale at which the photo's frame is as wide as the background
            if sides == {"left", "right"} and reach > scale:  # reach both side borders if the head allows it
                if "top" in fr.cut or reach <= hb / (box_h * (1 - HEAD_ROOM)):
                    scale = reach
            elif box_w * scale > wb:  # not cut across: as large as fits
                scale = wb / box_w
    new_h, new_w = max(1, round(box_h * scale)), max(1, round(box_w * scale))
    if given and (new_h > hb or (new_w > wb and not sides)):
        raise _too_large(new_w, new_h, wb, hb)
    crop = rgba[y0:y1, x0:x1]
    premult = np.concatenate([crop[..., :3] * crop[..., 3:], crop[..., 3:]], axis=2)
    interp = cv2.INTER_AREA if scale < 1 else cv2.INTER_LINEAR
    premult = cv2.resize(premult, (new_w, new_h), interpolation=interp)
    np.clip(premult, 0, 1, out=premult)
    feet_y = int(round(feet[1] * hb))
    top = feet_y - new_h
    feet_off = (fr.feet_x - x0) * scale  # the feet's column within the box
    left = int(round(feet[0] * wb - feet_off))
    if pos is None:  # the default place: a border that cut the person goes to the same border, else kept inside
        if sides == {"left", "right"}:
            left = int(round((wb - wp * scale) / 2 + x0 * scale))
        elif "left" in sides:
            left = int(round(x0 * scale))
        elif "right" in sides:
            left = int(round(wb - (wp - x1) * scale)) - new_w
        else:
            left = min(max(left, 0), wb - new_w) if new_w <= wb else (wb - new_w) // 2
    feet_x = left + feet_off
    feet_w = fr.feet_width * scale
    return Placement(premult, top, left, new_h, new_w, feet_y, fr.full_body, feet_x, feet_w)
