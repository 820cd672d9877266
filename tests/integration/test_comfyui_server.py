"""examples/comfyui_relight.json in a real ComfyUI server (headless, --cpu, 127.0.0.1), against the CLI.

Needs a ComfyUI checkout: $COMFYUI_DIR (github:comfyanonymous/ComfyUI), and $COMFYUI_PYTHON, the Python its
requirements are installed in (default: this one). Skipped without them. docs/COMFYUI.md says how to set one up.
"""

import importlib.util
import json
import os
import sys
from pathlib import Path

import pytest
from conftest import REPO


def test_workflow_matches_the_cli(tmp_path):
    comfy = os.environ.get("COMFYUI_DIR")
    if not comfy or not (Path(comfy) / "main.py").is_file():
        pytest.skip("$COMFYUI_DIR does not name a ComfyUI checkout")
    spec = importlib.util.spec_from_file_location("comfyui_workflow", REPO / "benchmarks" / "comfyui_workflow.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    python = os.environ.get("COMFYUI_PYTHON", sys.executable)
    rc = bench.main(["--comfyui", comfy, "--python", python, "--out", str(tmp_path)])
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert rc == 0, summary
    assert set(summary["max_abs_diff_8bit"]) == {"night", "lamp"}
    assert max(summary["max_abs_diff_8bit"].values()) <= 1  # 1/255: SaveImage truncates where the CLI rounds
    assert summary["shape"]["night"] == [600, 450, 3]
    ran = {"3 RelightRTDecompose", "6 RelightRTRelight", "7 RelightRTRelight", "10 RelightRTPasses", "11 SaveImage"}
    assert ran <= set(summary["node_s"])
    assert (tmp_path / "comfyui_normal.png").is_file()
