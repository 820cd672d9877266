"""The per-framing before/after table of docs/RESULTS.md from ``python -m export evaluate --baseline`` runs.

    python benchmarks/framing_table.py runs/e22/eval_{full,knees-up,waist-up,head-shoulders,face}

Each folder is one framing's evaluation (its name after the last "_" is the framing): --stage1 the new model,
--baseline the bundled one. Prints a markdown table: Table 1 errors before → after, the relighting RMSE of
stage 1 before → after, and the paired change per pair with its 95 % interval resampling subjects.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

KEYS = (("albedo_rmse", "albedo"), ("transport_rmse", "transport"), ("shading_rmse", "shading"),
        ("light_rmse", "light"))


def row(folder: Path) -> str:
    res = json.loads((folder / "results.json").read_text())
    syn, photos, change = res["synthetic"], res["photos"], res["baseline_effect"]
    before, after = syn["baseline stage 1"], syn["stage 1"]
    cells = [folder.name.rsplit("_", 1)[-1]]
    cells += [f"{before[k]:.3f} → {after[k]:.3f}" for k, _ in KEYS]
    cells.append(f"{photos['baseline stage 1']['recon_rmse']:.4f} → {photos['stage 1']['recon_rmse']:.4f}")
    cells.append(f"{photos['baseline stage 1']['relight_rmse']:.4f} → {photos['stage 1']['relight_rmse']:.4f}")
    c = change["relight_rmse"]
    cells.append(f"{c['mean']:+.4f} [{c['ci95'][0]:+.4f}, {c['ci95'][1]:+.4f}]")
    cells.append(f"{100 * c['improved']:.0f} % of {c['n']} ({c['subjects']} people)")
    return "| " + " | ".join(cells) + " |"


def main(argv: list[str]) -> int:
    head = ["framing", *(f"{name} RMSE" for _, name in KEYS), "recon RMSE (photos)", "relight RMSE",
            "relight change (95 % interval)", "pairs better"]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for folder in argv:
        print(row(Path(folder)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
