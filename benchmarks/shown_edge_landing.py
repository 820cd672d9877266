"""Where the shown edge moves the automatic matte, against people_masks' service masks (inner26).

    python benchmarks/shown_edge_landing.py [--half A|B|AB] [--n 0] [--set NAME=VALUE ...] [--worst 8]

For each photo of ``people_masks/photos`` (``--half``; ``--n`` > 0: the first n of them) the automatic matte and
its soft edge as the photo shows it (``relight.compose.shown_edge``, what the relit person goes over their own photo
with). Where the shown edge lowers the matte (alpha - shown > 0), the photo's service mask (a second opinion, not
truth: its outline runs about 1 px past the edge's half mix) says where the lowering lands: on background (outside
the mask grown by 1 px), on the person (inside it shrunk by 2 px) or between; likewise where it raises the matte.
``left``: the alpha the shown edge still holds on background within ``BAND`` px inside its own 0.5 line (what a
rule for background the matte holds there could take). Sums in pixels of alpha, per half and in all; the photos
where most is lowered on the person are listed. ``--set`` changes a constant of relight_rt.relight.compose for the
run (a threshold being tuned, ``--set _SHOWN_SPREAD=4``). Nothing of the data is written. About 3 min for both
halves (the Decomposition of each photo).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import cv2
import numpy as np

# real_photos puts this checkout (and benchmarks/) first on sys.path: the relight_rt imported below is this one
import real_photos  # noqa: F401

# isort: split
from _shared import missing, shared_path
from people_masks_eval import half_of, items, read_mask, read_rgb

import relight_rt
from relight_rt import RuntimeConfig
from relight_rt.relight import compose

BAND = 8  # px: ``left`` is counted this far inside the shown edge's 0.5 line
KEYS = ("lowered_background", "lowered_person", "lowered_between", "raised_background", "raised_person", "left")


def landing(alpha: np.ndarray, shown: np.ndarray, mask: np.ndarray) -> dict:
    """Where ``shown`` (h, w) lowers and raises the matte ``alpha`` against the service ``mask`` (h, w) uint8, and
    the alpha it leaves on background within ``BAND`` px inside its 0.5 line, in pixels of alpha."""
    ring = np.ones((3, 3), np.uint8)
    background = cv2.dilate(mask, ring) == 0
    person = cv2.erode(mask, ring, iterations=2) > 0
    lowered, raised = np.maximum(alpha - shown, 0), np.maximum(shown - alpha, 0)
    inside = (shown >= 0.5).astype(np.uint8)
    depth = cv2.distanceTransform(np.pad(inside, 1, constant_values=1), cv2.DIST_L2, 3)[1:-1, 1:-1]
    return {"lowered_background": float(lowered[background].sum()), "lowered_person": float(lowered[person].sum()),
            "lowered_between": float(lowered[~background & ~person].sum()),
            "raised_background": float(raised[background].sum()), "raised_person": float(raised[person].sum()),
            "left": float(shown[(inside > 0) & (depth <= BAND) & background].sum())}


def set_constants(pairs: list[str]) -> None:
    for pair in pairs:
        name, _, value = pair.partition("=")
        if not hasattr(compose, name):
            raise SystemExit(f"--set {pair}: relight_rt.relight.compose has no {name}")
        setattr(compose, name, type(getattr(compose, name))(float(value)))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--people", type=Path, default=shared_path("realdata", "people_masks"))
    p.add_argument("--half", choices=["A", "B", "AB"], default="AB")
    p.add_argument("--n", type=int, default=0)
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE")
    p.add_argument("--worst", type=int, default=8, help="list this many photos with the most lowered on the person")
    args = p.parse_args(argv)
    if not (args.people / "photos").is_dir():
        print(missing(args.people / "photos"), file=sys.stderr)
        return 2
    set_constants(args.set)
    listed = items(args.people, "photos")
    halves = half_of([n for n, _, _ in listed])
    listed = [x for x in listed if halves[x[0]] in args.half]
    if args.n > 0:
        listed = listed[: args.n]
    relighter = relight_rt.open(RuntimeConfig(device="cpu"))
    rows: dict[str, dict] = {}
    t0 = time.time()
    for name, photo, mask_path in listed:
        rgb = read_rgb(photo)
        try:
            dec = relighter.decompose(rgb)  # no mask: the automatic matte, as relight-rt relight
        except relight_rt.RelightError as e:
            print(f"{name}: {e}", file=sys.stderr)
            continue
        crop = dec.geometry.crop
        mask = crop(read_mask(mask_path, rgb.shape[:2]).astype(np.uint8))
        alpha = crop(dec.mask)
        rows[name] = {"half": halves[name], **landing(alpha, alpha if dec.edge is None else dec.edge, mask)}
    print(f"{len(rows)} photos, {time.time() - t0:.0f} s{' with ' + ' '.join(args.set) if args.set else ''}")
    for half in ("A", "B", "AB"):
        got = [r for r in rows.values() if r["half"] in half]
        if not got:
            continue
        t = {k: sum(r[k] for r in got) for k in KEYS}
        low = t["lowered_background"] + t["lowered_person"] + t["lowered_between"]
        print(f"half {half} ({len(got)} photos): lowered {low:.0f} px of alpha, on background "
              f"{t['lowered_background']:.0f} ({t['lowered_background'] / max(low, 1e-9):.0%}), on the person "
              f"{t['lowered_person']:.0f} ({t['lowered_person'] / max(low, 1e-9):.0%}); raised on background "
              f"{t['raised_background']:.0f}, on the person {t['raised_person']:.0f}; left on background within "
              f"{BAND} px inside the 0.5 line {t['left']:.0f}")
    for name, r in sorted(rows.items(), key=lambda kv: -kv[1]["lowered_person"])[: args.worst]:
        print(f"  {name} ({r['half']}): lowered on the person {r['lowered_person']:.1f}, on background "
              f"{r['lowered_background']:.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
