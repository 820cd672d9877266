"""The reference street photo's passers-by: which of them ``--person all`` covers, on 6 framings.

    PYTHONPATH=$PWD python benchmarks/street_pedestrians.py [--photo PATH] [--alphas OUT.npz | --load OUT.npz]

The bar (issue 33, docs/RESULTS.md "Automatic mattes"): everyone at least 6 % of the photo's height tall who stands
apart. ../shared/reference/photo/sample.jpg (1950x1302) shows nine pedestrians behind the subject, each 0.10-0.12 of
its height; their boxes below were read by hand at 300 % (photo pixels, x0, y0, x1, y1, exclusive ends). For each
framing of ``people_photos.FRAMINGS`` (0-2 rows or columns dropped at the top left: the graphs' 256-px crops, and so
the people found, move with a 1-px shift) the matte of ``PersonMatter(person="all")`` is scored per pedestrian as the
share of the box's middle third (its middle columns, head to shoes) at alpha >= 0.5. A pedestrian alone and fully
matted scores about 0.75-0.85 (background between the legs); >= 0.5 counts as covered. The photo stays in
../shared; nothing of it is written (``--alphas`` writes the mattes, for re-scoring, wherever you say: keep it out of
the repository).

The boxes hold each person's visible outline from hair to shoes, arms included. They stand in for the boxes behind the
first figure (2026-11-27, read by hand and not committed): at that commit (571dafc, run with ``PYTHONPATH`` set to an
export of its ``relight_rt``) they give 39 of 54 where that measurement gave 38 (G, half behind F, 0.55 against 0.49
on one framing); every other pedestrian-framing is called the same.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]

from _shared import missing, shared_dir, shared_path  # noqa: E402
from people_photos import FRAMINGS  # noqa: E402

# name, what it shows, box (x0, y0, x1, y1) in the full photo
PEDESTRIANS = (
    ("A", "man in a dark coat, left of the pair under the umbrella", (933, 425, 975, 575)),
    ("B", "man beside A, half behind him", (965, 423, 1014, 572)),
    ("C", "man under the umbrella, half behind D", (1033, 421, 1073, 572)),
    ("D", "woman in a red scarf", (1066, 434, 1114, 575)),
    ("E", "woman in purple by the kiosk", (1255, 437, 1305, 567)),
    ("F", "bald man, the left of three on the right", (1444, 420, 1477, 546)),
    ("G", "white-haired man beside F, half behind him", (1466, 426, 1498, 548)),
    ("H", "man in a blue jacket beside G", (1495, 420, 1533, 538)),
    ("I", "man by the bicycle, mostly hidden by the subject's hair and the bicycle", (838, 428, 878, 578)),
)
COVERED = 0.5


def middle_third_share(alpha: np.ndarray, box: tuple[int, int, int, int]) -> float:
    """Share of the box's middle third of columns (its full height) where ``alpha`` >= 0.5."""
    x0, y0, x1, y1 = box
    w = x1 - x0
    band = alpha[y0:y1, x0 + w // 3 : x1 - w // 3]
    return float((band >= 0.5).mean()) if band.size else 0.0


def mattes(photo: Path) -> list[np.ndarray]:
    """The ``person="all"`` matte on every framing (each at the framing's own size)."""
    import cv2

    sys.path.append(str(REPO))  # after PYTHONPATH: a checkout of another commit given there is the one measured
    import relight_rt

    if (Path(relight_rt.__file__).parent / "person").is_dir():
        from relight_rt.person import matting as M
    else:  # the layout before the package's folders (measuring an old commit given on PYTHONPATH)
        from relight_rt import matting as M
    print(f"street_pedestrians: {M.__file__}", file=sys.stderr)

    bgr = cv2.imread(str(photo), cv2.IMREAD_COLOR)
    if bgr is None:
        raise SystemExit(f"street_pedestrians: cannot read {photo}")
    rgb = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB).astype(np.float32) / 255.0
    everyone = M.PersonMatter(person="all")
    out = []
    for dy, dx in FRAMINGS:
        t = time.perf_counter()
        part = np.ascontiguousarray(rgb[dy:, dx:])
        people = everyone.people(part)
        out.append(everyone.alpha(part, people) if people else np.zeros(part.shape[:2], np.float32))
        print(f"framing {dy},{dx}: {len(people)} people, {time.perf_counter() - t:.1f} s", file=sys.stderr)
    return out


def report(alphas: list[np.ndarray]) -> int:
    """Prints the table; returns how many pedestrian-framings are covered."""
    framings = " ".join(f"{dy},{dx}" for dy, dx in FRAMINGS)
    print(f"| pedestrian | shows | height | middle third at alpha >= 0.5, framings {framings} |")
    print("|---|---|---|---|")
    covered = 0
    for name, shows, (x0, y0, x1, y1) in PEDESTRIANS:
        shifted = [(x0 - dx, y0 - dy, x1 - dx, y1 - dy) for dy, dx in FRAMINGS]
        shares = [middle_third_share(a, box) for a, box in zip(alphas, shifted, strict=True)]
        covered += sum(s >= COVERED for s in shares)
        cells = " ".join(f"**{s:.2f}**" if s < COVERED else f"{s:.2f}" for s in shares)
        print(f"| {name} | {shows} | {y1 - y0} px ({(y1 - y0) / 1302:.3f}) | {cells} |")
    total = len(PEDESTRIANS) * len(FRAMINGS)
    print(f"\ncovered (>= {COVERED}): {covered} of {total} pedestrian-framings")
    return covered


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--photo", type=Path, default=shared_path("reference", "photo", "sample.jpg"))
    ap.add_argument("--alphas", type=Path, help="also write the 6 mattes here (.npz), for re-scoring with --load")
    ap.add_argument("--load", type=Path, help="score mattes written by --alphas instead of computing them")
    args = ap.parse_args()
    if args.load is not None:
        with np.load(args.load) as z:
            alphas = [z[f"f{i}"] for i in range(len(FRAMINGS))]
    else:
        if not args.photo.exists() and shared_dir("reference") is None:
            raise SystemExit(missing(shared_path("reference")))
        alphas = mattes(args.photo)
        if args.alphas is not None:
            np.savez_compressed(args.alphas, **{f"f{i}": a.astype(np.float16) for i, a in enumerate(alphas)})
    report(alphas)


if __name__ == "__main__":
    main()
