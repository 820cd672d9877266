"""Where the mirror rule (``shadow_fill.mirror_shadow``, ``MIRROR_DARK``) acts on real photos, and by how much.

    python benchmarks/mirror_rule_photos.py --out runs/mirror_photos [--stride 4] [--max-side 1000]

The photos of benchmarks/photo_faults.py (the reference photo and every ``--stride``-th people_masks photo with its
given mask, reduced to ``--max-side``; ../shared/realdata is for evaluation only), relit under the white side lamps
``LEFT`` and ``RIGHT`` of benchmarks/real_photos.py with the rule on and off (``MIRROR_DARK`` None, each its own
Decomposition). Per photo: the face meshes and their sizes in the person's window (network pixels), the rule's own
largest share (``mirror_shadow``'s maximum; its time, best of ``REPEATS``), and the relit photo's change from the
rule, in 8-bit levels (max over channels): its maximum and the pixels over 2 levels, under each lamp. Prints the
photos with a mesh, those the rule touches (any level), the largest change and the rule's time. Writes
OUT/mirror_photos.json. The data is for evaluation only: keep OUT out of the repository.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

# real_photos puts this checkout (and benchmarks/) first on sys.path: the relight_rt imported below is this one
from real_photos import LEFT, RIGHT

# isort: split
from _shared import shared_path, warn_missing
from photo_faults import read_mask, read_rgb

from relight_rt import Relighter, RuntimeConfig
from relight_rt.relight import shadow_fill

REPEATS = 5  # mirror_shadow timed this many times per photo, the best kept


def levels(rgb: np.ndarray) -> np.ndarray:
    return (np.clip(rgb, 0, 1) * 255 + 0.5).astype(np.int16)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--people", type=Path, default=shared_path("realdata", "people_masks"))
    p.add_argument("--reference", type=Path, default=shared_path("reference"))
    p.add_argument("--stride", type=int, default=4)
    p.add_argument("--max-side", type=int, default=1000)
    args = p.parse_args(argv)
    inputs = []
    sample = args.reference / "photo" / "sample.jpg"
    if sample.is_file():
        inputs.append(("sample", sample, sample.with_name("sample_mask.png")))
    else:
        warn_missing(sample, "the reference photo")
    if (args.people / "photos").is_dir():
        people = sorted((args.people / "photos").glob("*.jpg"))[:: args.stride]
        inputs += [(f.stem, f, f.with_name(f"{f.stem}_mask.png")) for f in people]
    else:
        warn_missing(args.people / "photos", "the people_masks photos")
    if not inputs:
        print("no photos (../shared/reference, ../shared/realdata/people_masks)", file=sys.stderr)
        return 2
    relighter = Relighter(RuntimeConfig(device="cpu"))
    args.out.mkdir(parents=True, exist_ok=True)
    rule, photos, t0 = shadow_fill.MIRROR_DARK, {}, time.time()
    for name, image, mask_file in inputs:
        rgb = read_rgb(image, args.max_side)
        mask = read_mask(mask_file, rgb.shape[:2])
        if (mask > 0.5).sum() < 2000:
            continue
        relit, row = {}, {}
        for on in (True, False):  # each its own Decomposition: what a relight caches depends on the rule
            shadow_fill.MIRROR_DARK = rule if on else None
            try:
                dec = relighter.decompose(rgb, mask)
                relit[on] = [levels(relighter.relight(dec, light)) for light in (LEFT, RIGHT)]
                if on:
                    own = relighter._factor.own(dec, with_residual=False)
                    row["sizes"] = [round(float(np.ptp(q[:, :2], axis=0).max()), 1) for q in own["face_points"]]
                    share, best = 0.0, None
                    if own["face_opening"] is not None and own["face_points"]:
                        shading = own["transport"] @ dec.white_light[:, 0]
                        face = own["face_skin"] | own["face_opening"]
                        for _ in range(REPEATS):
                            t = time.perf_counter()
                            found = shadow_fill.mirror_shadow(shading, own["face_opening"], face, own["face_points"])
                            t = time.perf_counter() - t
                            best = t if best is None else min(best, t)
                        share = float(found.max())
                    row["share"], row["ms"] = share, None if best is None else round(1e3 * best, 3)
            finally:
                shadow_fill.MIRROR_DARK = rule
        for light, a, b in zip(("LEFT", "RIGHT"), relit[True], relit[False], strict=True):
            d = np.abs(a - b).max(axis=2)
            row[light] = {"max": int(d.max()), "over_2": int((d > 2).sum())}
        photos[name] = row
        print(f"{name}: {row} {time.time() - t0:.0f} s", flush=True)
    (args.out / "mirror_photos.json").write_text(json.dumps(photos, indent=1))
    meshed = [n for n, r in photos.items() if r["sizes"]]
    touched = [n for n, r in photos.items() if max(r["LEFT"]["max"], r["RIGHT"]["max"]) > 0]
    worst = max(photos, key=lambda n: max(photos[n]["LEFT"]["max"], photos[n]["RIGHT"]["max"]))
    sizes = [s for r in photos.values() for s in r["sizes"]]
    print(f"{len(photos)} photos, {len(meshed)} with a face mesh (sizes {min(sizes, default=0):.0f}-"
          f"{max(sizes, default=0):.0f} network px, median {np.median(sizes) if sizes else 0:.0f}); the rule's share "
          f">= 0.25 on {sum(r['share'] >= 0.25 for r in photos.values())}; relit photos touched {len(touched)}, "
          f"over 2 levels {sum(r['LEFT']['over_2'] + r['RIGHT']['over_2'] > 0 for r in photos.values())}; largest "
          f"change {max(photos[worst]['LEFT']['max'], photos[worst]['RIGHT']['max'])} levels ({worst})")
    times = [r["ms"] for r in photos.values() if r["ms"] is not None]
    if times:
        print(f"mirror_shadow, best of {REPEATS} per photo: median {np.median(times):.2f} ms, max {max(times):.2f} ms "
              f"({len(times)} photos)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
