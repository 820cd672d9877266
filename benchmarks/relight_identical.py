"""Whether this checkout relights photos to the same pixels as another one (a refactor's check), bit for bit.

    PYTHONPATH=$PWD python benchmarks/relight_identical.py OTHER_CHECKOUT PHOTO [PHOTO ...] [--presets studio,rim]

Each checkout runs in its own process (``PYTHONPATH`` set to it): the bundled models, the automatic matte, one
``decompose`` per photo, then ``relight`` of that Decomposition under each preset; the float32 results go to a
temporary .npz (outside the repository: the photos may be evaluation data) and are compared. Prints, per photo and
preset, whether the two are equal and the largest difference; exits 1 when any differs.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

PRESETS = "studio,window-left,campfire,night,rim"


def child(out: str, presets: list[str], photos: list[str]) -> None:
    import numpy as np

    import relight_rt
    from relight_rt import lights
    from relight_rt.image.io import read_image

    r = relight_rt.open()
    results = {}
    for i, photo in enumerate(photos):
        dec = r.decompose(read_image(photo))
        for name in presets:
            results[f"{i}:{name}"] = r.relight(dec, lights.preset(name))
    np.savez(out, **results)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("other", help="the other checkout (its root: relight_rt/ inside)")
    p.add_argument("photos", nargs="+")
    p.add_argument("--presets", default=PRESETS)
    p.add_argument("--child", default=None, help=argparse.SUPPRESS)
    args = p.parse_args()
    presets = args.presets.split(",")
    photos = [str(Path(x).resolve()) for x in args.photos]
    if args.child:
        child(args.child, presets, photos)
        return 0

    import numpy as np

    here = Path(__file__).resolve().parents[1]
    with tempfile.TemporaryDirectory() as tmp:
        saved = []
        for k, root in enumerate((here, Path(args.other).resolve())):
            out = str(Path(tmp) / f"{k}.npz")
            env = {**os.environ, "PYTHONPATH": str(root)}
            subprocess.run([sys.executable, str(Path(__file__).resolve()), str(root), *photos, "--presets",
                            args.presets, "--child", out], check=True, env=env, cwd=root)  # fmt: skip
            saved.append(np.load(out))
        a, b = saved
        same = True
        for key in a.files:
            i, name = key.split(":")
            equal = a[key].shape == b[key].shape and np.array_equal(a[key], b[key])
            worst = float(np.abs(a[key] - b[key]).max()) if a[key].shape == b[key].shape else float("inf")
            verdict = "identical" if equal else "DIFFERENT"
            print(f"{Path(photos[int(i)]).name} {name}: {verdict} (max |diff| {worst:.3g})")
            same &= equal
    print("all identical" if same else "some differ")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
