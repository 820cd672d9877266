"""Every runtime module imports on its own, first, in a fresh package (no import circle hidden by import order).

The package loads its public names lazily (relight_rt.__getattr__), so ``from . import x`` inside a module can
run the whole public surface before that module has finished: a module imported first then failed with "partially
initialized module" (relight_rt.person.face_mesh did, through ``from . import _faces``)."""

from __future__ import annotations

import ast
import re
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


# The wings, ground floor first: a module imports only its own wing and the ones before it (issue 47). The
# package face (relight_rt/__init__.py, which loads its public names lazily by name) and _version stand on the
# ground; builder.py (open: the Relighter with its matter) stands above the core and below the apps.
WINGS = ("engine", "image", "light", "person", "relight", "video", "builder", "apps", "cli", "entry")
ROOT = {"relight_rt": "engine", "relight_rt._version": "engine", "relight_rt.builder": "builder",
        "relight_rt._launch": "entry", "relight_rt.__main__": "entry"}  # fmt: skip
# the relighting core: the Relighter's modules, the video job, and the face mesh the face pass uses
CORE = ("relight_rt.relight", "relight_rt.video", "relight_rt.person.face_mesh")
MAX_LINES = 800
RELIGHTER_MAX_LINES = 500


def _modules() -> dict[str, Path]:
    found = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE.parent).with_suffix("")
        found[".".join(rel.parts[:-1] if rel.name == "__init__" else rel.parts)] = path
    return found


MODULES = _modules()


def _imports(name: str) -> list[tuple[str, str | None, int]]:
    """Every import of a module, function bodies included: (the relight_rt module it reaches, the name taken or
    None, the line). A name that is a submodule counts as that module."""
    path = MODULES[name]
    package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                full = ".".join([*base, *([node.module] if node.module else [])])
            else:
                full = node.module or ""
            if full == "relight_rt" or full.startswith("relight_rt."):
                for alias in node.names:
                    sub = f"{full}.{alias.name}"
                    found.append((sub, None, node.lineno) if sub in MODULES else (full, alias.name, node.lineno))
        elif isinstance(node, ast.Import):
            found += [(a.name, None, node.lineno) for a in node.names if a.name.split(".")[0] == "relight_rt"]
    return found


def _wing(name: str) -> str:
    return ROOT.get(name) or name.split(".")[1]


def test_every_module_stands_in_a_wing():
    assert {_wing(n) for n in MODULES} <= set(WINGS), sorted({_wing(n) for n in MODULES} - set(WINGS))
    flat = sorted(n for n, path in MODULES.items() if path.parent == PACKAGE and n not in ROOT)
    assert flat == [], f"modules outside the wings: {flat}"


def test_no_import_runs_back_up_the_wings():
    up = [f"{name}:{line} imports {target}" for name in MODULES for target, _, line in _imports(name)
          if WINGS.index(_wing(target)) > WINGS.index(_wing(name))]  # fmt: skip
    assert up == []


def test_no_import_circle():
    graph = {name: {t for t, _, _ in _imports(name) if t in MODULES and t != name} for name in MODULES}
    done: set[str] = set()
    path: list[str] = []

    def visit(name: str) -> list[str] | None:  # depth first; a module met again on the path is a circle
        if name in path:
            return path[path.index(name):] + [name]
        if name in done:
            return None
        path.append(name)
        for target in sorted(graph[name]):
            circle = visit(target)
            if circle:
                return circle
        path.pop()
        done.add(name)
        return None

    for name in MODULES:
        circle = visit(name)
        assert circle is None, " -> ".join(circle)


def test_no_private_name_is_imported_across_modules():
    """``from .x import _y`` anywhere in relight_rt, and a private module taken from outside its own package."""
    taken = []
    for name, path in MODULES.items():
        package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
        for target, attribute, line in _imports(name):
            if attribute is not None and attribute.startswith("_") and not attribute.startswith("__"):
                taken.append(f"{name}:{line} {target}.{attribute}")
            parent, _, leaf = target.rpartition(".")  # a private module, or a name out of one, from outside its package
            if leaf.startswith("_") and not leaf.startswith("__") and parent != package:
                taken.append(f"{name}:{line} {target}")
    assert taken == []


def test_no_private_name_is_read_across_modules_by_getattr():
    """Nor round the imports: ``getattr(module, "_NAME")`` on a module the file imported."""
    reads = []
    for name, path in MODULES.items():
        text = path.read_text(encoding="utf-8")
        bound = {alias.asname or alias.name.split(".")[0] for node in ast.walk(ast.parse(text))
                 if isinstance(node, (ast.Import, ast.ImportFrom)) for alias in node.names}  # fmt: skip
        reads += [f"{name}: {m.group(0)}" for m in re.finditer(r'getattr\((\w+), "_[A-Za-z]\w*"', text)
                  if m.group(1) in bound]  # fmt: skip
    assert reads == []


def test_only_the_cli_parses_arguments():
    outside = [name for name in MODULES if _wing(name) != "cli"
               for node in ast.walk(ast.parse(MODULES[name].read_text(encoding="utf-8")))
               if isinstance(node, (ast.Import, ast.ImportFrom))
               and "argparse" in ([a.name for a in node.names] if isinstance(node, ast.Import) else [node.module])]
    assert outside == []


def test_modules_are_room_sized():
    sizes = {name: len(path.read_text(encoding="utf-8").splitlines()) for name, path in MODULES.items()}
    assert {n: s for n, s in sizes.items() if s > MAX_LINES} == {}
    home = relight_rt.Relighter.__module__
    assert home == "relight_rt.relight.relighter" and sizes[home] <= RELIGHTER_MAX_LINES, sizes[home]


def test_the_relighting_core_imports_neither_matting_nor_scene():
    """Issue 47: the matter is handed in (``Relighter(config, matter=...)``; relight_rt.builder builds the bundled
    one) and compositing into a scene is an app over the core (``scene.composite(relighter, ...)``)."""
    core = [n for n in MODULES if n.startswith(CORE)]
    assert len(core) > 12 and "relight_rt.video.job" in core and "relight_rt.relight.relighter" in core
    reached = [f"{name}:{line} {target}" for name in core for target, _, line in _imports(name)
               if target.startswith(("relight_rt.person.matting", "relight_rt.apps", "relight_rt.builder"))]
    assert reached == []


def test_the_core_takes_no_matting_or_scene_by_name():
    """Nor a lazy way round the imports: importlib or a string naming the matting package or the scene module."""
    for name in (n for n in MODULES if n.startswith(CORE)):
        text = MODULES[name].read_text(encoding="utf-8")
        assert "import_module" not in text and "find_spec" not in text, name
