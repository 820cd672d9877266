"""Where the default matte's errors lie on people_masks' photos (issue 48): ../shared/realdata/people_masks, evaluation.

    python benchmarks/matte_fault_kinds.py                  # ~4 min: the split per half, the photos below the selfie
    python benchmarks/matte_fault_kinds.py --border 0.5 0.9 # ... and what a bottom-border rule would do (offline)
    python benchmarks/matte_fault_kinds.py --ceiling [--inset 1]   # ... and what following the selfie graph could win

Each photo's errors against its service mask (alpha >= 0.5 against mask >= 0.5, as benchmarks/people_masks_eval.py)
are split six ways: misses and additions within BAND px of the mask's outline (where the service's outline sits ~1 px
outside the edge's half mix: a convention, not a fault), and away from it, misses and additions each split into the
8-connected parts touching the photo's bottom border and the rest. For each kind, the IoU the photo would have with
those pixels right, less its IoU, averaged over the half: how much of the mean IoU that kind of error costs. The same
for MediaPipe's selfie graph on the whole photo (the ``selfie`` method).

Then, for the photos where the default matte is below the selfie graph, the matte without its refinement
(``refine=False``): where that is at or above the selfie graph, the loss is the outline's convention (the refined
edge goes to the half mix, the service's outline one pixel outside).

``--border T MEAN`` replays, on the mattes already made, the rule "add the parts of the selfie graph's whole-photo
answer (>= T) outside the matte that touch the bottom border and the matte, where the matte reaches the bottom border,
when the graph's mean over the part is >= MEAN": clothing the frame cuts that the matte misses (matte12: half A does not
move, so it cannot choose the rule).

``--ceiling`` (:func:`selfie_ceiling`, matte30): where ours and the selfie graph disagree, four kinds (within BAND px of
the mask's outline or away from it; ours takes what the selfie graph leaves, or misses what it has), and per kind and
half the change of the mean IoU if ours took the selfie graph's answer there: on every photo, on the photos it helps
only (what a perfect rule following the selfie graph on that kind could win at most), on those it hurts only.
``--inset PX`` erodes the service masks first (their outline's ~1-px rim). Nothing of the data is written.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

from people_masks_eval import data_root, half_of, iou, items, read_mask, read_rgb, whole_image  # noqa: E402

from relight_rt import RelightError  # noqa: E402
from relight_rt.person import matting as M  # noqa: E402

BAND = 2  # px: errors this close to the mask's outline are the outline's
KINDS = ("band miss", "band add", "bottom miss", "other miss", "bottom add", "other add")


def split(pred: np.ndarray, gt: np.ndarray) -> dict[str, float]:
    """IoU of ``pred`` against ``gt`` and, per kind (KINDS), what the IoU would gain with that kind's pixels right."""
    g = gt.astype(np.uint8)
    dist = np.where(gt, cv2.distanceTransform(g, cv2.DIST_L2, 3), cv2.distanceTransform(1 - g, cv2.DIST_L2, 3))
    band = dist <= BAND
    miss, add = gt & ~pred, pred & ~gt

    def at_bottom(err: np.ndarray) -> np.ndarray:
        _, labels = cv2.connectedComponents(err.astype(np.uint8), connectivity=8)
        touch = np.unique(labels[-1][err[-1]])
        return np.isin(labels, touch[touch > 0])

    far_miss, far_add = miss & ~band, add & ~band
    counts = {
        "band miss": (miss & band).sum(), "band add": (add & band).sum(),
        "bottom miss": (far_miss & at_bottom(far_miss)).sum(), "other miss": (far_miss & ~at_bottom(far_miss)).sum(),
        "bottom add": (far_add & at_bottom(far_add)).sum(), "other add": (far_add & ~at_bottom(far_add)).sum(),
    }  # fmt: skip
    inter, union = float((pred & gt).sum()), float((pred | gt).sum())
    out = {"iou": iou(pred, gt)}
    for k, n in counts.items():
        out[k] = ((inter + n) / union if "miss" in k else inter / max(union - n, 1.0)) - out["iou"] if union else 0.0
    return out


SIDES = ("band: ours adds", "band: ours misses", "away: ours adds", "away: ours misses")


def selfie_ceiling(pred: np.ndarray, selfie: np.ndarray, gt: np.ndarray) -> dict[str, float]:
    """Where ``pred`` (ours) and ``selfie`` (the selfie graph's hard mask) disagree, split four ways (SIDES: within
    BAND px of ``gt``'s outline or away from it; ours takes the pixel and the selfie graph leaves it, or the other way):
    the IoU ``pred`` would gain (or lose) taking the selfie graph's answer on that kind's pixels alone. A photo's gain
    on a kind is what a rule following the selfie graph there could win at most on that photo (``--ceiling``)."""
    g = gt.astype(np.uint8)
    dist = np.where(gt, cv2.distanceTransform(g, cv2.DIST_L2, 3), cv2.distanceTransform(1 - g, cv2.DIST_L2, 3))
    band, base, out = dist <= BAND, iou(pred, gt), {}
    for k, where in zip(SIDES, (band & pred & ~selfie, band & ~pred & selfie, ~band & pred & ~selfie,
                                ~band & ~pred & selfie), strict=True):  # fmt: skip
        out[k] = iou(np.where(where, selfie, pred), gt) - base
    return out


def border_rule(pred: np.ndarray, prob: np.ndarray, t: float, mean: float) -> np.ndarray:
    """``pred`` with the parts of ``prob`` >= t outside it that touch the bottom border and ``pred`` (which reaches the
    bottom border), where ``prob``'s mean over the part is >= mean (``--border``)."""
    if not pred[-1].any():
        return pred
    cand = (prob >= t) & ~pred
    _, labels = cv2.connectedComponents(cand.astype(np.uint8), connectivity=8)
    near = cv2.dilate(pred.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    out = pred.copy()
    for i in np.unique(labels[-1][cand[-1]]):
        part = labels == i
        if i > 0 and (part & near).any() and prob[part].mean() >= mean:
            out |= part
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--border", nargs=2, type=float, metavar=("T", "MEAN"), help="replay the bottom-border rule")
    ap.add_argument("--ceiling", action="store_true", help="what following the selfie graph could gain, per kind")
    ap.add_argument("--inset", type=int, default=0, metavar="PX", help="erode the service masks by PX pixels first")
    args = ap.parse_args(argv)
    root = data_root()
    listed = items(root, "photos")
    halves = half_of([n for n, _, _ in listed])
    matter, unrefined = M.PersonMatter(), M.PersonMatter(refine=False)
    rows: dict[str, dict] = {}
    for name, img, mask in listed:
        rgb = read_rgb(img)
        gt = read_mask(mask, rgb.shape[:2])
        if args.inset:
            gt = cv2.erode(gt.astype(np.uint8), np.ones((2 * args.inset + 1,) * 2, np.uint8)) > 0
        try:
            ours = matter(rgb, name) >= 0.5
        except RelightError:
            ours = np.zeros(gt.shape, bool)
        prob = whole_image(matter.roi, rgb, "segmentation", logits=False)
        row = {"ours": split(ours, gt), "selfie": split(prob >= 0.5, gt)}
        if row["ours"]["iou"] < row["selfie"]["iou"] - 1e-9:
            try:
                row["unrefined"] = iou(unrefined(rgb, name) >= 0.5, gt)
            except RelightError:
                row["unrefined"] = 0.0
        if args.border:
            row["border"] = iou(border_rule(ours, prob, *args.border), gt)
        if args.ceiling:
            row["ceiling"] = selfie_ceiling(ours, prob >= 0.5, gt)
        rows[name] = row
    print(f"what each kind of error costs the mean IoU (photos; BAND = {BAND} px)")
    print(f"{'method':7s} half  mean IoU  " + "  ".join(f"{k:>11s}" for k in KINDS))
    for who in ("ours", "selfie"):
        for h in "AB":
            part = [r[who] for n, r in rows.items() if halves[n] == h]
            cells = "  ".join(f"{np.mean([p[k] for p in part]):11.4f}" for k in KINDS)
            print(f"{who:7s} {h}     {np.mean([p['iou'] for p in part]):.4f}    {cells}")
    below = sorted(
        (n for n in rows if "unrefined" in rows[n]), key=lambda n: rows[n]["ours"]["iou"] - rows[n]["selfie"]["iou"]
    )
    outline = [n for n in below if rows[n]["unrefined"] >= rows[n]["selfie"]["iou"] - 5e-4]
    loss = sum(rows[n]["selfie"]["iou"] - rows[n]["ours"]["iou"] for n in outline)
    print(f"below the selfie graph: {len(below)}; at or above it unrefined (the outline's convention): {len(outline)}, "
          f"loss summed {loss:.3f}")  # fmt: skip
    print("the others (ours / unrefined / selfie): " + ", ".join(
        f"{n} {halves[n]} {rows[n]['ours']['iou']:.3f}/{rows[n]['unrefined']:.3f}/{rows[n]['selfie']['iou']:.3f}"
        for n in below if n not in outline))  # fmt: skip
    if args.ceiling:
        print(
            "following the selfie graph on one kind of disagreement, change of the mean IoU: all photos / the "
            "photos it helps only (a perfect rule's ceiling) / those it hurts only; the photos helped by > 0.005"
        )
        for k in SIDES:
            for h in "AB":
                v = {n: r["ceiling"][k] for n, r in rows.items() if halves[n] == h}
                d = np.array(list(v.values()))
                gain, cost = d[d > 0].sum() / d.size, d[d < 0].sum() / d.size
                best = sorted((n for n in v if v[n] > 0.005), key=lambda n: -v[n])
                print(f"  {k:18s} {h}  {d.mean():+.5f} / {gain:+.5f} / {cost:+.5f}  {len(best)}: "
                      + ", ".join(f"{n} {v[n]:+.3f}" for n in best[:8]))  # fmt: skip
    if args.border:
        for h in "AB":
            names = [n for n in rows if halves[n] == h]
            before, after = (
                np.mean([rows[n]["ours"]["iou"] for n in names]),
                np.mean([rows[n]["border"] for n in names]),
            )
            moved = [(n, rows[n]["border"] - rows[n]["ours"]["iou"]) for n in names]
            moved = sorted((m for m in moved if abs(m[1]) > 1e-4), key=lambda m: m[1])
            print(f"border rule {args.border}: half {h} {before:.4f} -> {after:.4f} "
                  + ", ".join(f"{n} {d:+.3f}" for n, d in moved))  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
