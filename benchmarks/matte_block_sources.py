"""Where a block of background in the automatic matte comes from (matte43, issue 48's first look): people_masks,
evaluation only.

    python benchmarks/matte_block_sources.py --only p186,p209,p255,p273 --out /tmp/blocks   # per photo, ~30 s
    python benchmarks/matte_block_sources.py --backed [--dump /tmp/pieces.json]   # what backed lifts, ~2 min
    python benchmarks/matte_block_sources.py --portraits   # what a portrait holds and the pose graph leaves, ~2 min
    python benchmarks/matte_block_sources.py --straight [--save-mattes /tmp/mattes]   # outlines' straight runs, ~2 min

Per photo (``--only``): the default matte's IoU and its pixels outside the service mask (alpha >= 0.5, mask < 0.5);
each person found (source, presence, region); the share of the matte's pixels each graph's own answer holds (>= 0.5):
the selfie and pose graphs on the whole photo, and on each person's region ("framed"); then each rule of
``matte_ablation.RULES`` switched off in turn, where it moves the matte: IoU and the pixels outside the mask. With
``--out``: a sheet per photo, photo | service mask | ours | each graph's answer (tinted), at 100 %.

``--backed``: every connected piece (8-connected, on the region's 256² canvas) of what ``_completion.backed`` lifts
(pose probability >= 0.1 and the selfie graph on the same region >= 0.5): its size in photo pixels, the service mask's
share of it, and the graphs' answers over it; summed per half (A: sorted names, even index; B: odd). Then a colour
cue a fix might use, a piece whose colour lies nearer the unlifted background ring round it than to the person's sure
pixels (``RATIO`` x), and what dropping such pieces would take from the person and from the background, per half.

``--portraits``: for every person matted by the selfie graph (a portrait), the connected parts of the matte that the
pose graph, framed on the same region and on the whole photo, leaves (< 0.1), their share of the matte and the service
mask's share of them: whether the pose graph's doubt tells a portrait's background block from its shoulders.

``--straight``: the longest straight run of each matte's outline off the photo's border (probabilistic Hough lines on
its 1-px outline, at least 8 % of the photo's diagonal), as a share of that diagonal, ours and the service mask's, and
where the four first-look photos rank: whether a man-made block's straight sides tell it from a person's outline.
``--save-mattes DIR`` keeps each matte there (uint8 .npy) for benchmarks/skeleton_reach.py.

The graphs' answers are memoised for the process (``matte_ablation.memoise_graphs``). Nothing of the data is written
except where --out points (keep it under /tmp).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

import matte_ablation as AB  # noqa: E402
import people_masks_eval as PME  # noqa: E402

from relight_rt import RelightError  # noqa: E402
from relight_rt.image.regions import crop_region, reductions_shared  # noqa: E402
from relight_rt.person import matting as M  # noqa: E402
from relight_rt.person.matting import _completion as CP  # noqa: E402
from relight_rt.person.matting import _matter as PM  # noqa: E402
from relight_rt.person.matting._coarse import region_alpha  # noqa: E402
from relight_rt.person.matting._detect import roi_prob  # noqa: E402
from relight_rt.person.matting._segmentation import Person, as_logits, canvas_points, sigmoid  # noqa: E402

RATIO = (0.25, 0.5, 1.0)  # --backed: the colour cue's ratios (background ring distance < RATIO x person distance)
MIN_AREA = (0, 500, 2000)  # ... and the pieces' least size in photo pixels
RING = 7  # ... the ring round a piece: this wide a square window (canvas pixels)
POSE_LEAVES = 0.1  # --portraits: the pose graph leaves a pixel below this
PART_MIN = 0.03  # ... parts at least this share of the matte are listed
DUMP_POINTS = 300  # --backed --dump: at most this many of a piece's pixels written


def _whole(matter: M.PersonMatter, rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The selfie and pose graphs' probabilities on the whole photo (letterboxed), (H, W) float32 each."""
    return (PME.whole_image(matter.roi, rgb, "segmentation", logits=False),
            PME.whole_image(matter.pose, rgb, "segmentation", logits=True))  # fmt: skip


def _framed(matter: M.PersonMatter, rgb: np.ndarray, p: Person) -> tuple[np.ndarray, np.ndarray]:
    """The selfie and pose graphs framed on ``p``'s region, unrefined, over the photo: (H, W) float32 each."""
    h, w = rgb.shape[:2]
    selfie = Person(p.region, as_logits(roi_prob(matter.roi, rgb, p.region)), 1.0, "roi")
    box = (0, 0, w, h)
    return (region_alpha(rgb, selfie, box, refine=False, guide="gray"),
            region_alpha(rgb, matter._pose(rgb, p.region), box, refine=False, guide="gray"))  # fmt: skip


def _tint(rgb: np.ndarray, alpha: np.ndarray, colour: tuple[float, float, float], label: str) -> np.ndarray:
    out = rgb * (1 - 0.6 * alpha[..., None]) + np.float32(colour) * 0.6 * alpha[..., None]
    out = (np.clip(out, 0, 1) * 255).astype(np.uint8)[..., ::-1].copy()
    cv2.putText(out, label, (8, 24), cv2.FONT_HERSHEY_SIMPLEX, 0.7, (255, 255, 255), 2)
    return out


def per_photo(matter: M.PersonMatter, names: list[str], out: Path | None) -> None:
    root = PME.data_root()
    for name in names:
        path = root / "photos" / f"{name}.jpg"
        rgb = PME.read_rgb(path)
        gt = PME.read_mask(path.with_name(f"{name}_mask.png"), rgb.shape[:2])
        with reductions_shared(rgb):
            people = matter.people(rgb, name)
            alpha = matter.alpha(rgb, people)
            answers = dict(zip(("selfie whole", "pose whole"), _whole(matter, rgb), strict=True))
            for i, p in enumerate(people):
                s, q = _framed(matter, rgb, p)
                answers[f"selfie framed on {i}"], answers[f"pose framed on {i}"] = s, q
        ours = alpha >= 0.5
        outside = int((ours & ~gt).sum())
        print(f"{name}: IoU {PME.iou(ours, gt):.4f}, matte {int(ours.sum())} px, outside the mask {outside}")
        for i, p in enumerate(people):
            print(f"  person {i}: {p.source}, presence {p.presence:.3f}, region {[round(v) for v in p.region.box()]}")
        for label, a in answers.items():
            held = ours & (a >= 0.5)
            print(f"  {label:18s} holds {held.sum() / max(ours.sum(), 1):.3f} of the matte, "
                  f"{int((held & ~gt).sum())} px of it outside the mask")  # fmt: skip
        for rule in AB.RULES:
            with AB.switched_off(rule):
                try:
                    off = matter(rgb, name) >= 0.5
                except RelightError:
                    off = np.zeros_like(ours)
            if (off != ours).any():
                print(f"  {rule:18s} off: IoU {PME.iou(off, gt):.4f}, outside the mask {int((off & ~gt).sum())}")
        if out is not None:
            tiles = [
                _tint(rgb, np.zeros_like(alpha), (0, 0, 0), "photo"),
                _tint(rgb, gt.astype(np.float32), (0, 1, 0), "service mask"),
                _tint(rgb, alpha, (1, 0, 1), "ours"),
            ]
            tiles += [_tint(rgb, a, (0, 0.6, 1) if k.startswith("selfie") else (1, 0.5, 0), k)
                      for k, a in answers.items()]  # fmt: skip
            tiles += [np.zeros_like(tiles[0])] * (-len(tiles) % 3)
            grid = np.concatenate([np.concatenate(tiles[i : i + 3], 1) for i in range(0, len(tiles), 3)], 0)
            out.mkdir(parents=True, exist_ok=True)
            cv2.imwrite(str(out / f"{name}_graphs.png"), grid)


def backed_pieces(matter: M.PersonMatter, dump: Path | None = None) -> None:
    """--backed (module docstring); ``dump``: every piece as JSON there, with its region's box and up to DUMP_POINTS of
    its pixels' photo coordinates (for benchmarks/skeleton_reach.py --pieces)."""
    root = PME.data_root()
    listed = PME.items(root, "photos")
    halves = PME.half_of([n for n, _, _ in listed])
    calls: list[tuple[Person, np.ndarray, np.ndarray]] = []
    backed = PM.backed

    def spy(roi, rgb, person):
        seen = roi_prob(roi, rgb, person.region)
        low = np.float32(np.log(CP._BACKED / (1.0 - CP._BACKED)))
        calls.append((person, seen, (seen > 0.5) & (person.logits > low) & (person.logits < 1.0)))
        return backed(roi, rgb, person)

    rows = []
    PM.backed = spy
    try:
        for name, path, mask in listed:
            rgb = PME.read_rgb(path)
            gt = PME.read_mask(mask, rgb.shape[:2])
            h, w = gt.shape
            calls.clear()
            try:
                matter(rgb, name)
            except RelightError:
                continue
            whole = PME.whole_image(matter.roi, rgb, "segmentation", logits=False)
            for person, seen, lift in calls:
                xs, ys = canvas_points(person.region)
                xi, yi = np.round(xs - 0.5).astype(int), np.round(ys - 0.5).astype(int)
                inside = (xi >= 0) & (xi < w) & (yi >= 0) & (yi < h)
                held, wh = np.zeros(xs.shape, bool), np.zeros(xs.shape, np.float32)
                held[inside], wh[inside] = gt[yi[inside], xi[inside]], whole[yi[inside], xi[inside]]
                canvas = crop_region(rgb, person.region)
                prob = sigmoid(person.logits)
                sure = (prob > 0.5) & inside
                body = canvas[sure].mean(0) if sure.any() else np.zeros(3, np.float32)
                n, lab = cv2.connectedComponents(lift.astype(np.uint8), connectivity=8)
                px = (person.region.side / 256) ** 2
                for c in range(1, n):
                    m = (lab == c) & inside
                    if m.sum() < 4:
                        continue
                    ring = cv2.dilate(m.astype(np.uint8), np.ones((RING, RING), np.uint8)).astype(bool)
                    ring &= ~lift & ~sure & inside
                    col = canvas[m].mean(0)
                    back = float(np.linalg.norm(col - canvas[ring].mean(0))) if ring.sum() >= 4 else np.inf
                    rows.append(
                        dict(
                            name=name,
                            half=halves[name],
                            area=float(m.sum() * px),
                            held=float(held[m].mean()),
                            pose=float(prob[m].mean()),
                            framed=float(seen[m].mean()),
                            whole=float(wh[m].mean()),
                            back=back,
                            body=float(np.linalg.norm(col - body)),
                        )
                    )
                    if dump is not None:
                        pick = np.linspace(0, m.sum() - 1, min(int(m.sum()), DUMP_POINTS)).astype(int)
                        rows[-1].update(region=[float(v) for v in person.region.box()],
                                        xs=xs[m][pick].tolist(), ys=ys[m][pick].tolist())  # fmt: skip
    finally:
        PM.backed = backed
    if dump is not None:
        dump.write_text(json.dumps([{k: (None if v == np.inf else v) for k, v in r.items()} for r in rows]))
    for hv in "AB":
        s = [r for r in rows if r["half"] == hv]
        person = sum(r["area"] * r["held"] for r in s)
        print(f"half {hv}: {len(s)} pieces lifted, {person:.0f} px the mask holds, "
              f"{sum(r['area'] for r in s) - person:.0f} px it leaves")  # fmt: skip
        for ratio in RATIO:
            for least in MIN_AREA:
                d = [r for r in s if r["back"] < ratio * r["body"] and r["area"] >= least]
                fg = sum(r["area"] * r["held"] for r in d)
                print(
                    f"  dropped where background-coloured (ring < {ratio} x person), pieces >= {least} px: "
                    f"{len(d)} pieces, person {fg:.0f} px, background {sum(r['area'] for r in d) - fg:.0f} px"
                )
    print("pieces over 2000 px mostly outside the mask:")
    for r in sorted(rows, key=lambda r: -r["area"] * (1 - r["held"])):
        if r["area"] > 2000 and r["held"] < 0.5:
            print(
                f"  {r['name']} ({r['half']}): {r['area']:.0f} px, mask holds {r['held']:.2f}, pose {r['pose']:.2f}, "
                f"selfie framed {r['framed']:.2f}, whole {r['whole']:.2f}"
            )


def portrait_parts(matter: M.PersonMatter) -> None:
    """--portraits (module docstring)."""
    root = PME.data_root()
    listed = PME.items(root, "photos")
    halves = PME.half_of([n for n, _, _ in listed])
    found = []
    for name, path, mask in listed:
        rgb = PME.read_rgb(path)
        gt = PME.read_mask(mask, rgb.shape[:2])
        with reductions_shared(rgb):
            people = matter.people(rgb, name)
            portraits = [p for p in people if p.source == "roi"]
            if not portraits:
                continue
            ours = matter.alpha(rgb, people) >= 0.5
            pose = PME.whole_image(matter.pose, rgb, "segmentation", logits=True)
            for p in portraits:
                pose = np.maximum(pose, _framed(matter, rgb, p)[1])
        left = (ours & (pose < POSE_LEAVES)).astype(np.uint8)
        n, lab, stats, _ = cv2.connectedComponentsWithStats(left, connectivity=8)
        for c in range(1, n):
            share = stats[c, 4] / max(ours.sum(), 1)
            if share >= PART_MIN:
                found.append((name, halves[name], int(stats[c, 4]), float(share), float(gt[lab == c].mean())))
    for hv in "AB":
        s = [f for f in found if f[1] == hv]
        held = sum(f[2] * f[4] for f in s)
        print(
            f"half {hv}: {len(s)} parts >= {PART_MIN:.0%} of a portrait's matte that the pose graph leaves, "
            f"{held:.0f} px the mask holds, {sum(f[2] for f in s) - held:.0f} px it leaves"
        )
    for name, hv, area, share, held in sorted(found, key=lambda f: -f[3]):
        print(f"  {name} ({hv}): {area} px, {share:.3f} of the matte, mask holds {held:.2f}")


def _longest_straight(mask: np.ndarray) -> float:
    """The longest straight run of ``mask``'s outline off the photo's border, as a share of the photo's diagonal."""
    h, w = mask.shape
    edge = cv2.morphologyEx(mask.astype(np.uint8), cv2.MORPH_GRADIENT, np.ones((3, 3), np.uint8))
    edge[:3], edge[-3:], edge[:, :3], edge[:, -3:] = 0, 0, 0, 0
    diag = float(np.hypot(h, w))
    lines = cv2.HoughLinesP(edge * 255, 1, np.pi / 180, threshold=40, minLineLength=int(0.08 * diag), maxLineGap=3)
    if lines is None:
        return 0.0
    seg = lines.reshape(-1, 4).astype(np.float64)
    return float(np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1]).max() / diag)


def straight_runs(matter: M.PersonMatter, save: Path | None) -> None:
    """--straight (module docstring)."""
    root = PME.data_root()
    listed = PME.items(root, "photos")
    halves = PME.half_of([n for n, _, _ in listed])
    runs = {}
    for name, alpha, gt in PME.matted(matter, listed):
        runs[name] = (_longest_straight(alpha >= 0.5), _longest_straight(gt))
        if save is not None:
            save.mkdir(parents=True, exist_ok=True)
            np.save(save / f"{name}.npy", (alpha * 255).astype(np.uint8))
    order = sorted(runs, key=lambda n: -runs[n][0])
    for hv in "AB":
        v = np.array([runs[n] for n in runs if halves[n] == hv])
        ours, mask = np.median(v[:, 0]), np.median(v[:, 1])
        print(f"half {hv}: longest straight run, median ours {ours:.3f}, the mask's {mask:.3f}")
    for name in order[:10] + [n for n in ("p186", "p209", "p255", "p273") if n in runs]:
        print(f"  {name} ({halves[name]}): ours {runs[name][0]:.3f}, mask {runs[name][1]:.3f}, "
              f"rank {order.index(name) + 1} of {len(order)}")  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", default="", help="comma list of photo names (people_masks/photos): per-photo figures")
    ap.add_argument("--out", type=Path, help="with --only: a sheet per photo here (under /tmp)")
    ap.add_argument("--backed", action="store_true", help="what _completion.backed lifts, over the photos")
    ap.add_argument("--dump", type=Path, help="with --backed: the pieces as JSON here (under /tmp)")
    ap.add_argument("--portraits", action="store_true", help="what a portrait holds and the pose graph leaves")
    ap.add_argument("--straight", action="store_true", help="the longest straight run of each matte's outline")
    ap.add_argument("--save-mattes", type=Path, help="with --straight: each matte as uint8 .npy here (under /tmp)")
    args = ap.parse_args(argv)
    if not (args.only or args.backed or args.portraits or args.straight):
        ap.error("nothing to do: --only, --backed, --portraits or --straight")
    AB.memoise_graphs()
    matter = M.PersonMatter(person="largest")
    if args.only:
        per_photo(matter, [n for n in args.only.split(",") if n], args.out)
    if args.backed:
        backed_pieces(matter, args.dump)
    if args.portraits:
        portrait_parts(matter)
    if args.straight:
        straight_runs(matter, args.save_mattes)
    return 0


if __name__ == "__main__":
    sys.exit(main())
