"""SH light files: read and write a (9, 3) light as .npy or .json (DESIGN.md §6), atomically.

Our own files are RGB; the reference implementation's are B, G, R, which is read or written only when asked
(``bgr=True``), never guessed. ``.npy`` is read without unpickling.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..engine.errors import RelightError
from .sh import N_COEFFS, check_light, check_magnitude, numbers_only

__all__ = ["load_light", "save_light"]

_LAYOUTS = (None, "27-kc", "3x9")
_JSON_MAX_BYTES = 1 << 20


def _shape_light(arr: np.ndarray, layout, p: Path) -> np.ndarray:
    if layout not in _LAYOUTS:
        raise RelightError(f"layout: expected None, '27-kc' or '3x9', got {layout!r}")
    if layout is None:
        if arr.shape in ((27,), (3, 9)):
            raise RelightError(
                f"{p}: light has shape {arr.shape}; say how to read it: layout='27-kc' (index 3k + c) "
                "for (27,), layout='3x9' (row c, column k) for (3, 9)"
            )
        if arr.shape != (N_COEFFS, 3):
            raise RelightError(f"{p}: expected an SH light of shape (9, 3), got {arr.shape}")
        return arr
    want = (27,) if layout == "27-kc" else (3, 9)
    if arr.shape != want:
        raise RelightError(f"{p}: layout={layout!r} expects shape {want}, got {arr.shape}")
    return arr.reshape(N_COEFFS, 3) if layout == "27-kc" else arr.T


def load_light(path, bgr: bool = False, layout: str | None = None) -> np.ndarray:
    """Read an SH light file as RGB.

    Formats: `.npy` holding (9, 3) (coefficient × colour), read with allow_pickle=False; `.json`
    {"sh": [[r, g, b] × 9], "order": "rgb"} ("order": "bgr" is honoured too).

    Args:
        path: file path.
        bgr: the file's columns are B, G, R (the reference implementation's light files, e.g.
            ../shared/reference/lights); they are swapped to RGB. An explicit choice, never guessed.
        layout: how to read a flat or transposed array: '27-kc' for (27,) with index 3k + c,
            '3x9' for (3, 9) with row c and column k. None accepts only (9, 3).

    Returns:
        (9, 3) float64 RGB light.

    Raises:
        RelightError: naming the file and the problem (missing, unreadable, wrong shape, NaN/Inf,
            conflicting colour order).
    """
    p = Path(path)
    ext = p.suffix.lower()
    if ext not in (".npy", ".json"):
        raise RelightError(f"{p}: unsupported light file type {ext!r}; expected .npy or .json")
    if not p.is_file():
        raise RelightError(f"{p}: light file {'is not a regular file' if p.exists() else 'not found'}")
    swap = bool(bgr)
    try:
        if ext == ".npy":
            from ..engine.limits import load_npy

            raw = load_npy(p, "light", max_bytes=1 << 20)
        else:
            if p.stat().st_size > _JSON_MAX_BYTES:
                size = p.stat().st_size
                raise RelightError(f"{p}: {size:,} bytes is too large for a light file (a light is 27 numbers)")
            doc = json.loads(p.read_text(encoding="utf-8"))
            if not isinstance(doc, dict) or "sh" not in doc:
                raise RelightError(f'{p}: expected a JSON object {{"sh": [[r, g, b] x 9], "order": "rgb"}}')
            order = str(doc.get("order", "bgr" if bgr else "rgb")).lower()
            if order not in ("rgb", "bgr"):
                raise RelightError(f"{p}: \"order\" must be 'rgb' or 'bgr', got {doc.get('order')!r}")
            if bgr and order == "rgb":
                raise RelightError(f'{p}: bgr=True but the file says "order": "rgb"')
            swap = order == "bgr"
            if not numbers_only(doc["sh"]):  # numpy reads "0.5" and true as numbers
                raise RelightError(f'{p}: cannot read light file ("sh" must hold numbers only: no strings, '
                                   "true/false or null)")  # fmt: skip
            raw = np.array(doc["sh"], dtype=np.float64)  # OverflowError below: an integer of 400 digits
    except RelightError:
        raise
    except RecursionError:
        raise RelightError(f"{p}: cannot read light file (JSON nested too deeply)") from None
    except (OSError, EOFError, ValueError, TypeError, OverflowError, UnicodeDecodeError) as exc:
        raise RelightError(f"{p}: cannot read light file ({exc})") from None
    if raw.dtype.kind not in "fiu":
        raise RelightError(f"{p}: expected a numeric SH light, got dtype {raw.dtype}")
    arr = _shape_light(np.asarray(raw, dtype=np.float64), layout, p)
    if not np.all(np.isfinite(arr)):
        raise RelightError(f"{p}: light contains NaN or Inf")
    check_magnitude(arr, str(p))
    if swap:
        arr = arr[:, ::-1]
    return np.array(arr, dtype=np.float64, copy=True)


def save_light(path, light, bgr: bool = False) -> None:
    """Write an SH light atomically (temporary file in the same folder, then os.replace).

    Args:
        path: `.npy` ((9, 3) float64) or `.json` ({"sh": [[r, g, b] × 9], "order": "rgb"}).
        light: (9, 3) RGB light.
        bgr: write the columns as B, G, R (the reference's order; .json then says "order": "bgr").
    """
    p = Path(path)
    lit = check_light(light)
    ext = p.suffix.lower()
    if ext not in (".npy", ".json"):
        raise RelightError(f"{p}: unsupported light file type {ext!r}; expected .npy or .json")
    if not p.parent.is_dir():
        raise RelightError(f"{p}: folder {p.parent} does not exist")
    data = lit[:, ::-1].copy() if bgr else lit
    from ..engine.files import atomic_path

    with atomic_path(p) as tmp, open(tmp, "wb") as f:
        if ext == ".npy":
            np.save(f, data, allow_pickle=False)
        else:
            doc = {"sh": data.tolist(), "order": "bgr" if bgr else "rgb"}
            f.write(json.dumps(doc, indent=1).encode("utf-8"))
