"""The video matte's gaps (issue 48, matte13, video14): ``VideoMatter`` on the reference video's 24 frames against their
hand masks, with and without the pocket decision (``matte_edges.open_pockets``, the photo matte's), and what it costs.

    PYTHONPATH=$PWD python benchmarks/video_pockets.py            # ~1-2 min
    PYTHONPATH=$PWD python benchmarks/video_pockets.py --rounds 6 # more timing rounds (a loaded machine)
    PYTHONPATH=$PWD python benchmarks/video_pockets.py --cost-only --height 1080   # the timings on 1080p frames
    git show 75de3c2:relight_rt/image/matte_edges.py > /tmp/matte_edges_base.py   # the module before video14
    PYTHONPATH=$PWD python benchmarks/video_pockets.py --cost-only --base /tmp/matte_edges_base.py

Rows: the default ``VideoMatter`` without the pocket decision (``pockets=False``), the default (it decides them),
``complete=True`` without and with it. Columns: IoU (alpha >= 0.5), boundary F and the edge band's mean error
(benchmarks/matting_eval.py's measures), outline flicker (motion-compensated), and pixels held at 0.5-0.95 per frame
(half-held: relit part person, part backdrop). Then the cost on 720p frames (matting_eval's 1280x720 frames; with
``--height``, those resized): ``open_pockets`` alone, median and best; and the default ``VideoMatter`` with / without
it, a frame of each in turn (their order swapped every frame) so that a loaded machine slows both alike: the paired
ratio's median is the figure.
With ``--base``, another version of relight_rt/image/matte_edges.py (a file) is timed against this one in turn, on the
same alphas, and their outputs compared.
The reference data stay in ../shared; nothing of them is written.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import time
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

import matting_eval as E  # noqa: E402

from relight_rt.image.matte_edges import open_pockets  # noqa: E402
from relight_rt.person import matting as M  # noqa: E402


def reference_video(ref: Path) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """The reference video's 24 frames (RGB float) and their hand masks, in order (shared with video_on_drop.py)."""
    files = sorted((ref / "video").glob("frame_[0-9][0-9][0-9].png"))
    return [E.read_rgb(f) for f in files], [E.read_gt(f.with_name(f"{f.stem}_mask.png")) for f in files]


def measures(alphas: list[np.ndarray], gts: list[np.ndarray]) -> np.ndarray:
    """(N, 3) per frame: IoU (alpha >= 0.5), boundary F, the edge band's mean error (matting_eval's measures)."""
    return np.array(
        [(E.iou(a, g), E.boundary_f(a, g), E.band_error(a, g)[0]) for a, g in zip(alphas, gts, strict=True)]
    )


def quality(ref: Path, pm: M.PersonMatter) -> None:
    frames, gts = reference_video(ref)
    print("| VideoMatter | IoU | boundary F | edge band error | flicker | px at 0.5-0.95 |")
    print("|---|---|---|---|---|---|")
    rows = (("default, pockets=False", False, False), ("default", False, True),
            ("complete=True, pockets=False", True, False), ("complete=True", True, True))  # fmt: skip
    for label, complete, pockets in rows:
        vm = M.VideoMatter(pm, complete=complete, pockets=pockets)
        outs = [vm(f) for f in frames]
        v = measures(outs, gts)
        held = np.mean([((a > 0.5) & (a < 0.95)).sum() for a in outs])
        f_min = v[:, 1].min()
        print(
            f"| {label} | {v[:, 0].mean():.4f} | {v[:, 1].mean():.4f} (min {f_min:.4f}) | {v[:, 2].mean():.3f} "
            f"| {M.outline_flicker(outs, frames):.4f} | {held:.0f} |"
        )


def cost(ref: Path, pm: M.PersonMatter, rounds: int, height: int = 720) -> None:
    hd = E.frames_720p(ref)
    if height != 720:  # the 720p frames resized (16:9 kept)
        hd = [cv2.resize(f, (round(f.shape[1] * height / 720), height), interpolation=cv2.INTER_LINEAR) for f in hd]
    vm = M.VideoMatter(pm, pockets=False)  # one over the frames in order, as a video is matted
    alphas = [vm(f) for f in hd]
    alone = []
    for _ in range(rounds):
        for f, a in zip(hd, alphas, strict=True):
            t = time.perf_counter()
            open_pockets(f, a)
            alone.append(time.perf_counter() - t)
    med, best = 1000 * np.median(alone), 1000 * min(alone)
    print(f"\nopen_pockets on {height}p frames: median {med:.1f} ms, best {best:.1f} ms")
    vms = {True: M.VideoMatter(pm), False: M.VideoMatter(pm, pockets=False)}
    times: dict[bool, list[float]] = {True: [], False: []}
    for k in range(rounds):
        for i, f in enumerate(hd):
            for pockets in (True, False) if (k * len(hd) + i) % 2 else (False, True):
                t = time.perf_counter()
                vms[pockets](f)
                times[pockets].append(time.perf_counter() - t)
    on, off = np.array(times[True]), np.array(times[False])
    q = np.percentile(on / off, [25, 50, 75])
    print(
        f"default VideoMatter on {height}p frames, with / without the pocket decision: median "
        f"{1000 * np.median(on):.1f} / {1000 * np.median(off):.1f} ms (best {1000 * on.min():.1f} / "
        f"{1000 * off.min():.1f}); paired ratio median {q[1]:.3f} (quartiles {q[0]:.3f}-{q[2]:.3f}), {len(on)} pairs"
    )


def against(ref: Path, pm: M.PersonMatter, base: Path, rounds: int) -> None:
    """``open_pockets`` of this module against that of ``base`` (loaded as a module of relight_rt.image), in turn."""
    spec = importlib.util.spec_from_file_location("relight_rt.image._matte_edges_base", base)
    old = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(old)
    hd = E.frames_720p(ref)
    vm = M.VideoMatter(pm, pockets=False)  # one over the frames in order, as a video is matted
    alphas = [vm(f) for f in hd]
    pairs = list(zip(hd, alphas, strict=True))
    differ = max(float(np.abs(old.open_pockets(f, a) - open_pockets(f, a)).max()) for f, a in pairs)
    t_old, t_new = [], []
    for _ in range(rounds):
        for f, a in pairs:
            for fn, ts in ((old.open_pockets, t_old), (open_pockets, t_new)):
                t = time.perf_counter()
                fn(f, a)
                ts.append(time.perf_counter() - t)
    new, was = np.array(t_new), np.array(t_old)
    print(
        f"open_pockets against {base}: largest difference {differ:.3g}; median {1000 * np.median(new):.1f} / "
        f"{1000 * np.median(was):.1f} ms (best {1000 * new.min():.1f} / {1000 * was.min():.1f}); paired ratio median "
        f"{np.median(new / was):.3f}, {len(new)} pairs"
    )


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3, help="timing rounds over the 24 frames (default 3)")
    ap.add_argument("--cost-only", action="store_true", help="only the timings")
    ap.add_argument("--height", type=int, default=720, help="time on the 720p frames resized to this height")
    ap.add_argument("--base", type=Path, help="another matte_edges.py to time open_pockets against (a file)")
    args = ap.parse_args(argv)
    ref = E.shared_reference()
    pm = M.PersonMatter()
    if not args.cost_only:
        quality(ref, pm)
    if args.base is not None:
        against(ref, pm, args.base, args.rounds)
    cost(ref, pm, args.rounds, args.height)


if __name__ == "__main__":
    main()
