"""Rules tried on the photos below the selfie graph (issue 48, matte23): ../shared/realdata/people_masks, evaluation.

    python benchmarks/matte_probes.py     # ~3 min: the matte and the two graphs once a photo, then the probes

Each probe is a rule replayed on the default matte's hard mask (alpha >= 0.5, kept as 8-bit) with the whole photo's
answers of the two bundled graphs (MediaPipe's selfie graph and the pose graph's segmentation, each on the photo
letterboxed to 256x256 as ``people_masks_eval.whole_image`` runs them: what the matter already has for a photo):

- ``drop``: parts of the matte that both graphs doubt (selfie < TS and pose < TP; 8-connected, MIN to 0.2x the
  matte's area) are left out; with ``gate`` G, only where the selfie answer's IoU with the matte is >= G (the whole
  photo sees the person, so a part it does not see is doubtful);
- ``add``: parts outside the matte both graphs see (selfie >= TS and pose >= TP), touching it, up to MAX x its area,
  are taken in.

For each setting: the change of the mean IoU on half A (the one thresholds are chosen on) and half B, the photos
below the selfie graph after it (42 before), and the photos it moves most. A rule is worth a place in the matter only
where A chooses it and B does not contradict it. Nothing of the data is written.
"""

from __future__ import annotations

import argparse
import itertools
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

DROP = {"TS": (0.01, 0.05, 0.1, 0.25), "TP": (0.05, 0.2, 0.5, 1.01), "MIN": (0.002, 0.01)}
GATED = {"TS": (0.01, 0.05, 0.2), "TP": (0.05, 0.2, 1.01), "MIN": (0.002, 0.01), "G": (0.8, 0.9)}
ADD = {"TS": (0.9, 0.97, 0.99), "TP": (0.0, 0.5, 0.9), "MAX": (0.05, 0.3, 1.0)}


def dropped(pred: np.ndarray, selfie: np.ndarray, pose: np.ndarray, ts: float, tp: float, least: float,
            gate: float | None = None) -> np.ndarray:  # fmt: skip
    """``pred`` less its parts that both graphs doubt (see the module's ``drop``)."""
    if gate is not None and iou(selfie >= 0.5, pred) < gate:
        return pred
    cand = pred & (selfie < ts) & (pose < tp)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(cand.astype(np.uint8), connectivity=8)
    total, out = pred.sum(), pred.copy()
    for i in range(1, n):
        if least * total <= stats[i, 4] <= 0.2 * total:
            out[labels == i] = False
    return out


def added(pred: np.ndarray, selfie: np.ndarray, pose: np.ndarray, ts: float, tp: float, most: float) -> np.ndarray:
    """``pred`` with the parts both graphs see joined to it (see the module's ``add``)."""
    cand = ~pred & (selfie >= ts) & (pose >= tp)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(cand.astype(np.uint8), connectivity=8)
    near = cv2.dilate(pred.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    total, out = pred.sum(), pred.copy()
    for i in range(1, n):
        part = labels == i
        if stats[i, 4] <= most * total and (part & near).any():
            out |= part
    return out


def main(argv: list[str] | None = None) -> int:
    argparse.ArgumentParser(description=__doc__.split("\n\n")[0]).parse_args(argv)
    root = data_root()
    listed = items(root, "photos")
    halves = half_of([n for n, _, _ in listed])
    matter = M.PersonMatter()
    seen: dict[str, tuple[np.ndarray, ...]] = {}
    for name, img, mask in listed:
        rgb = read_rgb(img)
        try:
            alpha = matter(rgb, name)
        except RelightError:
            alpha = np.zeros(rgb.shape[:2], np.float32)
        q = [(np.clip(m, 0, 1) * 255).astype(np.uint8) / 255.0 for m in (
            alpha, whole_image(matter.roi, rgb, "segmentation", logits=False),
            whole_image(matter.pose, rgb, "segmentation", logits=True))]  # fmt: skip
        seen[name] = (q[0] >= 0.5, q[1], q[2], read_mask(mask, rgb.shape[:2]))
    base = {n: iou(p, gt) for n, (p, _, _, gt) in seen.items()}
    selfie = {n: iou(s >= 0.5, gt) for n, (_, s, _, gt) in seen.items()}

    def report(label: str, rule) -> None:
        r = {n: iou(rule(p, s, q), gt) for n, (p, s, q, gt) in seen.items()}
        d = {h: np.mean([r[n] - base[n] for n in r if halves[n] == h]) for h in "AB"}
        moved = sorted((r[n] - base[n], n) for n in r if abs(r[n] - base[n]) > 1e-3)
        below = sum(r[n] < selfie[n] - 1e-9 for n in r)
        print(f"{label:34s} A {d['A']:+.5f} B {d['B']:+.5f} below {below:2d}  moved {len(moved):2d}: "
              + ", ".join(f"{n} {x:+.3f}" for x, n in moved[:3] + moved[-3:]))  # fmt: skip

    print(f"matte: A {np.mean([base[n] for n in base if halves[n] == 'A']):.5f}, "
          f"B {np.mean([base[n] for n in base if halves[n] == 'B']):.5f}, "
          f"below the selfie graph {sum(base[n] < selfie[n] - 1e-9 for n in base)}")  # fmt: skip
    for ts, tp, least in itertools.product(*DROP.values()):
        report(f"drop ts {ts} tp {tp} min {least}", lambda p, s, q, a=(ts, tp, least): dropped(p, s, q, *a))
    for ts, tp, least, gate in itertools.product(*GATED.values()):
        report(f"drop ts {ts} tp {tp} min {least} gate {gate}",
               lambda p, s, q, a=(ts, tp, least, gate): dropped(p, s, q, *a))  # fmt: skip
    for ts, tp, most in itertools.product(*ADD.values()):
        report(f"add ts {ts} tp {tp} max {most}", lambda p, s, q, a=(ts, tp, most): added(p, s, q, *a))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
