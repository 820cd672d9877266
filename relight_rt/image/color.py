"""Colour: the sRGB transfer functions (IEC 61966-2-1), the one place that converts between display and linear
values, the one luminance (Rec. 709 weights) and the brightest channel (``channel_max``).

Both functions work element-wise on arrays of any shape and channel order, return new arrays and
never modify their input. Float input keeps its dtype (float32 stays float32); integer images are
read as display values (uint8 / 255, uint16 / 65535) and give float32.
"""

from __future__ import annotations

import cv2
import numpy as np

from ..engine.errors import RelightError

__all__ = ["REC709", "SRGB8_TO_LINEAR", "channel_max", "colour_gradient", "linear_to_srgb", "srgb8_to_linear",
           "srgb_to_linear"]

# Luminance Y = 0.2126 R + 0.7152 G + 0.0722 B (ITU-R BT.709, the sRGB primaries), (3,) float32 in RGB order:
# ``rgb @ REC709`` on linear values is luminance; the pipeline also meters its encoded values with it.
REC709 = np.array([0.2126, 0.7152, 0.0722], np.float32)
REC709.flags.writeable = False


def channel_max(rgb: np.ndarray) -> np.ndarray:
    """(...) the brightest of the three channels of (..., 3) colours (any channel order), a new array of their dtype:
    two elementwise maxima (~10x faster than ``max(axis=-1)``, the same values). The highlight shoulder's peak
    (relight_rt.relight.look) and the exposure rule's (relight_rt.light.exposure) are this one function."""
    return np.maximum(np.maximum(rgb[..., 0], rgb[..., 1]), rgb[..., 2])


def colour_gradient(image: np.ndarray) -> np.ndarray:
    """(h, w) float32: the norm of (h, w, 3) float32 ``image``'s gradient over its three channels, per pixel (3 x 3
    Sobel, divided by its weights' sum 8: a step of d between two pixels reads about d). On Lab values it is a
    colour distance (dE) per pixel. The shown edge's photo step (relight_rt.relight.compose) and the cost of
    cutting between touching people (relight_rt.person.matting._parts) are this one function."""
    gx, gy = cv2.Sobel(image, cv2.CV_32F, 1, 0, ksize=3), cv2.Sobel(image, cv2.CV_32F, 0, 1, ksize=3)
    squares = cv2.add(cv2.multiply(gx, gx), cv2.multiply(gy, gy))
    return cv2.sqrt(cv2.transform(squares, np.full((1, 3), 1 / 64, np.float32)))


# Breakpoints and slopes of the sRGB curve (IEC 61966-2-1).
_SRGB_KNEE = 0.04045
_LINEAR_KNEE = 0.0031308
_SLOPE = 12.92
_GAMMA = 2.4
_OFFSET = 0.055


def _as_float(x, name: str) -> np.ndarray:
    """Return x as a float array (a new one for integer input); reject bools, complex and objects."""
    arr = np.asarray(x)
    if arr.dtype == np.uint8:
        return arr.astype(np.float32) / np.float32(255)
    if arr.dtype == np.uint16:
        return arr.astype(np.float32) / np.float32(65535)
    if arr.dtype.kind == "f":
        return arr
    raise RelightError(f"{name}: expected a float array (or uint8/uint16 image), got dtype {arr.dtype}")


def srgb_to_linear(x) -> np.ndarray:
    """Decode sRGB display values to linear light.

    Args:
        x: array of any shape, float in [0, 1] (values outside are extended: the linear segment below
            0, the power curve above 1), or uint8 / uint16 display values.

    Returns:
        New array of the same shape, linear values; float32 for float32 and integer input, float64 for
        float64.
    """
    v = _as_float(x, "srgb_to_linear input")
    t = v.dtype.type
    low = v / t(_SLOPE)
    high = ((np.maximum(v, t(_SRGB_KNEE)) + t(_OFFSET)) / t(1 + _OFFSET)) ** t(_GAMMA)
    return np.where(v <= _SRGB_KNEE, low, high).astype(v.dtype, copy=False)


def linear_to_srgb(x) -> np.ndarray:
    """Encode linear light as sRGB display values (no clipping: clip to [0, 1] before saving).

    Args:
        x: array of any shape, float linear values (usually in [0, 1]), or uint8 / uint16 (read as
            values / 255 or / 65535).

    Returns:
        New array of the same shape with sRGB-encoded values; float32 for float32 and integer input,
        float64 for float64.
    """
    v = _as_float(x, "linear_to_srgb input")
    t = v.dtype.type
    low = v * t(_SLOPE)
    high = t(1 + _OFFSET) * np.maximum(v, t(_LINEAR_KNEE)) ** t(1 / _GAMMA) - t(_OFFSET)
    return np.where(v <= _LINEAR_KNEE, low, high).astype(v.dtype, copy=False)


SRGB8_TO_LINEAR = srgb_to_linear(np.arange(256, dtype=np.uint8))  # (256,) float32: 8-bit sRGB level → linear
SRGB8_TO_LINEAR.flags.writeable = False


def srgb8_to_linear(image: np.ndarray) -> np.ndarray:
    """``srgb_to_linear`` for a uint8 image of any channel count, by a 256-entry table (cv2.LUT): new float32."""
    out = cv2.LUT(np.ascontiguousarray(image), SRGB8_TO_LINEAR.reshape(256, 1))
    return out if out.shape == image.shape else out.reshape(image.shape)
