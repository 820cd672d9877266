"""How far the matte's pixels lie from the pose landmarker's skeleton (matte43): a cue for parts no limb reaches.

    PYTHONPATH=$PWD python benchmarks/matte_block_sources.py --straight --save-mattes /tmp/mattes   # the mattes
    /tmp/mpvenv/bin/python benchmarks/skeleton_reach.py --mattes /tmp/mattes [--out /tmp/skel]     # ~1 min

The pose graph the matte runs (matte_pose.onnx) is MediaPipe's full pose landmarker with its landmark heads pruned
(``python -m export mask-models``). This asks what those landmarks would tell: MediaPipe's own pose solution (one person
per photo, the most prominent; needs ``mediapipe==0.10.21`` in a separate venv, as ``export mask-models`` does, since
it pins numpy < 2) gives 33 landmarks; the bones between those seen (visibility > VISIBLE) are drawn 1 px wide, and
every pixel of the saved matte (alpha >= 0.5) gets its distance to the nearest bone in shoulder widths. Printed per
half (sorted names, even index A, odd B): the matte's pixels beyond REACH shoulder widths of every bone that the
service mask holds (person) and leaves (background); and the same for the four first-look photos. ``--out``: the
matte's pixels outside the mask (magenta) and inside the mask but not the matte (green), the skeleton drawn over.
people_masks is evaluation only: nothing is written except where --out points (keep it under /tmp).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _shared import shared_path  # noqa: E402

REACH = (0.5, 1.0, 1.5)  # shoulder widths from every bone
VISIBLE = 0.3  # a landmark's visibility below this: its bones are not drawn
FIRST_LOOK = ("p186", "p209", "p255", "p273")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mattes", type=Path, required=True, help="the mattes saved by matte_block_sources.py")
    ap.add_argument("--out", type=Path, help="a picture per first-look photo here (under /tmp)")
    args = ap.parse_args(argv)
    try:
        import mediapipe as mp
    except ImportError:
        print("needs mediapipe==0.10.21 (a separate venv: it pins numpy < 2)", file=sys.stderr)
        return 2
    folder = shared_path("realdata", "people_masks") / "photos"
    names = sorted(f[:-4] for f in os.listdir(folder) if f.endswith(".jpg"))
    half = {n: "AB"[i % 2] for i, n in enumerate(names)}
    bones = mp.solutions.pose.POSE_CONNECTIONS
    far: dict[str, dict[float, tuple[int, int]]] = {}
    with mp.solutions.pose.Pose(static_image_mode=True, model_complexity=1) as pose:
        for name in names:
            bgr = cv2.imread(str(folder / f"{name}.jpg"))
            h, w = bgr.shape[:2]
            gt = cv2.resize(cv2.imread(str(folder / f"{name}_mask.png"), 0), (w, h), interpolation=cv2.INTER_NEAREST)
            gt = gt >= 128
            matte = np.load(args.mattes / f"{name}.npy") >= 128
            found = pose.process(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)).pose_landmarks
            if not found:
                continue
            pts = [(lm.x * w, lm.y * h, lm.visibility) for lm in found.landmark]
            skeleton = np.zeros((h, w), np.uint8)
            for i, j in bones:
                if pts[i][2] > VISIBLE and pts[j][2] > VISIBLE:
                    a, b = (int(pts[i][0]), int(pts[i][1])), (int(pts[j][0]), int(pts[j][1]))
                    cv2.line(skeleton, a, b, 255, 1)
            if not skeleton.any():
                continue
            shoulders = float(np.hypot(pts[11][0] - pts[12][0], pts[11][1] - pts[12][1])) or 1.0
            dist = cv2.distanceTransform((skeleton == 0).astype(np.uint8), cv2.DIST_L2, 5) / shoulders
            far[name] = {
                k: (int((matte & (dist > k) & gt).sum()), int((matte & (dist > k) & ~gt).sum())) for k in REACH
            }
            if args.out is not None and name in FIRST_LOOK:
                pic = bgr.astype(np.float32)
                pic[matte & ~gt] = pic[matte & ~gt] * 0.4 + np.float32([255, 0, 255]) * 0.6
                pic[~matte & gt] = pic[~matte & gt] * 0.4 + np.float32([0, 255, 0]) * 0.6
                pic = pic.astype(np.uint8)
                mp.solutions.drawing_utils.draw_landmarks(pic, found, bones)
                args.out.mkdir(parents=True, exist_ok=True)
                cv2.imwrite(str(args.out / f"{name}_skeleton.png"), pic)
    print(f"{len(far)} of {len(names)} photos with a skeleton")
    for hv in "AB":
        for k in REACH:
            person = sum(v[k][0] for n, v in far.items() if half[n] == hv)
            background = sum(v[k][1] for n, v in far.items() if half[n] == hv)
            print(f"half {hv}: matte pixels beyond {k} shoulder widths of every bone: "
                  f"the mask holds {person}, leaves {background}")  # fmt: skip
    for name in FIRST_LOOK:
        if name in far:
            print(f"  {name}: " + ", ".join(f"beyond {k}: {v[0]} held / {v[1]} left" for k, v in far[name].items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
