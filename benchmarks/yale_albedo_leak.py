"""How much of a real face's light stays in stage 1's albedo (Extended Yale B, ../shared/realdata/yale; stage 1 alone).

    PYTHONPATH=. python benchmarks/yale_albedo_leak.py --graphs shipped=relight_rt/models/stage1.onnx \
        run=runs/gpu_3/stage1.onnx [--yale ../shared/realdata/yale] [--json runs/albedo_leak.json]

Per subject, each graph runs on the frontal photo (lit from azimuth 0) and on the photos lit from azimuth +-50 and
+-70 (elevation 0), each as one face filling the network's square: the grey photo resized to the graph's resolution,
its values as they are (the relighter feeds sRGB), yale_eval's face ellipse as the mask. An albedo is the same under
every lamp, so the log of the side photo's albedo over the frontal photo's (channel mean, + 1e-3) would be 0 inside
the face (the ellipse eroded by 7 px at 256). Per graph and azimuth, means over the photos:

- ``dark``: that log ratio over the darkest two fifths of the face in the side photo, where its lamp reaches least
  (an albedo that reads a dark face as dark skin keeps the shadow there); ``lit``: over the brightest two fifths;
- ``slope``: the least-squares slope of the log ratio on the photos' own log change (side over frontal): 0 keeps
  none of the light, 1 all of it;
- ``broad`` and ``fine``: the log ratio's standard deviation after and before taking away its Gaussian blur
  (sigma 6 px at 256): whether the kept light is the shading's sweep or its fine detail.

Stage 1's albedo alone, before the relighter's face pass and fills: it says which graph keeps more light, for
comparing a newly trained stage 1 with the shipped one before the whole Yale protocol (``yale_eval.py``). The data
is for evaluation only.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import cv2
import numpy as np
from _shared import missing, shared_path
from yale_eval import ellipse, find_file

AZIMUTHS = (50, 70)
SIGMA = 6.0  # px at 256: the split between a shading's sweep and its detail
ERODE = 7  # px at 256: off the ellipse's rim


def leak(albedo_side: np.ndarray, albedo_front: np.ndarray, side: np.ndarray, front: np.ndarray,
         face: np.ndarray) -> dict:
    """The figures of one side photo (module docstring).

    Args:
        albedo_side, albedo_front: (S, S) float, the albedo's channel mean of the side and the frontal photo.
        side, front: (S, S) float, the photos (grey, [0, 1]).
        face: (S, S) bool, where to measure.

    Returns:
        dict of floats: dark, lit, slope, broad, fine.
    """
    ratio = np.log(albedo_side + 1e-3) - np.log(albedo_front + 1e-3)
    change = np.log(side + 1e-3) - np.log(front + 1e-3)
    sigma = SIGMA * ratio.shape[0] / 256
    broad = cv2.GaussianBlur(ratio.astype(np.float32), (0, 0), sigma)
    r, c = ratio[face], change[face]
    q = np.quantile(side[face], [0.4, 0.6])
    centred = c - c.mean()
    return {"dark": float(r[side[face] <= q[0]].mean()), "lit": float(r[side[face] >= q[1]].mean()),
            "slope": float(((r - r.mean()) * centred).sum() / max((centred * centred).sum(), 1e-12)),
            "broad": float(broad[face].std()), "fine": float((ratio - broad)[face].std())}


class Graph:
    """A stage-1 ONNX graph on the CPU: albedo channel mean of one grey photo under a mask."""

    def __init__(self, path: Path):
        import onnxruntime as ort

        self.session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
        self.names = [o.name for o in self.session.get_outputs()]
        self.size = int(self.session.get_inputs()[0].shape[-1])

    def albedo(self, grey: np.ndarray, mask: np.ndarray) -> np.ndarray:
        image = np.repeat(grey[None, None], 3, axis=1).astype(np.float32)
        out = dict(zip(self.names, self.session.run(None, {"image": image, "mask": mask[None, None]}), strict=True))
        return out["albedo"][0].mean(axis=0)


def read(path: Path, size: int) -> np.ndarray | None:
    g = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    return None if g is None else cv2.resize(g, (size, size), interpolation=cv2.INTER_AREA).astype(np.float32) / 255


def measure(graphs: dict[str, Graph], yale: Path) -> dict:
    """Per graph and azimuth the means of :func:`leak` over the subjects' photos from +- that azimuth."""
    rows: dict[str, dict[int, list[dict]]] = {name: {az: [] for az in AZIMUTHS} for name in graphs}
    for subject in sorted(p.name for p in yale.iterdir() if p.is_dir()):
        for name, graph in graphs.items():
            s = graph.size
            mask = ellipse((s, s))  # yale_eval's face ellipse of the square the photo is resized to
            face = cv2.erode(mask.astype(np.uint8), np.ones((2 * ERODE * s // 256 + 1,) * 2, np.uint8)) > 0
            front = read(find_file(yale, subject, 0), s)
            if front is None:
                continue
            a_front = graph.albedo(front, mask)
            for az in AZIMUTHS:
                for signed in (az, -az):
                    side = read(find_file(yale, subject, signed), s)
                    if side is not None:
                        rows[name][az].append(leak(graph.albedo(side, mask), a_front, side, front, face))
    return {name: {str(az): {"photos": len(r), **{k: float(np.mean([x[k] for x in r])) for k in r[0]}}
                   for az, r in by_az.items() if r} for name, by_az in rows.items()}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--graphs", nargs="+", required=True, help="name=stage1.onnx ...")
    p.add_argument("--yale", type=Path, default=shared_path("realdata", "yale"))
    p.add_argument("--json", type=Path, default=None, help="write the figures here too")
    args = p.parse_args(argv)
    if not args.yale.is_dir():
        print(missing(args.yale), file=sys.stderr)
        return 2
    graphs = {}
    for item in args.graphs:
        name, sep, path = item.partition("=")
        if not sep or not Path(path).is_file():
            p.error(f"--graphs: expected name=path to a stage-1 graph, got {item!r}")
        graphs[name] = Graph(Path(path))
    figures = measure(graphs, args.yale)
    for name, by_az in figures.items():
        for az, f in by_az.items():
            print(f"{name:>12} az {az}: dark {f['dark']:+.3f} lit {f['lit']:+.3f} slope {f['slope']:.3f} "
                  f"broad {f['broad']:.3f} fine {f['fine']:.3f} ({f['photos']} photos)")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(figures, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
