"""The deep shadow's fill: where the photo's own shading is near zero, the photo times the relighting factor stays
black with its speckle amplified, so there the change the new light makes is added instead (relight_rt.relight.factor
``Factor.gain_and_fill`` adds it under each light; module docstring there).

What of the fill does not depend on the light is found once per Decomposition (``ShadowFill``): its weight and colour
on the network's grid (``ShadowFill.shadow_weight``; the colour of the lit pixels around of the shadow's own material,
relight_rt.relight.fill_colour; off a face mesh's skin the albedo of its rim, relight_rt.relight.shadow_rim; a face's
socket in shadow by its mirror image, ``mirror_shadow``), its weight at the photo's resolution along the shadow's border
(``ShadowFill.fill_base``, relight_rt.relight.fill_edge) and the photo's own fine detail carried into what is added
(``ShadowFill.texture``). Under each light, where the ratio would multiply the photo past ``RATIO_CAP`` the rest of the
change is handed to the fill (``handover``).

The module's constants are read when the functions run: benchmarks and tests set them here.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import cv2
import numpy as np

from ..image.color import REC709
from ..person.face_mesh import reflection
from .decomposition import Decomposition, Memo, readonly
from .detail import shadow_texture, unpremultiply
from .fill_colour import lit_colour
from .fill_edge import crop_part, edge_weight, grid_weight, soften
from .shadow_rim import rim_lift, skin_gate, spread_mean
from .strength import EXPLAIN_ALBEDO_MIN

FILL_LOW, FILL_HIGH = 0.1, 0.35  # shown shading / its median: below LOW the deep shadow is filled, above HIGH not
FILL_SIGMA = 2.5  # ... the shading shown smoothed over this many network pixels first (texture is not a shadow)
FILL_EDGE_SIGMA = 1.0  # ... within its reach of a shadow each pixel's own shading (smoothed this much) counts
FILL_ALBEDO_SPREAD = 0.08  # ... its albedo that of the lit pixels around, over this share of the window's side,
FILL_ALBEDO_RANGE = 4.0  # ... at most this factor from stage 1's own albedo there
FILL_BY_MATERIAL = True  # the fill's colour from the lit pixels around of its own material (relight.fill_colour)
# beside a deep shadow the photo's own detail is multiplied at most this much (``handover``): on a face's skin (its
# edge softened over relight_rt.relight.factor ``CAP_SKIN_SPREAD``), and elsewhere, as far as stage 1 sees skin, ...
RATIO_CAP = 2.0
# ... over a Gaussian of this many network px around a deep shadow's core (all of it within about that of a wide
# core's edge; a narrow core's reach is weaker: 0.11 at a 3 x 3 core's centre)
CAP_SHADOW_REACH: float | None = 5.0
TEXTURE_SCALES = (1.0, 2.0)  # the fill's texture (ShadowFill.texture): the photo's log detail in this band (input px),
TEXTURE_BLOCK, TEXTURE_SHARE = 4.0, 0.35  # ... its power over this many px held to this quantile of the lit skin's
# an opening of a face (relight_rt.relight.factor ``OPENINGS_AS_SKIN``) far darker under the photo's own light than
# its mirror image through the face (``face_mesh.mirror``) is in the photo's deep shadow whatever stage 1's albedo
# says: the fill takes it whole (``mirror_shadow``; Extended Yale B from 70°, faces13). From MIRROR_DARK[1] of the
# mirror's shading down to MIRROR_DARK[0] the fill's weight there rises from none to all; None: off
MIRROR_DARK: tuple[float, float] | None = (0.35, 0.7)
# ... that share softened over this share of the face's size (its mesh's extent), face by face: on Extended Yale B
# (faces of 290-370 px in a 256-px window) the 0.02 of the window's side faces13 softened it over (faces14)
MIRROR_SPREAD = 0.015


def mirror_shadow(shading: np.ndarray, opening: np.ndarray, face: np.ndarray,
                  points: tuple[np.ndarray, ...]) -> np.ndarray:
    """(r, r') float32 in [0, 1]: how far each of a face's openings lies in the photo's own shadow by its mirror
    image through the face (``MIRROR_DARK``; the fill's weight is raised to it, ``ShadowFill.shadow_weight``).

    Args:
        shading: (r, r') the shading under the photo's own light (the transport the factor divides with).
        opening, face: (r, r') bool, the faces' openings, and their skin with the openings.
        points: the face meshes in the window's pixels (``FacePass.window_points``).

    On a side-lit face the socket on the dark side is black in the photo, and stage 1 often reads that black as the
    socket's albedo: the fill's weight, found from the photo over that albedo, then sees no shadow and the ratio
    multiplies the black (or the little grazing light there) into the relit socket. A face is near symmetric, so a
    socket whose shading is far below its mirror image's (the lit socket) is in shadow. (The shading is the
    transport the factor divides with: the mesh's shape, moved toward the photo by ``explain_photo``, so stage 1's
    albedo reaches it in part; the mesh-only transport was not measured.) Each face's mirror reads only that face:
    its own openings, and its own face where the mirror image lands (both inside its mesh's convex hull; a
    neighbour's sockets are another face's business), nothing where the mirror image lies off it. Each face's
    share is softened over ``MIRROR_SPREAD`` of its own size (an opening's border is no edge in the photo), so a
    small face in a large window keeps its share.
    """
    lo, hi = MIRROR_DARK
    h, w = shading.shape
    out = np.zeros((h, w), np.float32)
    for pts in points:
        m = reflection(pts)
        if m is None:  # no mirror to read
            continue
        xy = np.asarray(pts, np.float64)[:, :2]
        sigma = max(MIRROR_SPREAD * float(np.ptp(xy, axis=0).max()), 0.5)
        hull = np.zeros((h, w), np.uint8)  # this face's own pixels: its mesh's convex hull (4 bits of sub-pixel)
        cv2.fillConvexPoly(hull, np.round(cv2.convexHull(xy.astype(np.float32)) * 16).astype(np.int32), 1, shift=4)
        mine = opening & (hull > 0)
        if not mine.any():
            continue
        # where its share can reach once softened: its openings' box and the blur's reach, within the window
        ys, xs = np.nonzero(mine)
        reach = int(math.ceil(4 * sigma)) + 1
        y0, y1 = max(int(ys.min()) - reach, 0), min(int(ys.max()) + reach + 1, h)
        x0, x1 = max(int(xs.min()) - reach, 0), min(int(xs.max()) + reach + 1, w)
        at = m.astype(np.float64)  # the mirror from the box's pixels (its origin at (x0, y0)) to the window's
        at[:, 2] += at[:, :2] @ (x0, y0)
        there, on_face = (cv2.warpAffine(np.ascontiguousarray(a, np.float32), at, (x1 - x0, y1 - y0),
                                         flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_CONSTANT)
                          for a in (shading, face & (hull > 0)))
        q = np.clip((hi - shading[y0:y1, x0:x1] / np.maximum(there, 1e-6)) / (hi - lo), 0, 1)
        share = mine[y0:y1, x0:x1] * (there > 1e-4) * q * q * (3 - 2 * q) * on_face
        # no edge of its own: softened over the face's size (an opening's border crosses a shaded cheek)
        out[y0:y1, x0:x1] = np.maximum(out[y0:y1, x0:x1], cv2.GaussianBlur(share.astype(np.float32), (0, 0), sigma))
    return out


def handover(ratio: np.ndarray, reach: np.ndarray | None) -> np.ndarray | None:
    """(r, r') what the fill's weight is raised to under one light where it ``reach``es (``ShadowFill.fill_base``: a
    face mesh's skin and openings, the penumbra around a deep shadow's core): where the light multiplies the photo by
    more than ``RATIO_CAP``, the photo there is multiplied at most that much; None where the rule is off.

    Just above the fill's own handover (a side-lit face's lips and nose beside its black half, the photo at levels
    20-30) a light from the other side multiplies the photo 3-5x, and with it its noise and the part of the shadow
    stage 1 put into the albedo: a speckled bright patch, and a seam down the nose where the flat fill begins
    (Extended Yale B from 70°, benchmarks/yale_eval.py). The factor is (1 - w) x ratio + w and the fill adds w x the
    change, so w = (ratio - cap) / (ratio - 1) where the ratio passes the cap gives the photo x cap plus the rest of
    the change, added: the same light where the albedo is right, the photo's noise multiplied by the cap only. A
    light that brightens the photo less than the cap, the photo's own light included, changes nothing. On a
    face's skin and its openings (relight_rt.relight.factor ``OPENINGS_AS_SKIN``; its edge softened over
    ``CAP_SKIN_SPREAD`` of the window's side), where the fill carries the lit skin's albedo; elsewhere only around a
    deep shadow's core (a Gaussian of ``CAP_SHADOW_REACH`` network px: all of it within about that of a wide core's
    edge, less around a narrow one) and as far as stage 1 sees skin there (relight_rt.relight.shadow_rim
    ``skin_gate``): in a face's penumbra the
    transport's shading, smoother than the photo's edge, stays well above the photo's, and the ratio too low by
    1.5-2x drew a dark line between the fill and the lit side (Extended Yale B's yaleB21 from -50, no face mesh). On
    cloth and hair the added change, smooth in colour, flattens the photo's own texture: over a whole person a
    striped shirt's and jeans' (the bundled example under ``studio``, a cap of 2.5: 14 % of its values moved, up to
    50 levels); beside a shadow, ungated, a shirt's colour stripes lost a third of their contrast 2 px from the edge
    (tests/runtime/relight/test_fill_edges.py)."""
    if not RATIO_CAP > 1 or reach is None:  # the rule off, or nowhere to reach
        return None
    return (np.clip((ratio - RATIO_CAP) / np.maximum(ratio - 1, 1e-6), 0, 1) * reach).astype(np.float32)


class ShadowFill:
    """What the deep shadow's fill of a Relighter's decompositions needs whatever the light (cached per Decomposition).

    Args:
        memo: where what is computed once per Decomposition is kept (the Relighter's, shared with its ``Factor``).
        own: what every relight of a Decomposition divides by, without stage 2's residual (``Factor.own``'s dict:
            ``Factor.restored``'s entries among them).
    """

    def __init__(self, memo: Memo, own: Callable[[Decomposition], dict]) -> None:
        self.memo, self.own = memo, own

    def shadow_weight(self, dec: Decomposition) -> tuple[np.ndarray, np.ndarray] | None:
        """Where the photo's own shading is too low for the ratio (cached): (w, chroma) in the person's window, w
        (r, r') in [0, 1] (1: photo / shading is noise) and chroma (r, r', 3) the person's colour there at
        luminance 1, taken from the reliable pixels around of its own material (relight.fill_colour), and on a
        face mesh's skin (and its openings, factor ``OPENINGS_AS_SKIN``) times the albedo of the reliable skin around
        over stage 1's own there (within ``FILL_ALBEDO_RANGE``); None where no pixel is that dark, and for a video
        frame.

        In a deep shadow stage 1's albedo is a guess: it takes part of a hard cast shadow for dark skin (a nose's
        shadow on a cheek came out at 0.14-0.24 beside 0.6 on Extended Yale B) and ``unshaded_albedo`` lifts all of
        it by the same law (a shaded cheek 1.3-1.5); the new light on that albedo draws the shadow's hard outline
        and blotches. Skin is one material, so the lit skin around knows its albedo: on the mesh's skin the fill
        takes their mean albedo, spread over ``FILL_ALBEDO_SPREAD`` of the window's side (within 4x: at 2x a side-lit
        Yale face kept a dark patch, faces15), its weight softened past the mesh's outline (``cap_face``). Off it,
        as far as stage 1 sees skin, the albedo of the fill's own rim (relight_rt.relight.shadow_rim): the pixels around
        dark hair are often another material (a green shirt's albedo lifted a girl's shaded hair green).

        The shading the photo shows, its luminance over the albedo's (floored at ``EXPLAIN_ALBEDO_MIN``: black cloth
        shows its shading too) and smoothed over ``FILL_SIGMA`` pixels (a black stripe of a shirt whose albedo stage
        1 blurred is texture, not shadow), against its median over the person: from ``FILL_HIGH`` of it down to
        ``FILL_LOW`` the ratio's share goes from all to none (a hard shadow at levels 0-3 of a side-lit face is
        0.02 of the lit side's); within that smoothing's reach of such a shadow, each pixel's own shading counts too,
        so that the weight's edge is the photo's (smoothed alone it ended inside the black: a dark line, multiplied),
        and the weight grows into the near-black pixels beside it (relight_rt.relight.fill_edge ``grid_weight``).
        """
        state = self.memo(dec)
        if not dec.photo:  # a video frame: a weight found frame by frame would flicker where the shadow's edge moves
            return None
        if "shadow" not in state:
            own = self.own(dec)
            inner, photo = own["inner"], own["photo"]
            shown = photo / np.maximum(own["albedo"], EXPLAIN_ALBEDO_MIN)
            level = state["shadow_level"] = float(np.median(shown[inner])) if inner.any() else 0.0
            # a shadow is wide, a black stripe the albedo blurred away is not; near one each pixel's own shading places
            # its edge (relight_rt.relight.fill_edge ``grid_weight``)
            result = None
            if level > 0:
                w = grid_weight(shown, own["solid"], inner, level, FILL_LOW, FILL_HIGH, FILL_SIGMA, FILL_EDGE_SIGMA)
                if w is not None:
                    y0, y1, x0, x1 = own["window"]
                    rgb = dec.network_image[y0:y1, x0:x1]
                    trust = ((1 - w) * inner * (photo > 0.02)).astype(np.float32)
                    sigma = max(2.0, 0.03 * max(w.shape))
                    # the lit pixels around of the shadow's own material (relight.fill_colour)
                    albedo_rgb = unpremultiply(np.ascontiguousarray(dec.albedo[y0:y1, x0:x1]), own["alpha"])
                    chroma = lit_colour(rgb, photo, trust, albedo_rgb if FILL_BY_MATERIAL else None, sigma)
                    skin = own["face_skin"]
                    # off a face mesh's skin, as far as stage 1 sees skin: its rim's albedo (relight.shadow_rim)
                    off = rim_lift(own["albedo"], photo, own["own"], w, trust, self.skin_gate(dec), EXPLAIN_ALBEDO_MIN,
                                   rgb)
                    off = np.ones_like(w) if off is None else off
                    if skin.any():  # a face's skin (one material): the albedo of the lit skin around, not stage 1's
                        albedo, on = own["albedo"], skin.astype(np.float32)
                        around = spread_mean(albedo, trust * on, FILL_ALBEDO_SPREAD * max(w.shape), albedo)
                        lift = np.clip(around / np.maximum(albedo, EXPLAIN_ALBEDO_MIN), 1 / FILL_ALBEDO_RANGE,
                                       FILL_ALBEDO_RANGE)
                        on_face = skin if own["face_opening"] is None else skin | own["face_opening"]
                        face = np.where(on_face, 1, own["cap_face"])  # the mesh's outline softened: no edge of its own
                        chroma *= (off + face * (lift - off))[..., None]
                        if MIRROR_DARK is not None and own["face_opening"] is not None and own["face_points"]:
                            # a socket in the photo's shadow by the face's mirror, whatever stage 1's albedo says
                            shading = own["transport"] @ dec.white_light[:, 0]
                            w = np.maximum(w, mirror_shadow(shading, own["face_opening"], on_face,
                                                            own["face_points"]) * inner)
                    else:
                        chroma *= off[..., None]
                    result = (readonly(w.astype(np.float32)), readonly(chroma.astype(np.float32)))
            state["shadow"] = result
        return state["shadow"]

    def skin_gate(self, dec: Decomposition) -> np.ndarray:
        """(r, r') float32 in [0, 1]: how far stage 1 sees skin around each pixel of the person's window
        (relight_rt.relight.shadow_rim ``skin_gate`` of ``restored``'s "skin"; cached: the fill's rim and the
        penumbra's reach both read it)."""
        state = self.memo(dec)
        if "skin_gate" not in state:
            state["skin_gate"] = readonly(skin_gate(self.own(dec)["skin"]))
        return state["skin_gate"]

    def fill_base(self, dec: Decomposition, image: np.ndarray) -> dict | None:
        """What the deep shadow's fill needs at the photo's resolution whatever the light (cached; ``shadow_weight``
        not None): "reach" (r, r') where ``handover`` may raise the weight (None: nowhere), "where" (r, r') bool the
        network pixels the fill may cover, "box" and "weight" the crop box's part they map to and the weight there
        (relight_rt.relight.fill_edge ``edge_weight``: along the shadow's border each input pixel's own shading).
        ``image``: (h, w, 3) the person's colour in the crop box (``Composer.foreground``), float32 RGB."""
        state = self.memo(dec)
        if "fill_base" not in state:
            own = self.own(dec)
            w = self.shadow_weight(dec)[0]
            reach = None
            core = w > 0.5
            if CAP_SHADOW_REACH is not None and core.any():  # the penumbra around a deep shadow's core, as far as
                # stage 1 sees skin there (relight_rt.relight.shadow_rim ``skin_gate``): on cloth and hair the
                # added change, smooth in colour, flattened a striped shirt's stripes beside a shadow
                reach = soften(core, CAP_SHADOW_REACH, own["inner"]) * self.skin_gate(dec)
                reach = reach if reach.max() > 1e-3 else None  # (no skin near: nothing to map)
            if own["cap_skin"] is not None:  # a face's skin and openings
                reach = own["cap_face"] if reach is None else np.maximum(reach, own["cap_face"])
            where = (w > 1e-3) | (reach > 1e-3) if reach is not None else w > 1e-3
            y0, _, x0, _ = own["window"]
            around = np.ones((3, 3), np.uint8)
            maps = np.dstack([w, cv2.erode(w, around), cv2.dilate(w, around), own["albedo"]])
            mapped = crop_part(dec.geometry, maps, where, (y0, x0))
            result = None
            if mapped is not None:
                box, part = mapped
                luma = image[box] @ REC709  # the luminance the weight on the network's grid is measured on
                weight = edge_weight(part[..., 0], part[..., 1], part[..., 2], luma,
                                     np.maximum(part[..., 3], EXPLAIN_ALBEDO_MIN), state["shadow_level"],
                                     FILL_LOW, FILL_HIGH)
                result = {"reach": None if reach is None else readonly(reach.astype(np.float32)),
                          "where": readonly(where), "box": box, "weight": readonly(weight)}
            state["fill_base"] = result
        return state["fill_base"]

    def texture(self, dec: Decomposition, gray: np.ndarray) -> np.ndarray | None:
        """(h, w) the photo's own fine detail in the crop box as a factor on the deep shadow's fill (cached;
        relight_rt.relight.detail ``shadow_texture``), None without a fill.

        The fill adds the change in the person's smoothed colour: on a side-lit face's dark half relit from the
        front, a fifth of the face came out with under half the real photo's fine detail (Extended Yale B from 70°,
        benchmarks/yale_eval.py "flat"). The photo's own log detail there, in the band ``TEXTURE_SCALES`` (input
        pixels) and held to the ``TEXTURE_SHARE`` quantile of the power the lit person shows where the fill adds
        nothing (on a face mesh's skin, the lit skin's), multiplies the fill, so the added light falls on the pixel's
        own texture (de-light "flat" 0.158 -> 0.108, "speckle" 0.122 -> 0.127). ``gray``: the photo's grey in the
        crop box.
        """
        state = self.memo(dec)
        if "texture" not in state:
            shadow = self.shadow_weight(dec)
            result = None
            if shadow is not None:
                own = self.own(dec)
                y0, _, x0, _ = own["window"]
                lit = shadow[0] < 0.05

                def to_crop(a: np.ndarray) -> np.ndarray:
                    return dec.geometry.to_crop(a.astype(np.float32), (y0, x0))

                reference = to_crop(own["inner"] & lit) > 0.99
                skin = None  # a face's skin: held to the lit skin's own texture, its edge as soft as the ratio cap's
                if own["cap_skin"] is not None:
                    skin = (to_crop(own["cap_skin"]), to_crop(own["face_skin"] & lit) > 0.99)
                result = shadow_texture(gray, reference, TEXTURE_SCALES, TEXTURE_BLOCK, TEXTURE_SHARE, skin)
                result = None if result is None else readonly(result)
            state["texture"] = result
        return state["texture"]
