"""How far the graded original background follows the person (issue 51; docs/RESULTS.md).

Relights a photo (default: the bundled street photo, relight_rt/data/example_scene.jpg) under a preset with
``--grade-background``'s Background, and prints the person's change of mean luminance and the background's, in EV
(linear light: the photo's sRGB values decoded, Rec. 709 weights; the person weighted by the matte, the background
by one minus it), and the per-channel gain of each.

    PYTHONPATH=$PWD python benchmarks/background_grade.py [PHOTO] [--preset night]
"""

from __future__ import annotations

import argparse
import math

import numpy as np

import relight_rt
from relight_rt.image.color import srgb_to_linear
from relight_rt.image.compositing import Background
from relight_rt.light.exposure import REC709

EXAMPLE = "relight_rt/data/example_scene.jpg"


def weighted_mean(image: np.ndarray, weight: np.ndarray) -> np.ndarray:
    w = weight[..., None].astype(np.float64)
    return (image * w).sum(axis=(0, 1)) / max(float(w.sum()), 1e-9)


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("photo", nargs="?", default=EXAMPLE)
    p.add_argument("--preset", default="night")
    args = p.parse_args()
    rl = relight_rt.open()
    dec = rl.decompose(args.photo)
    alpha = np.asarray(dec.mask, np.float32)
    photo = np.asarray(dec.image, np.float32)
    plain = rl.relight(dec, args.preset)
    graded = rl.relight(dec, args.preset, background=Background.original(grade=True))
    lin = {name: srgb_to_linear(np.clip(img, 0, 1)) for name, img in
           (("photo", photo), ("plain", plain), ("graded", graded))}
    rows = []
    for who, weight in (("person", alpha), ("background", 1 - alpha)):
        before = weighted_mean(lin["photo"], weight)
        for run in ("plain", "graded"):
            after = weighted_mean(lin[run], weight)
            ev = math.log2(float(after @ REC709) / float(before @ REC709))
            rows.append((who, run, ev, after / before))
    print(f"{args.photo} ({photo.shape[1]}x{photo.shape[0]}), preset {args.preset}")
    for who, run, ev, gain in rows:
        print(f"  {who:10s} {run:6s} {ev:+.3f} EV  linear gain per channel R,G,B {np.round(gain, 3).tolist()}")
    person = rows[1][2]
    back = rows[3][2]
    print(f"background graded - person: {back - person:+.3f} EV")


if __name__ == "__main__":
    main()
