"""Recompose a relit photo from the passes that ``relight-rt decompose --format exr|png16`` wrote, from the files alone.

    python scripts/recompose_passes.py PASSES_DIR [--backdrop IMAGE] [-o OUT.png]

Reads albedo, shading, residual, beauty and alpha with a reader that is not relight_rt's (OpenEXR's Python
module, ``pip install openexr``, for .exr; OpenCV for 16-bit .png, undoing the offset and scale that passes.json
gives), computes albedo * shading + residual, and prints its largest difference from the beauty pass (RGB,
premultiplied); exits 1 when it is above 1e-3. With --backdrop, also writes the relit person over that image
(beauty + backdrop * (1 - alpha), the backdrop fitted by resizing) to OUT.png.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import cv2
import numpy as np

TOLERANCE = 1e-3


def read_pass(folder: Path, doc: dict, name: str) -> np.ndarray:
    """One pass as float32 (H, W, C) or (H, W), in the values it was written with."""
    entry = doc["passes"][name]
    path = folder / entry["file"]
    if doc["format"] == "exr":
        import OpenEXR  # the second reader: OpenEXR's own bindings

        with OpenEXR.File(str(path)) as f:
            channels = f.channels()
            if "RGBA" in channels or "RGB" in channels:
                return np.array(channels.get("RGBA", channels.get("RGB")).pixels, np.float32)
            return np.array(channels["Y"].pixels, np.float32)
    raw = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if raw is None or raw.dtype != np.uint16:
        raise SystemExit(f"{path}: expected a 16-bit PNG")
    if raw.ndim == 3:
        raw = cv2.cvtColor(raw, cv2.COLOR_BGR2RGB if raw.shape[2] == 3 else cv2.COLOR_BGRA2RGBA)
    return (raw.astype(np.float32) / 65535 * entry["scale"] + entry["offset"]).astype(np.float32)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("folder", type=Path)
    p.add_argument("--backdrop", type=Path, help="an image to put the relit person over")
    p.add_argument("-o", "--output", type=Path, help="where to write the person over --backdrop (PNG)")
    args = p.parse_args(argv)
    doc = json.loads((args.folder / "passes.json").read_text())
    albedo, shading, residual = (read_pass(args.folder, doc, n) for n in ("albedo", "shading", "residual"))
    beauty = read_pass(args.folder, doc, "beauty")
    recomposed = albedo * shading + residual
    error = float(np.abs(recomposed - beauty[..., :3]).max())
    print(f"{args.folder} ({doc['format']}): max |albedo x shading + residual - beauty| = {error:.2e}")
    if args.backdrop and args.output:
        alpha = read_pass(args.folder, doc, "alpha")
        back = cv2.imread(str(args.backdrop), cv2.IMREAD_COLOR)[..., ::-1].astype(np.float32) / 255
        back = cv2.resize(back, (alpha.shape[1], alpha.shape[0]), interpolation=cv2.INTER_AREA)
        over = recomposed + back * (1 - alpha[..., None])
        cv2.imwrite(str(args.output), (np.clip(over, 0, 1)[..., ::-1] * 255 + 0.5).astype(np.uint8))
    return 0 if error <= TOLERANCE else 1


if __name__ == "__main__":
    sys.exit(main())
