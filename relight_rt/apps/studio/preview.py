"""The studio's preview maths, as the page does it: the layers ``Studio.layers_bytes`` packs, unpacked
(``unpack_layers``, the page's decodeLayers) or over a box alone (an area reduction as cv2.INTER_AREA's, at a cost
that follows the box), the faces' cast shadows as a plane on the shading (``shadow_plane``) and the person drawn
under the shown light (``preview_picture``; the page's WebGL and Canvas renderers compute the same)."""

from __future__ import annotations

import math

import numpy as np

from ...engine.errors import RelightError
from ...image.color import REC709
from ...light import sh
from ...relight.compose import GradeSample, HeadBlend
from ...relight.look import shaded_skin


def unpack_layers(data: bytes, meta: dict) -> dict:
    """The inverse of ``Studio.layers_bytes`` (what the page's decodeLayers does): float32 planes
    "transport" (9, h, w), "albedo" (3, h, w) premultiplied, "mask" (h, w), "background" (3, h, w),
    "skin_chroma" (3, h, w) in [-1, 1] and "skin" (h, w) (relight_rt.relight.look.skin_chroma), and
    "exposure": {"transport" (n, 9), "albedo" (n, 3), "mask" (n,)}, the exposure sample, and "highlight":
    {"lit" (m, 3), "steady" (m, 3), "transport" (m, 9)}, the highlight guard's, and "grade": the background
    grade's ``GradeSample``."""
    h, w = meta["height"], meta["width"]
    n = h * w
    ns, offset = int(meta["exposure_samples"]), int(meta["exposure_offset"])
    nh, hoffset = int(meta["highlight_samples"]), int(meta["highlight_offset"])
    ng, goffset = int(meta["grade_samples"]), int(meta["grade_offset"])
    nb, boffset = int(meta["grade_head_samples"]), int(meta["grade_head_offset"])
    if (min(ns, nh, ng, nb) < 0 or nb > ng or offset < 29 * n or hoffset != offset + 52 * ns
            or goffset != hoffset + 60 * nh or boffset != goffset + 84 * ng or len(data) != boffset + 64 * nb):
        raise RelightError(f"layers: expected {boffset + 64 * nb} bytes for {h}x{w}, {ns}, {nh}, {ng} and {nb} "
                           f"samples, got {len(data)}")
    planes = np.frombuffer(data, "<f4", 13 * ns, offset).reshape(13, ns).astype(np.float32)
    sample = {"transport": planes[:9].T.copy(), "albedo": planes[9:12].T.copy(), "mask": planes[12].copy()}
    guard = np.frombuffer(data, "<f4", 15 * nh, hoffset).reshape(15, nh).astype(np.float32)
    highlight = {"lit": guard[:3].T.copy(), "steady": guard[3:6].T.copy(), "transport": guard[6:].T.copy()}
    g = np.frombuffer(data, "<f4", 21 * ng, goffset).reshape(21, ng).astype(np.float32)
    index = np.frombuffer(data, "<i4", nb, boffset).astype(np.int32)
    if nb and (index.min() < 0 or index.max() >= ng or (np.diff(index) <= 0).any()):
        raise RelightError(f"layers: the head pass's blend names grade samples outside 0..{ng - 1} or out of order")
    b = np.frombuffer(data, "<f4", 15 * nb, boffset + 4 * nb).reshape(15, nb).astype(np.float32)
    grade = GradeSample(g[:3].T.copy(), g[3:6].T.copy(), g[6:15].T.copy(), g[15].copy(), g[16].copy(),
                        g[17:20].T.copy(), g[20].copy(), HeadBlend(index, *(b[i].copy() for i in range(6)),
                                                                   b[6:].T.copy()))
    return {**layers_in_box(data, meta, (slice(None), slice(None))), "exposure": sample, "highlight": highlight,
            "grade": grade}


def _area_weights(n_in: int, n_out: int, lo: int, hi: int) -> tuple[slice, np.ndarray]:
    """Output pixels lo..hi-1 of ``n_in`` pixels reduced to ``n_out`` (<= n_in) by area (cv2.INTER_AREA's rule):
    the input pixels they read and (hi - lo, those) float32 weights, each row the overlaps of one output pixel's
    span with the input pixels, summing to 1."""
    s = n_in / n_out
    j0, j1 = int(math.floor(lo * s)), min(n_in, int(math.ceil(hi * s)))
    i = np.arange(lo, hi, dtype=np.float64)[:, None]
    j = np.arange(j0, j1, dtype=np.float64)[None]
    overlap = np.clip(np.minimum(j + 1, (i + 1) * s) - np.maximum(j, i * s), 0, None)
    return slice(j0, j1), (overlap / s).astype(np.float32)


def area_reduce(planes, size: tuple[int, int], box: list[int]) -> tuple[list[int], list[np.ndarray]]:
    """(H, W) ``planes`` reduced by area to ``size`` (at most (H, W)) over the output pixels that read the input
    ``box`` alone: that output box and each plane there (what a whole-frame cv2.INTER_AREA resize gives there,
    at a cost that follows the box, not the frame)."""
    (h, w), (hi, wi) = size, planes[0].shape
    out = [int(box[0] * h // hi), min(h, -(-box[1] * h // hi)), int(box[2] * w // wi), min(w, -(-box[3] * w // wi))]
    rows, wy = _area_weights(hi, h, out[0], out[1])
    cols, wx = _area_weights(wi, w, out[2], out[3])
    return out, [wy @ np.asarray(p, np.float32)[rows, cols] @ wx.T for p in planes]


def layers_in_box(data: bytes, meta: dict, box: tuple[slice, slice]) -> dict:
    """The page's pixel layers (``unpack_layers``' "transport", "albedo", "mask", "background", "skin_chroma",
    "skin") over ``box`` (preview pixels) of the packed ``data`` (``Studio.layers_bytes``, its length checked by the
    caller): the same quantised values the page draws with, decoded there alone."""
    h, w = meta["height"], meta["width"]
    n = h * w
    q16 = np.frombuffer(data, "<u2", 9 * n).reshape(9, h, w)[(slice(None), *box)].astype(np.float32)
    off = np.array(meta["transport_offset"], np.float32)[:, None, None]
    scale = np.array(meta["transport_scale"], np.float32)[:, None, None]
    eight = np.frombuffer(data, np.uint8, 11 * n, 18 * n).reshape(11, h, w)[(slice(None), *box)].astype(np.float32)
    eight /= 255
    return {"transport": off + q16 * scale, "albedo": eight[:3], "mask": eight[3], "background": eight[4:7],
            "skin_chroma": 2 * eight[7:10] - 1, "skin": eight[10]}


def shadow_plane(answer: dict, height: int, width: int) -> np.ndarray:
    """(height, width) float32 the factor ``Studio.shadow``'s ``answer`` puts on the preview's shading (1 outside
    its boxes): 1 - the cast shadows' depth times the head pass's change; what the page draws with."""
    plane = np.ones((height, width), np.float32)
    if answer["box"]:
        y0, y1, x0, x1 = answer["box"]
        depth = np.frombuffer(answer["depth"], np.uint8).reshape(y1 - y0, x1 - x0).astype(np.float32) / 255
        plane[y0:y1, x0:x1] = 1 - depth
    if answer.get("head_box"):
        y0, y1, x0, x1 = answer["head_box"]
        plane[y0:y1, x0:x1] *= np.frombuffer(answer["head"], "<f4").reshape(y1 - y0, x1 - x0)
    return plane


def preview_picture(layers: dict, meta: dict, light: np.ndarray, shadow: np.ndarray | None = None) -> np.ndarray:
    """(h, w, 3) float32 the person as the page draws it (premultiplied, over nothing) under the shown light (9, 3):
    albedo x max(0, T.L) x ``shadow`` (``shadow_plane``; None: none) x the shaded-skin gain of the final result
    (relight_rt.relight.look.shaded_skin on the layers' skin chroma and weight), clipped to [0, 1]. ``layers``:
    ``unpack_layers``'; the page's WebGL and Canvas renderers compute the same (tests/integration)."""
    t = layers["transport"].transpose(1, 2, 0)
    lit = sh.shading(t, np.asarray(light, np.float32))
    if shadow is not None:
        lit = lit * shadow[..., None]
    own = t @ np.array(meta["own_white"], np.float32)
    factor = shaded_skin(lit, (lit @ REC709) / np.maximum(own, 1e-3), layers["skin_chroma"].transpose(1, 2, 0),
                         layers["skin"])  # fmt: skip
    return np.clip(layers["albedo"].transpose(1, 2, 0) * factor, 0, 1).astype(np.float32)
