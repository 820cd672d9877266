"""A large group photo for memory measurements (issue 50 bug 1): the bundled example person, flattened onto grey,
tiled N x N on a square canvas, and the mask of the top-left person alone (to relight one person of the same photo).

    python benchmarks/group_photo.py --side 5000 --people 4 -o /tmp/g25.png    # 16 people, 25 MP
    /usr/bin/time -v python -m relight_rt relight /tmp/g25.png --person all --preset neon -o /tmp/all.png
    /usr/bin/time -v python -m relight_rt relight /tmp/g25.png --mask /tmp/g25_one_mask.png --preset neon \
        -o /tmp/one.png

Writes OUT and OUT's stem + ``_one_mask.png`` beside it.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np

EXAMPLE = Path(__file__).resolve().parents[1] / "relight_rt" / "data" / "example.png"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--side", type=int, default=5000, help="the canvas's side in pixels (default 5000: 25 MP)")
    ap.add_argument("--people", type=int, default=4, help="people per row and per column (default 4: 16 people)")
    ap.add_argument("-o", "--output", required=True)
    args = ap.parse_args(argv)
    rgba = cv2.imread(str(EXAMPLE), cv2.IMREAD_UNCHANGED)
    a = rgba[..., 3:] / 255.0
    person = (rgba[..., :3] * a + np.array([180, 190, 200]) * (1 - a)).astype(np.uint8)
    cell = args.side // args.people
    scale = cell / person.shape[0]
    tile = cv2.resize(person, None, fx=scale, fy=scale)
    alpha = cv2.resize(rgba[..., 3], None, fx=scale, fy=scale)
    th, tw = tile.shape[:2]
    n = args.people
    photo = np.full((n * cell, n * cell, 3), (200, 190, 180), np.uint8)
    for j in range(n):
        for i in range(n):
            x = i * cell + (cell - tw) // 2
            photo[j * cell : j * cell + th, x : x + tw] = tile
    one = np.zeros(photo.shape[:2], np.uint8)
    one[:th, (cell - tw) // 2 : (cell - tw) // 2 + tw] = alpha
    out = Path(args.output)
    cv2.imwrite(str(out), photo)
    cv2.imwrite(str(out.with_name(out.stem + "_one_mask.png")), one)
    print(f"{out}: {n * cell}x{n * cell}, {n * n} people; {out.stem}_one_mask.png: the top-left one")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
