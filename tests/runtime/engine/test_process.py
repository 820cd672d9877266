"""``relight_rt.engine.process.give_back_freed_memory``: the C allocator's freed pages handed back to the system (what
``relight_file`` does between a photo's relight and its encoding)."""

from __future__ import annotations

import os
import platform
import resource

import numpy as np
import pytest

from relight_rt.engine import process
from relight_rt.engine.process import give_back_freed_memory


def _resident() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * resource.getpagesize()


@pytest.mark.skipif(platform.system() != "Linux" or platform.libc_ver()[0] != "glibc"
                    or any(k.startswith("MALLOC_") for k in os.environ), reason="glibc's own malloc only")
def test_freed_arrays_under_the_mmap_threshold_go_back_to_the_system():
    big = np.ones(1 << 22, np.float32)  # 16 MB freed: glibc raises its mmap threshold to it ...
    del big
    arrays = [np.ones(1 << 20, np.float32) for _ in range(48)]  # ... so these 4-MB arrays come from the heap
    top = np.ones(1 << 20, np.float32)  # held above them: the heap's top cannot shrink
    before = _resident()
    del arrays
    freed = _resident()
    give_back_freed_memory()
    after = _resident()
    assert top.size and before - freed < 64e6  # glibc kept most of the 192 MB ...
    assert freed - after > 128e6  # ... which it hands back when asked


def test_it_can_be_called_any_time():
    give_back_freed_memory()
    give_back_freed_memory()


class _NoTrim:
    """A C library without ``malloc_trim`` (macOS's, musl's): the attribute lookup fails."""


@pytest.mark.parametrize("opened", [_NoTrim, OSError, TypeError])
def test_without_glibc_it_does_nothing(monkeypatch, opened):
    """Where ``ctypes.CDLL(None)`` opens a C library without ``malloc_trim`` (AttributeError) or cannot open the process
    itself (OSError; TypeError: Windows, which takes no None), the call is a no-op, never an error."""
    def cdll(name):
        if isinstance(opened, type) and issubclass(opened, Exception):
            raise opened("no C library here")
        return opened()

    monkeypatch.setattr(process, "_TRIM", [])
    monkeypatch.setattr(process.ctypes, "CDLL", cdll)
    give_back_freed_memory()
    give_back_freed_memory()
    assert process._TRIM == [None]
