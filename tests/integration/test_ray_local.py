"""``--ray local`` ends with its driver and says why it fails (issue 35, item 13).

- kill -9 of the driver left ``ray::DashboardAgent`` and ``ray::RuntimeEnvAgent`` running for 70 s and more:
  relight_rt.apps.ray_reaper (started by the driver, in a session of its own) ends every process below the driver
  when the driver dies. Tested with a stand-in driver (fast: a process tree, no Ray) and with the real
  CLI on a local Ray.
- under an address-space limit (ulimit -v) the raylet died at start-up (Ray's default object store does not
  fit) and the driver exited 1 with no message: the store is sized for the limit, a limit too small for Ray
  is refused in one line, and a driver that dies inside Ray is reported in one line by the watcher.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import cv2
import numpy as np
import pytest
from _graphs import models_dir, person

from relight_rt.apps import ray_jobs as distributed
from relight_rt.apps import ray_reaper

__all__ = ["models_dir"]  # fixture
REPO = Path(__file__).resolve().parents[2]
linux = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the watcher reads /proc (Linux)")


def wait_for(condition, what: str, limit: float = 60.0) -> None:
    """Poll until ``condition()`` holds (a bound on the wait, not a timing assertion)."""
    end = time.monotonic() + limit
    while not condition():
        if time.monotonic() > end:
            raise AssertionError(f"waited {limit:.0f} s for {what}")
        time.sleep(0.05)


def gone(noted: dict[int, int]) -> bool:
    return not ray_reaper.alive(noted)


def _limit(gib: float):
    def apply() -> None:
        import resource

        size = int(gib * 2**30)
        resource.setrlimit(resource.RLIMIT_AS, (size, size))

    return apply


# ------------------------------------------------------------------------------------------------ the watcher

# A stand-in for a driver: starts the watcher as relight_rt.apps.ray_jobs does, then a child that starts a
# grandchild in a session of its own (as the raylet starts its agents: they outlive a killed driver),
# prints the grandchild's pid, and waits; with "clean" it shuts down as ray_session does.
DRIVER = textwrap.dedent("""
    import subprocess, sys, time
    from relight_rt.apps import ray_jobs
    reaper = ray_jobs._start_reaper()
    agent = [sys.executable, "-c", "import time; time.sleep(300)"]
    middle = subprocess.Popen([sys.executable, "-c",
        "import subprocess, sys, time; p = subprocess.Popen(sys.argv[1:], start_new_session=True); "
        "print(p.pid, flush=True); time.sleep(300)", *agent], stdout=subprocess.PIPE, text=True)
    print(middle.pid, middle.stdout.readline().strip(), flush=True)
    time.sleep(1.5)  # the watcher notes the tree (it looks twice a second)
    if sys.argv[1] == "clean":
        ray_jobs._stop_reaper(reaper, clean=True)
        print("done", flush=True)
    time.sleep(300)
""")


def _stand_in(mode: str):
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    proc = subprocess.Popen([sys.executable, "-c", DRIVER, mode], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=env)  # fmt: skip
    middle, agent = map(int, proc.stdout.readline().split())
    table = ray_reaper.process_table()
    return proc, {p: table[p][1] for p in (middle, agent)}


@linux
def test_watcher_ends_the_tree_of_a_killed_driver():
    proc, tree = _stand_in("kill")
    try:
        time.sleep(1.0)  # the watcher notes the tree twice a second
        os.kill(proc.pid, signal.SIGKILL)
        _, err = proc.communicate(timeout=60)  # returns when the watcher, which shares the pipes, has exited
        wait_for(lambda: gone(tree), "the watcher to end the driver's tree", limit=30)
    finally:
        for pid in ray_reaper.alive(tree):  # only when the test failed
            os.kill(pid, signal.SIGKILL)
    lines = [x for x in err.splitlines() if x.strip()]
    assert len(lines) == 1 and f"the Ray driver (pid {proc.pid}) ended without shutting its local Ray down" in err


@linux
def test_watcher_leaves_a_clean_shutdown_alone():
    proc, tree = _stand_in("clean")
    try:
        assert proc.stdout.readline().strip() == "done"
        assert not gone(tree)  # after "clean" the watcher ended nothing (the driver shut Ray down itself)
    finally:
        for pid in ray_reaper.alive(tree):  # they hold the stand-in's stderr: first
            os.kill(pid, signal.SIGKILL)
        proc.kill()
        proc.communicate(timeout=60)


def test_object_store_fits_the_address_space_limit(monkeypatch):
    monkeypatch.setattr(distributed, "address_space_limit", lambda: None)
    assert distributed.object_store_bytes() is None  # Ray's default
    monkeypatch.setattr(distributed, "address_space_limit", lambda: 4 << 30)
    assert distributed.object_store_bytes() == 512 << 20
    monkeypatch.setattr(distributed, "address_space_limit", lambda: 64 << 30)
    assert distributed.object_store_bytes() == 2 << 30
    monkeypatch.setattr(distributed, "address_space_limit", lambda: 100 << 20)
    assert distributed.object_store_bytes() == distributed.OBJECT_STORE_MIN_BYTES


# ------------------------------------------------------------------------------------------------ the CLI


def _photos(folder: Path, n: int, size=(600, 400)) -> Path:
    folder.mkdir()
    h, w = size
    for i in range(n):
        img, mask = person(h, w, seed=i, box=(h // 8, h - h // 8, w // 5, w - w // 5))
        cv2.imwrite(str(folder / f"p{i:02d}.png"), (img[..., ::-1] * 255).round().astype(np.uint8))
        cv2.imwrite(str(folder / f"p{i:02d}_mask.png"), (mask * 255).astype(np.uint8))
    return folder


def _cli(src: Path, out: Path, models: Path) -> list[str]:
    return [sys.executable, "-m", "relight_rt", "relight", str(src), "--preset", "studio", "-o", str(out),
            "--models", str(models), "--device", "cpu", "--ray", "local", "--ray-actors", "1",
            "--ray-batch-size", "1"]  # fmt: skip


@linux
def test_too_small_address_space_is_one_line(tmp_path, models_dir):
    pytest.importorskip("ray")
    src = _photos(tmp_path / "in", 1, size=(60, 40))
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    proc = subprocess.run(_cli(src, tmp_path / "out", models_dir), capture_output=True, text=True, env=env,
                          timeout=120, preexec_fn=_limit(1.5))  # fmt: skip
    lines = [x for x in proc.stderr.splitlines() if x.strip()]
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr[-3000:]
    assert lines[0].startswith("relight-rt: error: --ray local: processes here may use 1.5 GiB of address space")


@pytest.mark.long
@linux
def test_ray_local_under_an_address_space_limit(tmp_path, models_dir):
    """With Ray's default object store (30 % of the memory) the raylet died at start-up and the job exited 1."""
    pytest.importorskip("ray")
    src = _photos(tmp_path / "in", 2, size=(60, 40))
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    proc = subprocess.run(_cli(src, tmp_path / "out", models_dir), capture_output=True, text=True, env=env,
                          timeout=300, preexec_fn=_limit(6))  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert sorted(p.name for p in (tmp_path / "out").glob("*.png")) == ["p00_relit.png", "p01_relit.png"]


def _command(pid: int) -> bytes:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")[0]
    except OSError:
        return b""


@pytest.mark.long
@linux
def test_kill_9_of_the_driver_ends_its_local_ray(tmp_path, models_dir):
    """The real thing: a ``--ray local`` job is SIGKILLed once its raylet has started its agents; every process
    below the driver (GCS, raylet, agents, workers) is gone soon after, not 70 s later."""
    pytest.importorskip("ray")
    src = _photos(tmp_path / "in", 30)  # long enough that the job is still running when it is killed
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    proc = subprocess.Popen(_cli(src, tmp_path / "out", models_dir), stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, env=env)  # fmt: skip
    tree: dict[int, int] = {}
    try:

        def agents_started() -> bool:
            if proc.poll() is not None:
                raise AssertionError(f"the job ended before it could be killed: {proc.stderr.read()[-2000:]}")
            below = ray_reaper.descendants(proc.pid, ray_reaper.process_table())
            tree.update(below)
            return {b"ray::DashboardAgent", b"ray::RuntimeEnvAgent"} <= {_command(p) for p in below}

        wait_for(agents_started, "the local Ray to start its agents", limit=180)
        time.sleep(1.0)  # the watcher notes the tree twice a second
        tree.update(ray_reaper.descendants(proc.pid, ray_reaper.process_table()))
        os.kill(proc.pid, signal.SIGKILL)
        _, err = proc.communicate(timeout=60)
        wait_for(lambda: gone(tree), "every process of the killed driver's local Ray to end", limit=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
        for pid in ray_reaper.alive(tree):  # only when the test failed: leave no Ray behind
            os.kill(pid, signal.SIGKILL)
    assert "ended without shutting its local Ray down" in err
