"""Whether two trees of the code give the very same mattes (a change meant to change no output, e.g. split40):
../shared/realdata/people_masks, evaluation only.

    python benchmarks/matte_identical.py /tmp/old_tree                       # 20 photos a half, 10 clip frames
    python benchmarks/matte_identical.py /tmp/old_tree --mirrored p193,p085  # and these photos mirrored too
    python benchmarks/matte_identical.py /tmp/old_tree --rules turned,peers --photos 4 --names p227,p093

OLD_TREE is another checkout of the repository (``git archive main | tar -x -C /tmp/old_tree``). Each tree runs in its
own subprocess (its own ``relight_rt`` first on the path, checked), matting the same images with
``PersonMatter(person="largest")`` and ``PersonMatter(person="all")``: photos evenly spaced over each half of
people_masks_eval.py's split, clip frames evenly spaced, relight_rt/data/example.png, the photos or clip frames named
by ``--names``, and the photos named by ``--mirrored`` flipped left-right. Printed: the largest absolute difference of
the two alphas per image and mode (a photo where neither finds anyone: "none"; where one does and the other does not:
"DIFFERS"), and the largest over all.

``--rules A,B`` switches each rule off in turn in both trees (each tree with its own benchmarks/matte_ablation.py's
switch, so that a switch whose target moved is judged where it now points; the graphs' answers memoised per process as
that tool does) and prints, per tree and rule, the images whose matte with the rule off differs from the rule in
place: a switch that still acts changes the same images in both trees, by the same amounts.

The alphas are kept in a temporary folder only while the script runs; exit status 1 when a difference is found.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
MODES = ("largest", "all")


def chosen(photos: int, frames: int, names: list[str], mirrored: list[str]) -> list[tuple[str, str, bool]]:
    """[(label, image path, mirrored)]: ``photos`` evenly spaced over each half, ``frames`` clip frames, the example,
    the photos or frames in ``names``, and the photos in ``mirrored`` mirrored."""
    sys.path.insert(0, str(REPO / "benchmarks"))
    from people_masks_eval import data_root, half_of, items

    root = data_root()
    listed = items(root, "photos")
    halves = half_of([n for n, _, _ in listed])
    out = []
    for half in "AB":
        mine = [(n, p) for n, p, _ in listed if halves[n] == half]
        picks = np.linspace(0, len(mine) - 1, min(photos, len(mine))).round().astype(int) if photos else []
        out += [(mine[i][0], str(mine[i][1]), False) for i in sorted(set(picks))]
    clip = items(root, "clip")
    picks = np.linspace(0, len(clip) - 1, min(frames, len(clip))).round().astype(int) if frames else []
    out += [(clip[i][0], str(clip[i][1]), False) for i in sorted(set(picks))]
    out.append(("example", str(REPO / "relight_rt" / "data" / "example.png"), False))
    by_name = {n: str(p) for n, p, _ in listed + clip}
    out += [(n, by_name[n], False) for n in names if n not in {label for label, _, _ in out}]
    out += [(f"{n}_mirrored", by_name[n], True) for n in mirrored]
    return out


def worker(tree: Path, listed: Path, out: Path, rules: list[str]) -> None:
    """In a subprocess: the mattes of the images in ``listed`` (JSON of :func:`chosen`) by ``tree``'s code, saved to
    ``out`` (npz, one array per "rule|label|mode", rule "" for every rule in place; a 0-size array where nobody is
    found). With ``rules``, the rules in place and each of them off in turn, the graphs' answers memoised."""
    sys.path[:0] = [str(tree), str(tree / "benchmarks")]
    import contextlib

    import cv2

    import relight_rt
    from relight_rt import RelightError
    from relight_rt.person import matting as M

    if not Path(relight_rt.__file__).resolve().is_relative_to(tree.resolve()):
        raise SystemExit(f"relight_rt came from {relight_rt.__file__}, not from {tree}")
    switches = {"": contextlib.nullcontext}
    if rules:
        import matte_ablation

        matte_ablation.memoise_graphs()
        switches.update({rule: (lambda r=rule: matte_ablation.switched_off(r)) for rule in rules})
    mattes = {}
    matters = {mode: M.PersonMatter(person=mode) for mode in MODES}
    for rule, switch in switches.items():
        with switch():
            for label, path, flip in json.loads(listed.read_text()):
                rgb = cv2.cvtColor(cv2.imread(path, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB).astype(np.float32) / 255.0
                rgb = np.ascontiguousarray(rgb[:, ::-1]) if flip else rgb
                for mode, matter in matters.items():
                    try:
                        mattes[f"{rule}|{label}|{mode}"] = matter(rgb, label)
                    except RelightError:
                        mattes[f"{rule}|{label}|{mode}"] = np.zeros(0, np.float32)
    np.savez(out, **mattes)


def run_tree(tree: Path, listed: Path, out: Path, rules: list[str]) -> dict[str, np.ndarray]:
    cmd = [sys.executable, str(Path(__file__).resolve()), str(tree), "--worker", str(listed), str(out)]
    env = dict(os.environ, PYTHONPATH=str(tree))  # its own relight_rt before any installed one
    subprocess.run(cmd + (["--rules", ",".join(rules)] if rules else []), check=True, cwd=str(tree), env=env)
    with np.load(out) as z:
        return {k: z[k] for k in z.files}


def difference(a: np.ndarray, b: np.ndarray) -> float | str:
    """The largest absolute difference of two mattes; "none" where neither finds anyone, "DIFFERS" where one does."""
    if a.size == 0 or b.size == 0:
        return "none" if a.size == b.size else "DIFFERS"
    if a.shape != b.shape:
        return "DIFFERS"
    return float(np.abs(a.astype(np.float64) - b.astype(np.float64)).max())


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("old_tree", type=Path, help="the other checkout (its relight_rt/ and benchmarks/)")
    ap.add_argument("--photos", type=int, default=20, help="photos per half (default 20)")
    ap.add_argument("--frames", type=int, default=10, help="clip frames (default 10)")
    ap.add_argument("--names", default="", help="photo or clip frame names, comma separated, matted too")
    ap.add_argument("--mirrored", default="", help="photo names, comma separated, also matted mirrored")
    ap.add_argument("--rules", default="", help="matte_ablation.py rules, comma separated, each switched off in turn")
    ap.add_argument("--worker", nargs=2, metavar=("LIST", "OUT"), help=argparse.SUPPRESS)  # old_tree: the tree run
    args = ap.parse_args(argv)
    rules = [r for r in args.rules.split(",") if r]
    if args.worker:
        worker(args.old_tree, Path(args.worker[0]), Path(args.worker[1]), rules)
        return 0
    listed = chosen(args.photos, args.frames, [n for n in args.names.split(",") if n],
                    [n for n in args.mirrored.split(",") if n])  # fmt: skip
    with tempfile.TemporaryDirectory(prefix="matte_identical_") as tmp:
        spec = Path(tmp) / "listed.json"
        spec.write_text(json.dumps(listed))
        trees = {"old": args.old_tree.resolve(), "new": REPO}
        got = {k: run_tree(t, spec, Path(tmp) / f"{k}.npz", rules) for k, t in trees.items()}
        if not rules:
            worst, bad = 0.0, 0
            for key in got["new"]:
                d = difference(got["old"][key], got["new"][key])
                print(f"{key[1:]:32s} {d if isinstance(d, str) else f'{d:.6g}'}")
                bad += d == "DIFFERS" or (isinstance(d, float) and d > 0.0)
                worst = max(worst, d) if isinstance(d, float) else worst
            print(f"{len(got['new'])} mattes, largest difference {worst:.6g}, {bad} differing")
            return 1 if bad else 0
        alike = True
        for rule in rules:
            moved = {}
            for k, z in got.items():
                on = {key: v for key, v in z.items() if key.startswith("|")}
                moved[k] = {key[1:]: difference(on[key], z[f"{rule}{key}"]) for key in on}
                moved[k] = {key: d for key, d in moved[k].items() if d not in ("none", 0.0)}
            same = moved["old"] == moved["new"]  # the same images, by the very same largest difference
            alike &= same
            changed = ", ".join(f"{key} {d if isinstance(d, str) else f'{d:.3g}'}" for key, d in moved["new"].items())
            print(f"{rule}: off changes {len(moved['old'])} (old tree) / {len(moved['new'])} (new tree) of "
                  f"{len(got['new']) // (len(rules) + 1)} mattes, {'the same' if same else 'NOT THE SAME'}: {changed}")
        return 0 if alike else 1


if __name__ == "__main__":
    raise SystemExit(main())
