"""What the deep-shadow fill (relight_rt.relight.factor ``Factor.gain_and_fill``) costs a relight.

    python benchmarks/shadow_fill_speed.py PHOTO MASK [--light front] [--repeats 12]

Decomposes PHOTO once, then relights it under ``--light`` with the fill and with it switched off
(``shadow_weight`` returning None), interleaved in one process so that a loaded CPU weighs on both alike; prints
the minimum and the 25th percentile of each. The fill costs nothing where no deep shadow is found, and in
proportion to the shadow's box where one is. Also the fill's texture (``ShadowFill.texture``, found once per
Decomposition over the crop box, then a multiply per light): its first computation timed alone, repeated; and the
fill's weight and colour (``ShadowFill.shadow_weight``, also once per Decomposition) the same way.
"""

from __future__ import annotations

import argparse
import time


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("photo")
    p.add_argument("mask")
    p.add_argument("--light", default="front")
    p.add_argument("--repeats", type=int, default=12)
    args = p.parse_args()

    import relight_rt
    from relight_rt import RuntimeConfig

    r = relight_rt.open(RuntimeConfig(device="cpu"))
    dec = r.decompose(args.photo, args.mask)
    fill = r._factor.fill  # the deep shadow's fill (relight_rt.relight.shadow_fill)
    real = fill.shadow_weight
    print(f"deep shadow found: {real(dec) is not None}")

    def off(*_):
        return None

    times: dict[str, list[float]] = {"with fill": [], "without": []}
    for fn in (real, off):  # warm both
        fill.shadow_weight = fn
        r.relight(dec, args.light)
    for _ in range(args.repeats):
        for name, fn in (("with fill", real), ("without", off)):
            fill.shadow_weight = fn
            t = time.perf_counter()
            r.relight(dec, args.light)
            times[name].append(time.perf_counter() - t)
    fill.shadow_weight = real
    state, gray = fill.memo(dec), fill.memo(dec).get("gray")
    times["texture, once"] = []
    for _ in range(args.repeats if gray is not None else 0):
        state.pop("texture", None)
        t = time.perf_counter()
        fill.texture(dec, gray)
        times["texture, once"].append(time.perf_counter() - t)
    times["weight, once"] = []  # where the fill goes and its colour (``shadow_weight``), found once per Decomposition
    for _ in range(args.repeats):
        state.pop("shadow", None)
        t = time.perf_counter()
        fill.shadow_weight(dec)
        times["weight, once"].append(time.perf_counter() - t)
    for name, ts in times.items():
        if not ts:
            continue
        ts.sort()
        print(f"{name:10s} min {1000 * ts[0]:.1f} ms, p25 {1000 * ts[len(ts) // 4]:.1f} ms")


if __name__ == "__main__":
    main()
