"""relight_rt.image.foreground.estimate_foreground against pymatting's estimate_foreground_ml (the method's reference
implementation, MIT; needs numba, so it runs in a side venv and is no dependency of the project).

    python3 -m venv /tmp/pmvenv && /tmp/pmvenv/bin/pip install pymatting onnxruntime opencv-python-headless
    PYTHONPATH=. /tmp/pmvenv/bin/python benchmarks/foreground_compare.py [--photo ../shared/reference/photo/sample.jpg]

- synthetic: a textured person (soft edge 10 px) over a textured background with known F: mean |F - F_true| on
  the soft pixels for the photo itself, ours and pymatting's (same regulariser 1e-5, gradient weight 1);
- real photo (with --photo): our automatic matte (edges refined), then mean |F_ours - F_pymatting| on its soft
  pixels (0.02-0.98), in 8-bit levels; and each one's time (pymatting's after its numba compilation).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from relight_rt.image.foreground import estimate_foreground  # noqa: E402


def synthetic(h: int = 600, w: int = 800, seed: int = 0):
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    tex = lambda s: cv2.GaussianBlur(rng.random((h, w, 3), dtype=np.float32), (0, 0), s)  # noqa: E731
    f = np.clip(0.25 + 2.0 * (tex(6) - 0.5) + np.array([0.5, 0.3, 0.2], np.float32), 0, 1)
    b = np.clip(0.25 + 2.0 * (tex(12) - 0.5) + np.array([0.0, 0.3, 0.5], np.float32), 0, 1)
    r = np.hypot((yy - h / 2) / 1.3, xx - w / 2) + 15 * np.sin(xx / 9) * np.cos(yy / 13)  # a wavy outline
    alpha = np.clip((min(h, w) / 3 - r) / 10 + 0.5, 0, 1).astype(np.float32)
    rgb = alpha[..., None] * f + (1 - alpha[..., None]) * b
    return rgb.astype(np.float32), alpha, f


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--photo", type=Path)
    args = ap.parse_args()
    from pymatting import estimate_foreground_ml

    rgb, alpha, f = synthetic()
    soft = (alpha > 0.02) & (alpha < 0.98)
    estimate_foreground_ml(rgb[:64, :64].astype(np.float64), alpha[:64, :64].astype(np.float64))  # compile
    t = time.perf_counter()
    ours = estimate_foreground(rgb, alpha)
    t_ours = time.perf_counter() - t
    t = time.perf_counter()
    theirs = estimate_foreground_ml(rgb.astype(np.float64), alpha.astype(np.float64))
    t_theirs = time.perf_counter() - t
    err = lambda x: 255 * float(np.abs(x - f)[soft].mean())  # noqa: E731
    print(f"synthetic {rgb.shape[1]}x{rgb.shape[0]}, {soft.sum()} soft pixels: mean |F - F_true| in 8-bit levels: "
          f"photo {err(rgb):.1f}, ours {err(ours):.1f}, pymatting {err(theirs):.1f}; "
          f"time ours {1000 * t_ours:.0f} ms, pymatting {1000 * t_theirs:.0f} ms")  # fmt: skip
    if args.photo is not None:
        from relight_rt.person.matting import PersonMatter

        img = cv2.cvtColor(cv2.imread(str(args.photo), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB).astype(np.float32) / 255
        a = PersonMatter()(img)
        soft = (a > 0.02) & (a < 0.98)
        t = time.perf_counter()
        ours = estimate_foreground(img, a)
        t_ours = time.perf_counter() - t
        t = time.perf_counter()
        theirs = estimate_foreground_ml(img.astype(np.float64), a.astype(np.float64))
        t_theirs = time.perf_counter() - t
        d = 255 * np.abs(ours - theirs)[soft]
        print(f"{args.photo.name} {img.shape[1]}x{img.shape[0]}, {soft.sum()} soft pixels: |ours - pymatting| mean "
              f"{d.mean():.1f}, 95th percentile {np.percentile(d, 95):.1f} levels; |photo - pymatting| mean "
              f"{255 * np.abs(img - theirs)[soft].mean():.1f}; time ours {1000 * t_ours:.0f} ms, "
              f"pymatting {1000 * t_theirs:.0f} ms")  # fmt: skip


if __name__ == "__main__":
    main()
