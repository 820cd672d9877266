"""Graph runs and CPU time of the default matte (PersonMatter(), person="largest") over people_masks and on one photo.

    python benchmarks/matte_graph_runs.py                 # ~5 min: clip + photos + the reference photo
    python benchmarks/matte_graph_runs.py --photo-only    # the reference photo alone, ~10 s
    python benchmarks/matte_graph_runs.py --code /tmp/base  # another checkout's relight_rt (a git archive of main)

Counts each bundled graph's runs (pose, selfie, face: a wrapper around each session's ``run``) over the clip's 100
frames and the 208 photos of ../shared/realdata/people_masks (evaluation only: nothing of it is written), and the
CPU time of a call (``time.process_time``: steadier than wall time on a shared machine). Graph runs do not depend on
the load, so two versions of the matte compare exactly on them: run it on this checkout and with ``--code`` on the
base's (``git archive`` into /tmp), alternately, and compare.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

from _shared import missing, shared_path  # noqa: E402

GRAPHS = ("pose", "roi", "face")


def counting(matter) -> dict[str, int]:
    """Wrap each of ``matter``'s graphs so that its runs are counted in the returned dict (by GRAPHS name)."""
    count = dict.fromkeys(GRAPHS, 0)
    for name in GRAPHS:
        model = getattr(matter, name)
        if model is None:
            continue
        run = model.run

        def counted(feeds, _run=run, _name=name):
            count[_name] += 1
            return _run(feeds)

        object.__setattr__(model, "run", counted)
    return count


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--photo", type=Path, default=shared_path("reference", "photo", "sample.jpg"))
    ap.add_argument("--photo-only", action="store_true", help="only the one photo")
    ap.add_argument("--repeats", type=int, default=15)
    ap.add_argument("--code", type=Path, help="the folder whose relight_rt to time (default: this checkout's)")
    args = ap.parse_args(argv)
    if not args.photo.is_file():
        raise SystemExit(missing(args.photo))
    if args.code is not None:
        sys.path.insert(0, str(args.code.resolve()))
    # imported here, so that --code's relight_rt is the one people_masks_eval's imports find loaded
    from relight_rt import RelightError  # noqa: I001 (before people_masks_eval, see above)
    from relight_rt.person import matting as M

    from people_masks_eval import data_root, items, read_rgb

    print(f"relight_rt from {Path(M.__file__).parents[2]}")
    matter = M.PersonMatter()
    count = counting(matter)
    if not args.photo_only:
        root = data_root()
        for which in ("clip", "photos"):
            count.update(dict.fromkeys(GRAPHS, 0))
            cpu, listed = 0.0, items(root, which)
            for name, img, _ in listed:
                rgb = read_rgb(img)
                t = time.process_time()
                try:
                    matter(rgb, name)
                except RelightError:
                    pass
                cpu += time.process_time() - t
            print(f"{which}: {len(listed)} images; graph runs pose {count['pose']}, selfie {count['roi']}, face "
                  f"{count['face']}; CPU {1000 * cpu / len(listed):.0f} ms an image")  # fmt: skip
    rgb = read_rgb(args.photo)
    matter(rgb)
    count.update(dict.fromkeys(GRAPHS, 0))
    times = []
    for _ in range(args.repeats):
        t = time.process_time()
        matter(rgb)
        times.append(1000 * (time.process_time() - t))
    n = args.repeats
    print(f"{args.photo.name} {rgb.shape[1]}x{rgb.shape[0]}: graph runs a call pose {count['pose'] / n:.0f}, selfie "
          f"{count['roi'] / n:.0f}, face {count['face'] / n:.0f}; CPU best {min(times):.0f}, median "
          f"{float(np.median(times)):.0f} ms ({n} calls)")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
