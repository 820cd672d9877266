"""The own colours' step on a photo's canvas, timed piece by piece (issue 48): ../shared/realdata/people_masks.

    python benchmarks/own_colours_speed.py p150 p259 p126 p093     # photos by name

The default matte (PersonMatter(), person="largest") is run once per photo with each piece of its own colours' step
(relight_rt.person.matting._completion.own_colours) watched: the arguments of the calls that step made (its last run
on the photo) are caught, and then each of those calls is timed again as made (process time, mean of --repeat calls),
so that only the pieces the step ran are timed, on what it ran them on: ``candidates``, ``photo_bottom`` and
``cut_body`` (the bottom border's candidates and the parts of them that lie where a cut body goes on),
``colour_model`` (the k-means: made only where a part can be kept), ``own_part``, ``CutBody.part`` (its second
backdrop included) and ``backdrop_less`` alone (that second backdrop, made once a part holds up), and the whole step
(``own_colours``, the framed graph's run included). Nothing of the data is written.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

from people_masks_eval import data_root, read_rgb  # noqa: E402

from relight_rt.person import matting as M  # noqa: E402
from relight_rt.person.matting import _completion, _cut_body  # noqa: E402

WATCHED = [  # (owner, name): the step's pieces, where the step looks them up
    (_completion, "own_colours"),
    (_completion, "candidates"),
    (_completion, "photo_bottom"),
    (_completion, "cut_body"),
    (_completion, "colour_model"),
    (_completion, "own_part"),
    (_cut_body.CutBody, "part"),
    (_cut_body, "backdrop_less"),
]


@contextmanager
def watched(calls: dict[str, tuple[Callable[..., object], tuple]]) -> Iterator[None]:
    """While open, each call of a :data:`WATCHED` piece is caught in ``calls`` (name -> (the piece, its arguments));
    a call of the step itself first forgets those of its earlier runs."""
    saved = [(owner, name, owner.__dict__[name]) for owner, name in WATCHED]

    def watch(owner: object, name: str, f: Callable[..., object]) -> Callable[..., object]:
        label = f"{owner.__name__}.{name}" if isinstance(owner, type) and name != "own_colours" else name

        def call(*args):
            if name == "own_colours":
                calls.clear()
            calls[label] = (f, args)
            return f(*args)

        return call

    try:
        for owner, name, f in saved:
            setattr(owner, name, watch(owner, name, f))
        yield
    finally:
        for owner, name, f in saved:
            setattr(owner, name, f)


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
    matter = M.PersonMatter(person="largest")
    for name in args.names:
        calls: dict[str, tuple[Callable[..., object], tuple]] = {}
        with watched(calls):
            matter(read_rgb(root / "photos" / f"{name}.jpg"), name)
        if not calls:
            print(f"{name}: no own colours' step")
            continue
        times = {k: per_call(f, a, args.repeat) for k, (f, a) in calls.items() if k != "own_colours"}
        f, a = calls["own_colours"]
        times["whole step"] = per_call(f, a, max(1, args.repeat // 4))
        print(f"{name}: " + ", ".join(f"{k} {v:.2f} ms" for k, v in times.items()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
