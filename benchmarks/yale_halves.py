"""Yale's guarded figures by half of the subjects, a run against a baseline run (benchmarks/yale_eval.py's yale.json).

    python benchmarks/yale_halves.py BASE/yale.json RUN/yale.json [RUN2/yale.json ...] [--no-gain]
    python benchmarks/yale_halves.py BASE/yale.json+BASE_M/yale.json RUN/yale.json+RUN_M/yale.json --no-gain

Per pair kind (relight, de-light) and subject set (all; "even": yaleB02 08 18 24 30 36, the set a threshold is
chosen on; "odd": yaleB05 11 15 21 27 33, checked once): the median correlation, contrast and relative error of the
change (yale_eval ``compare``) over the pairs, each run's difference from the first, and on how many pairs a run's
relative error is lower / higher than the first's (a set with no pairs, as in a run of one half, is left out). Then
light30's criterion (a) for each run against the first: correlation no lower by > 0.003 (both kinds, all subjects),
relerr no higher by > 0.003 (both kinds; all, even and odd), relight relerr over all lower by >= 0.005. Contrast is
printed, not judged (docs/RESULTS.md, oracle29).

A run given as "A/yale.json+B/yale.json" is their pairs pooled (yale_eval ``--mirror`` prefixes its ids, so a plain
run and a mirrored one pool into photos + mirrors: mirror31's criterion (b)); ``--no-gain`` leaves out the relight
gain (mirror31's criterion has none).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

KINDS = ("relight", "delight")
HALVES = ("all", "even", "odd")
TOL = 0.003  # criterion (a): how far correlation may fall and relerr rise
GAIN = 0.005  # ... how far the relight relerr over all subjects must fall


def subject_number(subject: str) -> int:
    """yaleB05 -> 5."""
    return int("".join(c for c in subject if c.isdigit()))


def in_half(subject: str, half: str) -> bool:
    return half == "all" or (subject_number(subject) % 2 == 0) == (half == "even")


def load(path: Path) -> dict[str, dict]:
    """A yale.json's pairs by id; "A+B": both files' pairs (ids must not repeat)."""
    pairs: dict[str, dict] = {}
    for part in str(path).split("+"):
        rows = {r["id"]: r for r in json.loads(Path(part).read_text())["pairs"]}
        if pairs.keys() & rows.keys():
            raise ValueError(f"{part} repeats pair ids of the runs before it")
        pairs |= rows
    return pairs


def medians(pairs: dict[str, dict], kind: str, half: str) -> dict[str, float] | None:
    """The median correlation, contrast and relerr of a run's ``kind`` pairs in ``half``; None where it has none."""
    rows = [r for r in pairs.values() if r["task"] == kind and in_half(r["subject"], half) and r.get("ours")]
    if not rows:
        return None
    return {k: float(np.median([r["ours"][k] for r in rows])) for k in ("corr", "contrast", "relerr")} | {
        "n": len(rows)}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("runs", nargs="+", type=Path, help="yale.json files (A+B: pooled); the first is the baseline")
    p.add_argument("--no-gain", action="store_true", help="do not require the relight relerr gain")
    args = p.parse_args(argv)
    if len(args.runs) < 2:
        p.error("need a baseline and at least one run")
    runs = []
    for path in args.runs:
        try:
            runs.append(load(path))
        except (OSError, ValueError, KeyError, TypeError) as e:
            p.error(f"{path}: not a yale_eval yale.json ({e})")
    names = [f"{i}:{'+'.join(Path(q).parent.name for q in str(path).split('+'))}" for i, path in enumerate(args.runs)]
    base = runs[0]
    table = [{(k, h): medians(run, k, h) for k in KINDS for h in HALVES} for run in runs]
    print(f"{'run':24s} {'kind':8s} {'half':5s} {'n':>3s} {'corr':>7s} {'contr':>7s} {'relerr':>7s}"
          f" {'d corr':>7s} {'d relerr':>8s} {'lower/higher':>12s}")
    for name, run, t in zip(names, runs, table, strict=True):
        for k in KINDS:
            for h in HALVES:
                m, b = t[(k, h)], table[0][(k, h)]
                if m is None or b is None:
                    continue
                ids = [i for i, r in base.items() if r["task"] == k and in_half(r["subject"], h) and i in run]
                lo = sum(run[i]["ours"]["relerr"] < base[i]["ours"]["relerr"] - 1e-9 for i in ids)
                hi = sum(run[i]["ours"]["relerr"] > base[i]["ours"]["relerr"] + 1e-9 for i in ids)
                print(f"{name:24s} {k:8s} {h:5s} {m['n']:3d} {m['corr']:7.4f} {m['contrast']:7.4f} {m['relerr']:7.4f}"
                      f" {m['corr'] - b['corr']:+7.4f} {m['relerr'] - b['relerr']:+8.4f} {lo:5d}/{hi:<5d}")
    print()
    for name, t in zip(names[1:], table[1:], strict=True):
        b = table[0]
        have = [(k, h) for k in KINDS for h in HALVES if t[(k, h)] is not None and b[(k, h)] is not None]
        fails = [f"{k} corr {t[(k, h)]['corr'] - b[(k, h)]['corr']:+.4f}" for k, h in have
                 if h == "all" and t[(k, h)]["corr"] < b[(k, h)]["corr"] - TOL]
        fails += [f"{k} {h} relerr {t[(k, h)]['relerr'] - b[(k, h)]['relerr']:+.4f}" for k, h in have
                  if t[(k, h)]["relerr"] > b[(k, h)]["relerr"] + TOL]
        if ("relight", "all") in have and not args.no_gain:
            gain = b[("relight", "all")]["relerr"] - t[("relight", "all")]["relerr"]
            if gain < GAIN:
                fails.append(f"relight all relerr gain {gain:+.4f} < {GAIN}")
        missing = len(KINDS) * len(HALVES) - len(have)
        note = f" ({missing} of the sets absent: not a full judgement)" if missing else ""
        print(f"(a) {name}: {'met' if not fails else 'failed: ' + '; '.join(fails)}{note}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
