"""What the black-beard rule costs once per Decomposition (relight_rt.relight.dark_beard; beard40).

    python benchmarks/dark_beard_speed.py [PHOTO [MASK]] [--repeats 21] [--models DIR]

Default photo: the reference photo (2.5 megapixels) with its hand mask. The photo is decomposed once; then, best
and median of ``--repeats`` after a warm-up, in process (the 2-core machine's load moves a whole relight by more than
this): ``dark_beard.dark_material`` on the inputs ``Factor.own`` hands it (each face mesh of the body pass and of the
head pass), and ``Factor.own`` itself (what the relighting factor divides by, computed once per Decomposition) with
the rule on and off (``BEARD``), alternately, its cache cleared each time. Says how much of the face's window the rule
weighs (its d summed) so a run on a photo without a beard is told from one with.
"""

from __future__ import annotations

import argparse
import statistics
import time

from _shared import opened_photo, photo_arguments, timed


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    photo_arguments(p, repeats=21)
    args = p.parse_args()

    from relight_rt.relight import dark_beard

    runtime, image, mask = opened_photo(args)
    dec = runtime.decompose(image, mask=mask)
    factor, memo = runtime._factor, runtime._memo
    for name, d in (("body", dec), ("head pass", dec.head)):
        if d is None:
            continue
        base = factor.restored(d)
        y0, y1, x0, x1 = base["window"]
        inputs = (d.network_image[y0:y1, x0:x1], base["albedo"], base["transport"], d.white_light[:, 0],
                  base["solid"], base["face_points"])
        found = dark_beard.dark_material(*inputs)[2]
        weight = 0.0 if found is None else float(found.sum())
        best, median = timed(lambda inputs=inputs: dark_beard.dark_material(*inputs), args.repeats)
        print(f"{name}: window {y1 - y0} x {x1 - x0}, {len(base['face_points'])} face mesh(es), beard weight "
              f"{weight:.1f}; dark_material best {best:.2f} ms, median {median:.2f} ms")

        def own(on: bool, d=d) -> None:
            dark_beard.BEARD = on
            state = memo(d)
            for key in ("own", "own_diffuse"):
                state.pop(key, None)
            factor.own(d, with_residual=False)

        rows = {on: [] for on in (False, True)}
        for _ in range(args.repeats):
            for on in (False, True):
                t = time.perf_counter()
                own(on)
                rows[on].append(1000 * (time.perf_counter() - t))
        dark_beard.BEARD = True
        print(f"{name}: Factor.own off / on, best {min(rows[False]):.1f} / {min(rows[True]):.1f} ms, median "
              f"{statistics.median(rows[False]):.1f} / {statistics.median(rows[True]):.1f} ms")


if __name__ == "__main__":
    main()
