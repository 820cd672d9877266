"""Any benchmark with face_refit's lamp target on (relight_rt.relight.strength ``LAMP_SHARE``, off in the product).

    python benchmarks/lamp_target.py [--share 0.5] [--explained 0.7] [--weight 1.0] -- SCRIPT [ARGS ...]
    python benchmarks/lamp_target.py -- benchmarks/yale_eval.py --out /tmp/y --no-dpr --yale ../shared/realdata/yale

Where a face mesh's skin shows one hard lamp (``strength.lamp_fit``: the lamp's share of the fitted shading at least
``--share``, a lamp explaining at least ``--explained`` of what nine free SH terms explain), ``face_refit`` turns the
photo's light toward ``--weight`` x the lamp fit + the rest its nine-term fit. SCRIPT then runs as
``python SCRIPT ARGS`` would, in this process. Figures: docs/results_pending.md (light29).
"""

from __future__ import annotations

import argparse
import runpy
import sys
from pathlib import Path

from relight_rt.relight import strength


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if "--" not in argv:
        print("lamp_target: expected '-- SCRIPT [ARGS ...]' after the options", file=sys.stderr)
        return 2
    cut = argv.index("--")
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--share", type=float, default=0.5)
    p.add_argument("--explained", type=float, default=0.7)
    p.add_argument("--weight", type=float, default=1.0)
    args = p.parse_args(argv[:cut])
    rest = argv[cut + 1:]
    if not rest or not Path(rest[0]).is_file():
        p.error(f"expected a benchmark script after '--', got {rest[:1]}")
    strength.LAMP_SHARE, strength.LAMP_EXPLAINED, strength.LAMP_WEIGHT = args.share, args.explained, args.weight
    sys.argv = rest
    sys.path.insert(0, str(Path(rest[0]).resolve().parent))
    runpy.run_path(rest[0], run_name="__main__")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
