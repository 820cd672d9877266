"""How long relighting a real photo takes through the Python API (issue 32's speed figure).

    python benchmarks/relight_speed.py [PHOTO [MASK]] [--repeats 7] [--models DIR]

Default photo: the reference photo in ../shared/reference (2.5 megapixels) with its hand mask. Prints, best and
median of ``--repeats`` after one warm-up call: ``relight`` of one Decomposition under three presets (decompose
once, relight many), the same with a new light every call (a lamp turned 7 degrees each time, as a user dragging it
in the studio: what is cached per light, e.g. a face mesh's cast shadows, is paid every time), and ``relight`` of the
photo itself (decompose + relight) with the given mask and with the
automatic matte. CPU, onnxruntime's default threads.
"""

from __future__ import annotations

import argparse

from _shared import opened_photo, photo_arguments, timed


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    photo_arguments(p, repeats=7)
    args = p.parse_args()

    import numpy as np

    from relight_rt import lights

    r, image, mask = opened_photo(args)
    dec = r.decompose(image, mask)
    print(f"{args.photo}: {image.shape[1]}x{image.shape[0]}, second pass on the face: "
          f"{dec.head is not None}")
    for name in ("studio", "window-left", "campfire"):
        light = lights.preset(name)
        best, median = timed(lambda light=light: r.relight(dec, light), args.repeats)
        print(f"relight a Decomposition, {name}: best {best:.0f} ms, median {median:.0f} ms")
    turn = iter(range(10**6))

    def turned() -> np.ndarray:
        a = np.radians(7.0 * next(turn))
        lamp = (np.cos(a) * 0.8, np.sin(a) * 0.8, 0.6)  # x toward the camera, y the image's right, z up
        return lights.directional(lamp, angular_radius=0.3) + lights.ambient(0.1)

    best, median = timed(lambda: r.relight(dec, turned()), args.repeats)
    print(f"relight a Decomposition, a new lamp every call: best {best:.0f} ms, median {median:.0f} ms")
    light = lights.preset("studio")
    for label, kwargs in (("the given mask", {"mask": mask}), ("the automatic matte", {})):
        best, median = timed(lambda kwargs=kwargs: r.relight(image, light, **kwargs), max(3, args.repeats // 2))
        print(f"decompose + relight, {label}: best {best:.0f} ms, median {median:.0f} ms")


if __name__ == "__main__":
    main()
