"""The runtime never imports torch: import every relight_rt module with torch made unimportable."""

import subprocess
import sys

from conftest import REPO

CODE = r"""
import sys, pkgutil, importlib
sys.modules['torch'] = None  # any 'import torch' now raises ImportError
import relight_rt
for info in pkgutil.walk_packages(relight_rt.__path__, 'relight_rt.'):
    if info.name.endswith('__main__'):
        continue
    importlib.import_module(info.name)
assert 'torch' not in {m for m in sys.modules if sys.modules[m] is not None}
print('ok')
"""


def test_runtime_imports_without_torch():
    out = subprocess.run([sys.executable, "-c", CODE], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().endswith("ok")
