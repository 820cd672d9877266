"""The relighting factor: how much, and in what colour, a new light changes each pixel of the photo.

Pipeline (DESIGN.md §1, §4, §5)::

    photo + mask ─► crop/pad/resize (CropGeometry) ─► stage 1 ─► albedo, skin, transport, light
    new light L' ─► diffuse D = clip(albedo ⊙ max(0, T·L'), 0, 1) ─► stage 2 ─► relit (network frame)
    relit ─► back to the input's size and position ─► composited over the background

Full-resolution detail (the default): the network's relit image is not simply upsampled, because on real
photos its colours are stage 1's guess (an albedo that may be green for fair skin, a light estimate whose colour
cast is wrong) and its resolution is the network's. Instead the photo itself is relit by a factor:

    colour = F ⊙ up(c' · max(Y(A ⊙ S' + r'), ε) / max(Y(A ⊙ Ŝ + r̂), ε))

The luminance Y of the pipeline's image under the new light (albedo A times the shading S' = max(0, T·L'),
plus stage 2's residual r'), over its luminance under the photo's own light (Ŝ = max(0, T·l̂), l̂ the
luminance of stage 1's estimate taken as white: cameras white-balance their photos), both unclipped, ε = 0.01;
T is stage 1's transport with its degree-1 and degree-2 bands scaled back up by the shrinkage measured against
true transports (relight_rt.relight.strength: a regressed transport makes every light look softer than it is), then
moved along the photo's own light half-way toward the shading the photo shows (``explain_photo``: what the
regression blurred away of the photo's own shading stays as far as a new light resembles the photo's);
and c' = S' / Y(S'), the colour of the new light arriving at that pixel (luminance 1). So the brightness change
is the whole pipeline's (stage 2's shadows and highlights included), its colour is the new light's alone, and
neither the albedo's colour nor an error in the estimated light's colour can tint the skin: under a white
light the photo keeps its colours. Skin that the new light darkens keeps more of its chroma than a grey dimming
would leave it, as real shaded skin does (``look.shaded_skin``). F is the person's own colour
(``Composer.foreground``: at a soft matte's edge, the photo without what lies behind). The factor is upsampled
edge-aware with a fast guided filter (He & Sun 2015: the local linear model g ≈ a·I + b is fitted at network
resolution on the gray input, and a, b are upsampled and applied with the full-resolution gray input I), so the
input's own high-frequency detail survives. Colours made brighter than the photo's own peak are rolled off by a
smooth shoulder on the brightest channel, all three channels scaled together (a bright lit side keeps its hue and
its gradation; a per-channel clip would turn it yellow, a hard clip flat). Relighting with the photo's own light
gives the input back. A face that stage 1 saw small gets a second pass (relight_rt.relight.face_pass). Where the
photo's own shading is near zero (a side-lit face's black half, levels 0-3) the photo times a factor stays black with
its speckle amplified; there the change is added instead, stage 1's albedo under the new shading less under the
photo's own (``Factor.gain_and_fill``, the fill's light-independent part relight_rt.relight.shadow_fill; Extended
Yale B de-lighting, benchmarks/yale_eval.py: 0.83 / 0.62 -> 0.87 / 0.70). On a photo with a face mesh, the share of
the photo's own shading that stage 1 put into the albedo is taken out first (``unshaded_albedo``; de-lighting 0.87 /
0.70 -> 0.88 / 0.78); on its skin the fill takes the albedo of the lit skin around, and all of a shadow the transport
misses goes with the photo's light (de-lighting with the face search's shadow lifts 0.89 / 0.80 -> 0.91 / 0.83); on
its skin a light that would multiply the photo more than ``RATIO_CAP`` multiplies it that much and adds the rest of
the change as the fill (shadow_fill ``handover``: the speckle and the seam beside a side-lit face's black half), and
so does the skin in the penumbra around a wide deep shadow; the fill's weight meets the ratio at the photo's own
shadow edge, per input pixel (relight_rt.relight.fill_edge). On a face mesh's skin a new light's lamp casts the
mesh's own shadows (the nose's, the brows'; relight_rt.relight.cast_shadow), where they are darker than the photo's
own light's: degree-2 SH cannot (Extended Yale B relight 0.859 / 0.6505 -> 0.870 / 0.734).
(``cv2.ximgproc.guidedFilter`` at full resolution gives the same kind of result but costs ~0.6 s per 2-megapixel
crop with a colour guide; this costs ~30 ms.)
With ``detail=False`` the network's relit image is upsampled as it is.

Without ``stage2.onnx`` the output is the diffuse image only: ``Relighter.diffuse_only`` is True, a
warning is logged at load, and ``RelightResult.diffuse_only`` says so.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable
from dataclasses import replace

import cv2
import numpy as np

from ..image.color import REC709
from ..light import sh
from ..person.face_mesh import mirror_held
from . import head_blend
from .cast_shadow import MeshView, shadow_factor
from .dark_beard import dark_material
from .decomposition import Decomposition, Memo, readonly
from .detail import extend_outward, guided_upsample, unpremultiply, window
from .exposure_meter import ExposureMeter
from .face_pass import FacePass
from .fill_edge import crop_part, soften
from .look import shaded_skin, skin_chroma, tint_range
from .shadow_fill import ShadowFill, handover
from .strength import (
    explain_photo,
    face_refit,
    refit_light,
    restore_bands,
    skin_shadow_share,
)
from .unshade import unshaded_albedo

_RATIO_EPS = np.float32(0.01)  # the ratio's denominator is floored here (dark pixels: noise, not light)
_OWN_FLOOR = np.float32(0.5)  # light the model misses, up to this share of the photo, stays under a new light (own)
# on a face's skin a light multiplies the photo at most relight_rt.relight.shadow_fill ``RATIO_CAP`` and the fill takes
# the lit skin's albedo (``own``'s "cap_skin"), its edge softened over this share of the window's side
CAP_SKIN_SPREAD = 0.02
# a face's openings (inside the mesh's outline, off its skin: the eyes' sockets) take the skin's ratio cap and fill
# albedo (shadow_fill ``handover``, ``ShadowFill.shadow_weight``): on a side-lit face's dark half the socket's grazing
# light was multiplied into a bright patch (Extended Yale B from 70°, its socket over the face's mean 0.75 against 1.48
# without, the real photo's 0.42; de-light correlation / contrast 0.9105 / 0.826 -> 0.9162 / 0.839, speckle 0.127 ->
# 0.088); one far darker than its mirror image is in the fill whole (shadow_fill ``MIRROR_DARK``)
OPENINGS_AS_SKIN = True
# a face in the photo's shadow against its mirror image takes at least the mirror's albedo (face_mesh.mirror_held)
MIRROR_ALBEDO = True
CAST_CACHE = 4  # Factor.cast keeps the cast shadows of this many light directions per Decomposition


def luminance_window(chw: np.ndarray, alpha: np.ndarray, box: tuple[int, int, int, int]) -> np.ndarray:
    """(r, r') Rec. 709 luminance of a masked (3, R, R) network output inside ``box``, unpremultiplied."""
    y0, y1, x0, x1 = box
    lum = np.tensordot(REC709, chw[:, y0:y1, x0:x1], axes=1)
    return np.divide(lum, alpha, out=np.zeros_like(lum), where=alpha > 0.5)


class Factor:
    """The relighting factor of a Relighter's decompositions; its deep shadow's fill (``fill``) and the exposure that
    keeps a relit person's level (``meter``) share its memo and what it divides by.

    Args:
        memo: where what is computed once per Decomposition is kept (the Relighter's).
        faces: the face pass (meshes blended into the transport of a face it finds).
        detail: the Relighter's ``detail`` (full-resolution detail transfer).
        own_residual: stage 2's residual (3, R, R) under a Decomposition's own light, None when diffuse-only.
    """

    def __init__(self, memo: Memo, faces: FacePass, detail: bool,
                 own_residual: Callable[[Decomposition], np.ndarray | None]) -> None:
        self.memo, self.faces, self.detail, self.own_residual = memo, faces, detail, own_residual
        self.fill = ShadowFill(memo, lambda dec: self.own(dec, with_residual=False))  # the deep shadow's fill
        self.meter = ExposureMeter(memo, detail, lambda dec: self.own(dec, with_residual=False),
                                   lambda dec, own, light: self.cast(dec, own, light))  # the exposure

    def restored(self, dec: Decomposition) -> dict:
        """What the relighting factor needs that does not depend on any light, in the person's window (cached).

        "window" (y0, y1, x0, x1): the network pixels near the person (the whole square when the network's square is not
        smaller than the photo's: to_crop takes a window only when enlarging); "alpha", "inner" (alpha > 0.5), "solid"
        (alpha > 0.9: the person's own pixels, no background mixed in), "skin" (r, r') float32 stage 1's skin
        probability unpremultiplied; "transport" (r, r', 9) unpremultiplied, its directional bands restored
        (relight_rt.relight.strength) and the face mesh's transport blended in, "albedo" luminance (r, r')
        unpremultiplied, "photo" (r, r') the luminance of the photo stage 1 saw, "face_skin" (r, r') bool, the person's
        pixels well inside a face mesh (``FacePass.add_faces``; none without one), "face_opening" (r, r') bool, the
        person's pixels inside a mesh's outline (its openings closed) by more than the skin's inset
        (``face_mesh.face_transport``) and off that skin: the eyes' sockets the inset leaves out, not the outline's ring
        (hair, the jaw's edge), and "face_points" the meshes in the window's pixels (``FacePass.window_points``: their
        cast shadows, ``cast``).
        """
        state = self.memo(dec)
        if "restored" not in state:
            geom = dec.geometry
            r = geom.resolution
            y0, y1, x0, x1 = window(dec.network_mask) if geom.side > r else (0, r, 0, r)
            alpha = dec.network_mask[y0:y1, x0:x1]
            # the directional bands restored to their true strength (relight_rt.relight.strength), for both sides of the
            # ratio
            transport = restore_bands(unpremultiply(np.ascontiguousarray(dec.transport[y0:y1, x0:x1]), alpha))
            skin, opening = np.zeros(alpha.shape, bool), np.zeros(alpha.shape, bool)
            points = ()
            if dec.face_meshes:  # a face's shape from its mesh where stage 1's transport is a blur; the face beyond
                # its skin: the eyes' sockets the skin's inset leaves out (not its outer ring: hair, the jaw's edge)
                skin, opening = self.faces.add_faces(dec, transport, (y0, y1, x0, x1))
                points = self.faces.window_points(dec, (y0, y1, x0, x1))
            albedo = unpremultiply(np.ascontiguousarray(dec.albedo[y0:y1, x0:x1]), alpha) @ REC709
            photo = dec.network_image[y0:y1, x0:x1] @ REC709
            skin_net = unpremultiply(dec.skin[y0:y1, x0:x1, None], alpha)[..., 0]
            state["restored"] = {"window": (y0, y1, x0, x1), "alpha": alpha, "inner": alpha > 0.5,
                                 "solid": readonly(alpha > 0.9), "skin": readonly(skin_net),
                                 "transport": readonly(transport), "albedo": readonly(albedo.astype(np.float32)),
                                 "photo": readonly(photo.astype(np.float32)),
                                 "face_skin": readonly(skin & (alpha > 0.5)), "face_points": points,
                                 "face_opening": readonly(opening & (alpha > 0.5))}
        return state["restored"]

    def materials(self, dec: Decomposition) -> dict:
        """``restored`` with a photo's albedo and transport read as materials (cached; ``own`` and its diffuse twin
        share it): the photo's own shading that stage 1 put into a face's albedo taken out, a face's albedo held by
        its mirror, a black beard taken as a dark material ("beard": its (h, w) weight, or None). A video frame's
        entries are ``restored``'s (a fit frame by frame would flicker)."""
        state = self.memo(dec)
        if "materials" not in state:
            base = self.restored(dec)
            if dec.photo:
                white = dec.white_light[:, 0]
                shading = base["transport"] @ white
                albedo = unshaded_albedo(base["albedo"], shading, base["face_skin"], base["inner"])
                if MIRROR_ALBEDO and base["face_points"] and base["face_skin"].any():  # stage 1 took part of a shadow
                    # for a dark albedo: the face's skin, edge softened (not its openings, whose edge reached a fringe)
                    keep = soften(base["face_skin"], CAP_SKIN_SPREAD * max(albedo.shape), base["inner"])
                    for pts in base["face_points"]:  # each face by its own mirror, on its own skin
                        albedo = mirror_held(albedo, pts, keep, base["photo"])
                # a black beard is a dark material, not shaded skin (relight_rt.relight.dark_beard)
                y0, y1, x0, x1 = base["window"]
                albedo, transport, beard = dark_material(dec.network_image[y0:y1, x0:x1], albedo, base["transport"],
                                                         white, base["solid"], base["face_points"])
                base = {**base, "albedo": readonly(albedo), "transport": readonly(transport),
                        "beard": None if beard is None else readonly(beard)}
            state["materials"] = base
        return state["materials"]

    def own(self, dec: Decomposition, with_residual: bool = True) -> dict:
        """What every relight of ``dec`` divides by, in the person's window of the network frame (cached).

        ``restored``'s entries, "transport" moved along the photo's own light toward the shading the photo shows
        (relight_rt.relight.strength ``explain_photo``), and "own" (r, r') the luminance of the pipeline's image under
        the photo's own light taken as white (diffuse plus stage 2's residual) plus "missing" (r, r'), what that falls
        short of ``_OWN_FLOOR`` x the photo's luminance (light the model misses; ``gain`` adds it to every new light
        too), floored at the ratio's floor.
        """
        state = self.memo(dec)
        key = "own" if with_residual else "own_diffuse"
        if key not in state:
            base = self.materials(dec)
            white = dec.white_light[:, 0]
            # the shading the photo shows and stage 1 misses, kept along the photo's own light
            # (relight_rt.relight.strength); on a face's skin, where the photo shows less, all of it (a shadow)
            skin = base["face_skin"]
            shadow = skin_shadow_share(skin, CAP_SKIN_SPREAD * max(skin.shape))
            moved = explain_photo(base["transport"], base["albedo"], base["photo"], white, base["inner"],
                                  shadow_share=shadow)
            base = {**base, "transport": readonly(moved)}
            own = base["albedo"] * sh.shading(base["transport"], dec.white_light)[..., 0]  # white: columns equal
            residual = self.own_residual(dec) if with_residual else None
            if residual is not None:
                own += luminance_window(residual, base["alpha"], base["window"])
            # where the photo is far brighter than its own reconstruction, the model misses light that is there
            # (stage 1's light from above and behind put a profile face in deep shade, then a front light made
            # it 3-5x brighter, blown out): that missing light, up to a share of the photo, is taken to stay under
            # every new light (added to both sides of the ratio, so the photo's own light still gives the photo)
            missing = np.maximum(_OWN_FLOOR * base["photo"] - own, 0).astype(np.float32)
            # where ``handover`` caps the ratio: the face's skin, its edge softened (the same for every light)
            cap = None
            if skin.any():
                spread = CAP_SKIN_SPREAD * max(skin.shape)
                cap = readonly(soften(skin, spread, base["inner"]))
            # the face beyond its skin (``restored``'s "face_opening"): the ratio cap and the fill's skin albedo reach
            # it too (``handover``, ``shadow_weight``)
            opening = cap_face = None
            found = base.get("face_opening")  # (a ``restored`` made elsewhere may not say)
            if cap is not None and OPENINGS_AS_SKIN and found is not None and found.any():
                opening = found
                cap_face = readonly(soften(skin | opening, spread, base["inner"]))
            # the faces' cast shadows under the photo's own light (relight_rt.relight.cast_shadow): a new light's are
            # taken relative to them
            cast, views = None, ()
            if cap is not None and base["face_points"]:
                triangles = self.faces.mesh().triangles
                views = tuple(MeshView(p, triangles, cap.shape, cap > 0) for p in base["face_points"])
                cast = shadow_factor(base["transport"], white, views, cap)
                cast = cast if cast is None else readonly(cast)
            state[key] = {**base, "missing": readonly(missing), "cap_skin": cap, "cast_own": cast, "mesh_views": views,
                          "face_opening": opening, "cap_face": cap if cap_face is None else cap_face,
                          "own": readonly(np.maximum(own + missing, _RATIO_EPS).astype(np.float32))}
        return state[key]

    def refit(self, dec: Decomposition) -> Decomposition:
        """``dec`` with its light refit to the transport the relighting factor divides with (relight_rt.relight.strength
        ``refit_light``), then turned toward what a face mesh's skin shows (``face_refit``); what was prepared for
        ``dec`` that does not depend on its light goes along."""
        base = self.restored(dec)
        albedo, transport, target = self.refit_inputs(dec)
        light = refit_light(dec.light, albedo, transport, target)
        # where a face mesh's shape says what light the skin shows (relight_rt.relight.strength)
        skin = base["face_skin"]
        if skin.any():
            light = face_refit(light, base["transport"][skin], base["photo"][skin], albedo, transport)
        return self.with_light(dec, light)

    def refit_inputs(self, dec: Decomposition) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """What ``refit`` fits ``dec``'s light to, on the person's pixels of the network's window: their albedo
        (N,), the transport the relit photo is divided by (N, 9) and the luminance that light should give (N,):
        stage 1's own reconstruction through that transport plus what it leaves unexplained of the photo."""
        base = self.restored(dec)
        y0, y1, x0, x1 = base["window"]
        inner = base["inner"]
        albedo, transport = base["albedo"][inner], base["transport"][inner]
        # what stage 1's own reconstruction (its transport, its light) leaves unexplained of the photo ...
        plain = unpremultiply(np.ascontiguousarray(dec.transport[y0:y1, x0:x1]), base["alpha"])[inner]
        white = dec.white_light[:, 0]
        unexplained = base["photo"][inner] - albedo * (plain @ white)
        # ... is what the light's correction explains, through the transport the relit photo is divided by
        return albedo, transport, albedo * (transport @ white) + unexplained

    def face_light(self, dec: Decomposition, head: Decomposition) -> Decomposition:
        """``dec`` with its light turned by the face its head pass ``head`` sees (relight_rt.relight.strength
        ``face_refit``), where the body pass saw the face too small for a mesh; ``dec`` itself otherwise."""
        base = self.restored(dec)
        if base["face_skin"].any():  # the body pass's own face turned it already (_refit)
            return dec
        face = self.restored(head)
        skin = face["face_skin"]
        if not skin.any():
            return dec
        inner = base["inner"]
        light = face_refit(dec.light, face["transport"][skin], face["photo"][skin], base["albedo"][inner],
                           base["transport"][inner])
        return self.with_light(dec, light)

    def with_light(self, dec: Decomposition, light: np.ndarray) -> Decomposition:
        """``dec`` with another light; what was prepared for it that does not depend on its light goes along."""
        return self.derive(dec, light=np.asarray(light, np.float32))

    def derive(self, dec: Decomposition, **changes) -> Decomposition:
        """``dataclasses.replace(dec, **changes)`` (its light, head, people, foreground, edge or origin); what was
        computed for ``dec`` that those leave as it was goes along: stage 1's outputs on the device, ``restored`` and
        the full-resolution guide (unless the foreground changes)."""
        if not set(changes) <= {"light", "head", "head_box", "people", "foreground", "edge", "origin"}:
            raise ValueError(f"derive: {sorted(changes)} change what is computed from them")
        new = replace(dec, **changes)
        old, state = self.memo(dec), self.memo(new)
        for key in ("restored", "device") if "foreground" in changes else ("restored", "device", "gray"):
            if key in old:
                state[key] = old[key]
        return new

    def beard(self, dec: Decomposition) -> np.ndarray | None:
        """(h, w) float32 in [0, 1] in the crop box: how far each pixel is a black beard (relight_rt.relight.dark_beard,
        ``own``'s "beard"), None where there is none (and for a video frame)."""
        own = self.own(dec, with_residual=False)
        if own.get("beard") is None:
            return None
        y0, _, x0, _ = own["window"]
        return np.clip(dec.geometry.to_crop(own["beard"], (y0, x0)), 0, 1)

    def cast(self, dec: Decomposition, own: dict, light: np.ndarray) -> np.ndarray | None:
        """(r, r') what the faces' cast shadows under ``light`` leave of its shading in the person's window
        (relight_rt.relight.cast_shadow), where darker than the photo's own light's (so that light gives the photo
        back); None without a face mesh or a lamp worth a shadow. Cached per light direction and shape (a light's
        scale changes nothing: the exposure meter and the factor share one), the last ``CAST_CACHE`` directions only."""
        if not own["mesh_views"]:
            return None
        lum = np.asarray(light, np.float32) @ REC709
        # the map is made from its key, the light without its scale: the meter's light and the exposed one share it,
        # and it was made from whichever came first (relights differed by up to 7e-7 by their order: fuzz8)
        lum = (lum / lum[0] if lum[0] > 1e-9 else lum).round(5)
        key = lum.tobytes()
        cache = self.memo(dec).setdefault("cast", OrderedDict())
        with self.memo.lock:  # relights of one Decomposition from several threads (the studio, a caller's pool)
            if key in cache:
                cache.move_to_end(key)
                return cache[key]
        cast = shadow_factor(own["transport"], lum, own["mesh_views"], own["cap_skin"])
        if cast is not None and own["cast_own"] is not None:
            cast = np.minimum(cast / np.maximum(own["cast_own"], 1e-3), 1)
        cast = None if cast is None else readonly(cast.astype(np.float32))
        with self.memo.lock:
            cache[key] = cast
            while len(cache) > CAST_CACHE:  # a light dragged about in the studio: each is a window-sized map
                cache.popitem(last=False)
        return cast

    def shadow_layer(self, dec: Decomposition, light: np.ndarray) -> tuple[np.ndarray | None, float]:
        """What the body pass's cast shadows under ``light`` take of its shading, in the input frame, and what "auto"
        lifts the light by for them: (depth, meter), depth (H, W) float32 in [0, 1] (1 - ``cast``: 0 where no shadow
        falls) or None without one, meter ``ExposureMeter.meter_shadows``'s factor (1 without a shadow). For the
        studio's preview, which relights without them (relight_rt.apps.studio): the final result's shading is its
        shading x (1 - depth) and, over the head pass's box, its change (the head pass's shadows in it: head_blend
        ``head_change``).
        """
        light = np.asarray(light, np.float32)
        if not self.detail:
            return None, 1.0
        own = self.own(dec, with_residual=False)
        cast = self.cast(dec, own, light)
        depth = None
        if cast is not None:
            y0, y1, x0, x1 = own["window"]
            full = np.zeros(dec.network_mask.shape, np.float32)
            full[y0:y1, x0:x1] = 1 - cast
            depth = np.clip(dec.to_input(full), 0, 1)
        meter = 1.0
        if depth is not None:
            metered = self.meter.meter_shadows(dec, light)
            size = float(np.linalg.norm(light))
            meter = float(np.linalg.norm(metered)) / size if size > 1e-12 else 1.0
        return depth, meter

    def _change(self, own: dict, light: np.ndarray, residual: np.ndarray | None,
                cast: np.ndarray | None = None) -> tuple:
        """Under ``light``, in the person's window: (ratio, tint, new): the luminance ratio of the relighting
        factor, the new light's colour at each pixel (luminance 1) and the new luminance the ratio divides.
        ``cast``: the faces' cast shadows under it (``cast``), a factor on its shading."""
        transport, alpha = own["transport"], own["alpha"]
        shading = sh.shading(transport, light)
        if cast is not None:
            shading = shading * cast[..., None]
        lum = shading @ REC709
        new = own["albedo"] * lum
        if residual is not None:
            new += luminance_window(residual, alpha, own["window"])
        new += own["missing"]  # the light the photo shows and the model misses stays (``own``)
        ratio = np.maximum(new, _RATIO_EPS) / own["own"]  # both floored: the photo's own light gives 1
        # the colour of the new light at each pixel, luminance 1 (where it leaves the pixel dark: its overall colour,
        # or white when that is not a colour: a light whose mean is not positive)
        dc_lum = float(light[0] @ REC709)
        dc = light[0] / dc_lum if dc_lum > 1e-6 and (light[0] > 0).all() else np.ones(3, np.float32)
        tint = np.divide(shading, lum[..., None], out=np.broadcast_to(dc.astype(np.float32), shading.shape).copy(),
                         where=lum[..., None] > 1e-4)
        span = tint_range(light)
        if span is not None:  # no colour the light cannot give (tint_range), at the same luminance
            np.clip(tint, *span, out=tint)
            tint /= np.maximum(tint @ REC709, 1e-6)[..., None]
            np.clip(tint, *span, out=tint)  # the rescale can lift one channel past its bound again
        return ratio, tint, new

    def gain(
        self, dec: Decomposition, light: np.ndarray, image: np.ndarray, residual: np.ndarray | None = None
    ) -> np.ndarray:
        """(h, w, 3) the factor on the photo in the crop box (module docstring), upsampled edge-aware.

        ``residual``: stage 2's residual under ``light`` (3, R, R), None for the diffuse image alone.
        """
        return self.gain_and_fill(dec, light, image, residual, fill=False)[0]

    def gain_and_fill(
        self, dec: Decomposition, light: np.ndarray, image: np.ndarray, residual: np.ndarray | None = None,
        fill: bool = True,
    ) -> tuple[np.ndarray, tuple | None]:
        """``gain`` and, with ``fill``, the deep shadow's fill: (box, part, weight) or None, ``part`` (3 channels) the
        change the light adds and ``weight`` its share, over ``box`` (a pair of slices of the crop box), decided at
        the photo's resolution (relight_rt.relight.fill_edge); the gain takes the photo as it is there (its share
        ``weight`` of the ratio's factor goes to 1).

        Where the photo's own shading is near zero, photo x ratio multiplies noise (a side-lit face's black half
        relit from the front stays black, its speckle amplified); there the change is added instead: the relit
        colour is the photo plus w x chroma x the new light's colour x (new - own), the luminance the light adds
        to stage 1's albedo under the new shading over the photo's own (zero under the photo's own light, so the
        photo comes back)."""
        own = self.own(dec, with_residual=residual is not None)
        y0, y1, x0, x1 = own["window"]
        light = np.asarray(light, np.float32)
        ratio, tint, new = self._change(own, light, residual, self.cast(dec, own, light))
        state = self.memo(dec)
        if "skin_chroma" not in state:  # the shaded-skin rule's light-independent inputs, kept for every light
            state["skin_chroma"] = tuple(map(readonly, skin_chroma(dec.network_image[y0:y1, x0:x1],
                                                                     dec.skin[y0:y1, x0:x1])))
        factor = shaded_skin(tint * ratio[..., None], ratio, *state["skin_chroma"])  # shaded skin keeps its colour
        gray = state.get("gray")  # the full-resolution guide, kept for every light (read once: a group's person
        if gray is None:  # drops theirs after use, relight_rt.relight.people, maybe in another thread)
            gray = state["gray"] = readonly(cv2.cvtColor(image, cv2.COLOR_RGB2GRAY))
        shadow = self.fill.shadow_weight(dec) if fill else None
        base = None if shadow is None else self.fill.fill_base(dec, image)
        if base is not None:
            chroma = shadow[1]
            over = handover(ratio, base["reach"])
            change = (np.maximum(new, _RATIO_EPS) - own["own"])[..., None] * tint * chroma  # as the ratio: 0 under
            # the photo's own light; a soft edge's own pixels take the solid person's beside (their albedo and colour
            # mix the background in: a bright one lifted the fill into a bright rim where a shadow meets the edge)
            # (far from any solid person the change stays its own: extend_outward's neutral 1 is a factor's)
            change = extend_outward(change, own["solid"], far_own=True)
            maps = change if over is None else np.dstack([change, over])
        gain = extend_outward(factor, own["inner"])
        gain = guided_upsample(dec.geometry, gain, dec.network_image[y0:y1, x0:x1], gray, (y0, x0))
        if base is None:
            return gain, None
        box, part = crop_part(dec.geometry, maps, base["where"], (y0, x0))
        weight = base["weight"] if over is None else np.maximum(base["weight"], part[..., 3])
        # (the box may be most of a photo: each pass over it counts, and numpy's (h, w, 1) x (h, w, 3) broadcast
        # costs about 8 ms a megapixel where the same product on 3 channels made by cv2.merge costs 1)
        region = gain[box]  # region += weight x (1 - region)
        rest = np.subtract(1, region)
        weight3 = cv2.merge([weight] * 3)
        rest *= weight3
        region += rest
        texture = self.fill.texture(dec, gray)  # the photo's own fine detail carried into what is added
        values = np.multiply(part[..., :3], weight3 if texture is None else cv2.merge([weight * texture[box]] * 3))
        return gain, (box, values, weight)


    def blend_head(self, dec: Decomposition, gain: np.ndarray, light: np.ndarray, fill: tuple | None = None) -> None:
        """Blend the head pass's (``dec.head``) change of shading into ``gain`` (the body's, crop frame), in place
        (relight_rt.relight.head_blend ``blend_head``); ``fill``: the body's deep-shadow fill (``gain_and_fill``)."""
        region = head_blend.head_region(dec)
        if region is not None:
            head = dec.head
            g_head = self.gain(head, light, np.ascontiguousarray(head.geometry.crop(head.image)))
            head_blend.blend_head(dec, gain, g_head, region, fill)

    def factor_inputs(self, dec: Decomposition) -> tuple[tuple[int, int, int, int], np.ndarray]:
        """The relighting factor's inputs that do not depend on the light, without stage 2's residual: ``own``'s
        "window" and (r, r', 11) float32 on it, albedo / own, missing / own and the transport (9), so that under a
        light with RGB shading S (luminance Y) the factor is (the first x Y + the second) x S / Y; taken from the
        inner pixels outward as ``gain`` takes the factor past the solid person (the window's own values there are
        0, which would leave the edge black)."""
        own = self.own(dec, with_residual=False)
        base = own["own"][..., None]
        maps = np.concatenate([own["albedo"][..., None] / base, own["missing"][..., None] / base, own["transport"]],
                              axis=2).astype(np.float32)
        maps = np.concatenate([extend_outward(maps[..., i : i + 4], own["inner"]) for i in range(0, 11, 4)], axis=2)
        return own["window"], maps

    def head_grade_inputs(self, dec: Decomposition) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """What ``blend_head`` does whatever the light, at the centres of the pixels of ``dec``'s window of the
        network frame (relight_rt.relight.head_blend ``grade_inputs``); None without a head pass or where
        ``blend_head`` would blend nothing (too little of the head pass's skin under it: ``head_blend.blends``)."""
        region = head_blend.head_region(dec)
        if region is None or not head_blend.blends(region):
            return None
        window = self.own(dec, with_residual=False)["window"]
        return head_blend.grade_inputs(dec, region, window, *self.factor_inputs(dec.head))
