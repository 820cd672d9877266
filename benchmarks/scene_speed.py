"""Speed of ``composite --view``: a 2-MP person photo into a 2-MP view of a panorama, files in and out (issue 49).

    python benchmarks/scene_speed.py --hdri ../shared/hdri --work runs/scene_speed [--repeats 7] [--map sunset.hdr]
        [--view 20,0] [--models DIR]

The person is composite_bench.py's (the bundled example, 1200 x 1700 = 2.04 MP JPEG with a PNG mask); the plate a
1920 x 1080 = 2.07 MP view of ``--map``. With the models loaded once (as a server or a batch would), each timed call
reads the person, its mask and the panorama file, renders the plate, relights, places and composites the person
and writes a JPEG: ``composite_panorama`` + ``write_image``. Median and min-max of ``--repeats`` calls after one
untimed warm-up, and the median CPU time of the process per call (all threads: what the call costs whatever else
the machine runs), then one call's split by step (the plate; the photo's decode and matte; stage 1; relight; place,
camera match, shadows and blending; the write). Writes WORK/results.json.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

import relight_rt  # noqa: E402
from relight_rt import RuntimeConfig  # noqa: E402
from relight_rt import scene as scene_mod  # noqa: E402
from relight_rt.apps import panorama as pano_mod  # noqa: E402
from relight_rt.image.io import write_image  # noqa: E402

SIZE = (1920, 1080)


def split(relighter, call) -> dict[str, float]:
    """Wall seconds of each step of one ``call()``, by wrapping the functions it goes through."""
    spent: dict[str, float] = {}
    wrapped = []

    def wrap(owner, name, label):
        fn = getattr(owner, name)

        def timed(*a, **k):
            t = time.perf_counter()
            try:
                return fn(*a, **k)
            finally:
                spent[label] = spent.get(label, 0.0) + time.perf_counter() - t

        setattr(owner, name, timed)
        wrapped.append((owner, name, fn))

    wrap(pano_mod, "panorama_view", "plate and light")
    wrap(scene_mod, "decode_person", "decode photo")
    wrap(scene_mod, "matte_on_the_photo", "matte")
    wrap(relighter, "decompose", "decompose (stage 1)")
    wrap(relighter, "relight", "relight (stage 2)")
    wrap(scene_mod, "place", "place")
    wrap(scene_mod, "camera_match", "camera match")
    wrap(scene_mod, "grade", "grade + encode")
    wrap(sys.modules[__name__], "write_image", "write JPEG")
    t = time.perf_counter()
    try:
        call()
    finally:
        for owner, name, fn in wrapped:
            setattr(owner, name, fn)
    spent["total"] = time.perf_counter() - t
    spent["rest"] = spent["total"] - sum(v for k, v in spent.items() if k != "total")
    return {k: round(v, 3) for k, v in spent.items()}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hdri", type=Path, required=True)
    ap.add_argument("--work", type=Path, required=True)
    ap.add_argument("--models", default=None)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--map", default="sunset.hdr")
    ap.add_argument("--view", default="20,0")
    args = ap.parse_args(argv)
    sys.path.insert(0, str(REPO / "benchmarks"))
    from composite_bench import make_inputs

    person, mask, _ = make_inputs(args.hdri, args.work, args.map)
    pano = args.hdri / args.map
    out = args.work / "out.jpg"
    relighter = relight_rt.open(RuntimeConfig(models=args.models, device="cpu"))

    def call():
        image = pano_mod.composite_panorama(relighter, person, pano, args.view, size=SIZE, mask=mask)
        write_image(out, image, protect=[person, mask, pano])

    def once():
        t, c = time.perf_counter(), time.process_time()
        call()
        return time.perf_counter() - t, time.process_time() - c

    once()
    runs = [once() for _ in range(args.repeats)]
    walls = [w for w, _ in runs]
    results = {
        "median_s": round(statistics.median(walls), 3), "min_s": round(min(walls), 3), "max_s": round(max(walls), 3),
        "cpu_median_s": round(statistics.median(c for _, c in runs), 3), "split_s": split(relighter, call),
        "inputs": {"person": "1200x1700 JPEG + PNG mask", "plate": f"{SIZE[0]}x{SIZE[1]} view {args.view} of "
                   f"{args.map}", "output": "JPEG"},
    }  # fmt: skip
    (args.work / "results.json").write_text(json.dumps(results, indent=1))
    print(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
