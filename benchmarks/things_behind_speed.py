"""The time of the things-behind rule (relight_rt.person.matting._things_behind) alone, on the default matte of photos.

    python benchmarks/things_behind_speed.py                          # the 2.5-MP reference photo
    python benchmarks/things_behind_speed.py PHOTO [PHOTO ...] --mp 2.5 --repeats 7
    python benchmarks/things_behind_speed.py PHOTO --before     # on the matte before the rule: a part leaves

For each photo (optionally enlarged or reduced to ``--mp`` megapixels first): the default matte's people and alpha
before the rule, then the rule on them ``--repeats`` times after one warm-up call, as PersonMatter.alpha calls it (a
selfie-graph person's pose-graph view is one more pose-graph run; with pose-graph people only the rule returns at
once; the faces are found only when a part would leave): best and median, milliseconds, and the matte's own time
(PersonMatter()(rgb), best of 3) beside it. The rule is read on the matte it made (a second call: no part is left to
take, so neither the faces nor the leaving are paid) unless ``--before`` gives it the matte without it (the cost of a
photo where a part leaves: the face-graph run and the leaving included).
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

from _shared import missing, shared_path  # noqa: E402

from relight_rt.person import matting as M  # noqa: E402
from relight_rt.person.matting import _matter  # noqa: E402
from relight_rt.person.matting._things_behind import without_things_behind  # noqa: E402


def read_rgb(path: Path, mp: float | None) -> np.ndarray:
    """The photo through the project's one intake (relight_rt.image.io.read_image), resized to ``mp`` megapixels."""
    from relight_rt.image.io import read_image

    rgb = read_image(path, path.name)[..., :3]
    if mp:
        s = float(np.sqrt(mp * 1e6 / (rgb.shape[0] * rgb.shape[1])))
        rgb = np.clip(cv2.resize(rgb, None, fx=s, fy=s, interpolation=cv2.INTER_CUBIC), 0.0, 1.0)
    return rgb


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("photos", nargs="*", type=Path)
    ap.add_argument("--mp", type=float, help="resize each photo to this many megapixels first")
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--before", action="store_true", help="time the rule on the matte before it (a part leaves)")
    args = ap.parse_args(argv)
    photos = args.photos or [shared_path("reference", "photo", "sample.jpg")]
    for path in photos:
        if not path.is_file():
            raise SystemExit(missing(path))
    matter = M.PersonMatter()
    for path in photos:
        rgb = read_rgb(path, args.mp)
        people = matter.people(rgb, path.name)
        if args.before:
            _matter.without_things_behind = lambda rgb, alpha, *rest: alpha
        try:
            alpha = matter.alpha(rgb, people)  # (with the rule: its input differs only where it took a part)
        finally:
            _matter.without_things_behind = without_things_behind

        def pose(p, rgb=rgb):  # as PersonMatter.alpha asks for the pose graph's view of a selfie-graph person
            return matter._pose(rgb, p.region).logits

        def faces(rgb=rgb):
            return matter.find_faces(rgb)

        without_things_behind(rgb, alpha, people, pose, faces)
        times = []
        for _ in range(args.repeats):
            t = time.perf_counter()
            without_things_behind(rgb, alpha, people, pose, faces)
            times.append(1000 * (time.perf_counter() - t))
        whole = []
        for _ in range(3):
            t = time.perf_counter()
            matter(rgb)
            whole.append(1000 * (time.perf_counter() - t))
        sources = "/".join(p.source for p in people)
        print(f"{path.name} {rgb.shape[1]}x{rgb.shape[0]} ({sources}): rule best {min(times):.1f} ms, median "
              f"{float(np.median(times)):.1f} ms; the matte best {min(whole):.0f} ms")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
