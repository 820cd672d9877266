"""``transport.npz`` as ``relight-rt decompose`` writes it: the light transport at the network's resolution.

Stage 1 computes the transport on the network's R x R square; the input-size map is only that square
resampled into the photo's frame (zero outside the crop box). So the file keeps what the network gave,
in float16, compressed, with the crop geometry that brings it back to the photo's size
(:meth:`relight_rt.image.crop.CropGeometry.to_input`, the same resampling the runtime uses):

==============  ===============  =====================================================================
key             dtype, shape     meaning
==============  ===============  =====================================================================
``format``      int64 ()         2 (format 1: key ``T`` only, float32 (H, W, 9) at the photo's size)
``transport``   float16 (R,R,9)  T_k per network pixel, zero off the mask (DESIGN.md §3 "Transport")
``frame``       int64 (2,)       (H, W) of the photo
``box``         int64 (4,)       (y0, y1, x0, x1): the crop in photo pixels, end exclusive
``offset``      int64 (2,)       (oy, ox): where the crop starts inside the padded square
``side``        int64 ()         S, the padded square's side in photo pixels
``mode``        str ()           "quality" or "reference" (the forward resize)
==============  ===============  =====================================================================

float16 keeps 11 significant bits: a relative error of at most 2^-11 (4.9e-4) per value. Size, measured
on the reference's 1950 x 1302 photo (2.5 megapixels) with the bundled 256-px stage 1: 0.27 MB, where
format 1 (float32 at the photo's size: 91 MB before compression) took 8.0 MB (51 MB was reported for a
photo where the person fills more of the frame);
the map read back differs from format 1's by 1.3e-4 relative (largest 4.7e-4). A 1024-px network's map
is at most 18.9 MB before compression, whatever the photo's size. :func:`load_transport` reads both.
"""

from __future__ import annotations

import os
import zipfile
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from ..engine.errors import RelightError
from ..engine.files import write_npz
from ..engine.limits import NPY_MAX_BYTES, require_file
from ..image.crop import MODES, CropGeometry

FORMAT = 2
__all__ = ["FORMAT", "load_transport", "save_transport", "transport_arrays"]


def transport_arrays(transport: np.ndarray, geometry: CropGeometry) -> dict[str, np.ndarray]:
    """The arrays of a format-2 transport file (see ``save_transport``), for writers that write several files."""
    t = np.asarray(transport)
    r = geometry.resolution
    if t.shape != (r, r, 9):
        raise RelightError(f"transport: expected ({r}, {r}, 9) (the network's square), got {t.shape}")
    return {
        "format": np.array(FORMAT, np.int64),
        "transport": t.astype(np.float16),
        "frame": np.array(geometry.frame, np.int64),
        "box": np.array(geometry.box, np.int64),
        "offset": np.array(geometry.offset, np.int64),
        "side": np.array(geometry.side, np.int64),
        "mode": np.array(geometry.mode),
    }


def save_transport(
    path: str | os.PathLike, transport: np.ndarray, geometry: CropGeometry, protect: Iterable = ()
) -> Path:
    """Write the network-frame transport (R, R, 9) and its crop geometry (format 2, atomically).

    Args:
        path: the .npz to write.
        transport: (R, R, 9) float, network frame (``Decomposition.transport``).
        geometry: the crop geometry of the decomposition (``Decomposition.geometry``).
        protect: inputs that must not be written over.
    """
    arrays = transport_arrays(transport, geometry)
    return write_npz(path, arrays, protect)


def _geometry(z, label: str) -> CropGeometry:
    try:
        mode = str(z["mode"][()])
        frame = tuple(int(v) for v in z["frame"])
        box = tuple(int(v) for v in z["box"])
        offset = tuple(int(v) for v in z["offset"])
        side, res = int(z["side"][()]), int(z["transport"].shape[0])
    except (KeyError, ValueError, TypeError, IndexError) as exc:
        raise RelightError(f"{label}: incomplete crop geometry ({exc})") from None
    y0, y1, x0, x1 = box if len(box) == 4 else (0, 0, 0, 0)
    ok = (
        len(frame) == 2 and len(box) == 4 and len(offset) == 2 and mode in MODES and res > 0
        and 0 <= y0 < y1 <= frame[0] and 0 <= x0 < x1 <= frame[1]
        and side == max(y1 - y0, x1 - x0) and 0 <= offset[0] <= side - (y1 - y0) and 0 <= offset[1] <= side - (x1 - x0)
    )  # fmt: skip
    if not ok:
        raise RelightError(f"{label}: inconsistent crop geometry (frame {frame}, box {box}, offset {offset}, "
                           f"side {side})")  # fmt: skip
    return CropGeometry(frame, box, offset, side, res, mode)


def load_transport(path: str | os.PathLike, *, network: bool = False) -> np.ndarray:
    """Read a ``transport.npz`` written by ``relight-rt decompose`` (format 2, or format 1's key ``T``).

    Args:
        path: the file.
        network: return the network-frame (R, R, 9) map as stored instead of the photo-size one (format 2
            only).

    Returns:
        New float32 array (H, W, 9) at the photo's size, zero outside the crop box (or (R, R, 9)).

    Raises:
        RelightError: unreadable, not an .npz, keys or shapes not of either format.
    """
    p = Path(path)
    label = f"transport {p}"
    require_file(p, "transport")
    try:
        with zipfile.ZipFile(p) as zf:  # every member's size before anything is inflated (a zip bomb)
            big = [i.filename for i in zf.infolist() if i.file_size > NPY_MAX_BYTES]
        if big:
            raise RelightError(f"{label}: {big[0]} is larger than {NPY_MAX_BYTES >> 20} MiB uncompressed; refused")
        with np.load(p, allow_pickle=False) as z:
            if "transport" in z.files:
                t = np.asarray(z["transport"])
                if t.ndim != 3 or t.shape[2] != 9 or t.shape[0] != t.shape[1] or t.dtype.kind != "f":
                    raise RelightError(f"{label}: expected a float (R, R, 9) 'transport', got {t.shape} {t.dtype}")
                t = t.astype(np.float32)
                return t if network else _geometry(z, label).to_input(t)
            if "T" in z.files:  # format 1: already at the photo's size
                if network:
                    raise RelightError(f"{label}: format 1 holds the photo-size map only, not the network's")
                t = np.asarray(z["T"])
                if t.ndim != 3 or t.shape[2] != 9 or t.dtype.kind != "f":
                    raise RelightError(f"{label}: expected a float (H, W, 9) 'T', got {t.shape} {t.dtype}")
                return t.astype(np.float32)
            raise RelightError(f"{label}: expected the key 'transport' (or 'T'), found {sorted(z.files)}")
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        if isinstance(exc, RelightError):
            raise
        raise RelightError(f"{label}: not a readable .npz ({exc})") from None
