"""Putting a relit person over a background: one module for photos and video.

A :class:`Background` says what lies behind the person: the photo's own pixels ("original"), nothing
(RGBA output, straight alpha = the mask), a solid colour, or another image fitted to the frame
("exact": it must have the frame's size; "stretch"; "cover": scaled to cover, centre-cropped;
"contain": letterboxed on black). Blending is ``out = backdrop + (colour - backdrop) * alpha`` for a
straight colour and ``out = premultiplied + backdrop * (1 - alpha)`` for a premultiplied one (a DVP
output), with alpha the soft mask in [0, 1].

Colours are RGB float32 in [0, 1]; sRGB values are blended as stored (as the reference does).

Over a new backdrop (anything but "original", transparent included) the person's soft edge is first
cleaned of the old background (:func:`clean_edge_colour` with ``relight_rt.image.foreground.estimate_foreground``):
an edge pixel of the photo mixes the person with what stood behind them, and that mix would otherwise
show as a fringe of the old background around hair and limbs.

Over the original background, ``Background(grade=True)`` (CLI ``--grade-background``) makes the backdrop follow the
new light: ONE global grade, a gain per channel, the same for every background pixel (no relighting of the scene:
its shadows and its own lamps stay where they were). The gain is the person's change, their relit colour over
their own colour summed over the matte (relight_rt.relight.compose.background_grade): the exposure's change
(relight_rt.light.exposure: the person is exposed to their own brightness, moved by an EV offset or a preset's own,
``night`` darker) and the new light's colour. It multiplies the backdrop outside the matte and the colour behind the
soft edge, clipped to [0, 1]. Other backgrounds are the user's choice and are never graded.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass

import cv2
import numpy as np

from ..engine.errors import RelightError
from .io import read_image

KINDS = ("original", "transparent", "color", "image")
FITS = ("exact", "stretch", "cover", "contain")
_NAMED = {"black": (0.0, 0.0, 0.0), "white": (1.0, 1.0, 1.0), "grey": (0.5, 0.5, 0.5), "gray": (0.5, 0.5, 0.5),
          "green": (0.0, 1.0, 0.0)}  # fmt: skip
_HEX = re.compile(r"#?([0-9a-fA-F]{6})")


@dataclass(frozen=True, eq=False)
class Background:
    """What the relit person is composited over.

    Attributes:
        kind: "original", "transparent", "color" or "image".
        color: (r, g, b) in [0, 1] for "color".
        image: a path or an (H, W, 3|4) array for "image" (alpha is dropped).
        fit: how an image of another size is fitted to the frame (module docstring).
        grade: the original background follows the new light (one global grade per channel: the module
            docstring); ignored by the other kinds. Off by default.
    """

    kind: str = "original"
    color: tuple[float, float, float] = (0.0, 0.0, 0.0)
    image: object = None
    fit: str = "cover"
    grade: bool = False

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise RelightError(f"background: kind {self.kind!r}, expected one of {list(KINDS)}")
        if self.fit not in FITS:
            raise RelightError(f"background: fit {self.fit!r}, expected one of {list(FITS)}")
        if not isinstance(self.grade, (bool, np.bool_)):
            raise RelightError(f"background: grade {self.grade!r}, expected True or False")
        object.__setattr__(self, "grade", bool(self.grade))
        c = np.asarray(self.color, dtype=np.float64)
        if c.shape != (3,) or not np.isfinite(c).all() or (c < 0).any() or (c > 1).any():
            raise RelightError(f"background: colour {self.color!r}, expected three values in [0, 1]")
        object.__setattr__(self, "color", tuple(float(v) for v in c))
        if self.kind == "image":
            if isinstance(self.image, (str, os.PathLike)):
                object.__setattr__(self, "image", os.fspath(self.image))
            elif not isinstance(self.image, np.ndarray):
                raise RelightError(f"background: expected a path or an image array, got {type(self.image).__name__}")

    @classmethod
    def original(cls, grade: bool = False) -> Background:
        return cls("original", grade=grade)

    @classmethod
    def transparent(cls) -> Background:
        return cls("transparent")

    @classmethod
    def solid(cls, color) -> Background:
        return cls("color", color=tuple(color))

    @classmethod
    def from_image(cls, image, fit: str = "cover") -> Background:
        return cls("image", image=image, fit=fit)

    @property
    def path(self) -> str | None:
        """The file it reads, if any (to protect it from being overwritten)."""
        return self.image if self.kind == "image" and isinstance(self.image, str) else None

    @property
    def graded(self) -> bool:
        """True when the backdrop follows the new light: the original background with ``grade``."""
        return self.grade and self.kind == "original"

    @property
    def channels(self) -> int:
        """3, or 4 for "transparent" (RGBA output)."""
        return 4 if self.kind == "transparent" else 3

    def backdrop(self, frame: np.ndarray) -> np.ndarray | None:
        """The (H, W, 3) float32 pixels behind the person in ``frame`` ((H, W, 3) RGB); None for transparent.

        "original" returns ``frame`` itself (not a copy): callers never write into a backdrop.
        """
        h, w = frame.shape[:2]
        if self.kind == "original":
            return frame
        if self.kind == "transparent":
            return None
        if self.kind == "color":
            return np.broadcast_to(np.asarray(self.color, np.float32), (h, w, 3))
        img = read_image(self.image, "background")[..., :3]
        return fit_image(img, (h, w), self.fit)


def parse_background(value, *, allow_paths: bool = True) -> Background:
    """A Background from the CLI's or the API's shorthand.

    Accepted: a Background; "original"; "transparent"; a colour name (black, white, grey, green) or
    "#RRGGBB"; an image path (``allow_paths``) or array. A path is fitted with "cover".

    Raises:
        RelightError: anything else (a server passes ``allow_paths=False`` and gets no file access).
    """
    if isinstance(value, Background):
        if not allow_paths and value.path is not None:
            raise RelightError("background: a file path is not accepted here")
        return value
    if isinstance(value, np.ndarray):
        return Background.from_image(value)
    if isinstance(value, str):
        if value in ("original", "transparent"):
            return Background(value)
        if value.lower() in _NAMED:
            return Background.solid(_NAMED[value.lower()])
        m = _HEX.fullmatch(value)
        if m and value.startswith("#"):
            h = m.group(1)
            return Background.solid(tuple(int(h[i : i + 2], 16) / 255 for i in (0, 2, 4)))
    if isinstance(value, (str, os.PathLike)):
        if not allow_paths:
            raise RelightError(f"background {os.fspath(value)!r}: expected original, transparent or a colour")
        if not os.path.isfile(value):
            raise RelightError(f"background {os.fspath(value)}: expected original, transparent, a colour "
                               "(black, white, #RRGGBB) or an image file")
        return Background.from_image(value)
    raise RelightError(f"background: expected 'original', 'transparent', a colour, a path or an image array, "
                       f"got {type(value).__name__}")


def fit_image(image: np.ndarray, size: tuple[int, int], fit: str = "cover") -> np.ndarray:
    """Fit an (h, w, 3) image to ``size`` = (H, W) by ``fit`` (module docstring); the same size is returned as is."""
    h, w = size
    ih, iw = image.shape[:2]
    if (ih, iw) == (h, w):
        return image
    if fit == "exact":
        raise RelightError(f"background: is {ih}x{iw} (HxW), expected the input's size {h}x{w} (or a fit mode)")
    if fit == "stretch":
        return _resize(image, w, h)
    if fit == "cover":
        s = max(h / ih, w / iw)
        sw, sh_ = max(w, round(iw * s)), max(h, round(ih * s))
        big = _resize(image, sw, sh_)
        y0, x0 = (sh_ - h) // 2, (sw - w) // 2
        return np.ascontiguousarray(big[y0 : y0 + h, x0 : x0 + w])
    if fit == "contain":
        s = min(h / ih, w / iw)
        sw, sh_ = max(1, min(w, round(iw * s))), max(1, min(h, round(ih * s)))
        out = np.zeros((h, w, 3), np.float32)
        y0, x0 = (h - sh_) // 2, (w - sw) // 2
        out[y0 : y0 + sh_, x0 : x0 + sw] = _resize(image, sw, sh_)
        return out
    raise RelightError(f"background: fit {fit!r}, expected one of {list(FITS)}")


def _resize(image: np.ndarray, w: int, h: int) -> np.ndarray:
    shrink = w < image.shape[1] or h < image.shape[0]
    return cv2.resize(image, (w, h), interpolation=cv2.INTER_AREA if shrink else cv2.INTER_LINEAR)


def over_box(colour: np.ndarray, alpha: np.ndarray, box: tuple[int, int, int, int], backdrop: np.ndarray | None,
             frame_alpha: np.ndarray, behind: np.ndarray | None = None, grade: np.ndarray | None = None) -> np.ndarray:
    """A straight-colour person inside ``box`` over a full-frame backdrop.

    Args:
        colour: (h, w, 3) straight colour of the person in the box (y0, y1, x0, x1).
        alpha: (h, w, 1) the mask inside the box.
        box: where the box lies in the frame.
        backdrop: (H, W, 3), or None for RGBA output.
        frame_alpha: (H, W) the mask of the whole frame (the RGBA output's alpha).
        behind: (h, w, 3) the backdrop's colours inside the box instead of ``backdrop``'s own (the photo's
            background behind a soft edge, relight_rt.image.foreground), or None.
        grade: (3,) gain per channel on the backdrop and ``behind`` (the background following the light), or None.

    Returns:
        New (H, W, 3) float32, or (H, W, 4) RGBA with straight alpha when ``backdrop`` is None.
    """
    y0, y1, x0, x1 = box
    if backdrop is None:
        out = np.zeros(frame_alpha.shape + (4,), np.float32)
        out[y0:y1, x0:x1, :3] = np.where(alpha > 0, colour, 0)
        out[..., 3] = frame_alpha
        return out
    if grade is None:
        out = np.array(backdrop, dtype=np.float32)  # the result: one full-size copy
    else:  # one global grade, still one full-size pass
        gain = np.asarray(grade, np.float32)
        out = np.multiply(backdrop, gain, dtype=np.float32)
        np.clip(out, 0, 1, out=out)
    region = out[y0:y1, x0:x1]
    if behind is not None:
        region[...] = behind if grade is None else np.clip(behind * gain, 0, 1)
    region += (colour - region) * alpha
    return out


_GAIN_RADIUS = 12  # px: the relighting's gain is taken from opaque pixels this near a soft one ...
_GAIN_RADIUS_FAR = 48  # ... or this near, where none is nearer
_OPAQUE = 0.9


def clean_edge_colour(colour: np.ndarray, photo: np.ndarray, foreground: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """The person's colour with the photo's old background taken out of its soft edge.

    ``colour`` was made from ``photo`` (the relit person, or the photo itself). Where the matte is soft the
    photo mixes the person with the old background, and so does ``colour``; there it is replaced by the
    decontaminated colour ``foreground`` (relight_rt.image.foreground) times the relighting's gain per channel,
    colour / photo, taken from the opaque pixels nearby (box means: the gain of a relighting varies slowly;
    a soft pixel's own ratio would be the old background's). Opaque and empty pixels are unchanged.

    Args:
        colour, photo, foreground: (h, w, 3) float32 RGB in [0, 1], the same pixels.
        alpha: (h, w) or (h, w, 1) matte in [0, 1].

    Returns:
        New (h, w, 3) float32 in [0, 1].
    """
    a = alpha.reshape(alpha.shape[:2])
    soft = (a > 0) & (a < 1)
    out = np.array(colour, dtype=np.float32)
    if not soft.any():
        return out
    # only the soft pixels' box needs gains, plus the far window's reach around it (a video frame's soft edge
    # is a thin band: the filters need not run over the whole frame)
    rows, cols = np.flatnonzero(soft.any(axis=1)), np.flatnonzero(soft.any(axis=0))
    reach = _GAIN_RADIUS_FAR + 1
    y0, y1 = max(int(rows[0]) - reach, 0), min(int(rows[-1]) + 1 + reach, a.shape[0])
    x0, x1 = max(int(cols[0]) - reach, 0), min(int(cols[-1]) + 1 + reach, a.shape[1])
    box = (slice(y0, y1), slice(x0, x1))
    opaque_all = a >= _OPAQUE
    opaque = opaque_all[box].astype(np.float32)[..., None]
    num, den = colour[box] * opaque, photo[box] * opaque
    gain = None
    for r in (_GAIN_RADIUS, _GAIN_RADIUS_FAR):
        k = (2 * r + 1, 2 * r + 1)
        n = cv2.boxFilter(num, -1, k, normalize=False)
        d = cv2.boxFilter(den, -1, k, normalize=False)
        g = np.divide(n, d, out=np.full_like(n, np.nan), where=d > 1e-3 * (2 * r + 1))
        gain = g if gain is None else np.where(np.isnan(gain), g, gain)
    edge = soft[box]
    gain = gain[edge]
    missing = np.isnan(gain[:, 0])
    if missing.any():  # no opaque pixel within the far window: the whole person's gain
        cn, cp = colour[opaque_all], photo[opaque_all]
        total = cp.sum(0)
        overall = cn.sum(0) / np.maximum(total, 1e-6) if float(total.sum()) > 0 else np.ones(3)
        gain[missing] = overall.astype(np.float32)
    region = out[box]
    region[edge] = np.clip(foreground[box][edge] * gain, 0.0, 1.0)
    return out


def over_premultiplied(premultiplied: np.ndarray, alpha: np.ndarray, backdrop: np.ndarray | None) -> np.ndarray:
    """A premultiplied (H, W, 3) person (e.g. a DVP output, already ⊙ mask) over an (H, W, 3) backdrop.

    With ``backdrop`` None the result is RGBA: straight colour (premultiplied / alpha) and alpha.
    """
    m = alpha[..., None]
    if backdrop is None:
        colour = np.divide(premultiplied, m, out=np.zeros_like(premultiplied), where=m > 1e-3)
        return np.concatenate([np.clip(colour, 0, 1), m], axis=2).astype(np.float32)
    return premultiplied + backdrop * (1.0 - m)
