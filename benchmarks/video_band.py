"""The background beside the person on VIDEO frames relit as ``relight-rt video`` relights them (issue 48's "nothing
outside the matte's soft edge changes" fault, measured on the video path).

    PYTHONPATH=$PWD python benchmarks/video_band.py [--frames 12] [--lights LEFT,RIGHT,night,campfire]

``benchmarks/photo_faults.py --skip-photos`` measures the reference clip's band with each frame decomposed as a PHOTO
(the automatic matte through intake, its shown edge and steepened rim: mean 0.01-0.09, worst p99 <= 0.24 levels).
``relight-rt video`` decomposes frames with ``decompose_batch(allow_full=True)`` and ``VideoMatter``'s mattes, which
skips the photo's once-per-photo reads (the shown edge among them). Here each of the reference video's first
``--frames`` frames (../shared/reference/video, read in place) is matted by ``VideoMatter`` in order and relit so,
with the frames' rim on (``automatic=True``, ``relight.compose.FRAME_RIM``) and their shown edge off and on
(``relight.compose.FRAME_EDGE``, videoedge44; ``--rim-off``: also the rim off, ``automatic=False``); printed per
arm and light: the mean and the worst frame's 99th percentile of the largest channel change (8-bit levels) on the
band where the frame's hand-drawn mask says background (outside it dilated 2 px, within 24 px: photo_faults' band).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _shared import missing, shared_path  # noqa: E402
from real_photos import LEFT, RIGHT  # noqa: E402

import relight_rt  # noqa: E402
from relight_rt.person.matting import PersonMatter, VideoMatter  # noqa: E402
from relight_rt.relight import compose  # noqa: E402

BAND = 24  # px beside the hand outline (photo_faults.py's)


def disc(r: int) -> np.ndarray:
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=12)
    ap.add_argument("--lights", default="LEFT,RIGHT,night,campfire")
    ap.add_argument("--rim-off", action="store_true", help="also the arm with the frames' rim off")
    args = ap.parse_args(argv)
    folder = shared_path("reference", "video")
    if not folder.is_dir():
        raise SystemExit(missing(folder))
    frames = sorted(p for p in folder.glob("frame_*.png") if not p.stem.endswith("_mask"))[: args.frames]
    lights = [(n, {"LEFT": LEFT, "RIGHT": RIGHT}.get(n, n)) for n in args.lights.split(",") if n]
    relighter = relight_rt.open()
    matter = VideoMatter(PersonMatter())
    arms = [("rim on, edge off", True, False), ("rim on, edge on", True, True)]
    if args.rim_off:
        arms.insert(0, ("rim off, edge off", False, False))
    found: dict[tuple[str, str], list[tuple[float, float]]] = {}
    for path in frames:
        rgb = cv2.cvtColor(cv2.imread(str(path)), cv2.COLOR_BGR2RGB).astype(np.float32) / 255
        truth = (cv2.imread(str(path.with_name(path.stem + "_mask.png")), cv2.IMREAD_GRAYSCALE) > 127).astype(np.uint8)
        alpha = matter(rgb)
        band = (cv2.dilate(truth, disc(2)) == 0) & (cv2.dilate(truth, disc(BAND)) > 0)
        for arm, automatic, edge in arms:
            compose.FRAME_EDGE = edge
            dec = relighter.decompose_batch([rgb], [alpha], allow_full=True, automatic=[automatic])[0]
            for name, light in lights:
                change = 255 * np.abs(relighter.relight(dec, light) - rgb).max(axis=2)
                found.setdefault((arm, name), []).append((float(change[band].mean()),
                                                          float(np.percentile(change[band], 99))))
    for (arm, name), rows in sorted(found.items()):
        a = np.array(rows)
        print(f"{arm} {name:9s} band mean {a[:, 0].mean():6.3f}, worst frame's p99 "
              f"{a[:, 1].max():7.3f} levels ({len(rows)} frames)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
