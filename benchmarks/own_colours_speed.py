"""The own colours' step on a photo's canvas, timed piece by piece (issue 48): ../shared/realdata/people_masks.

    python benchmarks/own_colours_speed.py p150 p259 p126 p101     # photos by name

The default matte (PersonMatter(), person="largest") is run once per photo to catch the canvas its own colours' step
(PersonMatter._own_colours) reads; then each piece of that step is timed on it (process time, mean of --repeat calls):
``_colours.candidates``, ``_cut_body.cut_body`` (the bottom border's candidates and the parts of them that lie where a
cut body goes on) and ``photo_bottom``, ``_colours.colour_model`` (the k-means: made only where a part can be kept),
``_colours.own_part``, ``CutBody.part`` (with the backdrop drawn again without what the framed graph alone sees, once
a part holds up) and ``_colours.backdrop_less`` alone (that second backdrop; timed wherever the framed graph alone sees
some pixels, though it is made only once a part holds up). Nothing of the data is written.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

from people_masks_eval import data_root, read_rgb  # noqa: E402

from relight_rt.person import matting as M  # noqa: E402
from relight_rt.person.matting import _colours, _cut_body, _matter  # noqa: E402


def per_call(f: Callable[..., object], args: tuple, repeat: int) -> float:
    """Mean process time of ``f(*args)`` over ``repeat`` calls, in ms."""
    t = time.process_time()
    for _ in range(repeat):
        f(*args)
    return (time.process_time() - t) / repeat * 1e3


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("names", nargs="+", help="photo names in people_masks/photos (p150 ...)")
    ap.add_argument("--repeat", type=int, default=20)
    args = ap.parse_args(argv)
    root = data_root()
    caught: dict[str, tuple] = {}
    photo_bottom = _matter.photo_bottom

    def catch_bottom(*a):
        caught["bottom"] = a
        return photo_bottom(*a)

    def catch_start(rgb, people, start=None):
        caught["start"] = (rgb, start if start is not None else _matter.around_people(matter.roi, rgb, people))
        return own_colours(rgb, people, caught["start"][1])

    _matter.photo_bottom = catch_bottom
    matter = M.PersonMatter(person="largest")
    own_colours, matter._own_colours = matter._own_colours, catch_start
    for name in args.names:
        caught.clear()
        matter(read_rgb(root / "photos" / f"{name}.jpg"), name)
        if caught.get("start", (None, None))[1] is None:
            print(f"{name}: no own colours' step")
            continue
        rgb, (region, seen, inside, mine) = caught["start"]
        canvas, bottom = M.crop_region(rgb, region), photo_bottom(*caught["bottom"])
        framed = _matter.roi_prob(matter.roi, rgb, region)
        cand = _colours.candidates(inside, mine, seen, framed)
        cut = _cut_body.cut_body(inside, mine, cand, framed, bottom)
        times = {
            "candidates": per_call(_colours.candidates, (inside, mine, seen, framed), args.repeat),
            "cut_body": per_call(_cut_body.cut_body, (inside, mine, cand, framed, bottom), args.repeat),
            "photo_bottom": per_call(_cut_body.photo_bottom, caught["bottom"], args.repeat),
        }
        own = cand.sum() >= max(1.0, _colours.OWN_MIN * mine.sum())
        model = _colours.colour_model(canvas, inside, mine, mine | cand) if own or cut is not None else None
        if model is not None:
            times["colour_model"] = per_call(_colours.colour_model, (canvas, inside, mine, mine | cand), args.repeat)
            if own:
                times["own_part"] = per_call(_colours.own_part, (mine, cand, model), args.repeat)
            if cut is not None:
                times["CutBody.part"] = per_call(cut.part, (model,), args.repeat)
                alone = cut.below & ~cand
                if alone.any():
                    times["backdrop_less"] = per_call(
                        _colours.backdrop_less, (model, inside, mine, mine | cand, alone), args.repeat
                    )
        print(f"{name}: " + ", ".join(f"{k} {v:.2f} ms" for k, v in times.items()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
