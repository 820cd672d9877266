"""How much of a relit person is at the limit under each preset (issue 32: where "auto" exposure flattens a face).

    python benchmarks/clipped_share.py PHOTO [PHOTO ...] [--limit 0.99]

Each photo is decomposed with the automatic matte and relit under every preset (``relight_rt.lights``) at the
default exposure; printed per photo and as a mean: the share of the person's pixels (alpha > 0.5) whose brightest
channel is at or above ``--limit``, in the input and under each preset. Where that share is large the lit side
is a flat colour at the limit (the highlight shoulder of relight_rt.relight.relighter holds it there), and shading
beside it reads as a blotch.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("photos", nargs="+", type=Path)
    parser.add_argument("--limit", type=float, default=0.99)
    args = parser.parse_args(argv)
    import relight_rt
    from relight_rt import RelightError, RuntimeConfig, lights
    from relight_rt.image.io import read_image

    relighter = relight_rt.open(RuntimeConfig(device="cpu"))
    presets = list(lights.list_presets())
    print("photo".ljust(22) + " ".join(name[:8].rjust(8) for name in ["input", *presets]))
    rows = []
    for path in args.photos:
        try:
            image = read_image(path, "photo")[..., :3]
            dec = relighter.decompose(image, "auto")
        except RelightError as exc:
            print(f"{path.name}: {exc}", file=sys.stderr)
            continue
        person = np.asarray(dec.mask) > 0.5
        row = [float(np.mean(image[person].max(axis=1) >= args.limit))]
        for name in presets:
            out = np.asarray(relighter.relight(dec, lights.preset(name)), np.float32)
            row.append(float(np.mean(out[person].max(axis=1) >= args.limit)))
        rows.append(row)
        print(path.name[:21].ljust(22) + " ".join(f"{v:8.3f}" for v in row), flush=True)
    if rows:
        print("mean".ljust(22) + " ".join(f"{v:8.3f}" for v in np.mean(rows, axis=0)))
    return 0 if rows else 2


if __name__ == "__main__":
    sys.exit(main())
