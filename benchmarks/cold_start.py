"""Where a cold relight of one photo spends its CPU time (issue 51, docs/BENCHMARKS.md): imports, opening the
Relighter, the first relight (the matte's graphs loaded, first runs, OpenCV's tables) and the same relight warm.

    PYTHONPATH=$PWD python benchmarks/cold_start.py PHOTO [--preset studio]

Run it as a fresh process each time (it measures the process's own first use); CPU seconds of all threads.
"""

import time

_C0 = time.process_time()

import argparse  # noqa: E402

import cv2  # noqa: E402, F401
import numpy  # noqa: E402, F401
import onnxruntime  # noqa: E402, F401

import relight_rt  # noqa: E402
import relight_rt.cli.relight  # noqa: E402, F401 - what `relight-rt relight` imports
import relight_rt.person.matting  # noqa: E402, F401
import relight_rt.relight.relighter  # noqa: E402, F401


def main() -> None:
    c1 = time.process_time()
    p = argparse.ArgumentParser()
    p.add_argument("photo")
    p.add_argument("--preset", default="studio")
    args = p.parse_args()
    r = relight_rt.open()
    c2 = time.process_time()
    r.relight(args.photo, args.preset)
    c3 = time.process_time()
    r.relight(args.photo, args.preset)
    c4 = time.process_time()
    print(f"imports {c1 - _C0:.3f}  open {c2 - c1:.3f}  first relight {c3 - c2:.3f}  warm relight {c4 - c3:.3f} "
          "(CPU s)")


if __name__ == "__main__":
    main()
