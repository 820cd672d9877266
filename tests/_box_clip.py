"""A synthetic clip for the video tests: a person (a box with a sharp edge) before a bright background."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

H, W = 120, 100


def box_clip(folder: Path, n: int = 3, grow: int = 0) -> np.ndarray:
    """Write ``n`` frames ``fNN.png`` of the box before the background into ``folder`` (created), each with its 8-bit
    mask beside it (``fNN_mask.png``): the box ``grow`` px wider on every side, its edge blurred 3 px (with ``grow``
    2, alpha ~0.5 two pixels past the box). The frames differ a little (a stripe moves down a row a frame). Returns
    the box (H, W) bool."""
    box = np.zeros((H, W), bool)
    box[10:110, 30:70] = True
    wide = np.zeros((H, W), np.float32)
    wide[10 - grow : 110 + grow, 30 - grow : 70 + grow] = 1
    soft = np.round(np.clip(cv2.GaussianBlur(wide, (0, 0), 3.0), 0, 1) * 255).astype(np.uint8)
    folder.mkdir()
    for t in range(n):
        img = np.empty((H, W, 3), np.uint8)
        img[:] = (150, 215, 230)  # BGR: a bright background
        img[box] = (90, 100, 128)
        img[50 + t, 40:60] = (80, 90, 110)
        cv2.imwrite(str(folder / f"f{t:02d}.png"), img)
        cv2.imwrite(str(folder / f"f{t:02d}_mask.png"), soft)
    return box
