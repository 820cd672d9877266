"""The environment variables' one reader each (relight_rt.engine.environment; issue 50 bugs 7 and 8)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from relight_rt import RelightError
from relight_rt.engine import environment as _env
from relight_rt.engine.session import cpu_session_options

PACKAGE = Path(_env.__file__).resolve().parent


@pytest.mark.parametrize("text, expected", [(None, None), ("", None), ("  ", None), ("0", 0), (" 2 ", 2), ("64", 64)])
def test_threads_accepts_whole_numbers_in_range(monkeypatch, text, expected):
    if text is None:
        monkeypatch.delenv(_env.THREADS, raising=False)
    else:
        monkeypatch.setenv(_env.THREADS, text)
    assert _env.threads() == expected


# 1000000 made onnxruntime create threads until the process died (SIGSEGV, no message); 2**64 + 1 raised
# pybind11's TypeError as a traceback; 99999999 was reported as "not a readable ONNX graph"
@pytest.mark.parametrize("text", ["1000000", "18446744073709551617", "99999999", "65", "-3", "two", "1e3", "٣",
                                  "0x10", "9" * 5000])  # fmt: skip
def test_threads_refuses_anything_else_before_onnxruntime_sees_it(monkeypatch, text):
    monkeypatch.setattr(_env.os, "cpu_count", lambda: 2)  # the cap: four per core, at least 64
    monkeypatch.setenv(_env.THREADS, text)
    with pytest.raises(RelightError, match=r"^\$RELIGHT_RT_THREADS is '.{1,43}', expected a whole number from 0 "
                                           r"\(onnxruntime's default\) to 64$"):  # fmt: skip
        cpu_session_options()


def test_max_threads_follows_the_cores(monkeypatch):
    monkeypatch.setattr(_env.os, "cpu_count", lambda: 32)
    monkeypatch.setenv(_env.THREADS, "128")
    assert _env.max_threads() == 128 and _env.threads() == 128


def test_openexr_switch(monkeypatch):
    for text, on in (("1", True), ("TRUE", True), (" on ", True), ("0", False), ("yes", False), ("", False)):
        monkeypatch.setenv(_env.OPENEXR, text)
        assert _env.openexr_enabled() is on


def test_no_other_module_reads_these_variables():
    names = "|".join(re.escape(n) for n in (_env.THREADS, _env.MODELS, _env.TENSORRT, _env.OPENEXR))
    read = re.compile(r"(environ\.get|getenv|environ\[)\(?\s*[\"'](" + names + r")[\"']")
    readers = sorted(str(p.relative_to(PACKAGE)) for p in PACKAGE.rglob("*.py") if read.search(p.read_text("utf-8")))
    assert readers == [], readers
    assert "os.environ.get(ENV_" not in "".join(p.read_text("utf-8") for p in PACKAGE.rglob("*.py"))
