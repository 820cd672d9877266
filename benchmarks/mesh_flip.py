"""Any benchmark with the face mesh's mirror averaging on or off (relight_rt.person.face_mesh ``MESH_FLIP``) and
stage 1's (``--stage1``: relight_rt.relight.network ``STAGE1_MIRROR``; default: as the product has it), for
before/after figures in one checkout.

    python benchmarks/mesh_flip.py --flip on -- SCRIPT [ARGS ...]
    python benchmarks/mesh_flip.py --flip off --stage1 off -- SCRIPT [ARGS ...]  # the product before mirror31
    python benchmarks/mesh_flip.py --flip on -- benchmarks/yale_eval.py --out /tmp/y --no-dpr --yale YALE

``--symmetric-crop on|off`` sets relight_rt.image.crop ``SYMMETRIC_CROP`` (the crop box placed alike on a photo and
its mirror) and ``--stage2 on|off`` relight_rt.relight.network ``STAGE2_MIRROR`` (stage 2 mirror-averaged): mirror31's
probes, product switches since mirror32. Each defaults to the product's setting.
SCRIPT then runs as ``python SCRIPT ARGS`` would, in this process. Figures: docs/RESULTS.md (face31,
mirror31-34).
"""

from __future__ import annotations

import argparse
import runpy
import sys
from pathlib import Path

from relight_rt.image import crop as crop_module
from relight_rt.person import face_mesh
from relight_rt.relight import network


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if "--" not in argv:
        print("mesh_flip: expected '-- SCRIPT [ARGS ...]' after the options", file=sys.stderr)
        return 2
    cut = argv.index("--")
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--flip", choices=("on", "off"), default="on" if face_mesh.MESH_FLIP else "off",
                   help="the face mesh's mirror averaging on or off")
    p.add_argument("--stage1", choices=("on", "off"), default="on" if network.STAGE1_MIRROR else "off",
                   help="stage 1's mirror averaging on or off")
    p.add_argument("--symmetric-crop", choices=("on", "off"), default="on" if crop_module.SYMMETRIC_CROP else "off",
                   help="the crop placed alike on a mirror (relight_rt.image.crop SYMMETRIC_CROP)")
    p.add_argument("--stage2", choices=("on", "off"), default="on" if network.STAGE2_MIRROR else "off",
                   help="stage 2's mirror averaging on or off (STAGE2_MIRROR)")
    args = p.parse_args(argv[:cut])
    rest = argv[cut + 1:]
    if not rest or not Path(rest[0]).is_file():
        p.error(f"expected a benchmark script after '--', got {rest[:1]}")
    face_mesh.MESH_FLIP = args.flip == "on"
    network.STAGE1_MIRROR = args.stage1 == "on"
    crop_module.SYMMETRIC_CROP = args.symmetric_crop == "on"
    network.STAGE2_MIRROR = args.stage2 == "on"
    sys.argv = rest
    sys.path.insert(0, str(Path(rest[0]).resolve().parent))
    runpy.run_path(rest[0], run_name="__main__")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
