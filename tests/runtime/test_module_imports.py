"""Every runtime module imports on its own, first, in a fresh package (no import circle hidden by import order).

The package loads its public names lazily (relight_rt.__getattr__), so ``from . import x`` inside a module can
run the whole public surface before that module has finished: a module imported first then failed with "partially
initialized module" (relight_rt.person.face_mesh did, through ``from . import _faces``)."""

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
    assert "relight_rt.person.face_mesh" in names and "relight_rt.cli.options" in names
    done = subprocess.run([sys.executable, "-W", "ignore", "-c", SCRIPT, *names], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr


WING = [f"relight/{p.name}" for p in sorted((PACKAGE / "relight").glob("*.py"))]
CORE = [*WING, "video/job.py", "person/face_mesh.py"]


def _imports(path: Path) -> list[tuple[str, list[str]]]:
    """Every import of a module, function bodies included: (the module as written, the names taken)."""
    import ast

    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found += [(alias.name, []) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            found.append(("." * node.level + (node.module or ""), [alias.name for alias in node.names]))
    return found


def test_the_relighting_core_imports_neither_matting_nor_scene():
    """Issue 47: the matter is handed in (``Relighter(config, matter=...)``; relight_rt.builder builds the bundled
    one) and compositing into a scene is an app over the core (``scene.composite(relighter, ...)``)."""
    assert len(CORE) > 8
    for name in CORE:
        for module, names in _imports(PACKAGE / name):
            words = module.replace(".", " ").split() + names
            assert "matting" not in words and "scene" not in words and "builder" not in words, (name, module, names)


def test_the_relighting_wing_imports_no_private_name_of_another_module():
    for name in WING:
        for module, names in _imports(PACKAGE / name):
            assert not [n for n in names if n.startswith("_") and n != "__future__"], (name, module, names)
