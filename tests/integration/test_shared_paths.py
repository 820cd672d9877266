"""benchmarks/_shared.py: the benchmarks find ../shared beside a main checkout, a git worktree and a clone alike, and
honour RELIGHT_RT_SHARED as tests/conftest.py does."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"


@pytest.fixture()
def shared(load_benchmark, monkeypatch):
    monkeypatch.delenv("RELIGHT_RT_SHARED", raising=False)
    return load_benchmark("_shared")


def _layout(root: Path, checkout: str, shared_at: str) -> Path:
    """A checkout at ``root/checkout`` and a shared/ holding reference/ and realdata/yale/ at ``root/shared_at``."""
    (root / checkout).mkdir(parents=True)
    for part in ("reference", "realdata/yale"):
        (root / shared_at / part).mkdir(parents=True)
    return root / checkout


@pytest.mark.parametrize(("checkout", "shared_at"), [("main", "shared"), ("wt/paths", "shared"),
                                                     ("x/clone", "x/shared")])
def test_shared_is_found_beside_a_checkout_or_above_it(shared, monkeypatch, tmp_path, checkout, shared_at):
    monkeypatch.setattr(shared, "REPO", _layout(tmp_path, checkout, shared_at))
    assert shared.shared_dir("reference") == tmp_path / shared_at
    assert shared.shared_path("realdata", "yale") == tmp_path / shared_at / "realdata" / "yale"
    assert shared.shared_dir("reference", "no_such_set") is None  # a shared/ that lacks the set does not count


def test_the_nearest_shared_that_holds_the_set_wins(shared, monkeypatch, tmp_path):
    repo = _layout(tmp_path, "wt/x", "shared")
    (tmp_path / "wt" / "shared" / "other_set").mkdir(parents=True)  # a nearer shared/ with another set only
    monkeypatch.setattr(shared, "REPO", repo)
    assert shared.shared_dir("other_set") == tmp_path / "wt" / "shared"
    assert shared.shared_dir("reference") == tmp_path / "shared"


def test_the_environment_overrides_and_a_missing_set_gets_a_path_that_says_where(shared, monkeypatch, tmp_path):
    repo = _layout(tmp_path, "main", "shared")
    monkeypatch.setattr(shared, "REPO", repo)
    other = tmp_path / "elsewhere"
    (other / "reference").mkdir(parents=True)
    monkeypatch.setenv("RELIGHT_RT_SHARED", str(other))
    assert shared.shared_dir("reference") == other
    assert shared.shared_dir("realdata", "yale") is None  # only the given folder, not the one beside the checkout
    monkeypatch.setenv("RELIGHT_RT_SHARED", "/nonexistent")
    assert shared.shared_dir("reference") is None
    assert shared.shared_path("reference") == Path("/nonexistent/reference")
    assert "RELIGHT_RT_SHARED" in shared.missing(shared.shared_path("reference"))
    monkeypatch.delenv("RELIGHT_RT_SHARED")
    assert shared.shared_path("reference", "no_such_set") == tmp_path / "shared" / "reference" / "no_such_set"


def test_a_script_says_when_its_set_is_missing(tmp_path):
    """yale_eval's default with RELIGHT_RT_SHARED pointing nowhere: exit status 2 and a line naming the path."""
    env = {"RELIGHT_RT_SHARED": str(tmp_path / "none"), "PYTHONPATH": str(BENCHMARKS.parent),
           "PATH": "/usr/bin:/bin"}
    run = subprocess.run([sys.executable, str(BENCHMARKS / "yale_eval.py"), "--out", str(tmp_path / "out"),
                          "--no-dpr"], env=env, capture_output=True, text=True, timeout=300)
    assert run.returncode == 2
    assert f"{tmp_path / 'none' / 'realdata' / 'yale'} not found" in run.stderr
