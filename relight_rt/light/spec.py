"""Where a new light comes from, typed: a preset, an SH light file, an environment map, a photo to copy from.

A :class:`LightSpec` says what its value is, so nothing has to guess from a string; the CLI builds one
from its light options (one set for every command), the API accepts one wherever a light goes, and a
server builds one with ``parse_light(text, allow_paths=False)``, which refuses anything but a preset
name: a request never names a file on the server's disk.

One rule for a light given as a single string (``parse_light`` with paths allowed; the API's
``Relighter.resolve_light("...")`` and ``video.resolve_light`` both use it):

- an existing ``.npy`` / ``.json`` file: an SH light file (RGB columns);
- an existing ``.hdr`` / ``.pic`` / ``.exr`` file: an environment map;
- an existing LDR image (``.png``, ``.jpg``, ...): an environment map when it is equirectangular
  (width = 2 x height, DESIGN.md §3), otherwise a photo of a person whose light is estimated;
- anything else: a preset name (``relight_rt.light.presets.list_presets()``); a string that looks like a
  path (a suffix or a folder separator) but names no file is an error, not a preset.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import cv2
import numpy as np

from ..engine.errors import RelightError
from ..engine.limits import header_size
from ..image.io import IMAGE_SUFFIXES
from . import envmap, presets, sh
from .files import load_light

SH_FILE_SUFFIXES = (".npy", ".json")
HDR_SUFFIXES = (".hdr", ".pic", ".exr")
SOURCES = ("preset", "file", "envmap", "photo", "sh")
MAX_NUMBER = 1e4  # the largest |coefficient| of a light given as numbers (LightSpec.from_numbers)

# estimate(photo_path, mask_path_or_None) -> (9, 3) light: how a photo's light is found (the Relighter's stage 1)
Estimator = Callable[[Path, "str | None"], np.ndarray]


def _angle(value) -> float:
    """A rotation in degrees as a finite float; RelightError for anything else (None, "x", an array, 10**400)."""
    try:
        angle = float(value)
    except (TypeError, ValueError, OverflowError):
        raise RelightError(f"rotate: expected an angle in degrees, got {str(value)[:80]!r}") from None
    if not math.isfinite(angle):
        raise RelightError(f"rotate: expected a finite angle in degrees, got {value!r}")
    return angle


@dataclass(frozen=True, eq=False)
class LightSpec:
    """A light and where it comes from.

    Attributes:
        source: "preset" (value: a name), "file" (an SH light file .npy/.json), "envmap" (an equirectangular
            map), "photo" (a photo of a person whose light stage 1 estimates) or "sh" (a (9, 3) array).
        value: the name, the path (str) or the array.
        bgr: (files) the columns are B, G, R, as in the reference implementation's light files.
        rotate: degrees to turn the light about the vertical axis (``sh.rotate_z``) after it is read.
        mask: (photos) the photo's mask file; None: its alpha, ``NAME_mask.png`` beside it, or a matte.
    """

    source: str
    value: object
    bgr: bool = False
    rotate: float = 0.0
    mask: str | None = None

    def __post_init__(self) -> None:
        if self.source not in SOURCES:
            raise RelightError(f"light source is {self.source!r}, expected one of {list(SOURCES)}")
        if self.source == "sh":
            object.__setattr__(self, "value", sh.check_light(self.value, "light"))
        elif not isinstance(self.value, (str, os.PathLike)):
            raise RelightError(f"light {self.source}: expected a name or path, got {type(self.value).__name__}")
        else:
            object.__setattr__(self, "value", os.fspath(self.value))
        object.__setattr__(self, "rotate", _angle(self.rotate))
        if self.mask is not None:
            if not isinstance(self.mask, (str, os.PathLike)):
                raise RelightError(f"light mask: expected a path, got {type(self.mask).__name__}")
            object.__setattr__(self, "mask", os.fspath(self.mask))
        if self.bgr and self.source != "file":
            raise RelightError("bgr: only an SH light file (.npy/.json) has a colour order to choose")

    # ------------------------------------------------------------------ constructors

    @classmethod
    def preset(cls, name: str, rotate: float = 0.0) -> LightSpec:
        """A named light of ``relight_rt.light.presets``."""
        return cls("preset", name, rotate=rotate)

    @classmethod
    def file(cls, path: str | os.PathLike, *, bgr: bool = False, rotate: float = 0.0) -> LightSpec:
        """An SH light file: .npy (9, 3) or .json (DESIGN.md §6)."""
        return cls("file", path, bgr=bgr, rotate=rotate)

    @classmethod
    def envmap(cls, path: str | os.PathLike, rotate: float = 0.0) -> LightSpec:
        """An equirectangular environment map (.hdr/.exr linear; .png/.jpg sRGB), projected to SH."""
        return cls("envmap", path, rotate=rotate)

    @classmethod
    def photo(cls, path: str | os.PathLike, *, mask: str | os.PathLike | None = None, rotate: float = 0.0) -> LightSpec:
        """The light of another photo of a person, estimated by stage 1 ("light me like that photo")."""
        return cls("photo", path, rotate=rotate, mask=mask)

    @classmethod
    def from_array(cls, light, rotate: float = 0.0) -> LightSpec:
        """A (9, 3) RGB SH light."""
        return cls("sh", light, rotate=rotate)

    @classmethod
    def from_numbers(cls, values, rotate: float = 0.0) -> LightSpec:
        """A light given as 27 numbers (index 3k + c: coefficient k, colour c, RGB) or 9 rows of 3, as a request
        or a text field sends it; each |value| <= ``MAX_NUMBER`` (a sensible light has values of about 1).

        Raises:
            RelightError: not 27 numbers, not finite, or too large.
        """
        try:
            if not sh.numbers_only(values):  # true/false or "0.5" would pass as numbers through numpy
                raise TypeError
            arr = np.array(values, dtype=np.float64)
        except (TypeError, ValueError, OverflowError, RecursionError):  # OverflowError: an integer of 400 digits
            raise RelightError("light: expected 27 numbers (9 rows of R, G, B) of sensible size") from None
        if arr.size != 27:
            raise RelightError(f"light: expected 27 numbers (9 rows of R, G, B), got {arr.size}")
        if not np.all(np.isfinite(arr)) or np.abs(arr).max() > MAX_NUMBER:
            raise RelightError(f"light: expected finite numbers of sensible size (|value| <= {MAX_NUMBER:g})")
        return cls.from_array(arr.reshape(9, 3), rotate=rotate)

    @classmethod
    def of(cls, light) -> LightSpec:
        """Any light argument as a LightSpec: a LightSpec as it is, a string or path by ``parse_light`` (the one
        rule: light file, environment map, photo of a person or preset name), anything else as a (9, 3) array."""
        if isinstance(light, LightSpec):
            return light
        if isinstance(light, (str, os.PathLike)):
            return parse_light(light)
        return cls.from_array(light)

    def rotated(self, degrees: float) -> LightSpec:
        """The same light turned a further ``degrees`` about the vertical axis."""
        return replace(self, rotate=self.rotate + _angle(degrees))

    @property
    def reads_files(self) -> bool:
        """True when resolving it reads a file (a server must not accept such a spec from a request)."""
        return self.source in ("file", "envmap", "photo")

    @property
    def paths(self) -> tuple[str, ...]:
        """The files this light reads (to protect them from being overwritten)."""
        if not self.reads_files:
            return ()
        return (str(self.value),) + ((self.mask,) if self.mask else ())

    # ------------------------------------------------------------------ resolving

    def resolve(self, estimate: Estimator | None = None, dtype=np.float32) -> np.ndarray:
        """The (9, 3) RGB SH light.

        Args:
            estimate: how to find a photo's light (``Relighter`` passes its stage 1); needed for "photo".
            dtype: of the result; the rotation, if any, runs in float64 before the cast.

        Raises:
            RelightError: unreadable file, unknown preset, a photo without ``estimate``, a bad light.
        """
        if self.source == "sh":
            base = self.value
        elif self.source == "preset":
            base = presets.preset(str(self.value))
        elif self.source == "file":
            base = load_light(self.value, bgr=self.bgr)
        elif self.source == "envmap":
            base = envmap.project_envmap(envmap.load_envmap(self.value))
        else:
            if estimate is None:
                raise RelightError(f"light: estimating the light of the photo {self.value} needs the stage-1 model")
            base = estimate(Path(self.value), self.mask)
        if self.rotate:
            base = sh.rotate_z(base, math.radians(self.rotate))
        return sh.check_light(base, "light").astype(dtype)

    def describe(self) -> str:
        """A short human description (logs, reports)."""
        what = "an SH array" if self.source == "sh" else f"{self.source} {self.value}"
        return what + (f" turned {self.rotate:g} deg" if self.rotate else "")


def _is_equirectangular(path: Path) -> bool:
    """Width twice the height (within a pixel), read from the header where it is parsed (exact at any size), else
    from a 1/8 decode (which may round each side: a small photo near 2:1 can pass for a panorama there)."""
    size = header_size(path, f"light {path}")
    if size is not None:
        w, h = size
        return abs(w - 2 * h) <= 1
    data = np.fromfile(path, dtype=np.uint8)
    img = cv2.imdecode(data, cv2.IMREAD_REDUCED_GRAYSCALE_8) if data.size else None
    if img is None:
        raise RelightError(f"light: cannot decode {path} as an image")
    h, w = img.shape[:2]
    return abs(w - 2 * h) <= 1


def parse_light(text: str | os.PathLike, *, allow_paths: bool = True) -> LightSpec:
    """A light given as one string, by the module's rule.

    Args:
        text: a preset name or a path.
        allow_paths: False (anything from a network request): only preset names; a string that names a
            file, or looks like a path, is refused without touching the disk.

    Raises:
        RelightError: an unknown preset (the message lists the known ones), a missing file, a path refused.
    """
    try:
        s = os.fspath(text)
    except TypeError:  # an object whose __fspath__ gives neither str nor bytes
        s = None
    if not isinstance(s, str) or not s:
        raise RelightError(f"light: expected a preset name or a file, got {text!r}")
    looks_like_path = bool(Path(s).suffix) or "/" in s or os.sep in s or (os.altsep or "/") in s
    if not allow_paths:
        if looks_like_path or s not in presets.list_presets():
            known = ", ".join(presets.list_presets())
            raise RelightError(f"light {s!r}: only preset names are accepted here ({known}); files cannot be named")
        return LightSpec.preset(s)
    path = Path(s)
    try:
        is_file = path.is_file()
    except OSError:  # a name longer than the system allows: no file, so a preset name (or a missing path) below
        is_file = False
    if is_file:
        suffix = path.suffix.lower()
        if suffix in SH_FILE_SUFFIXES:
            return LightSpec.file(path)
        if suffix in HDR_SUFFIXES:
            return LightSpec.envmap(path)
        if suffix in IMAGE_SUFFIXES:
            return LightSpec.envmap(path) if _is_equirectangular(path) else LightSpec.photo(path)
        raise RelightError(f"light: {path} is neither a light file (.npy/.json), an environment map nor a photo")
    if looks_like_path:
        raise RelightError(f"light: file {path} not found")
    if s not in presets.list_presets():
        presets.preset(s)  # raises with the list of known names
    return LightSpec.preset(s)
