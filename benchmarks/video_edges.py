"""How much of a relit video frame's soft edge is the new light on the backdrop (issue 32).

    python benchmarks/video_edges.py [FRAMES] [--preset golden-hour] [--frames 8]

Relights the first ``--frames`` frames of FRAMES (a folder of frames with STEM_mask.png beside them; default: the
reference video in ../shared/reference) through the video path (``relight_rt.video.job``, as ``relight-rt video``
does) and prints, per band of the mask's alpha, the 95th percentile of each pixel's largest channel change
(8-bit levels) divided by its alpha. Only the person's share of an edge pixel should take the new light, so
that figure should not grow as alpha falls; where it does, the backdrop's share is being relit (a line of the
new light's colour along the outline). Compare two checkouts by running it in each.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np
from _shared import missing, shared_path

REFERENCE = shared_path("reference", "video")
BANDS = ((0.02, 0.1), (0.1, 0.25), (0.25, 0.5), (0.5, 0.75))


def edge_figures(frames: list[Path], out_dir: Path) -> dict[tuple[float, float], float]:
    """Mean over frames of the p95 change per unit of alpha in each alpha band."""
    acc: dict[tuple[float, float], list[float]] = {b: [] for b in BANDS}
    for src in frames:
        before = cv2.imread(str(src), cv2.IMREAD_COLOR).astype(np.float32)
        after = cv2.imread(str(out_dir / src.name), cv2.IMREAD_COLOR).astype(np.float32)
        alpha = cv2.imread(str(src.with_name(src.stem + "_mask.png")), cv2.IMREAD_GRAYSCALE).astype(np.float32) / 255
        change = np.abs(after - before).max(axis=2)
        for lo, hi in BANDS:
            sel = (alpha > lo) & (alpha <= hi)
            if sel.any():
                acc[(lo, hi)].append(float(np.percentile(change[sel] / alpha[sel], 95)))
    return {b: float(np.mean(v)) for b, v in acc.items() if v}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("frames", nargs="?", type=Path, default=REFERENCE)
    parser.add_argument("--preset", default="golden-hour")
    parser.add_argument("--frames", dest="count", type=int, default=8)
    args = parser.parse_args(argv)
    from relight_rt.cli import main as cli

    frames = sorted(p for p in args.frames.glob("*.png") if not p.stem.endswith("_mask"))[: args.count]
    if not frames:
        print(missing(args.frames) if not args.frames.is_dir() else f"{args.frames}: no frames", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory() as tmp:
        clip = Path(tmp) / "clip"
        clip.mkdir()
        for f in frames:
            for p in (f, f.with_name(f.stem + "_mask.png")):
                (clip / p.name).write_bytes(p.read_bytes())
        out = Path(tmp) / "out"
        code = cli(["video", str(clip), "--preset", args.preset, "--frames-out", str(out), "-q"])
        if code:
            return code
        figs = edge_figures([clip / f.name for f in frames], out)
    print(f"{len(frames)} frames of {args.frames}, {args.preset}: p95 change per unit of alpha (8-bit levels)")
    print("  " + "  ".join(f"alpha {lo}-{hi}: {v:6.1f}" for (lo, hi), v in figs.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
