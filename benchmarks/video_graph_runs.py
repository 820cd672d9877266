"""Graph runs per frame of VideoMatter (the video path's matte) on portrait frames and on the clips.

    python benchmarks/video_graph_runs.py                    # ~2 min: portrait crops, reference 720p, parkour clip
    python benchmarks/video_graph_runs.py --code /tmp/base   # another checkout's relight_rt (a git archive of main)

Counts each bundled graph's runs (pose, selfie, face; benchmarks/matte_graph_runs.py's wrapper) per frame that
VideoMatter follows (the first frame, a search, left out), on:
- three portrait frames cut from relight_rt/data/example.png, each given 5 times: "head+chest" (260x260: the person
  fills the frame, so the selfie graph frames the whole photo and the whole-photo rule of
  relight_rt.person.matting._selfie.confirmed acts), "head+shoulders" (177x232) and "wide" (200x356, edges
  replicated: a portrait framed tighter than the photo, where that rule cannot act);
- the 24 reference frames at 720p (benchmarks/matting_eval.py's speed frames) and the 100 frames of
  ../shared/realdata/people_masks/clip when present (evaluation only: nothing of it is written).
Graph runs do not depend on the load, so two versions compare exactly on them (wall time on a shared machine
does not); the wall time per frame is printed for a rough idea only.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

from _shared import shared_path, warn_missing  # noqa: E402
from matte_graph_runs import GRAPHS, counting  # noqa: E402 (no relight_rt import: --code's is the one loaded)

_REPEAT = 5  # a portrait frame given this many times (the first one searched, the others followed)


def _read(path: Path) -> np.ndarray:
    return cv2.cvtColor(cv2.imread(str(path), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB).astype(np.float32) / 255.0


def clips(ref: Path) -> dict[str, list[np.ndarray]]:
    """The frame sequences: name -> frames in order."""
    from matting_eval import frames_720p

    img = _read(REPO / "relight_rt" / "data" / "example.png")
    wide = cv2.copyMakeBorder(img[0:200, 60:230], 0, 0, 93, 93, cv2.BORDER_REPLICATE)
    out = {
        "head+chest 260x260": [img[0:260, 15:275]] * _REPEAT,
        "head+shoulders 177x232": [img[0:177, 29:261]] * _REPEAT,
        "wide 200x356": [wide] * _REPEAT,
    }
    if (ref / "video").is_dir():
        out["reference 720p"] = frames_720p(ref)
    else:
        warn_missing(ref / "video", "the reference 720p clip")
    parkour = shared_path("realdata", "people_masks", "clip")
    if parkour.is_dir():
        out["people_masks clip"] = [_read(f) for f in sorted(parkour.glob("*[0-9].jpg"))]
    else:
        warn_missing(parkour, "the people_masks clip")
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ref", type=Path, default=shared_path("reference"))
    ap.add_argument("--code", type=Path, help="the folder whose relight_rt to count (default: this checkout's)")
    args = ap.parse_args(argv)
    if args.code is not None:
        sys.path.insert(0, str(args.code.resolve()))
    from relight_rt.person import matting as M  # imported here: --code's relight_rt is the one loaded

    print(f"relight_rt from {Path(M.__file__).parents[2]}")
    for name, frames in clips(args.ref).items():
        video = M.VideoMatter(M.PersonMatter())
        count = counting(video.matter)
        video(frames[0])
        count.update(dict.fromkeys(GRAPHS, 0))
        t = time.perf_counter()
        for frame in frames[1:]:
            video(frame)
        n = len(frames) - 1
        runs = ", ".join(f"{'selfie' if g == 'roi' else g} {count[g] / n:.2f}" for g in GRAPHS)
        print(f"{name}: {n} followed frames; graph runs a frame {runs}; {(time.perf_counter() - t) / n * 1e3:.0f} ms")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
