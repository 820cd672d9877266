"""The studio's uploads (an environment map, a background photo, a photo of a person to borrow the light of), taken as
bytes and never by a path or a client's file name: limited in size, typed by their first bytes, sized from their header
by the runtime's one header parser (relight_rt.engine.limits.header_size: a size it cannot read, or more than
MAX_UPLOAD_PIXELS, is refused before any decoder runs), shrunk to UPLOAD_WORK_PIXELS as decoded and, where a reader
needs a file, written to a temporary file whose name this module chooses, removed right after."""

from __future__ import annotations

import tempfile
import threading
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ...engine.errors import RelightError
from ...engine.limits import header_size, shrink
from ...image.io import as_colour, decode_bytes, read_image
from ...light import envmap

MAX_UPLOAD_BYTES = 32 << 20  # an env map or a photo; bigger uploads are refused before decoding
MAX_UPLOAD_PIXELS = 40_000_000  # decoded size limit (a small file can hold a huge image)
# what an upload is shrunk to right after decoding, before any float copy: each becomes 27 numbers (an env map's
# degree-2 SH, a background's or a person's light from stage 1), and at full size a 40-MP one cost ~60 bytes a
# pixel, four at once past 4 GB (issue 50 bug 6); decoded, a pixel costs 3-12 bytes
UPLOAD_WORK_PIXELS = 2_000_000
# the work on uploads larger than UPLOAD_WORK_PIXELS runs one at a time (``one_large_at_a_time``): decoded and shrunk, a
# 40-MP map still peaks at ~10 bytes a pixel (OpenCV's decode holds two copies: ~640 MB for a 16-bit RGBA photo), and
# the server's four upload slots at once took it from 0.3 to 1.6 GB (fuzz9)
_LARGE_WORK = threading.BoundedSemaphore(1)

# (leading bytes, kind, suffix the readers go by)
_MAGIC = (
    (b"\x89PNG\r\n\x1a\n", "png", ".png"),
    (b"\xff\xd8\xff", "jpeg", ".jpg"),
    (b"#?RADIANCE", "hdr", ".hdr"),
    (b"#?RGBE", "hdr", ".hdr"),
    (b"RIFF", "webp", ".webp"),  # checked further below: RIFF....WEBP
    (b"BM", "bmp", ".bmp"),
)


def sniff(data: bytes) -> tuple[str, str] | None:
    """(kind, suffix) of an upload from its first bytes, or None for anything else."""
    for magic, kind, suffix in _MAGIC:
        if data.startswith(magic):
            if kind == "webp" and data[8:12] != b"WEBP":
                return None
            return kind, suffix
    return None


def check_upload(data: bytes, name: str, allowed: tuple[str, ...], limit: int = MAX_UPLOAD_BYTES) -> str:
    """Check an upload's size and type (by content); returns the file suffix for its kind.

    Raises:
        RelightError: not bytes (a path is never opened), empty, larger than ``limit``, not one of ``allowed``
            kinds, a header whose image size cannot be read (relight_rt.engine.limits.header_size) or an image of
            more than MAX_UPLOAD_PIXELS.
    """
    if not isinstance(data, (bytes, bytearray)):
        raise RelightError(f"{name}: expected the upload's bytes, got {type(data).__name__} (a path is never "
                           "opened)")  # fmt: skip
    if not data:
        raise RelightError(f"{name}: the upload is empty")
    if len(data) > limit:
        raise RelightError(f"{name}: the upload is {len(data) / 2**20:.1f} MiB, the limit is {limit / 2**20:.0f} MiB")
    found = sniff(data)
    if found is None or found[0] not in allowed:
        what = "an unknown type" if found is None else f"a {found[0]} file"
        raise RelightError(f"{name}: expected {' or '.join(a.upper() for a in allowed)} (by content), got {what}")
    # the size from the header, read by the runtime's one parser, before any decoder allocates the image
    size = header_size(data, name)
    if size is None:
        raise RelightError(f"{name}: cannot read the image size from its {found[0].upper()} header (damaged or "
                           "truncated file)")  # fmt: skip
    if size[0] * size[1] > MAX_UPLOAD_PIXELS:
        raise RelightError(f"{name}: the image is {size[0]}x{size[1]}, more than {MAX_UPLOAD_PIXELS} pixels")
    return found[1]


def one_large_at_a_time(work: Callable[[bytes], object], data: bytes, name: str):
    """``work(data)``, the whole of an upload's work (decode, shrink, the light found in it), waiting for any other
    upload's when the header says ``data`` is larger than UPLOAD_WORK_PIXELS (or cannot say: ``work`` refuses it);
    smaller uploads run side by side. The studio runs every upload through it (relight_rt.apps.studio.app)."""
    try:
        size = header_size(data, name) if isinstance(data, (bytes, bytearray)) else None
    except RelightError:  # a header the parser refuses: ``work`` refuses it again, with the same message
        size = None
    if size is not None and size[0] * size[1] <= UPLOAD_WORK_PIXELS:
        return work(data)
    with _LARGE_WORK:
        return work(data)


def decode_upload(data: bytes, name: str, max_pixels: int = UPLOAD_WORK_PIXELS) -> np.ndarray:
    """An uploaded PNG/JPEG/WebP/BMP as float32 RGB(A) in [0, 1] (alpha kept), checked by content, shrunk to at
    most ``max_pixels`` (relight_rt.engine.limits ``shrink``) as decoded, before the float conversion."""
    check_upload(data, name, ("png", "jpeg", "webp", "bmp"))
    img = decode_bytes(np.frombuffer(data, np.uint8))  # turned as its EXIF orientation says
    if img is None:
        raise RelightError(f"{name}: cannot decode the image (corrupt file)")
    img = shrink(img, max_pixels)
    # (its size was checked from the header by check_upload) OpenCV's BGR(A) as RGB(A), gray as colour
    return read_image(as_colour(img, bgr=True), name)  # checks channels, depth, size; a new float32 array


def envmap_upload_light(data: bytes) -> np.ndarray:
    """(9, 3) float32 light of an uploaded equirectangular map (.hdr, or an sRGB PNG/JPEG, linearised), shrunk
    to UPLOAD_WORK_PIXELS as decoded (envmap.load_envmap's ``max_pixels``)."""
    suffix = check_upload(data, "environment map", ("hdr", "png", "jpeg"))
    with tempfile.TemporaryDirectory(prefix="relight-studio-") as folder:
        path = Path(folder) / f"upload{suffix}"  # our name; the client's is never used
        path.write_bytes(data)
        try:  # its size was checked from the header above
            env = envmap.load_envmap(path, max_pixels=UPLOAD_WORK_PIXELS)
        except RelightError as exc:  # told of the upload, not of the server's temporary file
            raise RelightError(str(exc).replace(str(path), "environment map")) from None
    return envmap.project_envmap(env).astype(np.float32)


def background_upload_light(data: bytes, key_light=None) -> np.ndarray:
    """(9, 3) float32 light of an uploaded background photo (relight_rt.light.from_background, 60° field of view),
    shrunk to UPLOAD_WORK_PIXELS as decoded; ``key_light`` "AZ,EL" (degrees) or a pair steers its key light
    (relight_rt.light.from_background ``parse_key_light``)."""
    from ...light.from_background import light_from_background, parse_key_light

    key = parse_key_light(key_light)  # checked before the upload is decoded
    image = decode_upload(data, "background")
    light, _ = light_from_background(np.ascontiguousarray(image[..., :3]), key_light=key)
    return np.asarray(light, dtype=np.float32)
