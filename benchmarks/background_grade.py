"""How far the graded original background follows the person (issue 51; docs/RESULTS.md).

Relights a photo (default: the bundled street photo, relight_rt/data/example_scene.jpg) under a preset with
``--grade-background``'s Background, and prints the person's change of mean luminance and the background's, in EV
(linear light: the photo's sRGB values decoded, Rec. 709 weights; the person weighted by the matte, the background
by one minus it), and the per-channel gain of each.

    PYTHONPATH=$PWD python benchmarks/background_grade.py [PHOTO] [--preset night]
    PYTHONPATH=$PWD python benchmarks/background_grade.py --clip ../shared/reference/video [--preset night]

``--clip FOLDER`` (frames with STEM_mask files; ``relight-rt video --grade-background``): the grade each frame
measures alone against the one the clip follows (relight_rt.video.job.BackgroundGrade), as the frame-to-frame change of
its luminance in EV (median and largest: the background's flicker), and the person's and the background's change
over the clip.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

import relight_rt
from relight_rt.image.color import REC709, srgb_to_linear
from relight_rt.image.compositing import Background
from relight_rt.light.exposure import for_light

EXAMPLE = "relight_rt/data/example_scene.jpg"


def weighted_mean(image: np.ndarray, weight: np.ndarray) -> np.ndarray:
    w = weight[..., None].astype(np.float64)
    return (image * w).sum(axis=(0, 1)) / max(float(w.sum()), 1e-9)


def clip(folder: str, preset: str) -> None:
    from relight_rt.video.job.job.job import (
        BackgroundGrade,
        FrameSource,
        LightSchedule,
        RelighterEngine,
        relight_frames,
    )

    from relight_rt.relight.compose import grade_of_sums, light_sums

    rl = relight_rt.open()
    source = FrameSource(folder)
    follow = BackgroundGrade(source.fps)
    lights = LightSchedule.constant(rl.resolve_light(preset))
    engine = RelighterEngine(rl, exposure=for_light("auto", preset))  # night: a stop darker
    alone, followed, person, back = [], [], [], []
    for frame, out, _ in relight_frames(source, lights, engine=engine, stabilizer=None):
        opaque = (frame.mask >= 1 - 1 / 255).astype(np.float32)
        alone.append(float(grade_of_sums(*light_sums(out, frame.image, opaque)) @ REC709))
        gain = follow.update(out, frame.image, frame.mask)
        followed.append(float(gain @ REC709))
        graded = follow.apply(out, frame.image, frame.mask, gain)
        lin_in, lin_out = srgb_to_linear(frame.image), srgb_to_linear(graded)
        for store, w in ((person, frame.mask), (back, 1 - frame.mask)):
            after, before = weighted_mean(lin_out, w) @ REC709, weighted_mean(lin_in, w) @ REC709
            store.append(math.log2(float(after) / float(before)))
    steps = lambda g: np.abs(np.diff(np.log2(np.array(g)) * 2.2))  # noqa: E731 - the grade's light, in EV
    print(f"{folder}: {len(alone)} frames, preset {preset}")
    for name, g in (("measured per frame", alone), ("followed (video)", followed)):
        st = steps(g)
        print(f"  background grade {name:18s}: frame-to-frame change median {np.median(st):.4f} EV, largest "
              f"{st.max():.4f} EV")
    print(f"  person {np.mean(person):+.3f} EV, background graded {np.mean(back):+.3f} EV (mean over frames)")


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("photo", nargs="?", default=EXAMPLE)
    p.add_argument("--preset", default="night")
    p.add_argument("--clip", help="a folder of frames with STEM_mask files: the grade over time")
    args = p.parse_args()
    if args.clip:
        clip(args.clip, args.preset)
        return
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
