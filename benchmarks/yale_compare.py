"""Two or more runs of benchmarks/yale_eval.py side by side, pair by pair.

    python benchmarks/yale_compare.py runs/yale_today/yale.json runs/yale_true/yale.json [...] [--moved-by J.json]

Per pair kind (relight, de-light) and lamp angle (the target's |azimuth| for relight, the source's for de-light): the
medians of the correlation, the contrast and the relative error of the change (yale_eval ``compare``: |ours -
truth's| / |truth's|, both centred, = sqrt(s^2 - 2 contrast + 1) with s = contrast / corr), and, for each run after
the first, on how many of the pairs both runs have its contrast and its relative error are lower than the first
run's. ``--moved-by RUN``: only the pairs whose contrast RUN (a yale.json) changes from the first run's (a rule that
leaves some photos as they were: what it did where it acted). Also the median angle between each run's own light and
the photo's true lamp (degree-1 band) and its directionality (``sh.dominant_direction``), as yale_eval records them.
Runs are named by their folder (yale_eval's ``--out``). Figures only: no picture of the data.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

GROUPS = (("relight", "target_az", (25, 50, 70)), ("delight", "source_az", (50, 70)))


def load(path: Path) -> tuple[str, dict]:
    """A run's name (its folder's: yale_eval ``--out``) and its pairs by id."""
    data = json.loads(path.read_text())
    return path.parent.name, {r["id"]: r for r in data["pairs"]}


def own(rows: list[dict], key: str) -> str:
    vals = [r["own_light"][key] for r in rows if r.get("own_light") and r["own_light"][key] is not None]
    return f"{np.median(vals):5.1f}" if key == "angle" and vals else f"{np.median(vals):.2f}" if vals else "  -  "


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("runs", nargs="+", type=Path,
                   help="yale.json files; the first is the one the others are counted against")
    p.add_argument("--moved-by", type=Path, default=None,
                   help="a yale.json: only the pairs whose contrast it changes from the first run's")
    args = p.parse_args(argv)
    missing = [str(f) for f in [*args.runs, *([args.moved_by] if args.moved_by else [])] if not f.is_file()]
    if missing:
        print(f"yale_compare: no such file: {', '.join(missing)}", file=sys.stderr)
        return 2
    runs = [load(f) for f in args.runs]
    base = runs[0][1]
    if args.moved_by is not None:
        mover = load(args.moved_by)[1]
        keep = {i for i, r in base.items()
                if i in mover and abs(mover[i]["ours"]["contrast"] - r["ours"]["contrast"]) > 1e-6}
        runs = [(name, {i: r for i, r in pairs.items() if i in keep}) for name, pairs in runs]
        base = runs[0][1]
    print("kind |az| | run | pairs | corr | contrast | relerr | contrast lower | relerr lower | own light: angle off, "
          "directionality")
    for task, key, angles in GROUPS:
        for a in (None, *angles):
            for name, pairs in runs:
                rows = [r for r in pairs.values() if r["task"] == task and (a is None or abs(r[key]) == a)]
                if not rows:
                    continue
                med = {k: float(np.median([r["ours"][k] for r in rows])) for k in ("corr", "contrast", "relerr")}
                both = [r for r in rows if r["id"] in base]
                lower = "-", "-"
                if pairs is not base:
                    lower = tuple(f"{sum(r['ours'][k] < base[r['id']]['ours'][k] for r in both)} / {len(both)}"
                                  for k in ("contrast", "relerr"))
                print(f"{task} {'all' if a is None else a} | {name} | {len(rows)} | {med['corr']:.4f} | "
                      f"{med['contrast']:.4f} | {med['relerr']:.4f} | {lower[0]} | {lower[1]} | "
                      f"{own(rows, 'angle')}, {own(rows, 'directionality')}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
