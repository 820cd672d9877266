"""The head pass's blend: the factor of a face stage 1 saw small (relight_rt.relight.face_pass), looked at again,
blended into the body's relighting factor (relight_rt.relight.factor ``Factor.blend_head``), and what of it a sample
of the relit person reads whatever the light (``grade_inputs``: the studio's background grade,
relight_rt.relight.compose ``HeadBlend``) or the relit person's luminance under one light (``head_change``: the
studio's preview).

Over the head pass's crop box the body's factor g is moved toward the head pass's h by the blend's weight w
(``face_pass.feather`` over the head's box times the matte): g + w (level h - g). The head pass gives the shape of
the change; its level is the body pass's, ``level`` = the body's factor's luminance over the head pass's, each summed
over the head pass's skin map times w (the two passes estimate the photo's light separately). On a full-body photo the
head's box is three face sizes a side and the skin map takes in some of the clothes: on the bundled street photo the
box holds two thirds of the person's own light, and under window-left the level is 0.79.
"""

from __future__ import annotations

import cv2
import numpy as np

from ..image.color import REC709
from .decomposition import Decomposition
from .face_pass import feather, feather_at

MIN_SKIN = 1.0  # the head pass's skin under the blend's weight, in photo pixels, below which there is no level to match


def head_region(dec: Decomposition) -> tuple | None:
    """Where the head pass ``dec.head`` is blended into ``dec``: the head pass's crop box within ``dec``'s, (cy0,
    cy1, cx0, cx1) in the input frame (end exclusive), the head pass's crop box's top-left (y, x) in the input frame,
    the blend's weight there (h, w) (``feather`` over ``dec.head_box`` times the matte) and the head pass's skin there
    (h, w) (where the two passes' levels are matched); None without a head pass or where its crop box misses
    ``dec``'s."""
    head, box = dec.head, dec.head_box
    if head is None or box is None:
        return None
    by0, by1, bx0, bx1 = dec.geometry.box
    hy0, hy1, hx0, hx1 = head.geometry.box  # in the head square's frame
    y0, y1, x0, x1 = box[0] + hy0, box[0] + hy1, box[2] + hx0, box[2] + hx1  # input frame
    cy0, cy1, cx0, cx1 = max(y0, by0), min(y1, by1), max(x0, bx0), min(x1, bx1)
    if cy1 <= cy0 or cx1 <= cx0:
        return None
    h_img, w_img = dec.geometry.frame
    weight = feather(box[1] - box[0], box[3] - box[2],
                     (box[0] == 0, box[1] == h_img, box[2] == 0, box[3] == w_img))
    weight = weight[cy0 - box[0] : cy1 - box[0], cx0 - box[2] : cx1 - box[2]]
    weight = weight * dec.mask[cy0:cy1, cx0:cx1]
    skin = head.to_input(head.skin)[cy0 - box[0] : cy1 - box[0], cx0 - box[2] : cx1 - box[2]]
    return (cy0, cy1, cx0, cx1), (y0, x0), weight, skin


def blends(where: tuple) -> bool:
    """Whether ``blend_head`` blends anything over ``head_region``'s answer ``where`` before the fill's share: the
    head pass's skin under the blend's weight sums to ``MIN_SKIN`` or more (without, there is no level to match and
    the body's factor stays as it is)."""
    _, _, weight, skin = where
    return float((skin * weight).sum()) >= MIN_SKIN


def blend_head(dec: Decomposition, gain: np.ndarray, g_head: np.ndarray, where: tuple, fill: tuple | None = None
               ) -> None:
    """Blend the head pass's factor ``g_head`` (the head pass's crop frame, ``Factor.gain`` on it without stage 2's
    residual) into ``gain`` (the body's, crop frame) over ``head_region``'s answer ``where``, in place (module
    docstring).

    ``fill``: the body's deep-shadow fill (``Factor.gain_and_fill``); where it adds the change (its weight w), the
    body's gain holds the photo as it is, and the head's ratio takes only the rest (1 - w): it would count the light
    a second time.
    """
    (cy0, cy1, cx0, cx1), (y0, x0), weight, skin = where
    by0, _, bx0, _ = dec.geometry.box
    g_head = g_head[cy0 - y0 : cy1 - y0, cx0 - x0 : cx1 - x0]
    if fill is not None:  # the fill's weight where its part (crop frame) meets the head's region (on a copy:
        weight = weight.copy()  # ``where`` is the caller's)
        (fy, fx), _, w = fill
        ry, rx = cy0 - by0, cx0 - bx0  # the head's region in the crop frame starts here
        ya, yb, xa, xb = max(fy.start, ry), min(fy.stop, cy1 - by0), max(fx.start, rx), min(fx.stop, cx1 - bx0)
        if yb > ya and xb > xa:
            weight[ya - ry : yb - ry, xa - rx : xb - rx] *= 1 - np.clip(
                w[ya - fy.start : yb - fy.start, xa - fx.start : xb - fx.start], 0, 1)
    region = gain[cy0 - by0 : cy1 - by0, cx0 - bx0 : cx1 - bx0]
    skin = skin * weight
    if skin.sum() < MIN_SKIN:
        return
    level = float((region @ REC709 * skin).sum()) / max(float((g_head @ REC709 * skin).sum()), 1e-6)
    region += weight[..., None] * (level * g_head - region)


def grade_inputs(dec: Decomposition, where: tuple, window: tuple[int, int, int, int],
                 head_window: tuple[int, int, int, int], head_maps: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What ``blend_head`` does whatever the light, read at the centres of the pixels of ``window`` (y0, y1, x0, x1)
    of ``dec``'s network frame ((r, r') each): ``feather``'s weight there (0 outside ``head_region``'s answer ``where``;
    the matte's share is the caller's), the head pass's skin there and ``head_maps`` (r_h, r_h', C: the head pass's
    ``Factor.factor_inputs`` on its own ``head_window`` of its network frame) there (bilinear). For a sample of the
    blended picture (relight_rt.relight.compose ``Composer.grade_inputs``); the fill's share taken out of the
    weight is left out (on the street photo it moves the result's grade by 0.012 EV at most)."""
    (cy0, cy1, cx0, cx1), _, _, _ = where
    head, box = dec.head, dec.head_box
    geom, hgeom = dec.geometry, head.geometry
    wy0, wy1, wx0, wx1 = window
    # the window's pixel centres in the input frame (network pixel u at (u + 0.5) k - 0.5 - offset + box)
    (by0, _, bx0, _), (oy, ox), k = geom.box, geom.offset, geom.scale
    ys = (np.arange(wy0, wy1, dtype=np.float64) + 0.5) * k - 0.5 - oy + by0
    xs = (np.arange(wx0, wx1, dtype=np.float64) + 0.5) * k - 0.5 - ox + bx0
    inside = ((ys >= cy0 - 0.5) & (ys < cy1 - 0.5))[:, None] & ((xs >= cx0 - 0.5) & (xs < cx1 - 0.5))[None, :]
    h_img, w_img = geom.frame
    ty = (ys - box[0] + 0.5) / (box[1] - box[0])
    tx = (xs - box[2] + 0.5) / (box[3] - box[2])
    weight = feather_at(ty[:, None], tx[None, :], (box[0] == 0, box[1] == h_img, box[2] == 0, box[3] == w_img))
    weight = np.where(inside, weight, 0).astype(np.float32)
    # ... and in the head pass's network frame, in its window's pixels
    (hy0, _, hx0, _), (hoy, hox), hk = hgeom.box, hgeom.offset, hgeom.scale
    vy0, vy1, vx0, vx1 = head_window
    uy = ((ys - box[0] - hy0 + hoy + 0.5) / hk - 0.5 - vy0).astype(np.float32)
    ux = ((xs - box[2] - hx0 + hox + 0.5) / hk - 0.5 - vx0).astype(np.float32)
    map_x = np.ascontiguousarray(np.broadcast_to(ux[None, :], weight.shape))
    map_y = np.ascontiguousarray(np.broadcast_to(uy[:, None], weight.shape))

    def read(a: np.ndarray) -> np.ndarray:
        out = cv2.remap(np.ascontiguousarray(a), map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        return out.reshape(weight.shape + (-1,))

    on_head = np.concatenate([read(head_maps[..., i : i + 4]) for i in range(0, head_maps.shape[2], 4)], axis=2)
    skin = read(np.asarray(head.skin[vy0:vy1, vx0:vx1], np.float32))[..., 0]
    return weight, (skin * (weight > 0)).astype(np.float32), on_head.astype(np.float32)


def head_change(factor, dec: Decomposition, light: np.ndarray, image: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray] | None:
    """What the head pass's blend does to the relit person's luminance under the (exposed) ``light`` (9, 3): (before,
    after), each (H, W) float32 in the input frame, the luminance of ``image`` (the person's colour in the crop box,
    ``Composer.foreground``) times the body's relighting factor as the result takes it (``factor``: the Relighter's
    relight_rt.relight.factor ``Factor``; its ``gain_and_fill`` without stage 2's residual, which the preview leaves
    out too, the deep-shadow fill's share included) before and after ``blend_head``, 0 outside the crop box; None
    where ``blend_head`` blends nothing. The studio's preview draws the person without the head pass and multiplies
    its shading by a factor that carries the change from before to after, both reduced to its size, into its own
    luminance (relight_rt.apps.studio ``Studio._head_factor``); the faces' cast shadows are in
    both (the head pass's in after), so the preview's own cast-shadow layer is the body pass's alone
    (``Factor.shadow_layer``)."""
    where = head_region(dec)
    if where is None or not blends(where):
        return None
    gain, fill = factor.gain_and_fill(dec, light, image)
    (by0, by1, bx0, bx1), frame = dec.geometry.box, dec.geometry.frame
    before, after = np.zeros(frame, np.float32), np.zeros(frame, np.float32)
    before[by0:by1, bx0:bx1] = (image * gain) @ REC709
    factor.blend_head(dec, gain, light, fill)
    after[by0:by1, bx0:bx1] = (image * gain) @ REC709
    return before, after
