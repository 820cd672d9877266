"""On-disk training data: the reference's stage-1 layout, SH light folders and stage-2 photos.

Files are BGR on disk (OpenCV, like the reference's), RGB in memory (DESIGN.md §3, §6).

Stage-1 sample ``NAME`` in a folder:
    ``NAME_tex.png``        albedo, 8-bit BGR
    ``NAME_mask.png``       foreground mask, 8-bit single channel (0 or 255)
    ``NAME_parsing.png``    skin mask, 8-bit single channel (255 = exposed skin)
    ``NAME_transport.npz``  key ``T``: float32 (H, W, 9) occlusion-aware transport, zero off the mask
                            (deflate-compressed, fixed timestamps, so the same render gives the same bytes;
                            float32 like the reference: about 0.4 MB at 256², 2.3 MB at 512², ~9 MB at 1024²
                            for a person covering 13-15 % of the image, so float16 was not worth its precision)

Light folder: ``NAME.npy`` float (9, 3) SH coefficients with columns B, G, R (the reference's order).

Stage-2 photo ``SUBJECT__L{j}`` in a folder (the same SUBJECT under several lights j):
    ``SUBJECT__L{j}_photo.png``    the non-diffuse photo, 8-bit BGR
    ``SUBJECT__L{j}_diffuse.png``  its diffuse part, albedo * max(0, T·L), 8-bit BGR
    ``SUBJECT__L{j}_mask.png``     8-bit single channel
    ``SUBJECT__L{j}_light.npy``    float (9, 3) BGR, the SH of the environment map that lit it
A folder of one's own photos (``prepare_user_photos``) has only the photo and the mask: the diffuse part
and the light are not known, which the paper's stage-2 training does not need (stage 1 gives both).
"""

from __future__ import annotations

import io
import os
import zipfile
from pathlib import Path

import cv2
import numpy as np

from relight_rt.engine.errors import RelightError
from relight_rt.engine.files import atomic_path
from relight_rt.light.files import load_light

_SAMPLE_SUFFIXES = ("_tex.png", "_mask.png", "_parsing.png", "_transport.npz")
_PHOTO_SUFFIXES = ("_photo.png", "_mask.png")  # required; _diffuse.png and _light.npy when rendered


# ----------------------------------------------------------------------------------------------
# low-level atomic file writing
# ----------------------------------------------------------------------------------------------


def atomic_write(path: Path, write) -> None:
    """Call ``write(tmp_path)`` on a temporary file beside ``path`` (same suffix), then rename it into
    place; the folder is created when missing."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        write(str(tmp))


def _write_png(path: Path, image: np.ndarray) -> None:
    def write(tmp: str) -> None:
        if not cv2.imwrite(tmp, image):
            raise RelightError(f"could not write image {path}")

    atomic_write(path, write)


def _write_npy(path: Path, array: np.ndarray) -> None:
    def write(tmp: str) -> None:
        with open(tmp, "wb") as f:
            np.save(f, array, allow_pickle=False)

    atomic_write(path, write)


def _write_npz(path: Path, **arrays: np.ndarray) -> None:
    """Like ``np.savez_compressed`` but byte-for-byte reproducible (fixed member timestamps)."""

    def write(tmp: str) -> None:
        with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_DEFLATED) as zf:
            for key, value in arrays.items():
                buf = io.BytesIO()
                np.save(buf, np.ascontiguousarray(value), allow_pickle=False)
                info = zipfile.ZipInfo(f"{key}.npy", date_time=(1980, 1, 1, 0, 0, 0))
                info.compress_type = zipfile.ZIP_DEFLATED
                zf.writestr(info, buf.getvalue())

    atomic_write(path, write)


def _to_uint8(x: np.ndarray) -> np.ndarray:
    return np.round(np.clip(x, 0.0, 1.0) * 255.0).astype(np.uint8)


# ----------------------------------------------------------------------------------------------
# checks and reads
# ----------------------------------------------------------------------------------------------


def _check_image(x, name: str, shape: tuple[int, int] | None = None) -> np.ndarray:
    a = np.asarray(x)
    if a.ndim != 3 or a.shape[2] != 3:
        raise RelightError(f"{name}: expected (H, W, 3) RGB image, got {a.shape} {a.dtype}")
    if shape is not None and a.shape[:2] != shape:
        raise RelightError(f"{name}: expected size {shape}, got {a.shape[:2]}")
    return _as_unit_float(a, name)


def _check_map(x, name: str, shape: tuple[int, int]) -> np.ndarray:
    a = np.asarray(x)
    if a.ndim == 0:
        return np.full(shape, float(a), np.float32)
    if a.shape != shape:
        raise RelightError(f"{name}: expected (H, W) = {shape} map, got {a.shape} {a.dtype}")
    return _as_unit_float(a, name)


def _as_unit_float(a: np.ndarray, name: str) -> np.ndarray:
    if a.dtype == np.uint8:
        return a.astype(np.float32) / 255.0
    if not np.issubdtype(a.dtype, np.floating) or not np.all(np.isfinite(a)):
        raise RelightError(f"{name}: expected uint8 or finite float values, got {a.dtype}")
    return a.astype(np.float32)


def _check_light(light, name: str) -> np.ndarray:
    a = np.asarray(light)
    if a.shape != (9, 3) or not np.issubdtype(a.dtype, np.number):
        raise RelightError(f"{name}: expected (9, 3) SH light, got {a.shape} {a.dtype}")
    a = a.astype(np.float32)
    if not np.all(np.isfinite(a)):
        raise RelightError(f"{name}: light has NaN or Inf values")
    return a


def _read_png(path: Path, color: bool) -> np.ndarray:
    if not path.is_file():
        raise RelightError(f"missing file {path}")
    flag = cv2.IMREAD_COLOR if color else cv2.IMREAD_UNCHANGED
    img = cv2.imread(str(path), flag)
    if img is None:
        raise RelightError(f"could not read image {path}")
    if img.dtype != np.uint8:
        raise RelightError(f"{path}: expected an 8-bit image, got {img.dtype}")
    if color:
        return img[:, :, ::-1].astype(np.float32) / 255.0
    if img.ndim == 3:  # some masks are stored as 3-channel images; all channels are equal
        img = img[:, :, 0]
    return img.astype(np.float32) / 255.0


def _read_light_bgr(path: Path) -> np.ndarray:
    return load_light(path, bgr=True).astype(np.float32)


def _names(root: Path, suffixes: tuple[str, ...]) -> list[str]:
    root = Path(root)
    if not root.is_dir():
        raise RelightError(f"data folder {root} does not exist")
    first = suffixes[0]
    names = [p.name[: -len(first)] for p in root.glob(f"*{first}")]
    return sorted(n for n in names if all((root / f"{n}{s}").is_file() for s in suffixes[1:]))


# ----------------------------------------------------------------------------------------------
# stage-1 samples
# ----------------------------------------------------------------------------------------------


def list_samples(root: str | os.PathLike) -> list[str]:
    """Names of the complete stage-1 samples (all four files present) in ``root``, sorted."""
    return _names(Path(root), _SAMPLE_SUFFIXES)


def read_sample(root: str | os.PathLike, name: str) -> dict[str, np.ndarray]:
    """Read one stage-1 sample.

    Returns:
        dict with ``albedo`` (H, W, 3) float32 RGB in [0, 1], ``mask`` (H, W) float32 in [0, 1],
        ``skin`` (H, W) float32 in [0, 1] and ``transport`` (H, W, 9) float32 (DESIGN.md §3 SH order).

    Raises:
        RelightError: a file is missing, unreadable, or the sizes disagree.
    """
    root = Path(root)
    albedo = _read_png(root / f"{name}_tex.png", color=True)
    mask = _read_png(root / f"{name}_mask.png", color=False)
    skin = _read_png(root / f"{name}_parsing.png", color=False)
    path = root / f"{name}_transport.npz"
    if not path.is_file():
        raise RelightError(f"missing file {path}")
    try:
        with np.load(path, allow_pickle=False) as z:
            transport = np.asarray(z["T"], dtype=np.float32)
    except (KeyError, ValueError, OSError) as exc:
        raise RelightError(f"could not read transport {path} (expected key 'T'): {exc}") from None
    shape = albedo.shape[:2]
    if mask.shape != shape or skin.shape != shape or transport.shape != (*shape, 9):
        raise RelightError(
            f"sample {name}: sizes disagree: albedo {albedo.shape}, mask {mask.shape}, skin {skin.shape}, "
            f"transport {transport.shape} (expected (H, W, 9))"
        )
    return {"albedo": albedo, "mask": mask, "skin": skin, "transport": transport}


def write_sample(
    root: str | os.PathLike,
    name: str,
    albedo: np.ndarray,
    mask: np.ndarray,
    skin: np.ndarray,
    transport: np.ndarray,
) -> None:
    """Write one stage-1 sample in the reference's layout, each file atomically.

    Args:
        root: output folder (created when missing).
        name: sample name; files are ``NAME_tex.png`` etc.
        albedo: (H, W, 3) RGB, float in [0, 1] or uint8; written as 8-bit BGR.
        mask: (H, W) float in [0, 1] or uint8.
        skin: (H, W) float in [0, 1] or uint8 (1 = exposed skin).
        transport: (H, W, 9) float; stored as float32 under key ``T``.
    """
    a = _check_image(albedo, "albedo")
    shape = a.shape[:2]
    m = _check_map(mask, "mask", shape)
    s = _check_map(skin, "skin", shape)
    t = np.asarray(transport)
    if t.shape != (*shape, 9) or not np.issubdtype(t.dtype, np.floating) or not np.all(np.isfinite(t)):
        raise RelightError(f"transport: expected finite float (H, W, 9) = {(*shape, 9)}, got {t.shape} {t.dtype}")
    root = Path(root)
    _write_png(root / f"{name}_tex.png", _to_uint8(a)[:, :, ::-1])
    _write_png(root / f"{name}_mask.png", _to_uint8(m))
    _write_png(root / f"{name}_parsing.png", _to_uint8(s))
    _write_npz(root / f"{name}_transport.npz", T=t.astype(np.float32))


# ----------------------------------------------------------------------------------------------
# lights
# ----------------------------------------------------------------------------------------------


def list_lights(root: str | os.PathLike) -> list[str]:
    """Names of the ``NAME.npy`` light files in ``root``, sorted."""
    root = Path(root)
    if not root.is_dir():
        raise RelightError(f"light folder {root} does not exist")
    return sorted(p.stem for p in root.glob("*.npy"))


def read_lights(root: str | os.PathLike) -> np.ndarray:
    """Every ``NAME.npy`` light of a folder (BGR files, the reference's layout), in name order.

    Returns:
        (N, 9, 3) float32, columns R, G, B.
    """
    names = list_lights(root)
    if not names:
        raise RelightError(f"light folder {root} has no .npy light files")
    return np.stack([_read_light_bgr(Path(root) / f"{n}.npy") for n in names])


def read_light(root: str | os.PathLike, name: str) -> np.ndarray:
    """One ``NAME.npy`` light (BGR on disk) as (9, 3) float32 RGB."""
    return _read_light_bgr(Path(root) / f"{name}.npy")


def write_light(root: str | os.PathLike, name: str, rgb: np.ndarray) -> None:
    """Write a (9, 3) RGB light as ``root/NAME.npy`` with columns B, G, R (float32), atomically."""
    light = _check_light(rgb, "light")
    _write_npy(Path(root) / f"{name}.npy", light[:, ::-1].copy())


# ----------------------------------------------------------------------------------------------
# stage-2 photos
# ----------------------------------------------------------------------------------------------


def photo_name(subject: str, j: int) -> str:
    """``SUBJECT__L{j}``: the name of subject ``subject`` photographed under light ``j``."""
    return f"{subject}__L{j}"


def split_photo_name(name: str) -> tuple[str, int]:
    """Inverse of :func:`photo_name`: ``"s0003__L2"`` -> ``("s0003", 2)``."""
    subject, sep, j = name.rpartition("__L")
    if not sep or not subject or not j.isdigit():
        raise RelightError(f"photo name {name!r}: expected 'SUBJECT__L<j>'")
    return subject, int(j)


def list_photos(root: str | os.PathLike) -> list[str]:
    """Names ``SUBJECT__L{j}`` of the photos (photo and mask present) in ``root``, sorted."""
    return [n for n in _names(Path(root), _PHOTO_SUFFIXES) if "__L" in n]


def read_photo(root: str | os.PathLike, name: str) -> dict[str, np.ndarray]:
    """Read one stage-2 photo.

    Returns:
        dict with ``photo`` and ``diffuse`` (H, W, 3) float32 RGB in [0, 1], ``mask`` (H, W) float32
        in [0, 1] and ``light`` (9, 3) float32 RGB (the SH of the environment map that lit it); ``diffuse``
        and ``light`` are None for a photo of one's own (no ``_diffuse.png`` / ``_light.npy``).
    """
    root = Path(root)
    photo = _read_png(root / f"{name}_photo.png", color=True)
    mask = _read_png(root / f"{name}_mask.png", color=False)
    rendered = (root / f"{name}_diffuse.png").is_file()
    diffuse = _read_png(root / f"{name}_diffuse.png", color=True) if rendered else None
    light = _read_light_bgr(root / f"{name}_light.npy") if (root / f"{name}_light.npy").is_file() else None
    if (diffuse is not None and diffuse.shape != photo.shape) or mask.shape != photo.shape[:2]:
        raise RelightError(
            f"photo {name}: sizes disagree: photo {photo.shape}, diffuse {None if diffuse is None else diffuse.shape}, "
            f"mask {mask.shape}"
        )
    return {"photo": photo, "diffuse": diffuse, "mask": mask, "light": light}


def write_photo(
    root: str | os.PathLike,
    name: str,
    photo: np.ndarray,
    diffuse: np.ndarray,
    mask: np.ndarray,
    light: np.ndarray,
) -> None:
    """Write one stage-2 photo (see the module docstring), each file atomically.

    Args:
        root: output folder (created when missing).
        name: ``SUBJECT__L{j}`` (see :func:`photo_name`).
        photo, diffuse: (H, W, 3) RGB float in [0, 1] (clipped when written) or uint8.
        mask: (H, W) float in [0, 1] or uint8.
        light: (9, 3) RGB SH light; written with columns B, G, R.
    """
    split_photo_name(name)
    p = _check_image(photo, "photo")
    shape = p.shape[:2]
    d = _check_image(diffuse, "diffuse", shape)
    m = _check_map(mask, "mask", shape)
    rgb = _check_light(light, "light")
    root = Path(root)
    _write_png(root / f"{name}_photo.png", _to_uint8(p)[:, :, ::-1])
    _write_png(root / f"{name}_diffuse.png", _to_uint8(d)[:, :, ::-1])
    _write_png(root / f"{name}_mask.png", _to_uint8(m))
    _write_npy(root / f"{name}_light.npy", rgb[:, ::-1].copy())


# ----------------------------------------------------------------------------------------------
# one's own photos for stage 2
# ----------------------------------------------------------------------------------------------


def prepare_user_photos(
    src: str | os.PathLike, out: str | os.PathLike, device: str = "cpu"
) -> tuple[list[str], list[str]]:
    """Turn a folder of ordinary photos of people into stage-2 photos ``NAME__L0`` (photo and mask).

    The mask of each photo: ``NAME_mask.png`` beside it, else its alpha channel, else the automatic matte
    (relight_rt.masks.resolve_mask with the bundled person matte). Photos already prepared in ``out`` are
    kept (a rerun goes on). Bad files are reported, never the end of the run.

    Returns:
        (names written or kept, "file: reason" per photo left out).
    """
    from relight_rt.image.io import list_images, read_image, sibling_mask
    from relight_rt.person.masks import resolve_mask

    src, out = Path(src), Path(out)
    out.mkdir(parents=True, exist_ok=True)
    matter = None
    names, failures = [], []
    for path in list_images(src):
        name = photo_name(path.stem.replace("__L", "_L"), 0)
        if (out / f"{name}_photo.png").is_file() and (out / f"{name}_mask.png").is_file():
            names.append(name)
            continue
        try:
            img = read_image(path, "photo")
            mask_file = sibling_mask(path)
            if mask_file is None and img.shape[2] == 3 and matter is None:
                from relight_rt.person.matting import shared_matter

                matter = shared_matter(device=device)
            m = resolve_mask(img, mask_file, matter=matter, name=str(path))
            _write_png(out / f"{name}_photo.png", _to_uint8(img[..., :3])[:, :, ::-1])
            _write_png(out / f"{name}_mask.png", _to_uint8(m))
            names.append(name)
        except RelightError as exc:
            failures.append(str(exc) if str(path) in str(exc) else f"{path}: {exc}")
    return names, failures
