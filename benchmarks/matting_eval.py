"""Automatic person matting (relight_rt.person.matting) against the reference masks, a GrabCut baseline, speed, flicker.

    python benchmarks/matting_eval.py                      # everything below, figures as in docs/RESULTS.md
    python benchmarks/matting_eval.py --only accuracy|speed|flicker|cputime|shifts

- accuracy: IoU (alpha >= 0.5), boundary F-measure (DAVIS: outline pixels matched within 0.8 % of the
  image diagonal) and the edge-band error (mean |alpha - hand mask| and SAD/1000 where the hand mask is soft,
  0.02-0.98) against every mask in ../shared/reference (photo/sample + video/frame_001..024), for
  PersonMatter (with and without the edge-band refinement of issue 33 and the guided filter) and for
  GrabCut (OpenCV, 5 iterations, started from the same person box: the box our region finder returns;
  run on the image reduced to a long side of 1000 px, its mask upsampled).
- speed: PersonMatter on a 2-megapixel photo (the reference photo resized to 1732x1155; the edge band and
  relight_rt.image.foreground.estimate_foreground on their own too), and VideoMatter
  on 720p frames (1280x720: the reference frames scaled to 720 px high, centred, edges replicated),
  median of repeated runs, plus where the time goes.
- shifts: the photo's accuracy over the 9 crops that drop 0-2 rows and 0-2 columns at its top left (the
  matte moves with its 256² crops: a 1-pixel shift moves the photo's IoU by up to 0.007), mean and min.
- flicker: relight_rt.person.matting.outline_flicker on the 24 reference frames for VideoMatter with and without
  temporal smoothing, per-image PersonMatter, and the reference masks themselves.

The reference data stay in ../shared (CC BY-NC-SA 4.0); nothing of them is written anywhere.
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

from _shared import missing, shared_dir, shared_path, timed  # noqa: E402

from relight_rt.person import matting as M  # noqa: E402


def shared_reference() -> Path:
    if shared_dir("reference") is None:
        raise SystemExit(missing(shared_path("reference")))
    return shared_path("reference")


def read_rgb(path: Path) -> np.ndarray:
    return cv2.cvtColor(cv2.imread(str(path), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB).astype(np.float32) / 255.0


def read_gt(path: Path) -> np.ndarray:
    return cv2.imread(str(path), cv2.IMREAD_GRAYSCALE).astype(np.float32) / 255.0


def cases(ref: Path) -> list[tuple[str, Path, Path]]:
    out = [("photo/sample", ref / "photo" / "sample.jpg", ref / "photo" / "sample_mask.png")]
    for f in sorted((ref / "video").glob("frame_[0-9][0-9][0-9].png")):
        out.append((f"video/{f.stem}", f, f.with_name(f"{f.stem}_mask.png")))
    return out


def iou(a: np.ndarray, b: np.ndarray) -> float:
    a, b = a >= 0.5, b >= 0.5
    return float((a & b).sum() / max((a | b).sum(), 1))


def _outline(m: np.ndarray) -> np.ndarray:
    m = m.astype(np.uint8)
    return (m - cv2.erode(m, np.ones((3, 3), np.uint8))) > 0


def boundary_f(pred: np.ndarray, gt: np.ndarray, tol_frac: float = 0.008) -> float:
    """DAVIS boundary F-measure: outline pixels matched within tol_frac x image diagonal."""
    tol = max(1, int(round(tol_frac * np.hypot(*gt.shape))))
    bp, bg = _outline(pred >= 0.5), _outline(gt >= 0.5)
    if not bp.any() and not bg.any():
        return 1.0
    if not bp.any() or not bg.any():
        return 0.0
    disk = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * tol + 1, 2 * tol + 1))
    near_g = cv2.dilate(bg.astype(np.uint8), disk) > 0
    near_p = cv2.dilate(bp.astype(np.uint8), disk) > 0
    precision = float((bp & near_g).sum() / bp.sum())
    recall = float((bg & near_p).sum() / bg.sum())
    return 0.0 if precision + recall == 0 else 2 * precision * recall / (precision + recall)


def grabcut(rgb: np.ndarray, box: tuple[float, float, float, float], long_side: int = 1000) -> np.ndarray:
    h, w = rgb.shape[:2]
    s = min(1.0, long_side / max(h, w))
    small = cv2.resize(rgb, (round(w * s), round(h * s)), interpolation=cv2.INTER_AREA) if s < 1 else rgb
    bgr = cv2.cvtColor((small * 255).astype(np.uint8), cv2.COLOR_RGB2BGR)
    x0, y0, x1, y1 = (int(round(v * s)) for v in box)
    x0, y0 = max(x0, 1), max(y0, 1)
    x1, y1 = min(x1, bgr.shape[1] - 2), min(y1, bgr.shape[0] - 2)
    mask = np.zeros(bgr.shape[:2], np.uint8)
    bgd, fgd = np.zeros((1, 65), np.float64), np.zeros((1, 65), np.float64)
    cv2.grabCut(bgr, mask, (x0, y0, x1 - x0, y1 - y0), bgd, fgd, 5, cv2.GC_INIT_WITH_RECT)
    fg = np.isin(mask, (cv2.GC_FGD, cv2.GC_PR_FGD)).astype(np.float32)
    return cv2.resize(fg, (w, h), interpolation=cv2.INTER_LINEAR) if s < 1 else fg


def band_error(pred: np.ndarray, gt: np.ndarray) -> tuple[float, float]:
    """(mean |alpha - gt|, SAD / 1000) over the edge band: the pixels where the hand mask is soft (0.02-0.98)."""
    soft = (gt > 0.02) & (gt < 0.98)
    err = np.abs(pred - gt)[soft]
    return float(err.mean()), float(err.sum() / 1000)


def accuracy(ref: Path) -> None:
    matters = {
        "PersonMatter (default: edge band refined, issue 33)": M.PersonMatter(),
        "PersonMatter, edges=False (the matte before issue 33)": M.PersonMatter(edges=False),
        "PersonMatter, edges=False, guide='color'": M.PersonMatter(guide="color", edges=False),
        "PersonMatter, refine=False": M.PersonMatter(refine=False),
    }
    rows = {key: [] for key in [*matters, "GrabCut, same box"]}
    for name, img_path, gt_path in cases(ref):
        rgb, gt = read_rgb(img_path), read_gt(gt_path)
        outs = [m(rgb, name) for m in matters.values()]
        box = matters[next(iter(matters))].find_people(rgb)[0][1]
        outs.append(grabcut(rgb, box))
        vals = [(iou(x, gt), boundary_f(x, gt), *band_error(x, gt)) for x in outs]
        for key, v in zip(rows, vals, strict=True):
            rows[key].append((name, *v))
        print(f"  {name:16s} " + "  ".join(f"IoU {v[0]:.4f} F {v[1]:.4f} band {v[2]:.3f}" for v in vals), flush=True)
    head = "| method | photo IoU | photo boundary F | photo edge band: mean error, SAD/1000 "
    head += "| video IoU (mean of 24, min) | video boundary F (mean, min) | video edge band: mean error, SAD/1000 |"
    print("\n" + head)
    print("|---|---|---|---|---|---|---|")
    for key, r in rows.items():
        photo = r[0]
        vid = np.array([x[1:] for x in r[1:]])
        print(
            f"| {key} | {photo[1]:.4f} | {photo[2]:.4f} | {photo[3]:.3f}, {photo[4]:.2f} "
            f"| {vid[:, 0].mean():.4f} ({vid[:, 0].min():.4f}) | {vid[:, 1].mean():.4f} ({vid[:, 1].min():.4f}) "
            f"| {vid[:, 2].mean():.3f}, {vid[:, 3].mean():.2f} |"
        )


def _median_ms(fn, repeat: int) -> float:
    return _times_ms(fn, repeat)[0]


def _times_ms(fn, repeat: int) -> tuple[float, float]:
    """(median, best) milliseconds of ``repeat`` calls after one warm-up call (``_shared.timed``)."""
    best, median = timed(fn, repeat)
    return median, best


def frames_720p(ref: Path) -> list[np.ndarray]:
    out = []
    for f in sorted((ref / "video").glob("frame_[0-9][0-9][0-9].png")):
        rgb = read_rgb(f)
        small = cv2.resize(rgb, (round(rgb.shape[1] * 720 / rgb.shape[0]), 720), interpolation=cv2.INTER_AREA)
        pad = (1280 - small.shape[1]) // 2
        out.append(cv2.copyMakeBorder(small, 0, 0, pad, 1280 - small.shape[1] - pad, cv2.BORDER_REPLICATE))
    return out


def speed(ref: Path, repeat: int) -> None:
    import os

    pm = M.PersonMatter()
    photo = cv2.resize(read_rgb(ref / "photo" / "sample.jpg"), (1732, 1155), interpolation=cv2.INTER_AREA)
    print(f"threads: {os.environ.get('RELIGHT_RT_THREADS') or 'onnxruntime default'}; cores: {os.cpu_count()}")
    print(f"load average before: {os.getloadavg()[0]:.1f}")
    full = _times_ms(lambda: pm(photo), repeat)
    pm.edges = False
    before = _times_ms(lambda: pm(photo), repeat)
    pm.refine = False
    coarse = _times_ms(lambda: pm(photo), repeat)
    pm.refine = True
    a0 = pm(photo)
    band = _times_ms(lambda: M.refine_edges(photo, a0), repeat)
    a1 = M.refine_edges(photo, a0)
    fg = _times_ms(lambda: M.estimate_foreground(photo, a1), repeat)
    both = _times_ms(lambda: M.estimate_foreground(photo, M.refine_edges(photo, a0)), repeat)
    pm.edges = True
    size = f"{photo.shape[1]}x{photo.shape[0]}"
    print(f"2-megapixel photo {size}, median (best) ms: PersonMatter {full[0]:.1f} ({full[1]:.1f}); ", end="")
    print(f"edges=False {before[0]:.1f} ({before[1]:.1f}); refine=False {coarse[0]:.1f} ({coarse[1]:.1f})")
    print(f"  edge band refinement {band[0]:.1f} ({band[1]:.1f}); estimate_foreground {fg[0]:.1f} ({fg[1]:.1f}); "
          f"both {both[0]:.1f} ({both[1]:.1f})")  # fmt: skip
    found = pm.find_people(photo)
    region = M.Region.around(*found[0][1])
    person = pm.segment(photo, region)
    zeros = {"image": np.zeros((1, 3, 256, 256), np.float32)}
    finder = _median_ms(lambda: pm.find_people(photo), repeat)
    pose = _median_ms(lambda: pm.pose.run(zeros), repeat)
    seg = _median_ms(lambda: pm.segment(photo, region), repeat)
    alpha = _median_ms(lambda: pm.alpha(photo, [person]), repeat)
    print(f"  region finder {finder:.1f} ms; pose graph (one run) {pose:.1f} ms; ", end="")
    print(f"segment (passes until stable + portrait check) {seg:.1f} ms; full-resolution alpha {alpha:.1f} ms")
    frames = frames_720p(ref)
    for smoothing in (0.7, 0.0):
        vm = M.VideoMatter(pm, smoothing=smoothing)
        vm(frames[0])
        times = []
        for _ in range(max(1, repeat // 5)):
            for f in frames:
                t = time.perf_counter()
                vm(f)
                times.append(time.perf_counter() - t)
        med, best = float(np.median(times)), float(np.min(times))
        print(
            f"720p video (1280x720), VideoMatter smoothing {smoothing}: median {1000 * med:.1f} ms/frame = "
            f"{1 / med:.1f} frames/s (best {1000 * best:.1f} ms)"
        )
    big = np.random.default_rng(0).random((3000, 4000, 3), dtype=np.float32)  # 12 MP float32 in [0, 1]
    copied = _times_ms(lambda: M.as_rgb(big), repeat)
    shared = _times_ms(lambda: M.as_rgb(big, copy=False), repeat)
    print(f"as_rgb of a 12-megapixel float32 photo, median (best) ms: a new array {copied[0]:.1f} ({copied[1]:.1f}); "
          f"copy=False (the matters' intake) {shared[0]:.1f} ({shared[1]:.1f})")  # fmt: skip
    print(f"load average after: {os.getloadavg()[0]:.1f}")


def cpu_time(ref: Path, repeat: int) -> None:
    """CPU time of one thread (cv2.setNumThreads(1)) for the edge refinement and the decontamination of a
    2-megapixel photo, and for the coarse matte (its graphs on one thread too): on a machine whose cores other
    jobs share, closer to an idle core's wall time."""
    import os

    cv2.setNumThreads(1)
    photo = cv2.resize(read_rgb(ref / "photo" / "sample.jpg"), (1732, 1155), interpolation=cv2.INTER_AREA)
    a0 = M.PersonMatter(edges=False)(photo)
    a1 = M.refine_edges(photo, a0)

    def best(fn) -> tuple[float, float]:
        fn()
        ts = []
        for _ in range(repeat):
            t = time.process_time()
            fn()
            ts.append(time.process_time() - t)
        return 1000 * min(ts), 1000 * float(np.median(ts))

    r = best(lambda: M.refine_edges(photo, a0))
    f = best(lambda: M.estimate_foreground(photo, a1))
    b = best(lambda: M.estimate_foreground(photo, M.refine_edges(photo, a0)))
    print(
        f"load {os.getloadavg()[0]:.1f}; CPU ms, one thread, best / median of {repeat}: refine_edges "
        f"{r[0]:.0f} / {r[1]:.0f}; estimate_foreground {f[0]:.0f} / {f[1]:.0f}; both {b[0]:.0f} / {b[1]:.0f}"
    )
    from relight_rt.engine.session import ENV_THREADS

    before = os.environ.get(ENV_THREADS)
    os.environ[ENV_THREADS] = "1"  # the graphs' sessions are made with one intra-op thread
    try:
        coarse = M.PersonMatter(edges=False)
        raw = M.PersonMatter(refine=False)
    finally:
        if before is None:
            del os.environ[ENV_THREADS]
        else:
            os.environ[ENV_THREADS] = before
    c = best(lambda: coarse(photo))
    u = best(lambda: raw(photo))
    print(
        f"load {os.getloadavg()[0]:.1f}; CPU ms, one thread (graphs too), best / median of {repeat}: coarse matte "
        f"(edges=False) {c[0]:.0f} / {c[1]:.0f}; refine=False {u[0]:.0f} / {u[1]:.0f}"
    )


def flicker(ref: Path) -> None:
    files = sorted((ref / "video").glob("frame_[0-9][0-9][0-9].png"))
    frames = [read_rgb(f) for f in files]
    gts = [read_gt(f.with_name(f"{f.stem}_mask.png")) for f in files]
    pm = M.PersonMatter()
    print("| matte | IoU (mean) | outline flicker, raw | outline flicker, motion-compensated |")
    print("|---|---|---|---|")

    def row(label, alphas):
        m_iou = np.mean([iou(a, g) for a, g in zip(alphas, gts, strict=True)])
        print(f"| {label} | {m_iou:.4f} | {M.outline_flicker(alphas):.4f} | {M.outline_flicker(alphas, frames):.4f} |")

    row("reference masks", gts)
    row("PersonMatter, each frame on its own", [pm(f) for f in frames])
    for s in (0.0, 0.7, 0.85):
        vm = M.VideoMatter(pm, smoothing=s)
        row(f"VideoMatter, smoothing {s}", [vm(f) for f in frames])


def shifts(ref: Path) -> None:
    name, img_path, gt_path = cases(ref)[0]
    rgb0, gt0 = read_rgb(img_path), read_gt(gt_path)
    for label, pm in (("PersonMatter()", M.PersonMatter()), ("PersonMatter(edges=False)", M.PersonMatter(edges=False))):
        r = []
        for dy in range(3):
            for dx in range(3):
                a, gt = pm(np.ascontiguousarray(rgb0[dy:, dx:]), name), gt0[dy:, dx:]
                r.append((iou(a, gt), boundary_f(a, gt), band_error(a, gt)[0]))
        v = np.array(r)
        print(
            f"{label}, {name} shifted by 0-2 px (9 crops): IoU mean {v[:, 0].mean():.4f} (min {v[:, 0].min():.4f}, "
            f"max {v[:, 0].max():.4f}); boundary F mean {v[:, 1].mean():.4f} (min {v[:, 1].min():.4f}); "
            f"edge band mean error {v[:, 2].mean():.3f}",
            flush=True,
        )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--only", choices=("accuracy", "speed", "flicker", "cputime", "shifts"))
    p.add_argument("--repeat", type=int, default=20)
    args = p.parse_args()
    ref = shared_reference()
    if args.only in (None, "accuracy"):
        accuracy(ref)
    if args.only in (None, "speed"):
        speed(ref, args.repeat)
    if args.only in (None, "flicker"):
        flicker(ref)
    if args.only in (None, "cputime"):
        cpu_time(ref, min(args.repeat, 10))
    if args.only in (None, "shifts"):
        shifts(ref)


if __name__ == "__main__":
    main()
