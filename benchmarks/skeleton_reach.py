"""How far the matte's pixels lie from the pose landmarker's skeleton (matte43): a cue for parts no limb reaches.

    PYTHONPATH=$PWD python benchmarks/matte_block_sources.py --straight --save-mattes /tmp/mattes   # the mattes
    /tmp/mpvenv/bin/python benchmarks/skeleton_reach.py --mattes /tmp/mattes [--out /tmp/skel]     # ~1 min
    PYTHONPATH=$PWD python benchmarks/matte_block_sources.py --backed --dump /tmp/pieces.json      # backed's pieces
    /tmp/mpvenv/bin/python benchmarks/skeleton_reach.py --pieces /tmp/pieces.json                  # ~30 s

The pose graph the matte runs (matte_pose.onnx) is MediaPipe's full pose landmarker with its landmark heads pruned
(``python -m export mask-models``). This asks what those landmarks would tell: MediaPipe's own pose solution (one person
per photo, the most prominent; needs ``mediapipe==0.10.21`` in a separate venv, as ``export mask-models`` does, since
it pins numpy < 2) gives 33 landmarks; the bones between those seen (visibility > VISIBLE) are drawn 1 px wide, and
every pixel of the saved matte (alpha >= 0.5) gets its distance to the nearest bone in shoulder widths. Printed per
half (sorted names, even index A, odd B): the matte's pixels beyond REACH shoulder widths of every bone that the
service mask holds (person) and leaves (background); and the same for the four first-look photos. ``--out``: the
matte's pixels outside the mask (magenta) and inside the mask but not the matte (green), the skeleton drawn over.
``--pieces``: per region, as the pruned heads would see it. Each piece ``_completion.backed`` lifts gets the median
distance of its pixels to the skeleton of the landmarker run on its person's region (the square region resampled to
256², as the pose graph sees it) in UNIT (the larger of the shoulder width and 0.4 x the torso's length). Printed per
half: the pieces beyond each distance, by the part the service mask holds and leaves, and the farthest large pieces.
people_masks is evaluation only: nothing is written except where --out points (keep it under /tmp).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _shared import shared_path  # noqa: E402

REACH = (0.5, 1.0, 1.5)  # shoulder widths from every bone
PIECE_REACH = (0.25, 0.5, 1.0)  # --pieces: a piece's median distance beyond this many UNITs ...
PIECE_AREA = (0, 500, 2000)  # ... and at least this many photo pixels
VISIBLE = 0.3  # a landmark's visibility below this: its bones are not drawn
FIRST_LOOK = ("p186", "p209", "p255", "p273")


def _to_segment(xs: np.ndarray, ys: np.ndarray, a: tuple[float, float], b: tuple[float, float]) -> np.ndarray:
    """Distance of the points (xs, ys) to the segment a-b."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    t = np.clip(((xs - a[0]) * dx + (ys - a[1]) * dy) / max(dx * dx + dy * dy, 1e-9), 0.0, 1.0)
    return np.hypot(xs - (a[0] + t * dx), ys - (a[1] + t * dy))


def pieces(path: Path, folder: Path, mp) -> None:
    """--pieces (module docstring)."""
    rows = json.loads(path.read_text())
    bones = list(mp.solutions.pose.POSE_CONNECTIONS)
    skeletons: dict[tuple, tuple[list, float] | None] = {}
    photo: dict[str, np.ndarray] = {}
    with mp.solutions.pose.Pose(static_image_mode=True, model_complexity=1) as pose:
        for r in rows:
            key = (r["name"], *r["region"])
            if key not in skeletons:
                if r["name"] not in photo:
                    photo.clear()
                    photo[r["name"]] = cv2.cvtColor(cv2.imread(str(folder / f"{r['name']}.jpg")), cv2.COLOR_BGR2RGB)
                x0, y0, x1, _ = r["region"]
                k = 256 / (x1 - x0)
                crop = cv2.warpAffine(photo[r["name"]], np.float32([[k, 0, -x0 * k], [0, k, -y0 * k]]), (256, 256),
                                      flags=cv2.INTER_AREA, borderMode=cv2.BORDER_CONSTANT)  # fmt: skip
                found = pose.process(crop).pose_landmarks
                skeletons[key] = None
                if found:
                    side = x1 - x0
                    pts = [(x0 + lm.x * side, y0 + lm.y * side, lm.visibility) for lm in found.landmark]
                    segs = [(pts[i][:2], pts[j][:2]) for i, j in bones if min(pts[i][2], pts[j][2]) > VISIBLE]
                    shoulders = np.hypot(pts[11][0] - pts[12][0], pts[11][1] - pts[12][1])
                    torso = np.hypot(pts[11][0] + pts[12][0] - pts[23][0] - pts[24][0],
                                     pts[11][1] + pts[12][1] - pts[23][1] - pts[24][1]) / 2  # fmt: skip
                    skeletons[key] = (segs, max(shoulders, 0.4 * torso, 1.0)) if segs else None
            found = skeletons[key]
            if found is not None:
                xs, ys = np.array(r["xs"]), np.array(r["ys"])
                r["reach"] = float(np.median(np.min([_to_segment(xs, ys, a, b) for a, b in found[0]], 0)) / found[1])
    seen = [r for r in rows if "reach" in r]
    print(f"{len(seen)} of {len(rows)} pieces on a region with a skeleton")
    for hv in "AB":
        for far in PIECE_REACH:
            for least in PIECE_AREA:
                d = [r for r in seen if r["half"] == hv and r["reach"] > far and r["area"] >= least]
                held = sum(r["area"] * r["held"] for r in d)
                print(f"half {hv}: pieces beyond {far} units, >= {least} px: {len(d)}, the mask holds {held:.0f} px, "
                      f"leaves {sum(r['area'] for r in d) - held:.0f}")  # fmt: skip
    print("the farthest pieces over 2000 px:")
    for r in sorted((r for r in seen if r["area"] > 2000), key=lambda r: -r["reach"])[:15]:
        print(f"  {r['name']} ({r['half']}): {r['area']:.0f} px, mask holds {r['held']:.2f}, {r['reach']:.2f} units")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mattes", type=Path, help="the mattes saved by matte_block_sources.py --save-mattes")
    ap.add_argument("--pieces", type=Path, help="backed's pieces saved by matte_block_sources.py --backed --dump")
    ap.add_argument("--out", type=Path, help="a picture per first-look photo here (under /tmp)")
    args = ap.parse_args(argv)
    try:
        import mediapipe as mp
    except ImportError:
        print("needs mediapipe==0.10.21 (a separate venv: it pins numpy < 2)", file=sys.stderr)
        return 2
    folder = shared_path("realdata", "people_masks") / "photos"
    if args.pieces is not None:
        pieces(args.pieces, folder, mp)
    if args.mattes is None:
        return 0
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
