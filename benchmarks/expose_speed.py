"""How long the Relighter's exposure of one light takes (``ExposureMeter.expose``: the mean kept, the faces' cast
shadows metered, the shoulder's loss given back, the highlight guard), on a real photo with the automatic matte.

    python benchmarks/expose_speed.py [PHOTO] [--repeats 40] [--lights studio,window-left,campfire]

Default photo: the reference photo in ../shared/reference (2.5 megapixels). Decomposes once, exposes each light
once (its cast shadows are then cached, as for a light asked again), then prints the best and median of
``--repeats`` calls. Run with PYTHONPATH set to the checkout being timed.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

from _shared import missing, shared_path

REFERENCE = shared_path("reference", "photo", "sample.jpg")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("photo", nargs="?", default=str(REFERENCE))
    p.add_argument("--repeats", type=int, default=40)
    p.add_argument("--lights", default="studio,window-left,campfire")
    args = p.parse_args()
    if not Path(args.photo).is_file():
        raise SystemExit(missing(Path(args.photo)))

    import relight_rt
    from relight_rt import RuntimeConfig, lights
    from relight_rt.image.io import read_image

    relighter = relight_rt.open(RuntimeConfig(device="cpu"))
    dec = relighter.decompose(read_image(args.photo), None)
    for name in args.lights.split(","):
        light = lights.preset(name)
        relighter._factor.meter.expose(dec, light, "auto")  # noqa: SLF001  (the step itself, warm)
        times = []
        for _ in range(args.repeats):
            t = time.perf_counter()
            relighter._factor.meter.expose(dec, light, "auto")  # noqa: SLF001
            times.append(time.perf_counter() - t)
        print(f"expose, {name}: best {1000 * min(times):.2f} ms, median {1000 * statistics.median(times):.2f} ms")


if __name__ == "__main__":
    main()
