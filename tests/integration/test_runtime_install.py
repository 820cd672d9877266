"""Issue 18 item 10: in a runtime-only install (numpy, onnxruntime, opencv, pytest) the runtime tests run or
skip with a reason that names the ``test`` extra; none fails to import."""

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

# Runs pytest with the packages of the extras made unimportable (as in `pip install . pytest`).
_DRIVER = """
import sys
BLOCK = {"onnx", "hypothesis", "torch", "tqdm", "av", "pytest_timeout", "onnxscript"}

class Block:
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in BLOCK:
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
        return None

sys.meta_path.insert(0, Block())
import pytest
sys.exit(pytest.main(["-q", "-rs", "-p", "no:cacheprovider", *sys.argv[1:]]))
"""


def test_runtime_tests_skip_with_a_reason_without_the_test_extra():
    files = ["tests/runtime/image/test_io.py", "tests/runtime/engine/test_limits.py",
             "tests/runtime/relight/test_relighter.py",
             "tests/runtime/cli/test_cli.py"]
    env = {**os.environ, "PYTEST_DISABLE_PLUGIN_AUTOLOAD": "1"}
    proc = subprocess.run([sys.executable, "-c", _DRIVER, *files], cwd=REPO, capture_output=True, text=True,
                          env=env, timeout=300)  # fmt: skip
    assert proc.returncode == 0, proc.stdout[-3000:]
    assert 'pip install "relight-rt[test]"' in proc.stdout
    assert " passed" in proc.stdout and "error" not in proc.stdout.lower().split("short test summary")[-1]
