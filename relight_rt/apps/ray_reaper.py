"""Ends a private local Ray when the process that started it dies, even by SIGKILL (issue 35, item 13).

``relight_rt.apps.ray_jobs`` runs this file as a script (``python -I _reaper.py``) before it starts a local
Ray: a child of the driver, in a session of its own (a Ctrl-C at the terminal does not reach it), its stdin
a pipe whose other end only the driver holds. While the driver lives it notes, twice a second, every
process descended from the driver (the GCS, the raylet, the raylet's agents, workers) with its start
time. When the pipe closes without the word ``clean`` (the driver was killed, or died before it could shut
Ray down), it ends every noted process that is still there and still the same process (same start time):
SIGTERM, then SIGKILL after a grace period, and says so in one line on stderr (not after ``quiet``: the
driver failed to start Ray and reports that itself). After ``clean`` (the driver called ``ray.shutdown()``)
it ends nothing.

Why: Ray's own fate sharing ends the GCS and the raylet with a driver that dies, but not the raylet's agents
(``ray::DashboardAgent``, ``ray::RuntimeEnvAgent``), which wait 60 s and more on the dead GCS before they
exit. Only the driver's own descendants are touched. Linux only (it reads /proc); elsewhere it only waits.
Standard library only: it must start fast and import nothing of the driver's.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
import time

GRACE_S = 3.0  # between SIGTERM and SIGKILL
POLL_S = 0.5


def process_table() -> dict[int, tuple[int, int, str]]:
    """pid -> (parent pid, start time in clock ticks, state) of every process in /proc ({} without /proc)."""
    table = {}
    try:
        names = os.listdir("/proc")
    except OSError:
        return table
    for name in names:
        if not name.isdigit():
            continue
        try:
            with open(f"/proc/{name}/stat", "rb") as f:
                stat = f.read()
        except OSError:  # ended meanwhile
            continue
        fields = stat[stat.rfind(b")") + 2 :].split()  # the name in parentheses may hold spaces
        if len(fields) > 19:
            table[int(name)] = (int(fields[1]), int(fields[19]), fields[0].decode())
    return table


def descendants(root: int, table: dict[int, tuple[int, int, str]]) -> dict[int, int]:
    """pid -> start time of every process below ``root`` in ``table``."""
    children: dict[int, list[int]] = {}
    for pid, (parent, _, _) in table.items():
        children.setdefault(parent, []).append(pid)
    found, todo = {}, list(children.get(root, ()))
    while todo:
        pid = todo.pop()
        if pid not in found:
            found[pid] = table[pid][1]
            todo.extend(children.get(pid, ()))
    return found


def alive(noted: dict[int, int]) -> list[int]:
    """The noted processes that are still the same processes and not yet ended (zombies are)."""
    table = process_table()
    return [p for p, start in noted.items() if p in table and table[p][1] == start and table[p][2] != "Z"]


def _signal(pids: list[int], sig: int) -> None:
    for pid in pids:
        try:
            os.kill(pid, sig)
        except OSError:
            pass


def reap(noted: dict[int, int], grace: float = GRACE_S) -> int:
    """End the noted processes still there: SIGTERM, then SIGKILL after ``grace`` seconds; returns how many."""
    left = alive(noted)
    count = len(left)
    _signal(left, signal.SIGTERM)
    deadline = time.monotonic() + grace
    while left and time.monotonic() < deadline:
        time.sleep(0.1)
        left = alive({p: noted[p] for p in left})
    _signal(left, signal.SIGKILL)
    return count


def main() -> int:
    driver = os.getppid()
    me = os.getpid()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    said: list[bytes] = []
    closed = threading.Event()

    def listen() -> None:  # blocks until the driver writes or its end of the pipe closes
        for line in sys.stdin.buffer:
            said.append(line.strip())
        closed.set()

    threading.Thread(target=listen, daemon=True).start()
    noted: dict[int, int] = {}
    while not closed.is_set():
        if driver == 1 or os.getppid() != driver:  # the driver is gone (this process was handed to init)
            closed.wait(1.0)  # the pipe closes with it
            break
        noted.update(descendants(driver, process_table()))
        noted.pop(me, None)
        closed.wait(POLL_S)
    if b"clean" in said:
        return 0
    ended = reap(noted)
    if ended and b"quiet" not in said:
        print(f"relight-rt: the Ray driver (pid {driver}) ended without shutting its local Ray down; ended "
              f"{ended} leftover Ray process(es){limit_hint()}", file=sys.stderr)  # fmt: skip
    return 0


def address_space_limit() -> int | None:
    """This process's address-space limit in bytes (``ulimit -v``), or None when there is none."""
    try:
        import resource

        soft = resource.getrlimit(resource.RLIMIT_AS)[0]
    except (ImportError, OSError, ValueError):
        return None
    return None if soft == resource.RLIM_INFINITY else soft


def limit_hint() -> str:
    """Under an address-space limit (ulimit -v), the likely reason a Ray process failed ("" without one)."""
    limit = address_space_limit()
    if limit is None:
        return ""
    return f" (processes here may use {limit / 2**30:.1f} GiB of address space, ulimit -v; Ray's need more)"


if __name__ == "__main__":
    sys.exit(main())
