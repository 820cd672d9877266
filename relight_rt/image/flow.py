"""Dense optical flow between video frames (OpenCV's DIS) and the warps it drives: the one home of flow.

Users: the video metrics (relight_rt.video.metrics: warping error, light-following), the stabiliser of the
intrinsic layers (relight_rt.video.stabilize) and the video matter (relight_rt.person.matting: the previous frame's
person probability warped onto this one, and the outline-flicker measure).

Conventions: a flow is (H, W, 2) float32 (dx, dy) in pixels with ``src[p] ≈ dst[p + flow[p]]``
(:func:`dis_flow`); :func:`warp` samples an image at ``p + flow[p]``, so it moves ``dst`` onto ``src``.
Flow runs on (H, W) uint8 gray frames (:func:`to_gray_u8`).
"""

from __future__ import annotations

import functools

import cv2
import numpy as np

from ..engine.errors import RelightError

PRESETS = {
    "ultrafast": cv2.DISOPTICAL_FLOW_PRESET_ULTRAFAST,
    "fast": cv2.DISOPTICAL_FLOW_PRESET_FAST,
    "medium": cv2.DISOPTICAL_FLOW_PRESET_MEDIUM,
}


def check_preset(preset: str, name: str = "preset") -> str:
    """``preset`` if it is one of :data:`PRESETS`; otherwise a RelightError naming ``name``."""
    if preset not in PRESETS:
        raise RelightError(f"{name}: expected one of {sorted(PRESETS)}, got {preset!r}")
    return preset


def to_gray_u8(image: np.ndarray) -> np.ndarray:
    """(H, W, 3) RGB float [0, 1] or uint8 -> (H, W) uint8 luma (rounded), the input of DIS flow."""
    arr = np.asarray(image)
    if arr.dtype != np.uint8:
        arr = np.clip(np.rint(arr * 255.0), 0, 255).astype(np.uint8)
    return cv2.cvtColor(np.ascontiguousarray(arr), cv2.COLOR_RGB2GRAY)


def dis_flow(src: np.ndarray, dst: np.ndarray, preset: str = "fast", max_side: int | None = None) -> np.ndarray:
    """Dense optical flow from ``src`` to ``dst`` with OpenCV's DIS.

    Args:
        src, dst: (H, W) uint8 grey frames (see :func:`to_gray_u8`).
        preset: "ultrafast", "fast" or "medium".
        max_side: when given and the frames' long side exceeds it, the flow runs on frames shrunk to it
            (area averaging, each side at least 8 px) and is scaled back up to (H, W) in pixels of the frame.

    Returns:
        (H, W, 2) float32 flow in pixels, (dx, dy): ``src[p] ≈ dst[p + flow[p]]``.
    """
    check_preset(preset)
    if src.shape != dst.shape or src.ndim != 2 or src.dtype != np.uint8 or dst.dtype != np.uint8:
        raise RelightError(f"flow frames: expected two (H, W) uint8 frames, got {src.shape} {src.dtype} and "
                           f"{dst.shape} {dst.dtype}")
    h, w = src.shape
    dis = cv2.DISOpticalFlow_create(PRESETS[preset])
    if max_side is None or max(h, w) <= max_side:
        return dis.calc(src, dst, None)
    k = max_side / max(h, w)
    size = (max(8, round(w * k)), max(8, round(h * k)))
    small = dis.calc(cv2.resize(src, size, interpolation=cv2.INTER_AREA),
                     cv2.resize(dst, size, interpolation=cv2.INTER_AREA), None)
    flow = cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR)
    return flow * np.array([w / size[0], h / size[1]], np.float32)


@functools.lru_cache(maxsize=4)
def _pixel_grid(h: int, w: int) -> np.ndarray:
    """(h, w, 2) float32 pixel coordinates (x, y), read-only, cached per size."""
    gx, gy = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    grid = np.stack([gx, gy], axis=-1)
    grid.flags.writeable = False
    return grid


def warp(image: np.ndarray, flow: np.ndarray, border_value: float | None = 0.0) -> np.ndarray:
    """Sample ``image`` at ``p + flow[p]`` (bilinear): moves ``dst`` of :func:`dis_flow` onto ``src``.

    Args:
        image: (H, W) or (H, W, C) float32, any C.
        flow: (H, W, 2) float32 as returned by :func:`dis_flow`.
        border_value: value of pixels that sample outside the image; None repeats the nearest edge pixel.

    Returns:
        New array of ``image``'s shape.
    """
    h, w = flow.shape[:2]
    coords = _pixel_grid(h, w) + flow.astype(np.float32, copy=False)  # (h, w, 2): one CV_32FC2 map
    src = np.ascontiguousarray(image, dtype=np.float32)
    if border_value is None:
        border = {"borderMode": cv2.BORDER_REPLICATE}
    else:
        border = {"borderMode": cv2.BORDER_CONSTANT, "borderValue": border_value}
    channels = 1 if src.ndim == 2 else src.shape[2]
    if channels <= 4:
        return cv2.remap(src, coords, None, cv2.INTER_LINEAR, **border).reshape(image.shape)
    out = np.empty((h, w, channels), np.float32)  # remap's constant border handles at most 4 channels
    for i in range(0, channels, 4):
        part = cv2.remap(np.ascontiguousarray(src[..., i:i + 4]), coords, None, cv2.INTER_LINEAR, **border)
        out[..., i:i + 4] = part.reshape(h, w, -1)
    return out


def _sq_norm(v: np.ndarray) -> np.ndarray:
    """|v|² of (..., 2) vectors (explicit: a reduction over a length-2 axis is slow in numpy)."""
    return v[..., 0] * v[..., 0] + v[..., 1] * v[..., 1]


def consistent_flow(forward: np.ndarray, backward: np.ndarray, alpha: float = 0.01, beta: float = 0.5) -> np.ndarray:
    """Forward-backward check (Sundaram et al. 2010): where ``forward`` can be trusted.

    Args:
        forward: (H, W, 2) flow from frame a to frame b.
        backward: (H, W, 2) flow from b to a.

    Returns:
        (H, W) bool, True where ``|f + b(p+f)|² < alpha (|f|² + |b(p+f)|²) + beta`` and p + f stays
        inside the frame.
    """
    back = warp(backward, forward, border_value=np.nan)
    ok = _sq_norm(forward + back) < alpha * (_sq_norm(forward) + _sq_norm(back)) + beta
    return ok  # NaN (outside the frame) compares False
