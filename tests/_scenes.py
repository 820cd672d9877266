"""Test scenes that make user-facing bugs visible (issue 26).

Grey lights, binary rectangle masks and a background equal to the photo hide a whole class of bugs: a
flag that swaps colours or turns the light changes nothing on a grey, frontal light; a blend that
thresholds the mask gives the same answer on a 0/1 mask. These helpers give:

- coloured, directional SH lights (``directional``, ``ambient``);
- a soft, irregular person mask (``soft_person``): a feathered body, a hole, thin hair-like strands of
  partial alpha, a fully opaque core;
- a background that differs from the person (``backdrop``);
- brightness and colour read-outs of the left/right half of the person (``side_means``).

Use with tests/_graphs.py's ``stage1_sides_model`` (normals -y on the left, +y on the right).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from relight_rt import sh


def directional(direction, colour=(1.0, 1.0, 1.0), strength: float = 1.5) -> np.ndarray:
    """(9, 3) float64 RGB light concentrated around the unit ``direction`` (its SH projection's shape)."""
    d = np.asarray(direction, np.float64)
    d = d / np.linalg.norm(d)
    return strength * sh.basis(d)[:, None] * np.asarray(colour, np.float64)[None, :]


def ambient(colour=(1.0, 1.0, 1.0)) -> np.ndarray:
    """(9, 3) float64 RGB light of constant radiance: shading = pi * Y_0 * L_0 = colour on every normal."""
    light = np.zeros((9, 3))
    light[0] = np.asarray(colour, np.float64) / (np.pi * 0.5 / np.sqrt(np.pi))
    return light


def soft_person(h: int = 150, w: int = 100, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A textured float32 RGB photo (H, W, 3) and a soft (H, W) float32 mask in [0, 1].

    The mask: an ellipse body with a feathered edge, a feathered hole in the torso, six thin strands of
    alpha ~0.4 above the head; its core is exactly 1 and its far background exactly 0. The photo's
    person is textured grey-ish; outside it the photo is a blue-green gradient (differs from the person).
    """
    rng = np.random.default_rng(seed)
    body = np.zeros((h, w), np.float32)
    cy, cx = int(h * 0.58), w // 2
    cv2.ellipse(body, (cx, cy), (int(w * 0.28), int(h * 0.33)), 0, 0, 360, 1.0, -1)
    cv2.circle(body, (cx, int(h * 0.2)), int(w * 0.13), 1.0, -1)  # head
    cv2.circle(body, (cx + int(w * 0.08), cy), max(3, w // 14), 0.0, -1)  # a hole (between arm and torso)
    body = cv2.GaussianBlur(body, (0, 0), 2.0)
    strands = np.zeros((h, w), np.float32)
    for k in range(6):
        x0 = cx - int(w * 0.12) + k * int(w * 0.05)
        cv2.line(strands, (x0, int(h * 0.12)), (x0 + int(rng.integers(-6, 7)), 2), 0.45, 1)
    strands = cv2.GaussianBlur(strands, (0, 0), 0.6)
    mask = np.clip(np.maximum(body, strands), 0, 1)
    mask[mask < 1e-3] = 0.0
    mask[mask > 1 - 1e-3] = 1.0
    photo = backdrop(h, w)
    texture = (0.25 + 0.5 * rng.random((h, w, 3))).astype(np.float32)
    photo = photo + (texture - photo) * mask[..., None]
    return photo.astype(np.float32), mask.astype(np.float32)


def backdrop(h: int, w: int) -> np.ndarray:
    """(H, W, 3) float32 blue-green diagonal gradient: nothing like the person."""
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    t = (yy / max(1, h - 1) + xx / max(1, w - 1)) / 2
    return np.stack([0.05 + 0.1 * t, 0.4 + 0.4 * t, 0.9 - 0.3 * t], axis=2).astype(np.float32)


def side_means(image: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean RGB of the opaque person (mask == 1) left and right of its centre column: (3,), (3,)."""
    core = mask >= 1.0
    cols = np.nonzero(core.any(axis=0))[0]
    centre = (cols[0] + cols[-1] + 1) / 2
    xx = np.arange(mask.shape[1])[None, :]
    left, right = core & (xx < centre - 2), core & (xx >= centre + 2)
    img = np.asarray(image, np.float64)[..., :3]
    return img[left].mean(axis=0), img[right].mean(axis=0)


def write_scene(folder: Path, name: str = "p", seed: int = 0, h: int = 150, w: int = 100) -> Path:
    """Write ``soft_person`` as NAME.png and NAME_mask.png (8-bit) into ``folder``; returns the photo's path."""
    img, mask = soft_person(h, w, seed)
    cv2.imwrite(str(folder / f"{name}.png"), (img[..., ::-1] * 255).round().astype(np.uint8))
    cv2.imwrite(str(folder / f"{name}_mask.png"), (mask * 255).round().astype(np.uint8))
    return folder / f"{name}.png"


def write_noise_clip(path: Path, n: int, w: int = 64, h: int = 48) -> Path:
    """``n`` frames of uniform noise (w x h), MPEG-4 part 2 through OpenCV: incompressible frames, so damage in
    the middle of the file hits many packets."""
    rng = np.random.default_rng(0)
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 25, (w, h))
    for _ in range(n):
        writer.write(rng.integers(0, 255, (h, w, 3), dtype=np.uint8))
    writer.release()
    return path
