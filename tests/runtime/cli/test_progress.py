"""relight_rt.cli.progress: a tqdm bar on the long commands, or log lines with the rate and the time left."""

from __future__ import annotations

import logging
import sys

import pytest

from relight_rt.cli.progress import Progress, progress


def test_without_tqdm_log_lines_say_count_rate_and_time_left(monkeypatch, caplog):
    monkeypatch.setitem(sys.modules, "tqdm", None)  # import tqdm raises ImportError
    with caplog.at_level(logging.INFO, logger="relight_rt.cli"), Progress(3, "frame", every=0) as bar:
        for _ in range(3):
            bar.update()
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 3
    assert lines[0].startswith("frame 1 / 3, ") and "frame/s" in lines[0] and lines[0].endswith(" s left")
    assert lines[2].startswith("frame 3 / 3, ") and "left" not in lines[2]


def test_unknown_total_and_throttling(monkeypatch, caplog):
    monkeypatch.setitem(sys.modules, "tqdm", None)
    with caplog.at_level(logging.INFO, logger="relight_rt.cli"):
        assert list(progress(["a", "b"], "image")) == ["a", "b"]  # every 10 s: the quick loop logs nothing
        with Progress(None, "frame", every=0) as bar:
            bar.update()
    assert [r.getMessage().split(",")[0] for r in caplog.records] == ["frame 1"]


def test_quiet_or_disabled_shows_nothing(monkeypatch, caplog, capsys):
    with caplog.at_level(logging.WARNING, logger="relight_rt.cli"), Progress(2, "frame", every=0) as bar:
        bar.update(2)
    with caplog.at_level(logging.INFO, logger="relight_rt.cli"), Progress(2, "frame", every=0, enabled=False) as b:
        b.update(2)
    assert caplog.records == [] and capsys.readouterr().err == ""


def test_with_tqdm_a_bar_on_a_terminal(caplog, capsys, monkeypatch):
    pytest.importorskip("tqdm")
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    with caplog.at_level(logging.INFO, logger="relight_rt.cli"), Progress(4, "frame") as bar:
        for _ in range(4):
            bar.update()
    err = capsys.readouterr().err
    assert "/4 [" in err and "frame/s" in err and caplog.records == []  # count / total, rate (and time left)


def test_no_bar_when_stderr_is_not_a_terminal(caplog, capsys, monkeypatch):
    """Piped or logged stderr (CI, a batch job's log, a caller reading one error line) gets no bar."""
    pytest.importorskip("tqdm")
    monkeypatch.setattr(sys.stderr, "isatty", lambda: False)
    with caplog.at_level(logging.INFO, logger="relight_rt.cli"), Progress(4, "frame") as bar:
        for _ in range(4):
            bar.update()
    assert "frame/s" not in capsys.readouterr().err
