"""What a face's cast shadows (relight_rt.relight.cast_shadow, ``Factor.cast``) cost a relight.

    python benchmarks/cast_shadow_speed.py PHOTO [MASK] [--light window-left] [--megapixels 2.5] [--repeats 12]

Decomposes PHOTO once (scaled to about ``--megapixels``; without MASK, yale_eval's face ellipse: a face filling the
frame), then relights it under ``--light`` with the shadows and with them switched off (``Factor.cast`` returning
None), interleaved in one process so that a loaded CPU weighs on both alike; prints the minimum and the 25th
percentile of each. The light is turned by a tenth of a degree about the vertical at every call: the shadows are
cached per light direction (a relight under a light seen before costs nothing more), and a new light is what a user
pays for. Also ``shadow_factor`` alone on the Decomposition's own window (the face's meshes as its body pass sees
them; none when only the head pass finds the face).
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("photo")
    p.add_argument("mask", nargs="?", default=None)
    p.add_argument("--light", default="window-left")
    p.add_argument("--megapixels", type=float, default=2.5)
    p.add_argument("--repeats", type=int, default=12)
    args = p.parse_args()

    import cv2
    from yale_eval import ellipse  # benchmarks/ is on sys.path when run as a script

    import relight_rt
    from relight_rt import RuntimeConfig, lights
    from relight_rt.image.color import REC709
    from relight_rt.image.io import read_image, read_mask
    from relight_rt.light import sh
    from relight_rt.relight.cast_shadow import shadow_factor
    from relight_rt.relight.factor import Factor

    image = read_image(args.photo)
    mask = read_mask(args.mask, image.shape[:2]) if args.mask else ellipse(image.shape[:2])
    k = math.sqrt(args.megapixels * 1e6 / (image.shape[0] * image.shape[1]))
    size = (round(image.shape[1] * k), round(image.shape[0] * k))
    image = np.clip(cv2.resize(image, size, interpolation=cv2.INTER_CUBIC), 0, 1)
    mask = np.clip(cv2.resize(np.asarray(mask, np.float32), size, interpolation=cv2.INTER_LINEAR), 0, 1)
    r = relight_rt.open(RuntimeConfig(device="cpu"))
    dec = r.decompose(image, mask)
    own = r._factor.own(r._factor.refit(dec), with_residual=False)
    print(f"{args.photo}: {size[0]}x{size[1]}, face meshes in the body pass's window: {len(own['mesh_views'])}, "
          f"head pass: {dec.head is not None}")
    base = np.asarray(lights.preset(args.light), np.float32)
    original = Factor.cast
    times: dict[str, list[float]] = {"with shadows": [], "without": []}
    turn = 0
    for i in range(2 * args.repeats + 2):
        label = "with shadows" if i % 2 == 0 else "without"
        Factor.cast = original if label == "with shadows" else (lambda self, *a: None)
        turn += 1
        light = sh.rotate_z(base, math.radians(0.1 * turn)).astype(np.float32)
        t = time.perf_counter()
        r.relight(dec, light)
        if i >= 2:  # the first pair warms up
            times[label].append(1000 * (time.perf_counter() - t))
    Factor.cast = original
    for label, ts in times.items():
        print(f"relight, {label}: min {min(ts):.0f} ms, p25 {np.percentile(ts, 25):.0f} ms")
    if own["mesh_views"]:
        alone = []
        for j in range(args.repeats):
            light = sh.rotate_z(base, math.radians(0.1 * (turn + j + 1))).astype(np.float32)
            t = time.perf_counter()
            shadow_factor(own["transport"], light @ REC709, own["mesh_views"], own["cap_skin"])
            alone.append(1000 * (time.perf_counter() - t))
        print(f"shadow_factor alone ({own['transport'].shape[1]}x{own['transport'].shape[0]} window): "
              f"min {min(alone):.1f} ms, median {np.median(alone):.1f} ms")


if __name__ == "__main__":
    main()
