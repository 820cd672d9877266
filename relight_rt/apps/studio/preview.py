"""The studio's preview maths, as the page does it: the layers ``Studio.layers_bytes`` packs, unpacked
(``unpack_layers``, the page's decodeLayers) or over a box alone (an area reduction as cv2.INTER_AREA's, at a cost
that follows the box), the faces' cast shadows as a plane on the shading (``shadow_plane``) and the person drawn
under the shown light (``preview_picture``; the page's WebGL and Canvas renderers compute the same)."""

from __future__ import annotations

import math

import numpy as np

from ...engine.errors import RelightError
from ...image.color import REC709, linear_to_srgb, srgb_to_linear
from ...light import sh
from ...relight.compose import GradeSample, HeadBlend
from ...relight.kept_rim import LEAST as RIM_LEAST  # half an 8-bit level on black (linear)
from ...relight.look import shaded_skin


def unpack_layers(data: bytes, meta: dict) -> dict:
    """The inverse of ``Studio.layers_bytes`` (what the page's decodeLayers does): float32 planes
    "transport" (9, h, w), "albedo" (3, h, w) premultiplied, "mask" (h, w), "background" (3, h, w),
    "skin_chroma" (3, h, w) in [-1, 1] and "skin" (h, w) (relight_rt.relight.look.skin_chroma), and
    "exposure": {"transport" (n, 9), "albedo" (n, 3), "mask" (n,)}, the exposure sample, and "highlight":
    {"lit" (m, 3), "steady" (m, 3), "transport" (m, 9)}, the highlight guard's, "grade": the background
    grade's ``GradeSample``, and "rim": {"index" (k,) int32 flat preview pixels, "rim" (k, 3) linear RGB}, the kept
    background's rim (``with_rim``)."""
    h, w = meta["height"], meta["width"]
    n = h * w
    ns, offset = int(meta["exposure_samples"]), int(meta["exposure_offset"])
    nh, hoffset = int(meta["highlight_samples"]), int(meta["highlight_offset"])
    ng, goffset = int(meta["grade_samples"]), int(meta["grade_offset"])
    nb, boffset = int(meta["grade_head_samples"]), int(meta["grade_head_offset"])
    nr, roffset = int(meta.get("rim_samples", 0)), int(meta.get("rim_offset", boffset + 64 * nb))
    if (min(ns, nh, ng, nb, nr) < 0 or nb > ng or nr > n or offset < 29 * n or hoffset != offset + 52 * ns
            or goffset != hoffset + 60 * nh or boffset != goffset + 84 * ng or roffset != boffset + 64 * nb
            or len(data) != roffset + 16 * nr):
        raise RelightError(f"layers: expected {roffset + 16 * nr} bytes for {h}x{w}, {ns}, {nh}, {ng}, {nb} and {nr} "
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
    rim_index = np.frombuffer(data, "<i4", nr, roffset).astype(np.int32)
    if nr and (rim_index.min() < 0 or rim_index.max() >= n or (np.diff(rim_index) <= 0).any()):
        raise RelightError(f"layers: the kept rim names pixels outside 0..{n - 1} or out of order")
    rim = np.frombuffer(data, "<f4", 3 * nr, roffset + 4 * nr).reshape(3, nr).T.astype(np.float32)
    grade = GradeSample(g[:3].T.copy(), g[3:6].T.copy(), g[6:15].T.copy(), g[15].copy(), g[16].copy(),
                        g[17:20].T.copy(), g[20].copy(), HeadBlend(index, *(b[i].copy() for i in range(6)),
                                                                   b[6:].T.copy()))
    return {**layers_in_box(data, meta, (slice(None), slice(None))), "exposure": sample, "highlight": highlight,
            "grade": grade, "rim": {"index": rim_index, "rim": rim}}


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
    out = np.clip(layers["albedo"].transpose(1, 2, 0) * factor, 0, 1).astype(np.float32)
    return with_rim(out, layers, meta) if "rim" in layers else out


def with_rim(person: np.ndarray, layers: dict, meta: dict) -> np.ndarray:
    """(h, w, 3) float32: the preview's ``person`` (premultiplied by the layers' mask, sRGB in [0, 1], not modified)
    with the kept background's rim where the light darkens it, as the final result adds it
    (relight_rt.relight.kept_rim ``with_kept_rim``): on the rim's pixels (``layers["rim"]``, ``unpack_layers``'),
    the straight colour decoded to linear light, g its luminance over the own colour's (the albedo under the photo's
    own light, white: the preview's own picture, so that the own light gives it back), rim x (1 - g) added where
    g < 1, encoded and premultiplied again. Pixels whose own luminance is below half an 8-bit level on black take
    none (as the render's). What preview.js draws (both renderers)."""
    index, rim = layers["rim"]["index"], layers["rim"]["rim"]
    if index.size == 0:
        return person
    m = layers["mask"].reshape(-1)[index]
    flat = person.reshape(-1, 3)
    lin = srgb_to_linear(np.clip(flat[index] / np.maximum(m, 1e-6)[:, None], 0, 1))
    own = rim_own(layers, meta)
    g = (lin @ REC709) / np.maximum(own, 1e-12)
    at = (own >= RIM_LEAST) & (g < 1) & (m > 0)
    lost = np.where(at, 1 - g, 0).astype(np.float32)
    shown = np.clip(linear_to_srgb(np.clip(lin + rim * lost[:, None], 0, 1)), 0, 1) * m[:, None]
    out = person.copy()
    out.reshape(-1, 3)[index[at]] = shown[at]
    return out


def rim_own(layers: dict, meta: dict) -> np.ndarray:
    """(k,) float32: the own colour's linear luminance on the kept rim's pixels as the preview draws it under the
    photo's own light (white): the straight albedo x T.W, clipped as the page clips, decoded."""
    index = layers["rim"]["index"]
    m = layers["mask"].reshape(-1)[index]
    t = layers["transport"].reshape(9, -1)[:, index].T
    own = t @ np.array(meta["own_white"], np.float32)
    albedo = layers["albedo"].reshape(3, -1)[:, index].T
    straight = np.clip(albedo * np.maximum(own, 0)[:, None], 0, 1) / np.maximum(m, 1e-6)[:, None]
    return (srgb_to_linear(np.clip(straight, 0, 1)) @ REC709).astype(np.float32)
