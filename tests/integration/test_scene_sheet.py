"""benchmarks/scene_sheet.py: a real photo of a place as a background (centre-cropped to the sheet's aspect)."""

from __future__ import annotations

import sys
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import scene_sheet  # noqa: E402


def test_a_photo_of_a_place_is_centre_cropped_to_the_sheets_aspect(tmp_path):
    wide = np.zeros((100, 300, 3), np.uint8)
    wide[:, 100:200] = 255  # the middle third white: a centre crop to 4:3 (133 px) keeps it in the middle
    cv2.imwrite(str(tmp_path / "wide.png"), wide)
    out = scene_sheet.photo_background(tmp_path / "wide.png", (60, 80))
    assert out.shape == (60, 80, 3) and out.dtype == np.uint8
    assert out[:, 40].min() == 255 and out[:, 0].max() == 0 and out[:, -1].max() == 0
    tall = np.zeros((400, 100, 3), np.uint8)
    tall[:, :, 1] = np.linspace(0, 255, 400).astype(np.uint8)[:, None]  # a vertical ramp: the middle rows kept
    cv2.imwrite(str(tmp_path / "tall.png"), tall)
    out = scene_sheet.photo_background(tmp_path / "tall.png", (60, 80))
    assert out.shape == (60, 80, 3) and 90 < int(out[:, :, 1].mean()) < 165
