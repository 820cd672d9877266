"""What looking again with the shadows lifted (relight_rt.relight.face_pass ``SHADOW_LIFTS``) costs a face search.

    python benchmarks/face_lift_speed.py PHOTO [MASK] [--repeats 12]

``FacePass.find`` on PHOTO's person box (MASK's, or the whole photo), with the lifts and without them, interleaved
in one process so that a loaded CPU weighs on both alike; prints how many faces each finds and the minimum and 25th
percentile of each. Where a face is found as the photo is, the lifts cost nothing; where none is found, each lift
is one more look at the box's square and at the square twice its size (two more detector runs).
"""

from __future__ import annotations

import argparse
import time


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("photo")
    p.add_argument("mask", nargs="?")
    p.add_argument("--repeats", type=int, default=12)
    args = p.parse_args()

    import numpy as np

    from relight_rt.engine.session import find_models
    from relight_rt.image.io import read_image, read_mask
    from relight_rt.relight import face_pass
    from relight_rt.relight.face_pass import FacePass

    rgb = read_image(args.photo)[..., :3]
    box = (0, rgb.shape[0], 0, rgb.shape[1])
    if args.mask:
        ys, xs = np.nonzero(read_mask(args.mask, rgb.shape[:2]) > 0.5)
        box = (int(ys.min()), int(ys.max()) + 1, int(xs.min()), int(xs.max()) + 1)
    faces = FacePass(find_models(None))
    lifts = face_pass.SHADOW_LIFTS
    times: dict[tuple, list[float]] = {lifts: [], (): []}
    found = {}
    for _ in range(args.repeats + 1):
        for key in times:
            face_pass.SHADOW_LIFTS = key
            t = time.perf_counter()
            found[key] = len(faces.find(rgb, box))
            times[key].append(time.perf_counter() - t)
    face_pass.SHADOW_LIFTS = lifts
    for key, ts in times.items():
        ts = sorted(ts[1:])  # the first is a warm-up
        label = f"lifts {key}" if key else "no lifts"
        print(f"{label:18s} faces {found[key]}  min {ts[0] * 1e3:6.1f} ms  p25 {ts[len(ts) // 4] * 1e3:6.1f} ms")


if __name__ == "__main__":
    main()
