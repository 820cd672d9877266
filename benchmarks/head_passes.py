"""How many faces get a head pass and a face mesh over the people_masks photos (issue 48, mesh42).

    python benchmarks/head_passes.py --out /tmp/heads.jsonl [--people DIR] [--only p272,p238]
    python benchmarks/head_passes.py --compare A.jsonl B.jsonl [C.jsonl]

Decomposes every photo as ``relight-rt relight`` does (the automatic matte, a group person by person) and writes one
JSON line per photo: "meshes" (the face meshes of the Decomposition and its people: the detector on the photo),
"heads" (head passes: relight_rt.relight.face_pass ``seen_head_box``, a second stage-1 look at a face stage 1 saw
small), "head_meshes" (meshes the head passes found) and "boxes" (each decomposition's head box or null, the group's
first). ``--compare`` sums the counts per file over the photos all of them hold and lists the photos whose head
passes or head meshes differ between the first two (the others shown beside). Relights with whatever ``relight_rt``
is importable: run it in two checkouts for before / after. Figures: docs/results_pending.md (mesh42).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import cv2
import numpy as np
from _shared import missing, shared_path

import relight_rt
from relight_rt import RuntimeConfig

KEYS = ("meshes", "heads", "head_meshes")


def counts(dec) -> dict:
    """The figures of one photo's Decomposition (module docstring)."""
    decs = [dec, *dec.people]
    return {"meshes": sum(len(d.face_meshes or ()) for d in decs),
            "heads": sum(d.head is not None for d in decs),
            "head_meshes": sum(len(d.head.face_meshes or ()) for d in decs if d.head is not None),
            "boxes": [None if d.head_box is None else [int(v) for v in d.head_box] for d in decs]}


def compare(paths: list[Path]) -> None:
    runs = [{row["name"]: row for row in map(json.loads, p.read_text().splitlines())} for p in paths]
    names = sorted(set.intersection(*(set(r) for r in runs)))
    for key in KEYS:
        print(f"{key:12s}", " / ".join(str(sum(r[n][key] for n in names)) for r in runs), f"({len(names)} photos)")
    for n in names:
        if any(runs[0][n][k] != runs[1][n][k] for k in KEYS[1:]):
            print(n, {k: " / ".join(str(r[n][k]) for r in runs) for k in KEYS[1:]})


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, default=None, help="JSON lines, one per photo")
    p.add_argument("--people", type=Path, default=shared_path("realdata", "people_masks"))
    p.add_argument("--only", default=None, help="comma-separated photo names: these only")
    p.add_argument("--compare", type=Path, nargs="+", default=None, help="two or more --out files")
    args = p.parse_args(argv)
    if args.compare:
        if len(args.compare) < 2:
            p.error("--compare takes two or more files")
        compare(args.compare)
        return 0
    if args.out is None:
        p.error("give --out (or --compare)")
    folder = args.people / "photos"
    if not folder.is_dir():
        print(missing(folder), file=sys.stderr)
        return 1
    only = None if args.only is None else set(args.only.split(","))
    relighter = relight_rt.open(RuntimeConfig(device="cpu"))
    with args.out.open("w") as out:
        for path in sorted(folder.glob("*.jpg")):
            if only is not None and path.stem not in only:
                continue
            rgb = cv2.cvtColor(cv2.imread(str(path), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB).astype(np.float32) / 255
            out.write(json.dumps({"name": path.stem, **counts(relighter.decompose(rgb))}) + "\n")
            out.flush()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
