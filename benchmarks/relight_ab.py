"""Warm decompose + relight of one photo with the automatic matte, this checkout (A) against another (B), interleaved.

    PYTHONPATH=$PWD python benchmarks/relight_ab.py PHOTO OTHER_CHECKOUT [--pairs 4] [--calls 5] [--preset studio]

Each run is a fresh process that imports relight_rt from its checkout (``PYTHONPATH``), opens the bundled models,
relights the photo twice to warm up, then times ``--calls`` more ``Relighter.relight(image, preset)`` calls (the
image already read: decompose with the automatic matte, then relight). A and B take turns (A B, B A, ...), so a
machine whose load drifts slows both alike; the ratios are taken pair by pair. Prints per checkout the median of
the runs' median wall and CPU times (CPU: all threads of the process) and the best call, and the A/B ratios with
the load average seen. On a shared machine quote the ratios; the absolute times are the load's as much as ours.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time


def child(photo: str, calls: int, preset: str) -> None:
    import relight_rt
    from relight_rt.image.io import read_image

    r = relight_rt.open()
    image = read_image(photo)
    for _ in range(2):
        r.relight(image, preset)
    wall, cpu = [], []
    for _ in range(calls):
        t, c = time.perf_counter(), time.process_time()
        r.relight(image, preset)
        wall.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    print(json.dumps({"wall": statistics.median(wall), "cpu": statistics.median(cpu), "best": min(wall),
                      "mp": image.shape[0] * image.shape[1] / 1e6}))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("photo")
    p.add_argument("other", nargs="?", help="the checkout to compare with (B); without it, this checkout alone")
    p.add_argument("--pairs", type=int, default=4)
    p.add_argument("--calls", type=int, default=5)
    p.add_argument("--preset", default="studio")
    p.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.child:
        child(args.photo, args.calls, args.preset)
        return
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    checkouts = {"A": here} if args.other is None else {"A": here, "B": os.path.abspath(args.other)}
    runs: dict[str, list[dict]] = {k: [] for k in checkouts}
    load = []
    for i in range(args.pairs):
        load.append(os.getloadavg()[0])
        order = list(checkouts) if i % 2 == 0 else list(reversed(checkouts))
        for k in order:
            env = dict(os.environ, PYTHONPATH=checkouts[k])
            out = subprocess.run([sys.executable, os.path.abspath(__file__), args.photo, "--child", "--calls",
                                  str(args.calls), "--preset", args.preset], env=env, capture_output=True, text=True,
                                 check=True)
            runs[k].append(json.loads(out.stdout.strip().splitlines()[-1]))
    mp = runs["A"][0]["mp"]
    for k, rs in runs.items():
        wall = statistics.median(r["wall"] for r in rs)
        cpu = statistics.median(r["cpu"] for r in rs)
        print(f"{k} ({checkouts[k]}): wall {1e3 * wall:.0f} ms ({1e3 * wall / mp:.0f} ms per MP), "
              f"CPU {1e3 * cpu:.0f} ms, best call {1e3 * min(r['best'] for r in rs):.0f} ms; {mp:.2f} MP, "
              f"{len(rs)} runs of {args.calls}")
    if "B" in runs:
        for name in ("cpu", "wall"):
            ratios = [a[name] / b[name] for a, b in zip(runs["A"], runs["B"], strict=True)]
            print(f"A/B {name}: median {statistics.median(ratios):.3f} ({min(ratios):.3f}-{max(ratios):.3f})")
    print(f"load average (1 min) {min(load):.1f}-{max(load):.1f} on {os.cpu_count()} CPUs")


if __name__ == "__main__":
    main()
