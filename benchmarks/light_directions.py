"""Where a set of training lights comes from: elevation quantiles, the share from below, the share frontal at face
height (stage 1's prior on a photo's own light; docs/RESULTS.md, "Faces", light28 and lights29).

    PYTHONPATH=. python benchmarks/light_directions.py data/lights_dir [data/lights_new ...] [--json OUT.json]
    PYTHONPATH=. python benchmarks/light_directions.py data/gpu_bank          # a gpu-train bank's lights.npy

Each argument is a folder written by ``python -m export lights`` (its NAME.npy lights, BGR on disk), a gpu-train bank
(its ``lights.npy``, RGB) or one (M, 9, 3) RGB ``.npy`` file. Per light, the direction of its luminance by the
degree-1 band (``relight_rt.light.sh.dominant_direction``; DESIGN.md §3's frame: +x toward the camera, +z up);
printed per set (``export.render.lights_cli.direction_figures``) and, for an ``export lights`` folder, per map kind
(the NAME's ``envNNNN_KIND_rNN``). Seconds; nothing is written but the figures.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

import numpy as np

from export import dataset
from export.gpu import bank
from export.render.lights_cli import direction_figures, format_direction_figures
from relight_rt import RelightError

_KIND = re.compile(r"env\d+_(?P<kind>.+)_r\d+")


def read_set(path: Path) -> tuple[np.ndarray, list[str] | None]:
    """(N, 9, 3) RGB lights of ``path`` and their names (None where the file holds none)."""
    if path.is_file():
        lights = np.load(path, allow_pickle=False)
        if lights.ndim != 3 or lights.shape[1:] != (9, 3):
            raise RelightError(f"{path}: expected (M, 9, 3) lights, got {lights.shape}")
        return lights.astype(np.float32), None
    if (path / "bank.json").is_file():
        return bank.read_lights(path, bank.read_index(path)), None
    return dataset.read_lights(path), dataset.list_lights(path)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("sets", nargs="+", type=Path, help="lights folders, banks or (M, 9, 3) .npy files")
    parser.add_argument("--json", type=Path, help="also write the figures here")
    args = parser.parse_args(argv)
    report = {}
    for path in args.sets:
        try:
            lights, names = read_set(path)
        except RelightError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        entry = {"all": direction_figures(lights)}
        print(f"{path}: {format_direction_figures(entry['all'])}")
        kinds = [m["kind"] if (m := _KIND.fullmatch(n)) else "other" for n in names] if names else []
        for kind in sorted(set(kinds)):
            keep = np.array([k == kind for k in kinds])
            entry[kind] = direction_figures(lights[keep])
            print(f"  {kind:>8}: {format_direction_figures(entry[kind])}")
        report[str(path)] = entry
    if args.json:
        args.json.write_text(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
