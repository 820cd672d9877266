"""Run a deterministic sample of mutmut's mutants against the focused tests (docs/MUTATION.md).

A full mutmut run over the runtime's core is thousands of mutants; on a shared 2-core machine it does not
finish in a working session. This picks ``--per-module`` mutants per module, evenly spaced over mutmut's
sorted mutant names (the same names for the same source), and runs the test selection of
``[tool.mutmut] pytest_add_cli_args_test_selection`` once per mutant in mutmut's ``mutants/`` copy, with
mutmut's own switch (the ``MUTANT_UNDER_TEST`` environment variable) turning the mutant on.

First let mutmut write ``mutants/`` (it mutates, runs its stats pass, then says that no mutant matched)::

    nice -n 10 mutmut run "relight_rt.none*"
    nice -n 10 python scripts/mutation_sample.py --per-module 30 --json mutation_sample.json

Outcomes: "killed" (a test failed), "survived" (every selected test passed), "timeout" (over ``--timeout``
seconds), "error" (pytest could not run: reported, not scored). The score is killed / (killed + survived).
The unmutated selection must pass first, or nothing is reported.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

MODULES = ("relighter", "cli", "video", "stabilize")


def sample(mutants: Path, module: str, n: int) -> list[str]:
    keys = sorted(json.loads((mutants / "relight_rt" / f"{module}.py.meta").read_text())["exit_code_by_key"])
    if n >= len(keys):
        return keys
    return [keys[i * len(keys) // n] for i in range(n)]


def run_tests(mutants: Path, tests: list[str], mutant: str | None, timeout: float) -> tuple[str, float]:
    env = dict(os.environ)
    env.pop("MUTANT_UNDER_TEST", None)
    if mutant is not None:
        env["MUTANT_UNDER_TEST"] = mutant
    cmd = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", *tests]
    start = time.perf_counter()
    try:
        rc = subprocess.run(cmd, cwd=mutants, env=env, capture_output=True, timeout=timeout).returncode
    except subprocess.TimeoutExpired:
        return "timeout", time.perf_counter() - start
    outcome = {0: "survived", 1: "killed"}.get(rc, f"error (pytest exit {rc})")
    return outcome, time.perf_counter() - start


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--per-module", type=int, default=30)
    p.add_argument("--modules", nargs="+", default=list(MODULES))
    p.add_argument("--timeout", type=float, default=180.0)
    p.add_argument("--json", metavar="FILE", help="write every outcome here")
    args = p.parse_args()
    root = Path.cwd()
    mutants = root / "mutants"
    try:
        import tomllib  # Python 3.11+
    except ImportError:  # 3.10: the pip-vendored parser
        from pip._vendor import tomli as tomllib
    cfg = tomllib.loads((root / "pyproject.toml").read_text())["tool"]["mutmut"]
    tests = list(cfg["pytest_add_cli_args_test_selection"])
    tests = [t for t in tests if (mutants / t).exists()]
    base, seconds = run_tests(mutants, tests, None, args.timeout)
    if base != "survived":
        print(f"the unmutated test selection does not pass in {mutants} ({base}); fix that first", file=sys.stderr)
        return 2
    print(f"selection: {' '.join(tests)} ({seconds:.1f} s unmutated)")
    results = {}
    for module in args.modules:
        for name in sample(mutants, module, args.per_module):
            outcome, seconds = run_tests(mutants, tests, name, args.timeout)
            results[name] = outcome
            print(f"{outcome:9s} {seconds:5.1f}s {name}", flush=True)
    killed = sum(v in ("killed", "timeout") for v in results.values())
    survived = sum(v == "survived" for v in results.values())
    for module in args.modules:
        mine = {k: v for k, v in results.items() if k.startswith(f"relight_rt.{module}.")}
        k = sum(v in ("killed", "timeout") for v in mine.values())
        s = sum(v == "survived" for v in mine.values())
        print(f"{module:10s} killed {k:3d}  survived {s:3d}  score {k / max(1, k + s):.0%}")
    print(f"{'total':10s} killed {killed:3d}  survived {survived:3d}  score {killed / max(1, killed + survived):.0%}")
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1, ensure_ascii=False))
    return 0


if __name__ == "__main__":
    sys.exit(main())
