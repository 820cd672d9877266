"""Re-make the bundled example person (relight_rt/data/example.png) and its test companions.

``python -m export.make_example --work DIR`` renders person seed 424243 at 512² with 256 transport
directions, renders two non-diffuse photos of it under two training environment maps, then writes:
- relight_rt/data/example.png: photo 0 cropped around the person, RGBA (alpha = mask);
- tests/data/example_L1.png: photo 1, the same crop (a ground-truth relit photo);
- tests/data/example_L{0,1}_light.json: the SH lights (RGB) of the two maps.
Needs the lights of ``python -m export lights --out DIR/lights`` (made when missing).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np

from export.__main__ import main as export_main
from relight_rt import lightfile

REPO = Path(__file__).resolve().parents[1]
SEED = 424243


def crop_box(mask: np.ndarray, pad: int = 24) -> tuple[slice, slice]:
    """Rows and columns around the mask with ``pad`` px above/below and 3·pad left/right."""
    ys, xs = np.nonzero(mask > 127)
    h, w = mask.shape
    rows = slice(max(0, ys.min() - pad), min(h, ys.max() + pad + 1))
    cols = slice(max(0, xs.min() - 3 * pad), min(w, xs.max() + 3 * pad + 1))
    return rows, cols


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m export.make_example", description=__doc__.splitlines()[0])
    parser.add_argument("--work", type=Path, required=True, help="scratch folder for the renders")
    args = parser.parse_args(argv)
    work = args.work
    if not (work / "lights" / "lights.json").is_file():
        export_main(["lights", "--out", str(work / "lights")])
    export_main(["render", "--n", "1", "--seed", str(SEED), "--resolution", "512", "--dirs", "256",
                 "--out", str(work / "src"), "--workers", "1"])
    export_main(["render-photos", "--data", str(work / "src"), "--envmaps", str(work / "lights"),
                 "--out", str(work / "photos"), "--k", "2", "--samples", "64", "--workers", "1"])
    name = f"anny_{SEED:06d}"
    mask = cv2.imread(str(work / "photos" / f"{name}__L0_mask.png"), cv2.IMREAD_GRAYSCALE)
    rows, cols = crop_box(mask)
    targets = {0: REPO / "relight_rt" / "data" / "example.png", 1: REPO / "tests" / "data" / "example_L1.png"}
    for j, target in targets.items():
        photo = cv2.imread(str(work / "photos" / f"{name}__L{j}_photo.png"))
        rgba = np.dstack([photo, mask])[rows, cols]
        cv2.imwrite(str(target), rgba, [cv2.IMWRITE_PNG_COMPRESSION, 9])
        light = lightfile.load_light(work / "photos" / f"{name}__L{j}_light.npy", bgr=True)
        lightfile.save_light(REPO / "tests" / "data" / f"example_L{j}_light.json", light)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
