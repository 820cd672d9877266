"""Speed of ``composite``: a 2-megapixel person photo onto a 2-megapixel background, files in and out.

    python benchmarks/composite_bench.py --hdri ../shared/hdri --work runs/composite_bench [--repeats 7] \
        [--models DIR] [--map city.hdr] [--rim [auto]]

Makes the inputs once (the bundled example person, sRGB-encoded and enlarged to 1200 x 1700 = 2.04 MP with
its mask; a 1920 x 1080 = 2.07 MP perspective view of ../shared/hdri/city.hdr, or ``--map``), then times,
with the models loaded once (as a server or a batch would), the whole call: read both files, estimate the background's
light, decompose, relight, place, composite, write the result (PNG and JPEG). Median and min-max of
``--repeats`` runs after one untimed warm-up (and the median CPU time of the process per call, all threads:
what the call costs whatever else the machine runs); also the wall time of one ``relight-rt composite`` process
(interpreter start and model loading included). ``--rim``: with the back key's rim (composite's step 7; it
draws one only where the view reads back-lit, e.g. ``--map sunset.hdr``). Writes WORK/results.json.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

import relight_rt  # noqa: E402
from relight_rt import RuntimeConfig  # noqa: E402
from relight_rt.apps.scene import composite  # noqa: E402
from relight_rt.image.color import linear_to_srgb  # noqa: E402
from relight_rt.image.io import read_image, write_image  # noqa: E402


def make_inputs(hdri: Path, work: Path, place: str = "city.hdr") -> tuple[Path, Path, Path]:
    sys.path.insert(0, str(REPO / "benchmarks"))
    from scene_sheet import background

    work.mkdir(parents=True, exist_ok=True)
    rgba = read_image(REPO / "relight_rt" / "data" / "example.png", "example")
    rgb = linear_to_srgb(rgba[..., :3])
    h, w = rgba.shape[:2]
    side = 1700 / h
    size = (round(w * side), 1700)
    big = cv2.resize(rgb, size, interpolation=cv2.INTER_CUBIC)
    mask = cv2.resize(rgba[..., 3], size, interpolation=cv2.INTER_LINEAR)
    # pad/crop to 1200 wide, person centred
    canvas = np.zeros((1700, 1200, 3), np.float32)
    cmask = np.zeros((1700, 1200), np.float32)
    x0 = (1200 - size[0]) // 2
    src0 = max(0, -x0)
    dst0 = max(0, x0)
    n = min(size[0] - src0, 1200 - dst0)
    canvas[:, dst0 : dst0 + n] = big[:, src0 : src0 + n]
    cmask[:, dst0 : dst0 + n] = mask[:, src0 : src0 + n]
    canvas += (1 - cmask[..., None]) * np.float32(0.6)  # a plain grey studio wall around the person
    person, mask_path, bg_path = work / "person.jpg", work / "person_mask.png", work / "background.jpg"
    write_image(person, np.clip(canvas, 0, 1))
    write_image(mask_path, np.clip(cmask, 0, 1))
    bg = background(hdri / place, (1080, 1920))
    cv2.imwrite(str(bg_path), bg[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, 95])
    return person, mask_path, bg_path


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hdri", type=Path, required=True)
    ap.add_argument("--work", type=Path, required=True)
    ap.add_argument("--models", default=None)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--map", default="city.hdr", help="the background's map in --hdri")
    ap.add_argument("--rim", nargs="?", const="on", choices=("on", "auto"), default=None,
                    help="composite with rim=True (auto: rim='auto', composite --rim-auto)")  # fmt: skip
    args = ap.parse_args(argv)
    person, mask, bg = make_inputs(args.hdri, args.work, args.map)
    rim = {"on": True, "auto": "auto"}.get(args.rim, False)
    relighter = relight_rt.open(RuntimeConfig(models=args.models, device="cpu"))
    results = {}
    for suffix in (".jpg", ".png"):
        out = args.work / f"out{suffix}"

        def once(out=out):
            t, c = time.perf_counter(), time.process_time()
            image = composite(relighter, person, bg, mask=mask, shadow=True, rim=rim)
            write_image(out, image, protect=[person, mask, bg])
            return time.perf_counter() - t, time.process_time() - c

        once()
        runs = [once() for _ in range(args.repeats)]
        times = [w for w, _ in runs]
        results[f"api_{suffix[1:]}"] = {"median_s": statistics.median(times), "min_s": min(times), "max_s": max(times),
                                        "cpu_median_s": statistics.median(c for _, c in runs)}  # fmt: skip
    cmd = [sys.executable, "-m", "relight_rt", "composite", str(person), "--mask", str(mask), "--background", str(bg),
           "-o", str(args.work / "cli.jpg"), "--shadow", "--device", "cpu"]  # fmt: skip
    if args.rim:
        cmd += ["--rim-auto" if args.rim == "auto" else "--rim"]
    if args.models:
        cmd += ["--models", args.models]
    t = time.perf_counter()
    subprocess.run(cmd, check=True, cwd=REPO)
    results["cli_process_jpg_s"] = time.perf_counter() - t
    results["inputs"] = {"person": "1200x1700 JPEG + PNG mask", "background": f"1920x1080 JPEG of {args.map}",
                         "rim": args.rim}  # fmt: skip
    (args.work / "results.json").write_text(json.dumps(results, indent=1))
    print(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
