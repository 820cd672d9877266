"""Light from one ordinary background photo: training-free, deterministic (DESIGN.md §3, "Background photos as light").

The photo shows what lies behind the subject as the camera sees it: directions around −x, the photo's
right toward +y, unmirrored (the orientation of an env map's centre), over a horizontal field of view
``fov`` (default 60°; the vertical one follows from the aspect ratio, square pixels, a level camera).
The rule, in order:

1. Linearise (sRGB → linear). Clipped highlights: a pixel whose brightest channel is >= 250/255 is
   taken as saturated and its linear value multiplied by ``HIGHLIGHT_GAIN`` (the sensor stopped counting
   there: lamps, windows, the sun are far brighter than 1). The photo is then area-averaged down to
   about the env map's angular resolution (energy-preserving).
2. Fill an equirectangular map (H × 2H, default H = 64) direction by direction:

   * in front (x < 0), inside the field of view: the photo itself (perspective projection);
   * behind the camera (x > 0): the photo mirrored through the image plane, ω = (x, y, z) → (−x, y, z)
     (what lies behind the camera is guessed to resemble what lies in front);
   * left and right beyond the field of view: the photo's side edges stretched sideways (the right
     edge fills the right, the left edge the left, so a scene bright on its right stays so);
   * above and below the photo: its top rows stretched up into a sky and its bottom rows down into a
     floor.

   Everything the camera did not see is blurred: the side and mirrored parts a little
   (``_SIDE_BLUR``), the sky and floor more and more toward the poles, where they become the mean
   colour of the photo's top (bottom) eighth. Blur is a mix of three images: the photo, the photo
   blurred by a Gaussian of 1/8 of its width, and the band means.
3. Project with ``sh.project_envmap`` and divide by π.

Scale: the light is in the photo's own linear units: a white diffuse surface that sees a uniform
background of linear value v all round gets shading v (it reflects what it receives; the project's
shading is irradiance, and a uniform radiance v gives irradiance π·v). So with ``exposure="physical"``
a person relit by it has the brightness the same camera would have recorded in that scene.
"""

from __future__ import annotations

import math
import os

import cv2
import numpy as np

from . import sh
from ._errors import RelightError
from .color import srgb_to_linear

__all__ = ["FOV_RANGE", "HIGHLIGHT_GAIN", "MIN_SIZE", "envmap_view", "light_from_background", "read_background"]

MIN_SIZE = 64  #: smallest accepted background side, pixels
FOV_RANGE = (10.0, 170.0)  #: open interval of accepted horizontal fields of view, degrees
#: linear gain on saturated pixels (see the module docstring; docs/RESULTS.md: 1 and 3 measure alike, 6 and 12 worse)
HIGHLIGHT_GAIN = 3.0
_CLIP_LEVEL = 250  # 8-bit value from which a pixel counts as saturated
_SIDE_BLUR = 0.35  # blur level of the parts beside and behind the camera (0 sharp, 0.5 blurred, 1 band mean)
_BEHIND_BLUR = _SIDE_BLUR  # blur level of the mirrored part behind the camera
_BAND = 8  # the sky / floor colour at the poles: the mean of the top / bottom 1/_BAND of the rows
_LUT = srgb_to_linear(np.arange(256, dtype=np.uint8))  # 8-bit sRGB → linear float32


def _check_fov(fov) -> float:
    try:
        f = float(fov)
    except (TypeError, ValueError):
        raise RelightError(f"fov: expected a horizontal field of view in degrees, got {fov!r}") from None
    if not (FOV_RANGE[0] < f < FOV_RANGE[1]):
        raise RelightError(f"fov: expected a horizontal field of view between {FOV_RANGE[0]:g} and {FOV_RANGE[1]:g} "
                           f"degrees (exclusive), got {fov!r}")  # fmt: skip
    return f


def read_background(src, name: str = "background") -> np.ndarray:
    """A background photo as given: (H, W, 3) RGB, uint8 (8-bit files) or float32 in [0, 1] (float arrays,
    16-bit files). Grayscale becomes colour; files are turned as their EXIF orientation says.

    Raises:
        RelightError: unreadable file, RGBA (an alpha channel has no meaning for a
            background: flatten it first), a side smaller than 64 px, bad values.
    """
    from ._io import _decode, as_colour

    if isinstance(src, (str, os.PathLike)):
        raw = as_colour(_decode(src, name), bgr=True)  # gray becomes colour; turned as its EXIF tag says
        label = f"{name} {os.fspath(src)}"
    elif isinstance(src, np.ndarray):
        raw, label = as_colour(src, bgr=False), name
    else:
        raise RelightError(f"{name}: expected a path or an (H, W, 3) RGB array, got {type(src).__name__}")
    if raw.dtype == np.uint16:  # 16-bit files and arrays
        raw = np.multiply(raw, np.float32(1 / 65535), dtype=np.float32)
    if raw.ndim == 3 and raw.shape[2] == 4:
        raise RelightError(f"{label}: expected an (H, W, 3) colour photo, got RGBA {raw.shape}; "
                           "flatten the alpha channel first")  # fmt: skip
    if raw.ndim != 3 or raw.shape[2] != 3:
        raise RelightError(f"{label}: expected an (H, W, 3) RGB photo, got {raw.shape}")
    if min(raw.shape[:2]) < MIN_SIZE:
        raise RelightError(f"{label}: expected at least {MIN_SIZE} x {MIN_SIZE} pixels, got "
                           f"{raw.shape[1]} x {raw.shape[0]} (W x H)")  # fmt: skip
    if raw.dtype == np.uint8:
        return raw
    if raw.dtype.kind != "f":
        raise RelightError(f"{label}: expected uint8 or float in [0, 1], got {raw.dtype}")
    out = raw.astype(np.float32)
    if not np.isfinite(out).all() or out.min() < -1e-3 or out.max() > 1 + 1e-3:
        raise RelightError(f"{label}: expected finite float values in [0, 1]")
    return np.clip(out, 0, 1)


def _linear_and_clipped(photo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Linear float32 RGB and the (H, W) float32 saturated-pixel indicator."""
    if photo.dtype == np.uint8:
        return _LUT[photo], (photo.max(axis=2) >= _CLIP_LEVEL).astype(np.float32)
    return srgb_to_linear(photo), (photo.max(axis=2) >= _CLIP_LEVEL / 255).astype(np.float32)


def _fill(lin: np.ndarray, fov: float, height: int) -> np.ndarray:
    """The (H, 2H, 3) env map filled from the small linear photo ``lin`` (see the module docstring)."""
    ph, pw = lin.shape[:2]
    half = math.radians(fov) / 2
    tan_h = math.tan(half)
    tan_v = tan_h * ph / pw  # square pixels
    d = sh.directions_envmap(height)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    fwd = np.abs(x)  # behind the camera: mirrored through the image plane
    psi = np.arctan2(y, fwd)  # horizontal angle from the view axis, toward +y (image right), in [−π/2, π/2]
    folded = np.clip(psi, -half, half)  # beside the field of view: the side edge stretched
    u = np.tan(folded) / tan_h  # −1 … 1 across the photo
    elev = np.arctan2(z, np.hypot(x, y))
    edge = np.arctan(tan_v * np.cos(folded))  # elevation of the photo's top edge at that column
    v = np.tan(np.clip(elev, -edge, edge)) / (np.cos(folded) * tan_v)  # −1 … 1, clamped: sky/floor stretch
    mapx = ((u + 1) * 0.5 * pw - 0.5).astype(np.float32)
    mapy = ((1 - v) * 0.5 * ph - 0.5).astype(np.float32)
    beta_v = np.clip((np.abs(elev) - edge) / (math.pi / 2 - edge), 0, 1)
    beside = np.where(np.abs(psi) > half, _SIDE_BLUR, 0.0)
    beta = np.maximum(beta_v, np.where(x > 0, _BEHIND_BLUR, beside)).astype(np.float32)[..., None]

    sigma = max(pw / 8, 0.5)
    blurred = cv2.GaussianBlur(lin, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)
    band = max(1, ph // _BAND)
    top, bottom = lin[:band].reshape(-1, 3).mean(0), lin[-band:].reshape(-1, 3).mean(0)
    pole = np.where((z >= 0)[..., None], top, bottom).astype(np.float32)

    def sample(img):
        return cv2.remap(img, mapx, mapy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)

    sharp, soft = sample(lin), sample(blurred)
    low = sharp + (soft - sharp) * np.minimum(2 * beta, 1)
    return np.where(beta <= 0.5, low, soft + (pole - soft) * (2 * beta - 1)).astype(np.float32)


def light_from_background(image, fov: float = 60.0, *, height: int = 64) -> tuple[np.ndarray, np.ndarray]:
    """Estimate the SH light of a scene from one ordinary photo of it (the module docstring has the rule).

    Args:
        image: the background photo: a path or an (H, W, 3) RGB array (uint8, or float in [0, 1]),
            sRGB-encoded as cameras write them; at least 64 px on each side.
        fov: its horizontal field of view in degrees, in (10, 170).
        height: height H of the filled env map (width 2H); 64 is plenty for degree-2 SH.

    Returns:
        (light, envmap): the (9, 3) float32 RGB SH light (in the photo's linear units, see the module
        docstring) and the filled (H, 2H, 3) float32 linear env map it was projected from (for previews).

    Raises:
        RelightError: bad image (see ``read_background``), fov outside (10°, 170°), bad height.
    """
    f = _check_fov(fov)
    if isinstance(height, bool) or not isinstance(height, (int, np.integer)) or not 8 <= height <= 1024:
        raise RelightError(f"height: expected an integer from 8 to 1024, got {height!r}")
    photo = read_background(image)
    lin, clipped = _linear_and_clipped(photo)
    ph, pw = photo.shape[:2]
    # about two samples per env-map pixel across the field of view
    width = int(min(pw, max(16, round(2 * (2 * height) * f / 360))))
    size = (width, max(4, int(round(width * ph / pw))))
    lin = cv2.resize(lin, size, interpolation=cv2.INTER_AREA)
    clipped = cv2.resize(clipped, size, interpolation=cv2.INTER_AREA)
    lin *= (1 + (HIGHLIGHT_GAIN - 1) * clipped)[..., None]
    env = _fill(lin, f, int(height))
    light = sh.project_envmap(env) / math.pi
    return light.astype(np.float32), env


def envmap_view(env, size: tuple[int, int], fov: float = 60.0) -> np.ndarray:
    """A perspective view of an equirectangular map, as a level camera at the subject looking along −x sees it.

    The inverse of the photo placement above: image right = +y, up = +z, unmirrored, horizontal field of
    view ``fov``. Bilinear look-up (wrapping in azimuth).

    Args:
        env: (H, 2H, 3) float linear RGB map (DESIGN.md §3 layout).
        size: (height, width) of the view in pixels.
        fov: horizontal field of view in degrees, in (10, 170).

    Returns:
        (height, width, 3) float32 linear RGB.
    """
    f = _check_fov(fov)
    arr = np.asarray(env, np.float32)
    if arr.ndim != 3 or arr.shape[2] != 3 or arr.shape[1] != 2 * arr.shape[0]:
        raise RelightError(f"env: expected an equirectangular (H, 2H, 3) map, got {arr.shape}")
    vh, vw = (int(s) for s in size)
    if vh < 1 or vw < 1:
        raise RelightError(f"size: expected a positive (height, width), got {size!r}")
    tan_h = math.tan(math.radians(f) / 2)
    cols = ((np.arange(vw) + 0.5) / vw * 2 - 1) * tan_h
    rows = (1 - (np.arange(vh) + 0.5) / vh * 2) * tan_h * vh / vw
    y, z = np.meshgrid(cols, rows)
    x = -np.ones_like(y)
    norm = np.sqrt(x * x + y * y + z * z)
    theta = np.arccos(z / norm)
    phi = np.mod(np.arctan2(-y, x), 2 * np.pi)  # ω = (sinθ cosφ, −sinθ sinφ, cosθ)
    eh, ew = arr.shape[:2]
    mapx = (phi / (2 * np.pi) * ew - 0.5).astype(np.float32)
    mapy = (theta / np.pi * eh - 0.5).astype(np.float32)
    padded = np.concatenate([arr[:, -1:], arr, arr[:, :1]], axis=1)  # wrap in azimuth
    return cv2.remap(padded, mapx + 1, mapy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
