"""The CLI run in the test's own process: a test's working folder, and ``relight-rt ARGV`` with what it printed."""

from __future__ import annotations

from pathlib import Path

from relight_rt import cli


def in_folder(folder: Path, models_dir: Path, monkeypatch) -> Path:
    """Work in ``folder`` (the current directory for the test) with the test graphs of ``models_dir`` as
    RELIGHT_RT_MODELS; returns ``folder``."""
    monkeypatch.setenv("RELIGHT_RT_MODELS", str(models_dir))
    monkeypatch.chdir(folder)
    return folder


def run(argv, capsys) -> tuple[int, str, str]:
    """``relight-rt ARGV`` (each item as str): (exit code, stdout, stderr)."""
    code = cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err
