"""How often ``relight_rt.apps.scene_people.find_people`` runs the face graph on a background: once per blob whose
segmentation checks for a close portrait (before scene12), or at most once per background (now); and whether the
people found are the same (issue 49, scene12).

    python benchmarks/scene_faces_once.py ../shared/realdata/people_masks/photos

Counts the calls by wrapping the matter's face search (``relight_rt.person.matting._matter.find_faces``, private:
this is a measurement of it) and runs each photo twice, with ``scene_people``'s once-per-background copy of the
matter turned off and on. Prints the totals; the photos are for measuring only.
"""

from __future__ import annotations

import sys
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

import relight_rt.apps.scene_people as people  # noqa: E402
import relight_rt.person.matting._matter as matter_module  # noqa: E402
from relight_rt.person.matting import shared_matter  # noqa: E402


def main(argv=None) -> int:
    folder = Path((argv or sys.argv[1:])[0])
    matter = shared_matter(device="cpu")
    calls = [0]
    search = matter_module.find_faces

    def counted(*args, **kwargs):
        calls[0] += 1
        return search(*args, **kwargs)

    matter_module.find_faces = counted
    once = people._faces_once
    paths = sorted(p for p in folder.iterdir() if p.suffix.lower() in (".jpg", ".png") and not p.stem.endswith("_mask"))
    total, several, same = {"before": 0, "now": 0}, 0, 0
    for path in paths:
        rgb = np.ascontiguousarray(cv2.imread(str(path))[..., ::-1])
        found = {}
        for mode in ("before", "now"):
            people._faces_once = (lambda m, r: m) if mode == "before" else once
            calls[0] = 0
            found[mode] = people.find_people(rgb, matter)
            total[mode] += calls[0]
            several += mode == "before" and calls[0] > 1
        same += found["before"] == found["now"]
    people._faces_once = once
    print(f"{len(paths)} backgrounds: face-graph runs before {total['before']}, now {total['now']}; backgrounds with "
          f"more than one before: {several}; people found identical on {same}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
