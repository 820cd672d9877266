"""Relight every photo of people_masks as a user would, and count the photos the product refuses (issue 48).

    python benchmarks/every_photo.py [--person auto|all] [--light night] [--set photos] [--limit N]

Each photo of ``../shared/realdata/people_masks/photos`` (both halves) is decomposed and relit under ``--light`` through
the public API with the automatic matte and the photo's own background, as ``relight-rt relight PHOTO`` does with no
mask beside it. A photo nobody chose should never be refused once a person is in it: every photo of the set holds one
(the service masked someone in each). Prints each refusal (its ``RelightError`` line) and any other exception, then
the count per half and the seconds per photo. Nothing of the data is written.

The matte alone is measured by people_masks_eval.py; this is the whole path (matte, people, stage 1, compositing),
which the matte's figures cannot see: before groups26, 5 of the 208 photos were refused with "mask is empty" (a group's
person whose share of the matte never reaches a half, handed to stage 1 as an empty mask); since, none.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from people_masks_eval import data_root, half_of, items  # noqa: E402

import relight_rt  # noqa: E402
from relight_rt import RelightError, RuntimeConfig  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--person", default="auto", choices=("auto", "all"), help="the matting mode (RuntimeConfig)")
    ap.add_argument("--light", default="night", help="a preset name (default night)")
    ap.add_argument("--set", default="photos", choices=("photos", "clip"))
    ap.add_argument("--limit", type=int, default=0, help="only the first N photos (0: all)")
    args = ap.parse_args(argv)

    listed = items(data_root(), args.set)
    if args.limit:
        listed = listed[: args.limit]
    halves = half_of([name for name, _, _ in items(data_root(), args.set)])
    runtime = relight_rt.open(RuntimeConfig(device="cpu", matting=args.person))
    refused: dict[str, list[str]] = {"A": [], "B": []}
    failed: list[str] = []
    start = time.perf_counter()
    for i, (name, path, _) in enumerate(listed, 1):
        try:
            runtime.relight(runtime.decompose(str(path)), args.light)  # the product's loader, as the CLI
        except RelightError as e:
            refused[halves[name]].append(name)
            print(f"{name} ({halves[name]}): refused: {e}", flush=True)
        except Exception as e:  # noqa: BLE001 - a crash is what this script is for finding
            failed.append(name)
            print(f"{name} ({halves[name]}): {type(e).__name__}: {e}", flush=True)
        if i % 25 == 0:
            print(f"  {i} / {len(listed)} photos, {time.perf_counter() - start:.0f} s", flush=True)
    n = {h: sum(halves[name] == h for name, _, _ in listed) for h in "AB"}
    seconds = (time.perf_counter() - start) / max(len(listed), 1)
    print(f"refused: A {len(refused['A'])} / {n['A']}, B {len(refused['B'])} / {n['B']}; other errors {len(failed)}; "
          f"--person {args.person}, {args.light}, {seconds:.2f} s a photo")
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
