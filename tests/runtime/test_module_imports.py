"""Every runtime module imports on its own, first, in a fresh package (no import circle hidden by import order).

The package loads its public names lazily (relight_rt.__getattr__), so ``from . import x`` inside a module can
run the whole public surface before that module has finished: a module imported first then failed with "partially
initialized module" (relight_rt._face_geometry did, through ``from . import _faces``)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import relight_rt

PACKAGE = Path(relight_rt.__file__).resolve().parent

SCRIPT = r"""
import importlib, sys, traceback
failed = []
for name in sys.argv[1:]:
    for key in [k for k in sys.modules if k == "relight_rt" or k.startswith("relight_rt.")]:
        del sys.modules[key]
    try:
        importlib.import_module(name)
    except Exception:
        failed.append(name + ": " + traceback.format_exc().strip().splitlines()[-1])
print("\n".join(failed))
sys.exit(1 if failed else 0)
"""


def runtime_modules() -> list[str]:
    names = []
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE.parent).with_suffix("")
        if rel.name == "__main__":
            continue  # runs the CLI
        parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
        names.append(".".join(parts))
    return names


def test_every_runtime_module_imports_first():
    names = runtime_modules()
    assert "relight_rt._face_geometry" in names and "relight_rt.cli.options" in names
    done = subprocess.run([sys.executable, "-W", "ignore", "-c", SCRIPT, *names], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
