"""People already in a background photo: the horizon their heads and feet give, and room beside them for a new
person (step 4 of ``relight_rt.apps.scene``, with ``relight_rt.apps.scene_place``).

**Who is there** (``find_people``): the bundled person graphs (relight_rt.person.matting: the selfie graph's blobs,
each segmented by the pose graph, as the matting finds people) on a copy of the photo at most ``DETECT_WIDTH`` wide,
at most ``MAX_PEOPLE`` blobs, kept where the pose graph's presence is at least ``PRESENCE``. A person is a **full
body** when their box reaches no border of the photo (within ``EDGE``: both feet and the head in frame), stands
upright (at least ``UPRIGHT`` times as tall as wide) and is at least ``MIN_HEIGHT`` of the photo tall.

**The horizon from them** (``people_horizon``; Hoiem, Efros & Hebert, "Putting objects in perspective", 2006): a
person H metres tall standing on flat ground, seen by a level camera c metres up, spans h = (H / c) · (feet − horizon)
rows (similar triangles), so each full body gives a line h = k · feet + b with k = H / c and horizon = −b / k. Several
people at different depths fix both (their heads' line and their feet's line meet at the horizon, whatever c); one
person, or people at one depth, fix the horizon through the prior k ≈ ``PERSON_M`` / camera height. Weighted least
squares, each person's height known to ``PERSON_SPREAD`` of itself (people's heights, posture, the matte's box), the
prior to ``RATIO_SPREAD`` (cameras from about 0.9 to 2 m: full bodies are often shot from waist height; at 0.12, for
standing cameras only, the people's horizon lay a median 0.17 of the height from the verticals' on 61 real photos of
people, far outside its error); the horizon's standard error by the delta method. With three people or more, one
whose residual exceeds ``OUTLIER`` standard deviations (a child, someone on a step) is left out once.

**Which horizon** (``combine_horizons``): the verticals' reading (``scene_place.horizon_reading``, its standard error
widened by ``VERTICALS_SE``: what it errs by on panorama views, where the focal length is a guess) and the people's
agree when they differ by at most ``DISAGREE`` combined standard errors: then their inverse-variance mean; when they
disagree, the people's (they stand on the ground the new person will stand on; slanted edges taken for verticals, or
a lens's distortion, mislead the verticals); without verticals, the people's; without people, the verticals'
rule as before (``scene_place.find_horizon``). Only people standing on the ground in view count: their feet below the
verticals' horizon (feet above it stand on something higher, or are a pattern the graphs took for a person: a lobby's
lit wall panels), or, without verticals, below ``FEET_LEVEL`` (a camera about level).

**Room** (``make_room``): a full body placed by default (no position given) whose box lies over a person already there
(more than ``OVERLAP`` of its box on theirs, widened by ``BESIDE``) moves along its row (the same depth, so the same
size) to the nearest place where it overlaps nobody and stays in the picture; with no such place, or at a given
position, it stays and a warning says so. Cut-off people (half bodies, portraits) keep their photo's framing and are
not moved.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, replace

import cv2
import numpy as np

from ..engine.errors import RelightError
from .scene_place import (
    CAMERA_M,
    HORIZON_ESTIMATE_MAX,
    PERSON_M,
    Placement,
    find_horizon,
    framing,
    horizon_reading,
    place,
)

__all__ = [
    "DETECT_WIDTH",
    "Someone",
    "combine_horizons",
    "find_people",
    "make_room",
    "people_finder",
    "people_horizon",
    "place_among_people",
]

log = logging.getLogger(__name__)

DETECT_WIDTH = 640  #: the people are looked for on a copy at most this wide
MAX_PEOPLE = 6  #: at most this many of the selfie graph's blobs (largest first) are segmented
PRESENCE = 0.5  #: the pose graph's presence for a person (relight_rt.person.matting's own threshold)
SEGMENT_PASSES = 2  #: pose-graph runs per blob while its region settles
EDGE = 0.01  #: a box edge within this fraction of a border is cut by it
UPRIGHT = 1.8  #: a standing full body is at least this many times as tall as wide
MIN_HEIGHT = 0.06  #: ... and at least this fraction of the photo's height tall
PERSON_SPREAD = 0.07  #: a person's height in the photo is known to this share of itself (heights, posture, box)
RATIO_SPREAD = 0.35  #: the prior on person height / camera height is known to this share of itself (module docstring)
OUTLIER = 3.0  #: with >= 3 people, one whose standardised residual exceeds this is left out (once)
VERTICALS_SE = 0.03  #: the verticals' standard error is widened by this (their errors on panorama views: median 0.022)
DISAGREE = 3.0  #: the two readings disagree beyond this many combined standard errors
FEET_LEVEL = 0.4  #: without verticals, people whose feet are higher than this row do not stand on the ground in view
OVERLAP = 0.02  #: a new person is over someone when more than this share of their box lies on that person's box ...
BESIDE = 0.1  #: ... widened by this share of its width on each side (the segmentation's box misses a bag, an elbow)


@dataclass(frozen=True)
class Someone:
    """A person found in a background: their box (x0, y0, x1, y1) in fractions of the photo (y down), the pose
    graph's presence, and whether they are a standing full body (module docstring)."""

    box: tuple[float, float, float, float]
    presence: float
    full_body: bool

    @property
    def head(self) -> float:
        return self.box[1]

    @property
    def feet(self) -> float:
        return self.box[3]


def find_people(photo, matter) -> list[Someone]:
    """The people ``matter`` (a relight_rt.person.matting.PersonMatter) finds in ``photo`` ((H, W, 3) RGB, uint8 or
    float in [0, 1]), largest first (module docstring)."""
    from ..image.regions import reductions_shared
    from ..person.face_detector import box_iou
    from ..person.matting import Region, as_rgb, person_box

    img = np.asarray(photo)
    if img.ndim != 3 or img.shape[2] != 3 or img.size == 0:  # a photo 1 px tall or wide has nobody in it: below
        raise RelightError(f"people: expected an (H, W, 3) RGB photo, got {img.shape} {img.dtype}")
    h, w = img.shape[:2]
    if w > DETECT_WIDTH:  # shrunk first: the intake below then converts only the small copy
        img = cv2.resize(img, (DETECT_WIDTH, max(2, round(h * DETECT_WIDTH / w))), interpolation=cv2.INTER_AREA)
        h, w = img.shape[:2]
    if min(h, w) < 16:
        return []
    rgb = as_rgb(img, "background", copy=False)  # the matters' one intake
    found: list[Someone] = []
    # one block for the search and every blob's segmentation: the graphs' answers on this photo are kept in its
    # reductions (relight_rt.image.regions), so the face graph runs once on it, however many blobs check for a portrait
    with reductions_shared(rgb):
        for _, blob in matter.find_people(rgb)[:MAX_PEOPLE]:
            p = matter.segment(rgb, Region.around(*blob), PRESENCE, passes=SEGMENT_PASSES)
            box = None if p.presence < PRESENCE else person_box(p, (h, w))
            if box is None or box[2] <= box[0] or box[3] <= box[1]:
                continue
            frac = (box[0] / w, box[1] / h, box[2] / w, box[3] / h)
            if any(box_iou(frac, other.box) > 0.5 for other in found):
                continue  # two blobs of one person
            inside = frac[0] > EDGE and frac[1] > EDGE and frac[2] < 1 - EDGE and frac[3] < 1 - EDGE
            tall = box[3] - box[1]
            full = inside and tall >= UPRIGHT * (box[2] - box[0]) and tall >= MIN_HEIGHT * h
            found.append(Someone(frac, float(p.presence), bool(full)))
    return found


def people_finder(relighter):
    """A ``photo -> list[Someone]`` for ``relighter``'s compositing: the bundled person graphs (``shared_matter``,
    on ``relighter.config.device``; nobody where they are not installed), or None where its config turns automatic
    matting off (nobody is looked for)."""
    config = getattr(relighter, "config", None)
    if getattr(config, "matting", "auto") == "off":
        return None
    device = getattr(config, "device", "cpu")

    def finder(photo) -> list[Someone]:
        from ..person.matting import shared_matter

        try:
            matter = shared_matter(device=device)  # loaded at the first full body (~0.3 s), then kept
        except RelightError:  # no graphs installed: nobody is looked for
            return []
        return find_people(photo, matter)

    return finder


def _fit(feet: np.ndarray, tall: np.ndarray, k0: float) -> tuple[np.ndarray, np.ndarray]:
    """(k, b) and their covariance: tall = k · feet + b, weighted by PERSON_SPREAD, with the prior k ≈ k0."""
    wt = 1.0 / (PERSON_SPREAD * tall) ** 2
    a = np.array([[wt @ (feet * feet), wt @ feet], [wt @ feet, wt.sum()]])
    r = np.array([wt @ (feet * tall), wt @ tall])
    prior = 1.0 / (RATIO_SPREAD * k0) ** 2
    a[0, 0] += prior
    r[0] += prior * k0
    cov = np.linalg.inv(a)
    return cov @ r, cov


def people_horizon(people: list[Someone], camera_height: float = CAMERA_M, below: float = 0.0
                   ) -> tuple[float, float] | None:  # fmt: skip
    """The horizon the full bodies among ``people`` whose feet are lower than the row ``below`` give, and its
    standard error (fractions of the height; module docstring), or None without any."""
    full = [p for p in people if p.full_body and p.feet > below]
    if not full:
        return None
    feet = np.array([p.feet for p in full], np.float64)
    tall = np.array([p.feet - p.head for p in full], np.float64)
    k0 = PERSON_M / camera_height
    (k, b), cov = _fit(feet, tall, k0)
    if feet.size >= 3:
        z = np.abs(tall - (k * feet + b)) / (PERSON_SPREAD * tall)
        if z.max() > OUTLIER:
            keep = z < z.max()
            feet, tall = feet[keep], tall[keep]
            (k, b), cov = _fit(feet, tall, k0)
    if k <= 0:
        return None
    grad = np.array([b / (k * k), -1.0 / k])  # horizon = −b / k
    return float(-b / k), float(math.sqrt(max(float(grad @ cov @ grad), 0.0)))


def combine_horizons(verticals: tuple[float, float] | None, people: tuple[float, float] | None
                     ) -> tuple[float, str] | None:  # fmt: skip
    """(horizon, which reading) from the verticals' and the people's readings, each (horizon, standard error) or
    None (module docstring): "people", "both", or None when there are no people (the verticals' rule stands)."""
    if people is None:
        return None
    if verticals is None:
        return people[0], "people"
    hv, sv = verticals[0], math.hypot(verticals[1], VERTICALS_SE)
    hp, sp = people
    if abs(hv - hp) > DISAGREE * math.hypot(sv, sp):
        return hp, "people"
    wv, wp = 1 / sv**2, 1 / sp**2
    return (wv * hv + wp * hp) / (wv + wp), "both"


def scene_horizon(photo, fov: float, people: list[Someone], camera_height: float = CAMERA_M) -> float:
    """The horizon composite uses when none is given: ``combine_horizons`` of the verticals and ``people``; without
    people ``scene_place.find_horizon``; at most ``HORIZON_ESTIMATE_MAX``."""
    verticals = horizon_reading(photo, fov)
    below = FEET_LEVEL if verticals is None else verticals[0]
    both = combine_horizons(verticals, people_horizon(people, camera_height, below))
    if both is None:
        return find_horizon(photo, fov, verticals)
    return min(max(both[0], 0.0), HORIZON_ESTIMATE_MAX)


def _over(lefts: np.ndarray, top: float, width: float, height: float, boxes: np.ndarray) -> np.ndarray:
    """For each left edge in ``lefts``, the largest share of the box (left, top, width, height) that lies on one of
    ``boxes`` ((n, 4) pixels, n >= 1)."""
    x = np.asarray(lefts, np.float64)[:, None]
    ix = np.clip(np.minimum(x + width, boxes[:, 2]) - np.maximum(x, boxes[:, 0]), 0, None)
    iy = np.clip(np.minimum(top + height, boxes[:, 3]) - np.maximum(top, boxes[:, 1]), 0, None)
    return (ix * iy).max(axis=1) / max(width * height, 1.0)


def make_room(placed: Placement, people: list[Someone], background_shape: tuple[int, ...], moved: bool = True
              ) -> Placement:  # fmt: skip
    """``placed`` moved along its row off the people already there (module docstring); ``moved`` False (a given
    position): only the warning."""
    if not placed.full_body or not people:
        return placed
    hb, wb = background_shape[:2]
    boxes = np.array([p.box for p in people], np.float64)
    pad = BESIDE * (boxes[:, 2] - boxes[:, 0])
    boxes = np.stack([boxes[:, 0] - pad, boxes[:, 1], boxes[:, 2] + pad, boxes[:, 3]], axis=1) * [wb, hb, wb, hb]
    top, left, w, h = placed.top, placed.left, placed.width, placed.height
    if _over(np.array([left]), top, w, h, boxes)[0] <= OVERLAP:
        return placed
    if moved and w < wb:
        lefts = np.arange(0, wb - w + 1)
        lefts = lefts[np.argsort(np.abs(lefts - left), kind="stable")]  # the nearest first, the left one on a tie
        free = lefts[_over(lefts, top, w, h, boxes) <= OVERLAP]
        if free.size:
            shift = int(free[0]) - left
            feet_x = None if placed.feet_x is None else placed.feet_x + shift
            log.info("composite: the person moved %+d px along their row, off someone already in the background", shift)
            return replace(placed, left=left + shift, feet_x=feet_x)
    where = "at the given position" if not moved else "and no free ground on its row"
    log.warning(
        "composite: the person stands over someone already in the background (%s); give --position X,Y on free ground",
        where,
    )
    return placed


def place_among_people(rgba: np.ndarray, background, position, height, horizon: float | None,
                       camera_height: float, fov: float, finder) -> tuple[Placement, float]:  # fmt: skip
    """Step 4 of relight_rt.apps.scene.composite: ``scene_place.place`` with the horizon, when none is given, from
    the background's verticals and its people (``scene_horizon``), and a default place off the people there
    (``make_room``). ``finder``: ``photo -> list[Someone]`` (``people_finder``) or None (nobody looked for).
    Returns the placement and the horizon used."""
    framed = framing(rgba[..., 3])  # read once: place takes it
    people = finder(background) if finder is not None and framed.full_body else []
    hz = horizon
    if hz is None:
        hz = scene_horizon(background, fov, people, camera_height)
    placed = place(rgba, background.shape, position, height, hz, camera_height, framed)
    return make_room(placed, people, background.shape, moved=position is None), hz
