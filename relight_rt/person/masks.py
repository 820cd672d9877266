"""Where a photo's person mask comes from: one resolver for photos, the CLI and video.

Order (DESIGN.md §3, "Mattes"): a mask the caller gives always wins, then the image's alpha
channel (unless it is opaque everywhere: no mask then), then an automatic matte (a :class:`Matter`),
else a :class:`RelightError` that says how to give one. Every mask is read by one rule
(``relight_rt.image.io.read_mask``): files as 8/16-bit grey, colour arrays through Rec. 601 grey, floats
in [0, 1], the image's size. Photos need an outline to relight (not empty, not all foreground); a
video frame may have nobody in it.

On disk (the reference's layout): ``NAME_mask.png`` beside ``NAME.jpg``, or a folder of such files
(:func:`find_mask_file`).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Protocol, runtime_checkable

import numpy as np

from ..engine.errors import RelightError
from ..image.io import read_mask, sibling_mask

AUTO = "auto"  # as a mask argument: use the automatic matte even when a mask file or alpha exists

MaskLike = str | os.PathLike | np.ndarray


@runtime_checkable
class Matter(Protocol):
    """An automatic person matte: RGB photo in, soft alpha out, at the photo's full resolution.

    ``matter(rgb, name)`` takes (H, W, 3) float32 RGB in [0, 1] and returns (H, W) float32 in [0, 1]
    (1 = person). It raises RelightError when it finds no person (naming the image by ``name``).
    relight_rt.person.matting.PersonMatter is the bundled one.
    """

    def __call__(self, rgb: np.ndarray, name: str = "image") -> np.ndarray: ...


def _no_mask_message(name: str, matter_note: str) -> str:
    return (f"{name}: no mask given and the image has no alpha channel{matter_note}; give a mask "
            "(--mask FILE in the CLI, mask= in the API) or an RGBA image whose alpha is the person")


def resolve_mask(
    image: np.ndarray,
    mask: MaskLike | None = None,
    *,
    matter: Matter | None = None,
    allow_empty: bool = False,
    name: str = "image",
) -> np.ndarray:
    """The person mask of one image.

    Args:
        image: (H, W, 3) RGB or (H, W, 4) RGBA float32 in [0, 1] (as ``relight_rt.image.io.read_image`` returns).
        mask: a path or array (see ``relight_rt.image.io.read_mask``), ``"auto"`` (the automatic matte, even when
            the image has alpha), or None (alpha, else the automatic matte; an alpha channel that is opaque
            everywhere is no mask and is passed over).
        matter: the automatic matte; None: there is none.
        allow_empty: accept a mask with no person or no background (video frames); photos need an outline.
        name: what to call the image in error messages.

    Returns:
        New float32 (H, W) in [0, 1].

    Raises:
        RelightError: a bad mask, or no mask to be had (the message says how to give one).
    """
    shape = image.shape[:2]
    if isinstance(mask, str) and mask == AUTO:
        if matter is None:
            raise RelightError(f"{name}: mask 'auto' asked for, but no automatic matting model is available")
        return _check_matte(_run_matter(matter, image, name), shape, name, allow_empty)
    if mask is not None:
        return read_mask(mask, shape, "mask", allow_empty=allow_empty)
    opaque = image.ndim == 3 and image.shape[2] == 4 and _fully_opaque(image[..., 3])
    if image.ndim == 3 and image.shape[2] == 4 and not opaque:
        return read_mask(image[..., 3], shape, f"{name} alpha (used as the mask)", allow_empty=allow_empty)
    if matter is None:
        if opaque:
            raise RelightError(f"{name}: its alpha channel is opaque everywhere, so it is no mask, and no automatic "
                               "matting model is available; give a mask (--mask FILE in the CLI, mask= in the API)")
        raise RelightError(_no_mask_message(name, ""))
    note = "; its alpha channel is opaque everywhere, so it is no mask" if opaque else ""
    return _check_matte(_run_matter(matter, image, name, note), shape, name, allow_empty)


def _fully_opaque(alpha: np.ndarray) -> bool:
    """True for an alpha channel with no transparent pixel at all (RGBA files that editors and screenshots write
    opaque): it tells nothing about where the person is, so it is not taken as the mask."""
    return bool(np.asarray(alpha).min() >= 1.0 - 0.5 / 255)


def _run_matter(matter: Matter, image: np.ndarray, name: str, note: str = "") -> np.ndarray:
    try:
        return matter(np.ascontiguousarray(image[..., :3]), name=name)
    except RelightError as exc:
        if "no person found" not in str(exc):
            raise
        hint = "if there is one, give its mask (--mask FILE in the CLI, mask= in the API)"
        raise RelightError(f"{exc}{note}; {hint}") from None


def _check_matte(alpha: np.ndarray, shape: tuple[int, int], name: str, allow_empty: bool) -> np.ndarray:
    a = np.asarray(alpha)
    if a.shape != tuple(shape) or a.dtype.kind != "f":
        raise RelightError(f"{name}: the automatic matte returned {a.shape} {a.dtype}, expected {tuple(shape)} float")
    return read_mask(a.astype(np.float32), shape, f"{name} automatic matte", allow_empty=allow_empty)


def find_mask_file(image_path: str | os.PathLike, mask_arg: str | os.PathLike | None, *, single: bool = True
                   ) -> Path | str | None:
    """The mask file the CLI uses for ``image_path``.

    Args:
        image_path: the photo.
        mask_arg: the ``--mask`` value: None (``NAME_mask.png`` beside the photo, if any), a folder
            holding ``NAME_mask.png``, a file (one input only), or ``"auto"`` (returned as is).
        single: whether this is the only input (a mask file cannot serve several).

    Returns:
        A path, ``"auto"``, or None (no file: the resolver goes on to alpha, then the automatic matte).
    """
    if mask_arg is None:
        return sibling_mask(image_path)
    if isinstance(mask_arg, str) and mask_arg == AUTO:
        return AUTO
    m = Path(mask_arg)
    if m.is_dir():
        found = sibling_mask(m / Path(image_path).name)
        if found is None:
            raise RelightError(f"mask folder {m} has no {Path(image_path).stem}_mask.png")
        return found
    if not single:
        raise RelightError("--mask FILE works with one input; for several, give a folder with NAME_mask.png files")
    return m
