"""The video matte completed where it drops what the flow carries (issue 48, video16): ``VideoMatter`` completes a
frame as a photo (``PersonMatter.completed``) only where the followed matte drops ``complete_on_drop`` of the matte
carried over from the last frame. Quality on the reference video, which frames of the parkour clip are completed, and
the 720p cost against another version of ``_video.py`` in turn.

    PYTHONPATH=$PWD python benchmarks/video_on_drop.py                 # reference video quality + 720p cost (~2 min)
    git show main:relight_rt/person/matting/_video.py > /tmp/video_base.py
    PYTHONPATH=$PWD python benchmarks/video_on_drop.py --cost-only --base /tmp/video_base.py --rounds 4
    PYTHONPATH=$PWD python benchmarks/video_on_drop.py --cost-only --complete --base /tmp/video_base.py --rounds 2
    PYTHONPATH=$PWD python benchmarks/video_on_drop.py --clip          # the parkour clip: frames completed, IoU
    PYTHONPATH=$PWD python benchmarks/video_on_drop.py --worst --rounds 2   # every frame dropping: the rule's worst

Quality rows (the reference video's 24 frames against their hand masks, benchmarks/matting_eval.py's measures): the
rule off (``complete_on_drop=None``: the default before video16), the default, ``complete=True``; columns IoU,
boundary F (min), edge band error, outline flicker (motion-compensated) and the frames completed.
Cost: this ``VideoMatter`` (default) and ``base``'s (its module loaded in relight_rt.person.matting, default too) on
matting_eval's 720p frames in order, a frame of each in turn (their order swapped every frame) so that a loaded machine
slows both alike: medians, best, and the paired ratio's median (new / base). Without ``--base``, the rule off stands
for the base. ``--clip`` reads ../shared/realdata/people_masks/clip (evaluation only; nothing is written).
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

import matting_eval as E  # noqa: E402
from video_pockets import measures, reference_video  # noqa: E402

from relight_rt.person import matting as M  # noqa: E402
from relight_rt.person.matting import _video  # noqa: E402


def quality(ref: Path, pm: M.PersonMatter) -> None:
    frames, gts = reference_video(ref)
    print("| VideoMatter | IoU | boundary F (min) | edge band error | flicker | frames completed |")
    print("|---|---|---|---|---|---|")
    rows = (("complete_on_drop=None (before video16)", {"complete_on_drop": None}), ("default", {}),
            ("complete=True", {"complete": True}))  # fmt: skip
    for label, options in rows:
        vm = M.VideoMatter(pm, **options)
        outs = [vm(f) for f in frames]
        v = measures(outs, gts)
        print(
            f"| {label} | {v[:, 0].mean():.4f} | {v[:, 1].mean():.4f} ({v[:, 1].min():.4f}) | {v[:, 2].mean():.3f} "
            f"| {M.outline_flicker(outs, frames):.4f} | {vm.completions} of {len(frames)} |"
        )


def clip(pm: M.PersonMatter) -> None:
    """The default VideoMatter over the parkour clip (854x480) and one with the rule off, a frame of each in turn
    (their order swapped every frame): IoU, the frames completed, the time a frame."""
    import people_masks_eval as P

    items = P.items(P.data_root(), "clip")
    vms = {"default": M.VideoMatter(pm), "off": M.VideoMatter(pm, complete_on_drop=None)}
    done, ious, times = [], {k: [] for k in vms}, {k: [] for k in vms}
    for i, (name, img, mask) in enumerate(items):
        rgb = P.read_rgb(img)
        gt = P.read_mask(mask, rgb.shape[:2])
        before = vms["default"].completions
        for key in ("default", "off") if i % 2 else ("off", "default"):
            t = time.perf_counter()
            a = vms[key](rgb, name)
            times[key].append(time.perf_counter() - t)
            ious[key].append(P.iou(a >= 0.5, gt))
        if vms["default"].completions > before:
            done.append(i)
    ratio = np.array(times["default"][1:]) / np.array(times["off"][1:])
    print(
        f"parkour clip, VideoMatter default / complete_on_drop=None: mean IoU {np.mean(ious['default']):.5f} / "
        f"{np.mean(ious['off']):.5f}; median {1000 * np.median(times['default']):.1f} / "
        f"{1000 * np.median(times['off']):.1f} ms a frame, mean {1000 * np.mean(times['default']):.1f} / "
        f"{1000 * np.mean(times['off']):.1f}; paired ratio median {np.median(ratio):.3f}, mean {ratio.mean():.3f}; "
        f"{len(done)} of {len(items)} frames completed: {done}"
    )


def cost(
    ref: Path, pm: M.PersonMatter, rounds: int, base: Path | None, smoothing: float, complete: bool = False
) -> None:
    """With ``complete``, both VideoMatters complete every frame (``complete=True``)."""
    if base is not None:
        spec = importlib.util.spec_from_file_location("relight_rt.person.matting._video_base", base)
        old = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(old)
        was = old.VideoMatter(pm, smoothing=smoothing, complete=complete)
    else:
        was = M.VideoMatter(pm, smoothing=smoothing, complete=complete, complete_on_drop=None)
    now = M.VideoMatter(pm, smoothing=smoothing, complete=complete)
    hd = E.frames_720p(ref)
    was(hd[0])  # warm-up (and the first frame's search)
    now(hd[0])
    times: dict[str, list[float]] = {"new": [], "base": []}
    for k in range(rounds):
        for i, f in enumerate(hd):
            pair = (("new", now), ("base", was)) if (k * len(hd) + i) % 2 else (("base", was), ("new", now))
            for key, vm in pair:
                t = time.perf_counter()
                vm(f)
                times[key].append(time.perf_counter() - t)
    new, old_t = np.array(times["new"]), np.array(times["base"])
    q = np.percentile(new / old_t, [25, 50, 75])
    label = base or "complete_on_drop=None"
    med_new, med_old = np.median(new), np.median(old_t)
    mode = ", complete=True" if complete else ""
    print(
        f"720p VideoMatter (smoothing {smoothing}{mode}), this / {label}: median {1000 * med_new:.1f} / "
        f"{1000 * med_old:.1f} ms ({1 / med_new:.1f} / {1 / med_old:.1f} frames/s; best {1000 * new.min():.1f} / "
        f"{1000 * old_t.min():.1f}); paired ratio median {q[1]:.3f} (quartiles {q[0]:.3f}-{q[2]:.3f}), "
        f"{len(new)} pairs; frames completed {now.completions} of {len(hd) * rounds + 1}"
    )


def worst(ref: Path, pm: M.PersonMatter, rounds: int, smoothing: float) -> None:
    """The rule's worst case, a video where every frame drops what the flow carries: the rule made to fire on every
    frame (``_video.dropped_share`` read as 1 while that VideoMatter runs), against the default and
    ``complete=True`` on matting_eval's 720p frames, a frame of each in turn (the order rotated every frame): medians
    and paired ratios."""
    share = _video.dropped_share
    vms = {
        "default": M.VideoMatter(pm, smoothing=smoothing),
        "every frame dropping": M.VideoMatter(pm, smoothing=smoothing),
        "complete=True": M.VideoMatter(pm, smoothing=smoothing, complete=True),
    }
    hd = E.frames_720p(ref)
    keys = list(vms)
    times: dict[str, list[float]] = {k: [] for k in keys}
    try:
        for vm in vms.values():
            vm(hd[0])  # warm-up (and the first frame's search)
        for k in range(rounds):
            for i, f in enumerate(hd):
                j = (k * len(hd) + i) % len(keys)
                for key in keys[j:] + keys[:j]:
                    _video.dropped_share = (lambda p, c, a: 1.0) if key == "every frame dropping" else share
                    t = time.perf_counter()
                    vms[key](f)
                    times[key].append(time.perf_counter() - t)
    finally:
        _video.dropped_share = share
    t = {k: np.array(v) for k, v in times.items()}
    print(
        f"720p VideoMatter (smoothing {smoothing}), "
        + "; ".join(f"{k}: median {1000 * np.median(v):.1f} ms, {vms[k].completions} completed" for k, v in t.items())
        + f"; paired ratio medians: every frame dropping / default "
        f"{np.median(t['every frame dropping'] / t['default']):.3f}, / complete=True "
        f"{np.median(t['every frame dropping'] / t['complete=True']):.3f}; {len(t['default'])} frames each"
    )


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3, help="timing rounds over the 24 frames (default 3)")
    ap.add_argument("--cost-only", action="store_true", help="only the timings")
    ap.add_argument("--base", type=Path, help="another _video.py to time VideoMatter against (a file)")
    ap.add_argument("--smoothing", type=float, default=0.7, help="the VideoMatters' smoothing (cost; default 0.7)")
    ap.add_argument("--clip", action="store_true", help="only the parkour clip: the frames completed and the IoU")
    ap.add_argument("--complete", action="store_true", help="cost: both VideoMatters with complete=True")
    ap.add_argument("--worst", action="store_true", help="only the cost when every frame drops (the rule forced)")
    args = ap.parse_args(argv)
    pm = M.PersonMatter()
    if args.clip:
        clip(pm)
        return
    if args.worst:
        worst(E.shared_reference(), pm, args.rounds, args.smoothing)
        return
    ref = E.shared_reference()
    if not args.cost_only:
        quality(ref, pm)
    cost(ref, pm, args.rounds, args.base, args.smoothing, args.complete)


if __name__ == "__main__":
    main()
