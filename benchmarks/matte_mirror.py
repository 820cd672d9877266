"""Is the automatic matte mirror-symmetric? matte(mirror(photo)) against mirror(matte(photo)), and the matte's time.

    python benchmarks/matte_mirror.py [--photos DIR] [--repeat N]

The bundled example (relight_rt/data/example.png) and, with ``--photos``, every .jpg/.png in DIR: per photo the 99th
percentile and max of |matte(mirror(photo)) mirrored back - matte(photo)| in 8-bit levels over the two mattes'
union (either >= 0.5), the IoU of their hard masks (:func:`mirror_gap`), and the matte's best and median wall time
over ``--repeat`` runs (the example only). The matte as it ships; a photo it finds nobody in is reported and skipped.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

from relight_rt import RelightError
from relight_rt.person.matting import PersonMatter

EXAMPLE = Path(__file__).resolve().parents[1] / "relight_rt" / "data" / "example.png"


def read(path: Path) -> np.ndarray:
    bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if bgr is None:
        raise SystemExit(f"cannot read {path}")
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB).astype(np.float32) / 255


def mirror_gap(matter: Callable[[np.ndarray], np.ndarray], rgb: np.ndarray) -> dict[str, float]:
    """``matter`` (an (H, W, 3) float32 RGB photo -> its (H, W) matte in [0, 1]) on ``rgb`` and on its mirror image,
    mirrored back: {"p99", "max"}: the 99th percentile and max of their difference in 8-bit levels over the two
    mattes' union (either >= 0.5; 0 when the union is empty), "iou": of their hard masks (1 when both are empty)."""
    a = matter(rgb)
    b = matter(np.ascontiguousarray(rgb[:, ::-1]))[:, ::-1]
    union = (a >= 0.5) | (b >= 0.5)
    if not union.any():
        return {"p99": 0.0, "max": 0.0, "iou": 1.0}
    diff = np.abs(a - b)[union] * 255
    inter = ((a >= 0.5) & (b >= 0.5)).sum()
    return {"p99": float(np.percentile(diff, 99)), "max": float(diff.max()), "iou": float(inter / union.sum())}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--photos", type=Path, default=None, help="also every .jpg/.png in this folder")
    ap.add_argument("--repeat", type=int, default=5, help="timed runs of the matte on the example (best, median)")
    args = ap.parse_args(argv)
    if args.repeat < 1:
        ap.error("--repeat: expected at least 1")
    matter = PersonMatter()
    photos = [("example", read(EXAMPLE))]
    if args.photos is not None:
        photos += [(p.name, read(p)) for p in sorted(args.photos.iterdir()) if p.suffix.lower() in (".jpg", ".png")]
    for name, rgb in photos:
        try:
            row = mirror_gap(matter, rgb)
        except RelightError as e:
            print(f"{name}: skipped ({e})")
            continue
        print(f"{name}: mirror gap p99 {row['p99']:.2f} levels, max {row['max']:.1f}, hard-mask IoU {row['iou']:.5f}")
    rgb = photos[0][1]
    times = []
    for _ in range(args.repeat):
        t = time.perf_counter()
        matter(rgb)
        times.append((time.perf_counter() - t) * 1000)
    print(f"example {rgb.shape[1]}x{rgb.shape[0]}: matte best {min(times):.0f} ms, median {np.median(times):.0f} ms")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
