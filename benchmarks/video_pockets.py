"""The video matte's gaps (issue 48, matte13): ``VideoMatter`` on the reference video's 24 frames against their hand
masks, with and without ``matte_edges.open_pockets`` (the photo matte's pocket decision), and what it costs at 720p.

    PYTHONPATH=$PWD python benchmarks/video_pockets.py     # ~1-2 min

Rows: the default ``VideoMatter`` (no pocket decision), the same with ``open_pockets`` applied to each frame's alpha
(not the default: its cost, below), ``complete=True`` with the pocket decision taken out, and ``complete=True`` as it
is. Columns: IoU (alpha >= 0.5), boundary F and the edge band's mean error (benchmarks/matting_eval.py's measures),
outline flicker (motion-compensated), and pixels held at 0.5-0.95 per frame (half-held: relit part person, part
backdrop). Last, ``open_pockets`` alone on 720p frames (matting_eval's 1280x720 frames), median and best.
The reference data stay in ../shared; nothing of them is written.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

import matting_eval as E  # noqa: E402

from relight_rt.image.matte_edges import open_pockets  # noqa: E402
from relight_rt.person import matting as M  # noqa: E402
from relight_rt.person.matting import _video  # noqa: E402


def main() -> None:
    ref = E.shared_reference()
    files = sorted((ref / "video").glob("frame_[0-9][0-9][0-9].png"))
    frames = [E.read_rgb(f) for f in files]
    gts = [E.read_gt(f.with_name(f"{f.stem}_mask.png")) for f in files]
    pm = M.PersonMatter()
    print("| VideoMatter | IoU | boundary F | edge band error | flicker | px at 0.5-0.95 |")
    print("|---|---|---|---|---|---|")
    rows = (("default", False, False), ("default + open_pockets", False, True),
            ("complete=True, no pocket decision", True, False), ("complete=True", True, True))  # fmt: skip
    for label, complete, pockets in rows:
        _video.open_pockets = open_pockets if pockets or not complete else (lambda rgb, alpha: alpha)
        vm = M.VideoMatter(pm, complete=complete)
        outs = []
        for f in frames:
            a = vm(f)
            outs.append(open_pockets(f, a) if pockets and not complete else a)
        v = np.array([(E.iou(a, g), E.boundary_f(a, g), E.band_error(a, g)[0]) for a, g in zip(outs, gts, strict=True)])
        held = np.mean([((a > 0.5) & (a < 0.95)).sum() for a in outs])
        f_min = v[:, 1].min()
        print(
            f"| {label} | {v[:, 0].mean():.4f} | {v[:, 1].mean():.4f} (min {f_min:.4f}) | {v[:, 2].mean():.3f} "
            f"| {M.outline_flicker(outs, frames):.4f} | {held:.0f} |"
        )
    _video.open_pockets = open_pockets
    hd = E.frames_720p(ref)
    vm = M.VideoMatter(pm)
    alphas = [vm(f) for f in hd]
    ts = []
    for _ in range(3):
        for f, a in zip(hd, alphas, strict=True):
            t = time.perf_counter()
            open_pockets(f, a)
            ts.append(time.perf_counter() - t)
    print(f"\nopen_pockets on 720p frames: median {1000 * np.median(ts):.1f} ms, best {1000 * min(ts):.1f} ms")


if __name__ == "__main__":
    main()
