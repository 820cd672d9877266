"""Reading images and masks, and writing images: the one image intake.

Images are returned as float32 RGB(A) in [0, 1], (H, W, 3) or (H, W, 4); files are read and written
with OpenCV, whose BGR order is converted here, at the boundary (DESIGN.md §3). Images are written through
relight_rt.engine.files (atomic, never over an input).
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Iterable
from pathlib import Path

import cv2
import numpy as np

from ..engine.errors import RelightError
from ..engine.files import atomic_write, bytes_writer
from ..engine.limits import check_array_pixels, check_pixels, header_size
from .exif import apply_orientation, exif_orientation

log = logging.getLogger(__name__)

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp")
_FLOAT_SLACK = 1e-3  # float images may stray this far outside [0, 1] (rounding); they are clipped


def _describe(a: np.ndarray) -> str:
    return f"{tuple(a.shape)} {a.dtype}"


def decode_bytes(data: np.ndarray, flags: int = cv2.IMREAD_UNCHANGED) -> np.ndarray | None:
    """``cv2.imdecode`` of an encoded file (uint8 array), turned the way its EXIF orientation tag says
    (relight_rt.image.exif: one rule for every flag; OpenCV's own handling is switched off). None when it
    cannot be decoded."""
    if not data.size:
        return None
    try:
        image = cv2.imdecode(data, flags if flags == cv2.IMREAD_UNCHANGED else flags | cv2.IMREAD_IGNORE_ORIENTATION)
    except cv2.error:  # OpenCV's own limits (e.g. OPENCV_IO_MAX_IMAGE_PIXELS) raise instead of returning None
        return None
    return None if image is None else apply_orientation(image, exif_orientation(data))


def decode_file(path: Path, name: str, flags: int = cv2.IMREAD_UNCHANGED) -> np.ndarray:
    """Decode an image file (default: as stored, depth and channels unchanged, BGR(A) as OpenCV gives it),
    turned as its EXIF orientation says (a phone photo comes out the way the phone shows it).

    The size in the file's header is checked against :func:`max_pixels` before anything is decoded
    (relight_rt.engine.limits.header_size); formats whose header is not parsed here are checked after decoding.
    """
    path = Path(path)
    if not path.is_file():  # also keeps FIFOs and devices (/dev/zero) from blocking or filling memory
        what = "not found" if not path.exists() else "not a regular file"
        raise RelightError(f"{name}: cannot read {path}: {what}")
    try:
        size = header_size(path, f"{name} {path}")
        if size is not None:
            check_pixels(size[0], size[1], f"{name} {path}")
        data = np.fromfile(path, dtype=np.uint8)  # works for non-ASCII paths, unlike cv2.imread
    except OSError as exc:
        raise RelightError(f"{name}: cannot read {path}: {exc.strerror or exc}") from None
    image = decode_bytes(data, flags)
    if image is None:
        raise RelightError(f"{name}: cannot decode {path} as an image (unreadable, empty or not an image file)")
    check_pixels(image.shape[1], image.shape[0], f"{name} {path}")
    return image


def as_colour(a: np.ndarray, *, bgr: bool) -> np.ndarray:
    """Channels as colour, dtype unchanged: grayscale (H, W) or (H, W, 1) repeated into (H, W, 3);
    (H, W, 3|4) kept, BGR(A) → RGB(A) when ``bgr`` (a decoded file). Other shapes are returned as they are
    (the caller says what is wrong with them)."""
    if a.ndim == 3 and a.shape[2] == 1:
        a = a[..., 0]
    if a.ndim == 2:
        return np.repeat(a[..., None], 3, axis=2)
    if bgr and a.ndim == 3 and a.shape[2] in (3, 4):
        return np.ascontiguousarray(a[..., [2, 1, 0, 3][: a.shape[2]]])
    return a


def _to_unit_float(a: np.ndarray, name: str, copy: bool = True) -> np.ndarray:
    """Any accepted dtype → float32 array in [0, 1]: a new one, or with ``copy=False`` the caller's own array
    when it already is float32 in [0, 1] with each row's pixels contiguous (for callers that only read it; nothing
    is allocated then)."""
    if a.dtype == np.uint8:
        return np.multiply(a, np.float32(1 / 255), dtype=np.float32)
    if a.dtype == np.bool_:
        return a.astype(np.float32)
    if a.dtype == np.uint16:
        return np.multiply(a, np.float32(1 / 65535), dtype=np.float32)
    if a.dtype.kind == "f":
        # min and max propagate NaN, and Inf lies outside the range: one read-only pass each checks everything
        lo, hi = float(a.min()), float(a.max())
        if np.isnan(lo) or np.isnan(hi) or np.isinf(lo) or np.isinf(hi):
            raise RelightError(f"{name}: expected finite values in [0, 1], got NaN or Inf ({_describe(a)})")
        if lo < -_FLOAT_SLACK or hi > 1 + _FLOAT_SLACK:
            raise RelightError(f"{name}: expected float values in [0, 1], got [{lo:.4g}, {hi:.4g}] ({_describe(a)})")
        # each row's pixels contiguous, rows at any distance: a C-contiguous photo, or a window of one (a group's
        # person: relight_rt.relight.people.windows), which OpenCV and numpy read as they are
        rows = a.strides[-1] == a.itemsize and (a.ndim < 3 or a.strides[-2] == a.shape[-1] * a.itemsize)
        if not copy and a.dtype == np.float32 and rows and lo >= 0.0 and hi <= 1.0:
            return a
        out = a.astype(np.float32, order="C")  # a copy: never alias the caller's array
        if lo < 0.0 or hi > 1.0 or a.dtype != np.float32:  # float64 may round past 1 in float32
            np.clip(out, 0.0, 1.0, out=out)
        return out
    raise RelightError(f"{name}: expected uint8, uint16 or float, got {_describe(a)}")


def read_image(src: str | os.PathLike | np.ndarray, name: str = "image", *, copy: bool = True) -> np.ndarray:
    """Read a colour image from a file or an array: the one intake for photos.

    Args:
        src: a path (PNG/JPEG/TIFF/WebP/..., 8- or 16-bit, gray, gray + alpha, colour, colour + alpha, CMYK
            JPEG; turned as its EXIF orientation tag says) or an array (H, W), (H, W, 1), (H, W, 3) RGB or
            (H, W, 4) RGBA, uint8 (0-255), uint16 (0-65535) or float (0-1). Grayscale becomes colour (the
            gray repeated in R, G and B).
        name: what to call the input in error messages.
        copy: False lets a caller that only reads the result have ``src`` itself back when it already is a
            float32 (H, W, 3|4) array in [0, 1] with each row's pixels contiguous (a photo, or a window of one:
            no copy of a 12-megapixel photo; checked all the same).

    Returns:
        New float32 array (H, W, 3) RGB or (H, W, 4) RGBA, values in [0, 1] (with ``copy=False``: possibly
        ``src`` itself; do not write into it).

    Raises:
        RelightError: unreadable file, wrong channel count, another dtype, NaN/Inf, values out of range, a
            side under 2 px.
    """
    if isinstance(src, np.ndarray):
        a = as_colour(src, bgr=False)
        label = name
        check_array_pixels(a, name)
    elif isinstance(src, (str, os.PathLike)):
        path = Path(src)
        a = as_colour(decode_file(path, name), bgr=True)  # files are BGR(A)
        label = f"{name} {path}"
    else:
        raise RelightError(f"{name}: expected a path or an (H, W, 3) array, got {type(src).__name__}")
    if a.ndim != 3 or a.shape[2] not in (3, 4):
        got = _describe(src if isinstance(src, np.ndarray) else a)
        raise RelightError(f"{label}: expected an (H, W, 3) RGB or (H, W, 4) RGBA image, got {got}")
    if a.shape[0] < 2 or a.shape[1] < 2:
        raise RelightError(f"{label}: image is too small, got {_describe(a)}")
    return _to_unit_float(a, label, copy)


def read_mask(
    src: str | os.PathLike | np.ndarray, shape: tuple[int, int], name: str = "mask", *, allow_empty: bool = False
) -> np.ndarray:
    """Read a person mask (binary or soft) and check it against the image.

    Args:
        src: a path (8- or 16-bit, any channels) or an array (H, W), (H, W, 1) or (H, W, 3); bool, uint8,
            uint16 or float in [0, 1]. Colour is turned to gray as the reference does (a file is decoded with
            cv2.IMREAD_GRAYSCALE; an RGB array goes through cv2.COLOR_RGB2GRAY: 0.299 R + 0.587 G + 0.114 B).
        shape: (H, W) of the image the mask belongs to.
        name: what to call the input in error messages.
        allow_empty: accept a mask with no pixel >= 0.5 or with every pixel >= 0.5 (a video frame with
            nobody in it); a photo needs an outline to relight.

    Returns:
        New float32 array (H, W) in [0, 1].

    Raises:
        RelightError: unreadable, wrong shape or dtype, size differs from ``shape``, empty (no pixel >= 0.5),
            or all foreground (every pixel >= 0.5: no outline to relight), unless ``allow_empty``.
    """
    if isinstance(src, np.ndarray):
        a, label = src, name
        check_array_pixels(a, name)
        if a.ndim == 3 and a.shape[2] == 3 and a.dtype in (np.uint8, np.uint16, np.float32, np.float64):
            a = cv2.cvtColor(np.ascontiguousarray(a), cv2.COLOR_RGB2GRAY)
    elif isinstance(src, (str, os.PathLike)):
        label = f"{name} {src}"
        a = decode_file(Path(src), name, cv2.IMREAD_GRAYSCALE | cv2.IMREAD_ANYDEPTH)  # as the reference reads masks
    else:
        raise RelightError(f"{name}: expected a path or an (H, W) array, got {type(src).__name__}")
    if a.ndim == 3 and a.shape[2] == 1:
        a = a[..., 0]
    elif a.ndim != 2:
        raise RelightError(f"{label}: expected an (H, W) or (H, W, 3) mask, got {_describe(a)}")
    if tuple(a.shape[:2]) != tuple(shape):
        raise RelightError(f"{label}: mask is {a.shape[0]}x{a.shape[1]} (HxW), the image is {shape[0]}x{shape[1]}")
    m = _to_unit_float(a, label)
    if allow_empty:
        return m
    if not (m >= 0.5).any():
        raise RelightError(f"{label}: mask is empty (no pixel >= 0.5); expected the person in white")
    if (m >= 0.5).all():
        raise RelightError(f"{label}: mask covers the whole image (every pixel >= 0.5); expected the person only")
    return m


def image_writer(image: np.ndarray, path: str | os.PathLike) -> Callable[[object], None]:
    """A writer of a float [0, 1] image as 8-bit in the format of ``path``'s suffix (see ``write_image``)."""
    path = Path(path)
    return bytes_writer(encode_image(image, path.suffix or ".png", name=str(path)))


def encode_image(image: np.ndarray, suffix: str, name: str = "image") -> bytes:
    """Encode a float [0, 1] RGB(A) (H, W, 3|4) or gray (H, W) image as 8-bit PNG/JPEG/... bytes."""
    a = np.asarray(image)
    if a.ndim not in (2, 3) or (a.ndim == 3 and a.shape[2] not in (1, 3, 4)):
        raise RelightError(f"{name}: expected (H, W), (H, W, 3) or (H, W, 4) to write, got {_describe(a)}")
    if a.dtype != np.uint8:
        a = np.clip(np.nan_to_num(a, nan=0.0), 0.0, 1.0) * 255.0 + 0.5
        a = a.astype(np.uint8)
    if a.ndim == 3 and a.shape[2] == 3:
        a = cv2.cvtColor(a, cv2.COLOR_RGB2BGR)
    elif a.ndim == 3 and a.shape[2] == 4:
        if suffix.lower() in (".jpg", ".jpeg", ".bmp"):
            raise RelightError(f"{name}: {suffix} cannot hold transparency; write a .png")
        a = cv2.cvtColor(a, cv2.COLOR_RGBA2BGRA)
    try:
        ok, buf = cv2.imencode(suffix, a)
    except cv2.error:
        ok = False
    if not ok:
        raise RelightError(f"{name}: cannot encode an image as {suffix!r}; use one of {', '.join(IMAGE_SUFFIXES)}")
    return buf.tobytes()


def write_image(path: str | os.PathLike, image: np.ndarray, protect: Iterable[str | os.PathLike] = ()) -> Path:
    """Write a float [0, 1] image (RGB, RGBA or gray) as 8-bit, atomically; format from the suffix.

    Raises:
        RelightError: ``path`` is one of ``protect``, its folder is missing, or the format is unknown.
    """
    return atomic_write(path, protect, image_writer(image, path))


OUTPUT_STEM = "_relit"  # ``relight`` writes NAME_relit.png into its output folder


def is_own_file(path: str | os.PathLike) -> bool:
    """True for names this project writes and never takes as input when listing a folder: hidden files
    (``.NAME.XXXX.tmp.png``, the atomic writers' temporary files, left behind only by SIGKILL) and
    ``relight``'s outputs (``NAME_relit.png``)."""
    p = Path(path)
    return p.name.startswith(".") or p.stem.endswith(OUTPUT_STEM)


def list_images(folder: str | os.PathLike) -> list[Path]:
    """Image files in ``folder`` (sorted), leaving out masks (``*_mask.*``) and this project's own
    temporary and output files (:func:`is_own_file`)."""
    folder = Path(folder)
    return sorted(
        p
        for p in folder.iterdir()
        if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES and not p.stem.endswith("_mask") and not is_own_file(p)
    )


def sibling_mask(image_path: str | os.PathLike) -> Path | None:
    """The reference's mask naming: NAME_mask.png beside NAME.jpg; None when there is none."""
    p = Path(image_path)
    for suffix in (".png", p.suffix):
        candidate = p.with_name(f"{p.stem}_mask{suffix}")
        if candidate.is_file():
            return candidate
    return None
