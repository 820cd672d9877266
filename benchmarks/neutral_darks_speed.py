"""What the near-neutral darks rule costs (relight_rt.relight.look ``neutral_darks`` / ``keep_neutral``).

    python benchmarks/neutral_darks_speed.py [PHOTO [MASK]] [--repeats 15]

Default photo: the reference photo in ../shared/reference (2.5 megapixels) with its hand mask. Prints, for
``relight`` of one Decomposition under studio, window-left, campfire and the white side lamps LEFT and RIGHT
(benchmarks/real_photos.py), the best wall and CPU time (``time.process_time``: every thread of the process, less
moved by other processes' load than wall time) of ``--repeats`` calls after one, and the best CPU time of the first
relight of a new Decomposition (three made; what is computed once per Decomposition is paid there). Where the
checkout has the rule, also ``keep_neutral`` alone on the colour and gain each light gave it, and ``neutral_darks``
alone. Run it with another checkout's code (``cd OTHER && PYTHONPATH=$PWD python PATH/TO/neutral_darks_speed.py``)
to compare, alternately: the script reads only the public API and, where present, the rule's functions.
``--clip``: instead, the reference clip's frames (../shared/reference/video, each frame its own Decomposition, as a
video's are): per frame the first relight's wall time and, where the checkout has the rule, ``neutral_darks``'s
within it (what a video pays for the rule once a frame).
"""

from __future__ import annotations

import argparse
import time

from real_photos import LEFT, RIGHT

# isort: split
from _shared import missing, opened_photo, photo_arguments, shared_path

CLIP = shared_path("reference", "video")


def best(fn, repeats: int, clock=time.perf_counter) -> float:
    """The shortest of ``repeats`` calls of ``fn`` after one, in ms of ``clock``."""
    fn()
    times = []
    for _ in range(repeats):
        t = clock()
        fn()
        times.append(clock() - t)
    return 1000 * min(times)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    photo_arguments(p, repeats=15)
    p.add_argument("--clip", action="store_true", help="time the reference clip's frames instead (module docstring)")
    args = p.parse_args()
    if args.clip:
        clip(args.models)
        return

    from relight_rt import lights
    from relight_rt.relight import compose

    r, image, mask = opened_photo(args)
    firsts = []
    for _ in range(3):
        dec = r.decompose(image, mask)
        t = time.process_time()
        r.relight(dec, lights.preset("studio"))
        firsts.append(1000 * (time.process_time() - t))
    print(f"{args.photo}: {image.shape[1]}x{image.shape[0]}; first relight of a new Decomposition, CPU best "
          f"{min(firsts):.0f} ms")
    rule = getattr(compose, "keep_neutral", None)
    seen = {}
    if rule is not None:  # what the rule was given under each light, to time it alone
        def spy(colour, gain, neutral):
            seen["args"] = colour.copy(), gain.copy(), neutral
            return rule(colour, gain, neutral)
        compose.keep_neutral = spy
    for name, light in (("studio", lights.preset("studio")), ("window-left", lights.preset("window-left")),
                        ("campfire", lights.preset("campfire")), ("LEFT", LEFT), ("RIGHT", RIGHT)):
        wall = best(lambda light=light: r.relight(dec, light), args.repeats)
        cpu = best(lambda light=light: r.relight(dec, light), args.repeats, time.process_time)
        line = f"relight {name}: best {wall:.0f} ms wall, {cpu:.0f} ms CPU"
        if seen:
            colour, gain, neutral = seen["args"]
            count = 0 if neutral is None else neutral.weight.size
            alone = best(lambda c=colour, g=gain, n=neutral: rule(c, g, n), args.repeats)
            line += f"; keep_neutral alone {alone:.2f} ms on {count} pixels of {colour.shape[0] * colour.shape[1]}"
        print(line, flush=True)
    if rule is not None:
        from relight_rt.relight.look import neutral_darks

        crop = compose.photo_crop(dec), compose.crop_origin(dec), compose.solid_crop(dec)
        print(f"neutral_darks alone (once per Decomposition): best {best(lambda: neutral_darks(*crop), 5):.1f} ms")


def clip(models: str | None, count: int = 6) -> None:
    """``--clip``: the first ``count`` frames of the reference clip decomposed as one batch (as the video job does),
    each relit once under studio."""
    import numpy as np

    import relight_rt
    from relight_rt import RuntimeConfig, lights
    from relight_rt.image.io import read_image, read_mask
    from relight_rt.relight import compose

    frames = sorted(p for p in CLIP.glob("frame_*.png") if not p.stem.endswith("_mask"))[:count]
    if not frames:
        raise SystemExit(missing(CLIP))
    r = relight_rt.open(RuntimeConfig(models=models, device="cpu"))
    images = [read_image(str(f)) for f in frames]
    masks = [read_mask(str(f.with_name(f.stem + "_mask.png")), images[0].shape[:2]) for f in frames]
    found = getattr(compose, "neutral_darks", None)
    spent: list[float] = []
    if found is not None:  # the rule's once-a-Decomposition step, timed where the composer calls it
        def timed(*a, **k):
            t = time.perf_counter()
            out = found(*a, **k)
            spent.append(1000 * (time.perf_counter() - t))
            return out
        compose.neutral_darks = timed
    relit = []
    for dec in r.decompose_batch(images, masks, allow_full=True):
        t = time.perf_counter()
        r.relight(dec, lights.preset("studio"))
        relit.append(1000 * (time.perf_counter() - t))
    h, w = images[0].shape[:2]
    line = f"reference clip, {len(frames)} frames of {w}x{h}: first relight a frame {np.round(relit).astype(int)} ms"
    if spent:
        line += f", of which neutral_darks {np.round(spent, 1)} ms"
    print(line)


if __name__ == "__main__":
    main()
