"""Shared fixtures: the reference data in ../shared (skipped when absent) and tiny test models."""

from __future__ import annotations

import importlib.util
import os
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
TEST_DATA = REPO / "tests" / "data"
BENCHMARKS = REPO / "benchmarks"


@pytest.fixture(scope="session")
def load_benchmark():
    """``load_benchmark(NAME)``: benchmarks/NAME.py imported as module NAME (the scripts are not a package: their
    folder goes on sys.path so that they import each other, and the module is registered so that their dataclasses
    find it)."""

    def load(name: str):
        if str(BENCHMARKS) not in sys.path:
            sys.path.insert(0, str(BENCHMARKS))
        spec = importlib.util.spec_from_file_location(name, BENCHMARKS / f"{name}.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
        return module

    return load


@pytest.fixture(scope="session", autouse=True)
def _graph_cache(tmp_path_factory):
    """Optimised graphs (relight_rt.engine.graph_cache) go to a folder of the test run, not the user's cache
    (subprocesses inherit it); a test that sets $RELIGHT_RT_CACHE itself wins."""
    if "RELIGHT_RT_CACHE" not in os.environ:
        os.environ["RELIGHT_RT_CACHE"] = str(tmp_path_factory.mktemp("graph_cache"))
    yield


def _find_shared() -> Path | None:
    env = os.environ.get("RELIGHT_RT_SHARED")
    if env:
        return Path(env) if Path(env, "reference").is_dir() else None
    for parent in REPO.parents:  # ../shared beside the checkout (or beside a worktree folder)
        candidate = parent / "shared"
        if (candidate / "reference").is_dir():
            return candidate
    return None


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    """The ../shared folder (DESIGN.md §8); the test is skipped when it is absent."""
    path = _find_shared()
    if path is None:
        pytest.skip("../shared/reference is not present")
    return path


@pytest.fixture(scope="session")
def reference_dir(shared_dir: Path) -> Path:
    """../shared/reference: the reference implementation's test data (CC BY-NC-SA 4.0; never copied)."""
    return shared_dir / "reference"


@pytest.fixture(scope="session")
def test_data_dir() -> Path:
    """tests/data: tiny ONNX models with random weights and other small committed fixtures."""
    return TEST_DATA


def _find_dpr() -> Path | None:
    env = os.environ.get("DPR_REPO")  # benchmarks/real_photos.py's convention
    for candidate in ([Path(env)] if env else []) + [Path("/work/.mirror/zhhoper+DPR/repo")]:
        if candidate.is_dir():
            return candidate
    return None


@pytest.fixture(scope="session")
def dpr_portrait(tmp_path_factory):
    """DPR's demo portrait (data/obama.jpg of github:zhhoper/DPR) as float32 RGB, read from a checkout or bare
    git directory ($DPR_REPO, else the mirror /work/.mirror/zhhoper+DPR/repo) into a temporary folder (never
    into the repo); the test is skipped when it is absent."""
    import subprocess

    from relight_rt.image.io import read_image

    repo = _find_dpr()
    if repo is None:
        pytest.skip("DPR's repository is not present ($DPR_REPO)")
    if (repo / "data" / "obama.jpg").is_file():
        data = (repo / "data" / "obama.jpg").read_bytes()
    else:
        run = subprocess.run(["git", f"--git-dir={repo}", "show", "HEAD:data/obama.jpg"], capture_output=True)
        if run.returncode != 0 or not run.stdout:
            pytest.skip(f"data/obama.jpg is not readable from {repo}")
        data = run.stdout
    path = tmp_path_factory.mktemp("dpr") / "obama.jpg"
    path.write_bytes(data)
    return read_image(path)


def _people_photo(name: str):
    """A photo of benchmarks/people_photos.py's cache ($RELIGHT_RT_PEOPLE, else its default folder) as float32
    RGB; the test is skipped when it is absent."""
    import os
    import tempfile

    from relight_rt.image.io import read_image

    folder = Path(os.environ.get("RELIGHT_RT_PEOPLE", Path(tempfile.gettempdir()) / "relight_rt_people"))
    path = folder / name
    if not path.is_file():
        pytest.skip(f"{path} is absent (run benchmarks/people_photos.py --cache {folder})")
    return read_image(path)


@pytest.fixture(scope="session")
def grace_hopper():
    """matplotlib's sample photo grace_hopper.jpg (512x600), from people_photos' cache; skipped when absent."""
    return _people_photo("grace_hopper.jpg")


@pytest.fixture(scope="session")
def group_t1():
    """insightface's sample photo t1.jpg (six people round a table, 1280x886), from people_photos' cache;
    skipped when absent."""
    return _people_photo("group_t1.jpg")


@pytest.fixture(scope="session")
def rose_hair():
    """face_recognition's example photo of Rose Leslie (knn_examples/train/rose_leslie/img2.jpg, 577x878),
    from people_photos' cache; skipped when absent."""
    return _people_photo("rose_hair.jpg")


@pytest.fixture(scope="session")
def two_dancers():
    """U-2-Net's test photo of two dancers in the air (people_photos' two_dancers.jpg, 633x800), from people_photos'
    cache; skipped when absent."""
    return _people_photo("two_dancers.jpg")


@pytest.fixture(scope="session")
def skater():
    """U-2-Net's test photo of a figure skater (people_photos' skater.jpg, 2405x1603: a raised hand the matte holds
    apart from her arm), from people_photos' cache; skipped when absent."""
    return _people_photo("skater.jpg")
