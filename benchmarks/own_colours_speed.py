"""The own colours' step on a photo's canvas, timed piece by piece (issue 48): ../shared/realdata/people_masks.

    python benchmarks/own_colours_speed.py p150 p259 p126 p101     # photos by name

The default matte (PersonMatter(), person="largest") is run once per photo to catch the canvas its own colours' step
(PersonMatter._own_colours) reads; then each piece of that step is timed on it (process time, mean of --repeat calls):
``_colours.candidates`` (the candidates and their colour models, the k-means), ``_colours.own_part``,
``_cut_body.cut_part`` and ``photo_bottom``, and ``_colours.colour_model`` alone (the call each of the two steps made
for itself before they shared one), and the bottom border's own model where it has one (its candidates are more than
the own colours'). Nothing of the data is written.
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
    candidates, photo_bottom = _matter.candidates, _matter.photo_bottom

    def catch_candidates(*a):
        caught["canvas"] = a
        return candidates(*a)

    def catch_bottom(*a):
        caught["bottom"] = a
        return photo_bottom(*a)

    _matter.candidates, _matter.photo_bottom = catch_candidates, catch_bottom
    matter = M.PersonMatter(person="largest")
    for name in args.names:
        caught.clear()
        matter(read_rgb(root / "photos" / f"{name}.jpg"), name)
        own = candidates(*caught["canvas"]) if "canvas" in caught else None
        if own is None:
            print(f"{name}: no candidates")
            continue
        canvas, inside, mine, seen, framed, bottom = caught["canvas"]
        (cand, model), (below, below_model) = own
        times = {
            "candidates": per_call(candidates, caught["canvas"], args.repeat),
            "own_part": per_call(_colours.own_part, (mine, cand, model), args.repeat),
            "cut_part": per_call(_cut_body.cut_part, (mine, below, below_model, bottom), args.repeat),
            "photo_bottom": per_call(_cut_body.photo_bottom, caught["bottom"], args.repeat),
            "colour_model alone": per_call(_colours.colour_model, (canvas, inside, mine, mine | cand), args.repeat),
        }
        if below_model is not model:
            times["bottom border's model"] = per_call(
                _colours.colour_model, (canvas, inside, mine, mine | cand, below & ~cand, model), args.repeat
            )
        print(f"{name}: " + ", ".join(f"{k} {v:.2f} ms" for k, v in times.items()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
