"""The review's probes of the things-behind rule (relight_rt.person.matting._things_behind), on photos of
../shared/realdata/people_masks (evaluation only: nothing of them is written).

    python benchmarks/things_behind_probes.py

Each probe finds the people on the photo as it is, makes the default matte without the rule, then changes the photo
and runs the rule alone on it, as PersonMatter.alpha calls it (the pose graph's view of a selfie-graph person is read
on the changed photo): what share of the matte it takes and the IoU against the service's mask before and after.

- couple: p089, its second partner (the part of the matte right of 0.45 x the width that the pose graph does not see)
  blurred by 1 and 2 px, 60 black rows added below (the bottom border no longer guards the partner);
- band: p285 (a portrait whose torso the pose graph hardly sees) and p287 (a phone held up to the camera) with a white
  band of 40 and 100 rows below;
- slivers: p104, p064 and p089 enlarged to 2.5 MP (as the pieces of the matte, >= 0.5, that the rule leaves apart
  from the rest are counted): the pieces before and after the rule.
"""

from __future__ import annotations

import sys
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

import people_masks_eval as E  # noqa: E402
from _shared import missing, shared_path  # noqa: E402

from relight_rt.person import matting as M  # noqa: E402
from relight_rt.person.matting import _matter  # noqa: E402
from relight_rt.person.matting._segmentation import Person, logits_on_grid, sigmoid  # noqa: E402
from relight_rt.person.matting._things_behind import without_things_behind  # noqa: E402

PHOTOS = shared_path("realdata", "people_masks", "photos")


def before_rule(matter: M.PersonMatter, rgb: np.ndarray) -> tuple[list, np.ndarray]:
    """The people and the default matte without the things-behind rule."""
    people = matter.people(rgb)
    rule = _matter.without_things_behind
    _matter.without_things_behind = lambda rgb, alpha, *rest: alpha
    try:
        return people, matter.alpha(rgb, people)
    finally:
        _matter.without_things_behind = rule


def rule(matter: M.PersonMatter, rgb: np.ndarray, alpha: np.ndarray, people: list) -> np.ndarray:
    return without_things_behind(rgb, alpha, people, lambda p: matter._pose(rgb, p.region).logits,
                                 lambda: matter.find_faces(rgb))  # fmt: skip


def pieces(alpha: np.ndarray) -> tuple[int, int]:
    """(pieces of the matte >= 0.5 less the largest, their pixels)."""
    n, _, stats, _ = cv2.connectedComponentsWithStats((alpha >= 0.5).astype(np.uint8), connectivity=8)
    sizes = np.sort(stats[1:, cv2.CC_STAT_AREA])
    return int(n - 2) if n > 1 else 0, int(sizes[:-1].sum())


def taken(alpha: np.ndarray, out: np.ndarray) -> float:
    """The share of the matte (>= 0.5) that the rule takes."""
    return float(((alpha >= 0.5) & (out < 0.5)).sum() / max(int((alpha >= 0.5).sum()), 1))


def report(name: str, alpha: np.ndarray, out: np.ndarray, gt: np.ndarray) -> None:
    print(f"{name}: the rule takes {taken(alpha, out):.1%} of the matte; IoU {E.iou(alpha >= 0.5, gt):.4f} -> "
          f"{E.iou(out >= 0.5, gt):.4f}")  # fmt: skip


def pad(a: np.ndarray, rows: int, value: float) -> np.ndarray:
    return np.concatenate([a, np.full((rows, *a.shape[1:]), value, a.dtype)])


def read(name: str) -> tuple[np.ndarray, np.ndarray]:
    rgb = E.read_rgb(PHOTOS / f"{name}.jpg")
    return rgb, E.read_mask(PHOTOS / f"{name}_mask.png", rgb.shape[:2])


def couple(matter: M.PersonMatter, sigma: float, rows: int = 60) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """p089, its second partner blurred by ``sigma`` px, ``rows`` black rows below: (matte before the rule, after it,
    the service's mask), all with the rows."""
    rgb, gt = read("p089")
    people, alpha = before_rule(matter, rgb)
    h, w = alpha.shape
    main = people[0]
    view = Person(main.region, matter._pose(rgb, main.region).logits, 0.0)
    seen = sigmoid(logits_on_grid(view, (w, h, 1.0, 1.0, -0.5, -0.5)))
    partner = (seen < 0.1) & (alpha >= 0.5) & (np.arange(w)[None, :] > 0.45 * w)
    partner = cv2.dilate(partner.astype(np.uint8), np.ones((21, 21), np.uint8)).astype(bool)
    blurred = rgb.copy()
    blurred[partner] = cv2.GaussianBlur(rgb, (0, 0), sigma)[partner]
    alpha = pad(alpha, rows, 0.0)
    return alpha, rule(matter, pad(blurred, rows, 0.0), alpha, people), pad(gt, rows, False)


def band(matter: M.PersonMatter, name: str, rows: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Photo ``name`` with a white band of ``rows`` rows below: as :func:`couple`."""
    rgb, gt = read(name)
    people, alpha = before_rule(matter, rgb)
    alpha = pad(alpha, rows, 0.0)
    return alpha, rule(matter, pad(rgb, rows, 1.0), alpha, people), pad(gt, rows, False)


def main() -> int:
    if not PHOTOS.is_dir():
        raise SystemExit(missing(PHOTOS))
    matter = M.PersonMatter()
    for sigma in (1.0, 2.0):
        report(f"couple p089, partner blurred {sigma:g} px, 60 rows below", *couple(matter, sigma))
    for name in ("p285", "p287"):
        for rows in (40, 100):
            report(f"band {name}, {rows} white rows below", *band(matter, name, rows))
    for name in ("p104", "p064", "p089"):
        rgb = E.read_rgb(PHOTOS / f"{name}.jpg")
        k = float(np.sqrt(2.5e6 / (rgb.shape[0] * rgb.shape[1])))
        rgb = np.clip(cv2.resize(rgb, None, fx=k, fy=k, interpolation=cv2.INTER_CUBIC), 0.0, 1.0)
        people, alpha = before_rule(matter, rgb)
        out = rule(matter, rgb, alpha, people)
        (n0, px0), (n1, px1) = pieces(alpha), pieces(out)
        print(f"slivers {name} at 2.5 MP: the rule takes {taken(alpha, out):.1%}; pieces apart {n0} ({px0} px) -> "
              f"{n1} ({px1} px)")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
