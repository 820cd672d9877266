"""Is the automatic matte mirror-symmetric? matte(mirror(photo)) against mirror(matte(photo)), and its cost.

    python benchmarks/matte_mirror.py [--mirror on|off] [--photos DIR] [--repeat N]
    python benchmarks/matte_mirror.py --mirror on --masks -- --set photos --half A   # people_masks_eval.py under it
    python benchmarks/matte_mirror.py --mirror on --masks -- --speed                 # the matte's speed row under it

The bundled example (relight_rt/data/example.png) and, with ``--photos``, every .jpg/.png in DIR: per photo the 99th
percentile and max of |matte(mirror(photo)) mirrored back - matte(photo)| in 8-bit levels over the two mattes'
union (either >= 0.5), the IoU of their hard masks, and the matte's best wall time over ``--repeat`` runs (the example
only). ``--mirror`` sets relight_rt.person.matting._matter.MATTE_MIRROR for this run (default: as shipped);
``--masks`` runs benchmarks/people_masks_eval.py with the arguments after ``--`` under that setting instead, and
``--relight`` benchmarks/mirror_equivariance.py (the relit photo and its mirror, automatic matte), ``--speed``
benchmarks/relight_speed.py (decompose + relight with the automatic matte among its rows).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from relight_rt.person.matting import PersonMatter, _matter  # noqa: E402

EXAMPLE = Path(__file__).resolve().parents[1] / "relight_rt" / "data" / "example.png"


def read(path: Path) -> np.ndarray:
    bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if bgr is None:
        raise SystemExit(f"cannot read {path}")
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB).astype(np.float32) / 255


def mirror_gap(matter: PersonMatter, rgb: np.ndarray) -> dict:
    """The figures of one photo (module docstring)."""
    a = matter(rgb)
    b = matter(np.ascontiguousarray(rgb[:, ::-1]))[:, ::-1]
    union = (a >= 0.5) | (b >= 0.5)
    diff = np.abs(a - b)[union] * 255
    inter = ((a >= 0.5) & (b >= 0.5)).sum()
    return {"p99": float(np.percentile(diff, 99)), "max": float(diff.max()), "iou": float(inter / max(union.sum(), 1))}


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    rest = argv[argv.index("--") + 1 :] if "--" in argv else []
    argv = argv[: argv.index("--")] if "--" in argv else argv
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mirror", choices=("on", "off"), default="on" if _matter.MATTE_MIRROR else "off")
    ap.add_argument("--photos", type=Path, default=None)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--masks", action="store_true", help="run people_masks_eval.py with the arguments after --")
    ap.add_argument("--relight", action="store_true", help="run mirror_equivariance.py with the arguments after --")
    ap.add_argument("--speed", action="store_true", help="run relight_speed.py with the arguments after --")
    args = ap.parse_args(argv)
    _matter.MATTE_MIRROR = args.mirror == "on"
    print(f"MATTE_MIRROR = {_matter.MATTE_MIRROR}")
    if args.masks:
        import people_masks_eval

        return people_masks_eval.main(rest)
    if args.relight:
        import mirror_equivariance

        return mirror_equivariance.main(rest)
    if args.speed:
        import relight_speed

        sys.argv = ["relight_speed.py", *rest]
        relight_speed.main()
        return 0
    matter = PersonMatter()
    photos = [("example", read(EXAMPLE))]
    if args.photos is not None:
        photos += [(p.name, read(p)) for p in sorted(args.photos.iterdir()) if p.suffix.lower() in (".jpg", ".png")]
    for name, rgb in photos:
        row = mirror_gap(matter, rgb)
        print(f"{name}: mirror gap p99 {row['p99']:.2f} levels, max {row['max']:.1f}, hard-mask IoU {row['iou']:.5f}")
    rgb = photos[0][1]
    times = []
    for _ in range(max(1, args.repeat)):
        t = time.perf_counter()
        matter(rgb)
        times.append((time.perf_counter() - t) * 1000)
    print(f"example {rgb.shape[1]}x{rgb.shape[0]}: matte best {min(times):.0f} ms, median {np.median(times):.0f} ms")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
