"""benchmarks/video_eval.py: the comparison sheet (the table itself is measured by relight_rt.video.metrics tests)."""

import importlib.util
from pathlib import Path

import cv2
import numpy as np
import pytest

from relight_rt.image.io import write_image

pytest.importorskip("torch")  # the sheet uses export.render.contact_sheet

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "video_eval.py"


def _load_script():
    spec = importlib.util.spec_from_file_location("video_eval", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_comparison_sheet_has_a_row_per_method_and_shows_flicker(tmp_path):
    video_eval = _load_script()
    frames = tmp_path / "frames"
    frames.mkdir()
    h, w, n = 40, 24, 8
    mask = np.zeros((h, w), np.float32)
    mask[5:35, 4:20] = 1
    rng = np.random.default_rng(0)
    for d in ("steady", "flicker"):
        (tmp_path / d).mkdir()
    for t in range(n):
        name = f"f{t:02d}"
        write_image(frames / f"{name}.png", np.full((h, w, 3), 0.5, np.float32))
        write_image(frames / f"{name}_mask.png", mask)
        write_image(tmp_path / "steady" / f"{name}.png", np.full((h, w, 3), 0.4, np.float32))
        write_image(tmp_path / "flicker" / f"{name}.png", rng.uniform(0.2, 0.6, (h, w, 3)).astype(np.float32))
    rows = {"steady": {"dir": "steady"}, "flicker": {"dir": "flicker"}}
    tile = 32
    video_eval.write_comparison(tmp_path / "comparison.png", frames, rows, columns=6, tile=tile)

    sheet = cv2.imread(str(tmp_path / "comparison.png"))
    assert sheet.shape == (4 * tile, 6 * tile, 3)  # input, two methods, the change row; six frames
    change_row = sheet[3 * tile:].astype(np.float32)
    steady_change = change_row[16:, :tile].mean()  # below the label
    flicker_change = change_row[16:, tile:2 * tile].mean()
    assert flicker_change > steady_change + 20
