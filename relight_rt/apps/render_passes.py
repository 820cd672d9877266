"""Render passes of a relit photo for compositors (Nuke, After Effects, Blender): float EXR or 16-bit PNG.

``compute_passes(relighter, photo, light)`` relights the photo once and returns, at the photo's own size:

- ``albedo`` (RGB): the person's albedo (the photo's detail in it,
  ``relight_rt.relight.decomposition.intrinsic_layers``), premultiplied by alpha;
- ``shading_photo`` (RGB): the shading under the photo's own light (white), straight (not premultiplied), 0 off
  the person;
- ``shading`` (RGB): the shading under the new light, exposed as the relit picture is, straight;
- ``diffuse`` (RGB): albedo x shading (premultiplied);
- ``residual`` (RGB, signed): beauty - diffuse, what the diffuse term does not explain: stage 2's residual
  (highlights, sheen), the photo's detail carried into the relit picture, clipping;
- ``beauty`` (RGBA): the relit person, premultiplied: RGB = foreground x alpha;
- ``foreground`` (RGB): the relit person's own colour, straight, its soft edge cleaned of the old background
  (``Relighter.relight(..., background="transparent")``);
- ``alpha`` (Y): the person's matte;
- ``normal`` (RGB): a normal map derived from the transport (below), camera space.

So ``albedo * shading + residual == beauty.rgb`` and ``beauty.rgb + backdrop * (1 - alpha)`` puts the relit person over
any backdrop (``scripts/recompose_passes.py`` checks the first from the files alone). Colours are the pipeline's own
values: the photo's encoded (sRGB-like) values, not linearised, as the networks see them; set the files' colour space
to raw / non-colour data in the compositor.

The normal map is not predicted by any network: it is read off the light transport. For an unoccluded surface the
degree-1 SH coefficients of the transport point along its normal (T_1, T_2, T_3 = A_1 * 0.4886 * (n_y, n_z, n_x),
DESIGN.md §3), so normalising (T_3, T_1, T_2) gives n in the subject frame; where the surface is partly occluded the
same vector is the "bent normal", tilted toward the open directions. It is written in camera space as compositors
expect it: R = +y (image right), G = +z (up), B = +x (toward the camera), components in [-1, 1]; 0 off the person.

Formats: ``exr`` (32-bit float, ZIP; relight_rt.image.exr), or ``png16`` (16-bit PNG: each pass stored as
(value - offset) / scale, clipped to [0, 1]; ``passes.json`` gives offset and scale per pass: 0 and 1 for albedo,
foreground, beauty and alpha; 0 and a power of two for the shadings and the diffuse term; symmetric about 0 for the
residual and the normal).
Beside them: ``light.json`` (the new light as used, exposed) and ``light_photo.json`` (the photo's own light, white),
in relight_rt's light-file format, and ``passes.json`` describing each file. Everything is written at once or not at
all (``relight_rt.engine.files.write_all``).
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from .. import __version__
from ..engine.errors import RelightError
from ..engine.files import ProtectedPaths, bytes_writer, write_all
from ..image.exr import encode_exr
from ..relight.decomposition import shading_layer
from ..relight.relighter import Decomposition, Relighter

FORMATS = ("exr", "png16")
PASSES = ("albedo", "shading_photo", "shading", "diffuse", "residual", "beauty", "foreground", "alpha", "normal")
_ALPHA_MIN = 1e-4  # below this alpha a pixel has no straight colour or shading worth dividing out


@dataclass(frozen=True)
class Passes:
    """The passes of one relit photo (module docstring).

    Attributes:
        layers: pass name → float32 (H, W, 3), (H, W, 4) for "beauty", (H, W) for "alpha".
        light: (9, 3) the new light as used (exposed), RGB.
        photo_light: (9, 3) the photo's own light, white (``Decomposition.white_light``).
    """

    layers: dict
    light: np.ndarray
    photo_light: np.ndarray


def _straight(premultiplied: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """Divide out alpha where it is above ``_ALPHA_MIN``; 0 elsewhere."""
    a = alpha[..., None]
    return np.where(a > _ALPHA_MIN, premultiplied / np.maximum(a, _ALPHA_MIN), 0).astype(np.float32)


def transport_normals(dec: Decomposition) -> np.ndarray:
    """The (H, W, 3) camera-space normal map read off the transport (module docstring): R = +y, G = +z, B = +x.

    Unit vectors where the person is (alpha > 0), 0 elsewhere; float32.
    """
    t = dec.transport  # (R, R, 9), masked: the mask scales the vector and cancels in the normalisation
    camera = np.ascontiguousarray(np.stack([t[..., 1], t[..., 2], t[..., 3]], axis=-1), dtype=np.float32)
    full = dec.to_input(camera)  # bilinear, then normalised again
    norm = np.linalg.norm(full, axis=-1, keepdims=True)
    ok = (norm > 1e-8) & (dec.mask[..., None] > 0)
    return np.where(ok, full / np.maximum(norm, 1e-8), 0).astype(np.float32)


def compute_passes(relighter: Relighter, image, light=None, *, mask=None, exposure="auto") -> Passes:
    """Relight ``image`` under ``light`` once and return its passes at the photo's size.

    Args:
        relighter: a ``relight_rt.Relighter``.
        image: a photo (path or array, see ``Relighter.decompose``) or a ``Decomposition``.
        light: anything ``Relighter.relight`` takes; None: the photo's own light (white).
        mask: the photo's mask (not with a Decomposition).
        exposure: as for ``Relighter.relight``.

    Raises:
        RelightError: as ``Relighter.relight``.
    """
    if isinstance(image, Decomposition) and mask is not None:
        raise RelightError("mask: a Decomposition already has its mask; pass mask only with an image")
    dec = image if isinstance(image, Decomposition) else relighter.decompose(image, mask)
    if light is None:
        light = dec.white_light
    result = relighter.layers(dec, light, background="transparent", exposure=exposure)
    alpha = np.asarray(result.image[..., 3], np.float32)
    foreground = np.ascontiguousarray(result.image[..., :3], dtype=np.float32)
    # the albedo (premultiplied: intrinsic_layers', which the layers hold) and the shading under the photo's own
    # light and under the new one, the same way (premultiplied)
    albedo = np.asarray(result.layers["albedo"], np.float32)
    shading = _straight(shading_layer(dec, dec.shading(result.light)), alpha)
    diffuse = albedo * shading
    beauty_rgb = foreground * alpha[..., None]
    layers = {
        "albedo": albedo,
        "shading_photo": _straight(shading_layer(dec), alpha),
        "shading": shading,
        "diffuse": diffuse,
        "residual": beauty_rgb - diffuse,
        "beauty": np.concatenate([beauty_rgb, alpha[..., None]], axis=-1),
        "foreground": foreground,
        "alpha": alpha,
        "normal": transport_normals(dec),
    }
    return Passes(layers, np.array(result.light, np.float32), np.array(dec.white_light, np.float32))


def _png16_range(name: str, values: np.ndarray) -> tuple[float, float]:
    """(offset, scale) of a pass in a 16-bit PNG: stored = (value - offset) / scale."""
    peak = float(np.abs(values).max()) if values.size else 0.0
    if not math.isfinite(peak):  # as exr refuses them (no range holds them; a NaN would be stored as 0)
        raise RelightError(f"png16: the {name} pass holds NaN or Inf values")
    if name in ("albedo", "foreground", "beauty", "alpha"):
        return 0.0, 1.0
    top = 2.0 ** max(0, math.ceil(math.log2(max(peak, 1e-6))))  # a power of two >= the largest value, >= 1
    if name == "normal":
        return -1.0, 2.0
    if name == "residual":
        return -top, 2 * top
    return 0.0, top  # the shadings and the diffuse term: >= 0, may pass 1


def _png16(values: np.ndarray, offset: float, scale: float) -> bytes:
    q = np.clip((values - offset) / scale, 0, 1) * 65535 + 0.5
    a = q.astype(np.uint16)
    if a.ndim == 3:
        a = cv2.cvtColor(a, cv2.COLOR_RGB2BGR if a.shape[2] == 3 else cv2.COLOR_RGBA2BGRA)
    ok, buf = cv2.imencode(".png", a)
    if not ok:
        raise RelightError("png16: OpenCV could not encode a 16-bit PNG")
    return buf.tobytes()


def _exr(values: np.ndarray) -> bytes:
    if values.ndim == 2:
        return encode_exr({"Y": values})
    names = "RGBA"[: values.shape[2]]
    return encode_exr({c: values[..., i] for i, c in enumerate(names)})


def _light_json(light: np.ndarray) -> bytes:
    return json.dumps({"sh": np.asarray(light, np.float64).tolist(), "order": "rgb"}, indent=1).encode()


def write_passes(folder: str | os.PathLike, passes: Passes, fmt: str = "exr", protect=()) -> list[Path]:
    """Write ``passes`` into ``folder`` (made if missing) as ``NAME.exr`` or ``NAME.png``, with ``light.json``,
    ``light_photo.json`` and ``passes.json``: all of them or none.

    Args:
        folder: the output folder.
        passes: from ``compute_passes``.
        fmt: "exr" (32-bit float) or "png16".
        protect: inputs no file may replace.

    Returns:
        The paths written.

    Raises:
        RelightError: an unknown format, an input among the targets, a failed write.
    """
    if fmt not in FORMATS:
        raise RelightError(f"format: expected one of {list(FORMATS)}, got {fmt!r}")
    out = Path(folder)
    if out.exists() and not out.is_dir():
        raise RelightError(f"cannot write the passes into {out}: it is not a folder")
    suffix = ".exr" if fmt == "exr" else ".png"
    files, manifest = [], {}
    for name in PASSES:
        values = np.asarray(passes.layers[name], np.float32)
        entry = {"file": name + suffix, "channels": "Y" if values.ndim == 2 else "RGBA"[: values.shape[2]]}
        if fmt == "exr":
            data = _exr(values)
        else:
            offset, scale = _png16_range(name, values)
            data = _png16(values, offset, scale)
            entry.update(offset=offset, scale=scale)
        files.append((out / entry["file"], bytes_writer(data)))
        manifest[name] = entry
    doc = {
        "relight_rt": __version__,
        "format": fmt,
        "colour": "the pipeline's own values (the photo's encoding, not linearised): raw / non-colour data",
        "premultiplied": ["albedo", "diffuse", "residual", "beauty"],
        "recompose": "albedo * shading + residual = beauty.rgb; beauty.rgb + backdrop * (1 - alpha) = over backdrop",
        "normal": "from the transport's degree-1 SH (bent normal where occluded); camera space: R = image right, "
                  "G = up, B = toward the camera",
        "png16": "stored = (value - offset) / scale, in [0, 1]" if fmt == "png16" else None,
        "passes": manifest,
        "light": "light.json",
        "photo_light": "light_photo.json",
    }
    files += [
        (out / "light.json", bytes_writer(_light_json(passes.light))),
        (out / "light_photo.json", bytes_writer(_light_json(passes.photo_light))),
        (out / "passes.json", bytes_writer(json.dumps(doc, indent=1).encode())),
    ]
    out.mkdir(parents=True, exist_ok=True)
    return write_all(files, protect if isinstance(protect, ProtectedPaths) else ProtectedPaths(protect))
