"""Running hostile cases as a user's process would meet them: in a subprocess under a memory limit.

issue 35 (must show): every CLI and API fuzz case runs with its address space limited (RLIMIT_AS, as
``ulimit -v``: MEMORY_LIMIT) and reports its own peak resident memory, which must stay under PEAK_LIMIT; the
subprocess is killed at its timeout. A case that crashes the interpreter (a segfault: exit -11) or blocks
fails its test instead of taking the test run down with it.
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
MEMORY_LIMIT = 4 << 30  # address space of a hostile case's process (ulimit -v 4194304)
PEAK_LIMIT = 1 << 30  # no case may reach 1 GB resident
CASE_SECONDS = 30  # the bound of issue 35 for one case

# The peak of this process's own memory: VmHWM of /proc/self/status (its address space's high-water mark, new at
# exec). ru_maxrss is not that on Linux: it keeps the high-water mark of the process before exec, here the forked
# test runner, so a long test run's own ~1 GB showed as every case's peak. Elsewhere, ru_maxrss.
_REPORT = """
def _peak_kb():
    try:
        with open("/proc/self/status") as f:
            return int(next(line for line in f if line.startswith("VmHWM:")).split()[1])
    except (OSError, StopIteration, ValueError):
        import resource
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print("PEAK_KB", _peak_kb())
"""


def _limit_memory() -> None:  # runs in the child, before exec
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))


def run_limited(code: str, *, cwd: str | os.PathLike | None = None, env: dict | None = None, input: str | None = None,
                cases: int = 1) -> tuple[int, str, str, int]:
    """Run Python ``code`` in a subprocess under MEMORY_LIMIT with CASE_SECONDS per case (``cases`` of them);
    returns (exit code, stdout without the report line, stderr, peak resident bytes; -1 when it died)."""
    env = {**os.environ, "PYTHONPATH": f"{REPO}{os.pathsep}{REPO / 'tests'}", **(env or {})}
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", code + _REPORT], input=input, capture_output=True, text=True,
                          env=env, cwd=cwd, timeout=CASE_SECONDS * cases, preexec_fn=_limit_memory)  # fmt: skip
    peak, out = -1, []
    for line in proc.stdout.splitlines():
        if line.startswith("PEAK_KB "):
            peak = int(line.split()[1]) * 1024  # KiB (VmHWM, or ru_maxrss)
        else:
            out.append(line)
    _log(code if input is None else input, proc.returncode, peak, out, time.perf_counter() - start)
    return proc.returncode, "\n".join(out), proc.stderr, peak


def _log(what: str, code: int, peak: int, out: list[str], wall: float) -> None:
    """With $RELIGHT_RT_HOSTILE_LOG set, append each case's peak and time there (docs/BENCHMARKS.md)."""
    path = os.environ.get("RELIGHT_RT_HOSTILE_LOG")
    if not path:
        return
    seconds = [line.split()[2] for line in out if line.startswith("CODE ")]
    first = " ".join(what.strip().splitlines()[0].split())[:100]
    with open(path, "a", encoding="utf-8") as f:
        f.write(f"{first}\texit {code}\tpeak {peak / 2**20:.0f} MiB\t{wall:.1f} s in all\t"
                f"seconds per route {' '.join(seconds) or '-'}\n")


CLI_DRIVER = """
import sys, time
from relight_rt import cli
for line in sys.stdin.read().splitlines():
    start = time.perf_counter()
    code = cli.main(line.split("\\t"))
    print("CODE", code, f"{time.perf_counter() - start:.2f}", flush=True)
"""


def run_cli_limited(routes: list[list[str]], *, cwd, env: dict | None = None) -> tuple[list[int], str, int]:
    """Each argv of ``routes`` through ``cli.main`` in one limited process: (exit codes, stderr, peak bytes)."""
    code, out, err, peak = run_limited(CLI_DRIVER, cwd=cwd, env=env, input="\n".join("\t".join(r) for r in routes),
                                       cases=len(routes))  # fmt: skip
    assert code == 0, (code, out, err)
    codes = [int(line.split()[1]) for line in out.splitlines() if line.startswith("CODE ")]
    return codes, err, peak
