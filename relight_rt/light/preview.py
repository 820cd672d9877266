"""What ``relight-rt lights show`` draws for an environment map, and what it says about any light.

An environment map is shown as a sheet: the map (layout of DESIGN.md §3) with the subject's axes drawn on
it — the camera at both side edges (the subject faces it), behind the subject at the centre, the image's
left and right at the quarters, the horizon — turned by ``--rotate`` as the light is; beside it the
sphere the map's SH light gives, as the camera sees it; under both, how ``--rotate`` turns the map and,
when most of the light comes from behind the subject, that the face gets only the rest (a low sun behind
the subject lights the face with the blue of the sky) and which ``--rotate`` brings the main light round.

The text is ASCII (OpenCV's Hershey font); panels are 8-bit sRGB, each scaled to its own brightest part.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from ..image.color import REC709, linear_to_srgb
from . import sh

_LUMA = REC709.astype(np.float64)
_FRONT, _BACK = np.array([1.0, 0.0, 0.0]), np.array([-1.0, 0.0, 0.0])


def back_to_front(light: np.ndarray) -> float:
    """Irradiance (luminance) of a surface facing away from the camera over one facing it: > 1 when most
    of the light comes from behind the subject."""
    e = sh.irradiance(np.asarray(light, np.float64), np.stack([_FRONT, _BACK])) @ _LUMA
    front, back = max(float(e[0]), 0.0), max(float(e[1]), 0.0)
    return back / front if front > 0 else math.inf if back > 0 else 1.0


def main_light_azimuth(light: np.ndarray) -> float:
    """Degrees from the camera side (+x) toward the image's right (+y) of the light's main direction (its
    luminance's degree-1 band, sh.dominant_direction); 0 for a light without a direction."""
    d, _ = sh.dominant_direction(np.asarray(light, np.float64) @ _LUMA)
    return 0.0 if d is None else math.degrees(math.atan2(d[1], d[0]))


def brightest_direction(env: np.ndarray) -> tuple[float, float]:
    """(azimuth in degrees from +x toward +y, elevation in degrees) of the brightest part of a map (its
    luminance smoothed over about 1/64 of the width, so a hot pixel does not count): the sun, a window."""
    h, w = env.shape[:2]
    sigma = max(w / 64, 1.0)
    pad = int(3 * sigma) + 1  # azimuth wraps round: pad with the other side before smoothing
    lum = np.pad(np.asarray(env, np.float32) @ _LUMA.astype(np.float32), ((0, 0), (pad, pad)), mode="wrap")
    lum = cv2.GaussianBlur(lum, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)[:, pad : pad + w]
    i, j = np.unravel_index(int(np.argmax(lum)), lum.shape)
    phi = 2 * math.pi * (j + 0.5) / w  # DESIGN.md §3: ω = (sinθ cosφ, −sinθ sinφ, cosθ)
    return _turn(-math.degrees(phi)), 90 - 180 * (i + 0.5) / h


def _turn(degrees: float) -> float:
    """An angle in (-180, 180], rounded to a whole degree."""
    d = round(degrees) % 360
    return float(d - 360 if d > 180 else d)


def notes(light: np.ndarray, rotate: float, azimuth: float | None = None) -> list[str]:
    """Plain-text lines about ``light`` (already turned by ``rotate`` degrees): where most of it comes from.

    ``azimuth``: of the main light (degrees from +x toward +y, after ``rotate``), when known better than
    from the light's degree-1 band (an environment map's sun: :func:`brightest_direction`).
    """
    ratio = back_to_front(light)
    if ratio <= 1:
        return []
    turn = _turn(rotate - (main_light_azimuth(light) if azimuth is None else azimuth))
    how = f"--rotate {turn:g}" if turn != 0 else "no --rotate"
    return [
        f"Most of the light comes from behind the subject ({ratio:.1f}x more than from the camera's side):",
        f"the face is lit by the rest (with a low sun, by the blue sky). {how} turns the main light to the face.",
    ]


def _text(img: np.ndarray, text: str, org: tuple[int, int], scale: float, colour=(255, 255, 255),
          align: str = "left") -> None:  # fmt: skip
    thick = max(1, round(scale * 2))
    (w, _), _ = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, scale, thick)
    x = org[0] - (w if align == "right" else w // 2 if align == "centre" else 0)
    x = int(min(max(x, 2), img.shape[1] - w - 2))
    cv2.putText(img, text, (x, org[1]), cv2.FONT_HERSHEY_SIMPLEX, scale, (0, 0, 0), thick + 2, cv2.LINE_AA)
    cv2.putText(img, text, (x, org[1]), cv2.FONT_HERSHEY_SIMPLEX, scale, colour, thick, cv2.LINE_AA)


def _display(linear: np.ndarray) -> np.ndarray:
    """Linear RGB → 8-bit sRGB, scaled so that the 99.5th percentile of luminance is white (OpenCV draws
    text on 8-bit images only)."""
    lum = linear @ _LUMA.astype(np.float32)
    peak = float(np.percentile(lum, 99.5)) if lum.size else 0.0
    scaled = np.clip(linear / peak if peak > 0 else linear, 0, 1)
    return np.ascontiguousarray(linear_to_srgb(scaled) * 255 + 0.5).astype(np.uint8)


def turned_envmap(env: np.ndarray, rotate: float) -> np.ndarray:
    """``env`` (H, 2H, 3) turned ``rotate`` degrees about the vertical axis as ``sh.rotate_z`` turns its light
    (to the nearest column): new(φ) = old(φ + rotate), φ the map's azimuth."""
    w = env.shape[1]
    return np.roll(env, -round(rotate / 360 * w), axis=1)


def envmap_sheet(env: np.ndarray, light: np.ndarray, rotate: float, size: int) -> tuple[np.ndarray, list[str]]:
    """The sheet for an environment map: (rows, 3 size + gap, 3) uint8 sRGB, and its notes (:func:`notes`).

    Args:
        env: (H, 2H, 3) linear RGB map as read (before ``rotate``).
        light: its (9, 3) SH light, turned by ``rotate``.
        rotate: degrees (``--rotate``).
        size: height of the map and of the sphere in pixels.
    """
    h, w, gap = size, 2 * size, max(4, size // 32)
    scale = max(size / 640, 0.3)
    line = int(round(40 * scale)) + 4
    shown = cv2.resize(turned_envmap(np.asarray(env, np.float32), rotate), (w, h), interpolation=cv2.INTER_AREA)
    panel = _display(shown)
    grey = (150, 150, 150)
    for x in (w // 4, w // 2, 3 * w // 4):
        cv2.line(panel, (x, 0), (x, h - 1), grey, 1, cv2.LINE_AA)
    cv2.line(panel, (0, h // 2), (w - 1, h // 2), grey, 1, cv2.LINE_AA)
    top = line
    _text(panel, "camera", (2, top), scale, (255, 215, 80))
    _text(panel, "camera", (w - 2, top), scale, (255, 215, 80), align="right")
    _text(panel, "left", (w // 4, top), scale, align="centre")
    _text(panel, "behind the subject", (w // 2, top), scale, align="centre")
    _text(panel, "right", (3 * w // 4, top), scale, align="centre")
    _text(panel, "horizon", (3 * w // 8, h // 2 - 4), scale * 0.8, grey, align="centre")
    az, elev = brightest_direction(shown)  # the main light, marked where it lies on the turned map
    col = int(round((-az % 360) / 360 * w)) % w
    row = int(round((90 - elev) / 180 * h))
    cv2.circle(panel, (col, min(max(row, 0), h - 1)), max(4, size // 24), (255, 50, 50), 2, cv2.LINE_AA)
    sphere = sh.render_sphere(light, size=size)
    sphere = _display(sphere)
    _text(sphere, "the sphere it gives", (size // 2, top), scale * 0.9, align="centre")
    _text(sphere, "(seen from the camera)", (size // 2, top + line), scale * 0.8, align="centre")
    lines = [
        "The map as seen from the subject, who faces the camera (both side edges); the centre is behind the",
        "subject. Red circle: the brightest part of the map. --rotate DEG turns the map about the vertical",
        "axis: --rotate 90 brings what is on the left round to the camera side (the face).",
    ]
    if rotate:
        lines.append(f"Shown turned by --rotate {rotate:g}.")
    warn = notes(light, rotate, az)
    sheet = np.zeros((h + line * (len(lines) + len(warn)) + line // 2, w + gap + size, 3), np.uint8)
    sheet[:h, :w] = panel
    sheet[:h, w + gap :] = sphere
    y = h + line
    for text in lines:
        _text(sheet, text, (4, y - line // 4), scale * 0.85)
        y += line
    for text in warn:
        _text(sheet, text, (4, y - line // 4), scale * 0.85, (255, 140, 50))
        y += line
    return sheet, warn
