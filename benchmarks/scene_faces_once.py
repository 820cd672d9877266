"""How often ``relight_rt.apps.scene_people.find_people`` runs each person graph on a background, and who it finds
(issue 49, scene12; issue 48's review: the face graph's answers are kept per window in the photo's reductions,
``relight_rt.image.regions.Pyramid.answer``, inside the one ``reductions_shared`` block ``find_people`` opens, so each
blob's portrait check reads the whole photo's faces from one run).

    python benchmarks/scene_faces_once.py ../shared/realdata/people_masks/photos [--save found.json]
    python benchmarks/scene_faces_once.py ../shared/realdata/people_masks/photos --code /tmp/base --save base.json

Counts the runs of the shared matter's pose, selfie and face graphs (a wrapper around each graph's ``run``) over every
photo of the folder used as a background, and with ``--save`` writes the people found (box, presence, full body) per
photo as JSON: run it on this checkout and with ``--code`` on another's relight_rt (``git archive`` into /tmp), and
compare the two files. The photos are for measuring only: nothing of them is written but the boxes.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
GRAPHS = ("pose", "roi", "face")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folder", type=Path, help="photos used as backgrounds (*_mask files are skipped)")
    ap.add_argument("--code", type=Path, help="the folder whose relight_rt to measure (default: this checkout's)")
    ap.add_argument("--save", type=Path, help="write the people found per photo here (JSON)")
    args = ap.parse_args(argv)
    sys.path.insert(0, str((args.code or REPO).resolve()))
    # imported here, so that --code's relight_rt is the one loaded
    import relight_rt.apps.scene_people as people
    from relight_rt.person.matting import shared_matter

    matter = shared_matter(device="cpu")
    count = dict.fromkeys(GRAPHS, 0)
    for name in GRAPHS:
        run = getattr(matter, name).run

        def counted(feeds, _run=run, _name=name):
            count[_name] += 1
            return _run(feeds)

        object.__setattr__(getattr(matter, name), "run", counted)
    paths = sorted(p for p in args.folder.iterdir()
                   if p.suffix.lower() in (".jpg", ".png") and not p.stem.endswith("_mask"))  # fmt: skip
    found = {}
    for path in paths:
        rgb = np.ascontiguousarray(cv2.imread(str(path))[..., ::-1])
        found[path.name] = [[list(map(float, s.box)), s.presence, s.full_body] for s in people.find_people(rgb, matter)]
    print(f"relight_rt from {Path(people.__file__).parents[2]}")
    print(f"{len(paths)} backgrounds, {sum(bool(f) for f in found.values())} with people: graph runs pose "
          f"{count['pose']}, selfie {count['roi']}, face {count['face']}")  # fmt: skip
    if args.save is not None:
        args.save.write_text(json.dumps(found, indent=0))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
