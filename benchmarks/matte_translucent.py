"""How much of a person the default matte leaves translucent (issue 48): ../shared/realdata/people_masks, evaluation.

    python benchmarks/matte_translucent.py --set photos --half A     # ~1 min a half
    python benchmarks/matte_translucent.py --set clip

For each image, the interior of its mask (the mask eroded by two edge bands, relight_rt.image.matte_edges.band_width:
well inside the outline, where hair and soft edges are not) is taken, and we count the share of it where the default
matte (PersonMatter(), person="largest") is neither 0 nor 1 (0.05 < alpha < 0.95). Relit, such pixels mix the relit
person with the old photo: the old light shows through the person. Printed: the mean share over the images, how many
images are over 5 %, and the worst. Where a service mask takes in things that are not people (a sculpture), their
interior counts too. Nothing of the data is written.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

from people_masks_eval import data_root, half_of, items, matted  # noqa: E402

from relight_rt.image.matte_edges import band_width  # noqa: E402
from relight_rt.person import matting as M  # noqa: E402

SOFT = (0.05, 0.95)
MANY = 0.05


def translucent_share(alpha: np.ndarray, mask: np.ndarray) -> float:
    """Share of ``mask``'s interior (eroded by 2 band widths) where ``alpha`` lies strictly inside SOFT; 0.0 when the
    mask has no interior."""
    r = 2 * band_width(mask.shape)
    inner = cv2.erode(mask.astype(np.uint8), np.ones((2 * r + 1, 2 * r + 1), np.uint8)) > 0
    if not inner.any():
        return 0.0
    a = alpha[inner]
    return float(((a > SOFT[0]) & (a < SOFT[1])).mean())


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--set", choices=("clip", "photos"), default="photos")
    ap.add_argument("--half", choices=("A", "B"), help="only this half of the photos")
    args = ap.parse_args(argv)
    root = data_root()
    listed = items(root, args.set)
    if args.half and args.set == "photos":
        halves = half_of([n for n, _, _ in listed])
        listed = [t for t in listed if halves[t[0]] == args.half]
    matter = M.PersonMatter()
    shares = {}
    for name, alpha, gt in matted(matter, listed):
        shares[name] = translucent_share(alpha, gt)
    v = np.array(list(shares.values()))
    worst = sorted(shares, key=shares.get, reverse=True)[:5]
    print(
        f"{args.set} {args.half or 'all'} ({len(v)}): translucent interior mean {v.mean():.2%}, images over "
        f"{MANY:.0%}: {int((v > MANY).sum())}; worst: " + ", ".join(f"{n} {shares[n]:.0%}" for n in worst)
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
