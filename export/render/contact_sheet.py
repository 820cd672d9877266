"""Contact sheets: rendered samples (albedo, shading, diffuse image, photos) side by side, one row each.

Images are shown as stored (linear values, no gamma), clipped to [0, 1].
"""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np

from relight_rt.light.sh import basis

from .. import dataset


def light_from_above(elevation_deg: float = 60.0, ambient: float = 0.15) -> np.ndarray:
    """(9, 3) RGB white light: a distant light in front of the subject (+x) at ``elevation_deg`` plus a
    uniform fill giving ``ambient`` of the distant light's peak irradiance; scaled so that the brightest
    unoccluded irradiance is 1."""
    from .envmaps import max_irradiance

    el = math.radians(elevation_deg)
    d = np.array([math.cos(el), 0.0, math.sin(el)])
    light = np.repeat(basis(d)[:, None], 3, axis=1)  # a delta light: L_k = Y_k(d)
    light[0] += ambient / math.pi * math.sqrt(4 * math.pi)  # uniform radiance a: L_0 = a √(4π), irradiance π a
    return light / max_irradiance(light)


def _tile(img: np.ndarray, size: int) -> np.ndarray:
    img = np.clip(np.asarray(img, np.float32), 0.0, 1.0)
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=2)
    h, w = img.shape[:2]
    if h != w:  # letterbox to a square (black bars) rather than stretch the person
        side = max(h, w)
        top, left = (side - h) // 2, (side - w) // 2
        img = cv2.copyMakeBorder(img, top, side - h - top, left, side - w - left, cv2.BORDER_CONSTANT, value=0)
    return cv2.resize(img, (size, size), interpolation=cv2.INTER_AREA if img.shape[0] > size else cv2.INTER_NEAREST)


def _label(tile: np.ndarray, text: str) -> np.ndarray:
    out = np.round(tile * 255).astype(np.uint8)
    cv2.putText(out, text, (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (255, 255, 60), 1, cv2.LINE_AA)
    return out


def write_sheet(path: str | Path, rows: list[list[tuple[str, np.ndarray]]], tile: int = 192) -> None:
    """Write a grid of labelled RGB tiles as an 8-bit PNG (rows may have different lengths; non-square
    images are letterboxed)."""
    width = max(len(r) for r in rows)
    blank = np.zeros((tile, tile, 3), np.uint8)
    lines = []
    for row in rows:
        tiles = [_label(_tile(img, tile), text) for text, img in row]
        tiles += [blank] * (width - len(tiles))
        lines.append(np.concatenate(tiles, axis=1))
    sheet = np.concatenate(lines, axis=0)
    img = np.ascontiguousarray(sheet[:, :, ::-1])
    dataset.atomic_write(Path(path), lambda tmp: cv2.imwrite(tmp, img))


def sample_row(root: str | Path, name: str, light: np.ndarray | None = None) -> list[tuple[str, np.ndarray]]:
    """Tiles of one stage-1 sample: albedo, skin, shading and diffuse image under ``light`` (default: from above)."""
    from relight_rt.light.sh import shading

    s = dataset.read_sample(root, name)
    light = light_from_above() if light is None else light
    shade = shading(s["transport"], light) * s["mask"][..., None]
    grey = s["albedo"].mean(axis=-1, keepdims=True) * s["mask"][..., None]
    skin = grey * 0.6 + s["skin"][..., None] * np.array([0.4, 0.0, 0.0], np.float32)  # skin in red
    return [
        (f"{name} albedo", s["albedo"]),
        ("skin (red)", skin),
        ("shading (light above)", shade),
        ("diffuse", s["albedo"] * shade),
    ]


def photo_row(root: str | Path, name: str, sample_root: str | Path | None = None) -> list[tuple[str, np.ndarray]]:
    """Tiles of one stage-2 photo: albedo (when its sample is found), shading, diffuse image, photo."""
    p = dataset.read_photo(root, name)
    subject, _ = dataset.split_photo_name(name)
    tiles = []
    albedo = None
    if sample_root is not None and subject in dataset.list_samples(sample_root):
        albedo = dataset.read_sample(sample_root, subject)["albedo"]
        tiles.append((f"{name} albedo", albedo))
        shade = np.where(albedo > 1e-3, p["diffuse"] / np.maximum(albedo, 1e-3), 0.0) * p["mask"][..., None]
        tiles.append(("shading", shade))
    tiles += [("diffuse" if albedo is not None else f"{name} diffuse", p["diffuse"]), ("photo", p["photo"])]
    tiles.append(("photo - diffuse (x4)", np.abs(p["photo"] - p["diffuse"]) * 4))
    return tiles
