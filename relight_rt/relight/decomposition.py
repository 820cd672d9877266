"""Stage 1's answer for a photo (``Decomposition``), what a relight returns with its layers (``RelightResult``),
and what is read off a Decomposition alone: its diffuse images (``diffuse_batch``) and its intrinsic layers at
the photo's resolution (``intrinsic_layers``). ``Memo`` is where a Relighter keeps what it computes once per
Decomposition."""

from __future__ import annotations

import os
import threading
import weakref
from dataclasses import dataclass, fields

import numpy as np

from ..image.color import REC709
from ..image.crop import CropGeometry
from ..light import sh
from .detail import extend_outward, guided_upsample, unpremultiply, window

ImageLike = str | os.PathLike | np.ndarray
_SHADING_MIN = np.float32(1e-3)  # full-resolution albedo: photo / shading, shading floored here
_SHADING_TRUST = np.float32(0.1)  # ... and trusted fully from this shading up (blended into the network's below)


def readonly(a: np.ndarray) -> np.ndarray:
    """``a`` itself, made read-only."""
    a.flags.writeable = False
    return a



@dataclass(frozen=True, eq=False)
class Decomposition:
    """Stage 1's answer for one photo, with what is needed to put results back into the photo: plain data.

    Only arrays, the crop geometry and the decompositions of its head and its people: a Decomposition carries
    everything its relighting needs besides the models, so pickled (to another process, a Ray worker, a file)
    and reloaded it relights to the same picture. It holds no session or device memory; what a Relighter
    computes from it once (device copies, the reconstruction under the own light) it keeps on its own side
    (``Memo``), and losing that changes nothing. Network-frame arrays are R x R views of the crop/pad/resize
    square (see ``geometry``); input-frame arrays have the photo's (H, W). All arrays are read-only, float32
    but for the face meshes; colours are RGB.

    Attributes:
        albedo_chw: (3, R, R) albedo in [0, 1], masked (``albedo`` is the (R, R, 3) view).
        skin: (R, R) skin probability in [0, 1], masked.
        transport_chw: (9, R, R) SH light transport (DESIGN.md §3 order), masked (``transport``: (R, R, 9)).
        light: (9, 3) the photo's estimated SH light, RGB columns: stage 1's estimate, for a photo refit so
            that albedo x shading explains it (relight_rt.relight.strength ``refit_light``; a video frame keeps
            stage 1's). Relighting with it gives the photo back.
        network_mask: (R, R) the mask in the network frame, in [0, 1].
        network_image: (R, R, 3) the input photo in the network frame (what stage 1 saw, before masking).
        mask: (H, W) the person mask in the input frame, in [0, 1].
        image: (H, W, 3) the input photo, RGB in [0, 1].
        geometry: the CropGeometry mapping network pixels to input pixels.
        photo: True for a photo (``Relighter.decompose``), False for a video frame (``allow_full``): a photo's
            matte edge gets the multilevel foreground estimate, a frame's the colours beside it.
        face_meshes: the meshes of the faces found in the photo ((468, 3) float64 x, y, z in input pixels,
            relight_rt.person.face_mesh), blended into the transport; None: no face mesh is used (video frames,
            ``detail=False``).
        head: the head's second stage-1 pass, for a face stage 1 saw small (relight_rt.relight.face_pass), with this
            decomposition's light; None without one. ``head_box`` (y0, y1, x0, x1): where it lies in the photo.
        people: a group photo's people, each decomposed on their own with their share of the matte, in a window
            of the photo around them (``origin``; relight_rt.relight.people; empty: one person, or the group relit
            as one).
        foreground: (h, w, 3) twice, in the crop box: the person's own colour F and the colour behind it B at
            the soft edge (``relight.compose.own_colours``; the same array twice for a hard mask); None: found
            on first use (video frames; a group relit person by person, whose people carry their own).
        origin: (y, x) of ``image``'s top-left pixel in the photo it was cut from: a group's person, decomposed
            in a window of the group's photo; (0, 0) for a photo of its own.
        edge: (h, w) in the crop box: the automatic matte's soft edge as the photo's colours show it
            (``relight.compose.shown_edge``), which the relit person goes over their own photo with (``foreground``'s
            B is then the colour behind this edge; a group relit person by person: its matte's, its people's B the
            colour behind it, relight_rt.relight.people ``with_shown_edge``); None: the mask's own (a mask or alpha
            channel given, a hard matte, video frames).
        upright: the quarter turns (counter-clockwise, ``np.rot90``) stage 1 saw the crop turned by, a person lying
            or tilted seen upright (relight_rt.relight.upright); its arrays here are turned back, in the photo's
            frame. 0: as the photo is.
        skin_views: (2, R, R) stage 1's skin map on the picture and on its mirror image mapped back (their mean is
            ``skin``; relight_rt.relight.network ``STAGE1_MIRROR``), for the head pass's search, which takes its
            threshold on each (relight_rt.relight.face_pass ``seen_head_box``); None: stage 1 looked once, or at the
            person turned upright (who gets no head pass).
        automatic: the mask is the automatic matte (intake's matter for a photo, ``person.matting.VideoMatter`` for a
            video frame, ``RelighterEngine``), not a mask or alpha channel given: over its own background the relit
            person keeps the background's rim on its outline (relight_rt.relight.compose ``Composer.shown_rim``; a
            frame only with ``compose.FRAME_RIM``). A given mask is the user's word and takes none.
    """

    albedo_chw: np.ndarray
    skin: np.ndarray
    transport_chw: np.ndarray
    light: np.ndarray
    network_mask: np.ndarray
    network_image: np.ndarray
    mask: np.ndarray
    image: np.ndarray
    geometry: CropGeometry
    photo: bool = False
    face_meshes: tuple[np.ndarray, ...] | None = None
    head: Decomposition | None = None
    head_box: tuple[int, int, int, int] | None = None
    people: tuple[Decomposition, ...] = ()
    foreground: tuple[np.ndarray, np.ndarray] | None = None
    origin: tuple[int, int] = (0, 0)
    edge: np.ndarray | None = None
    upright: int = 0
    skin_views: np.ndarray | None = None
    automatic: bool = False

    def __post_init__(self) -> None:
        put = lambda name, value: object.__setattr__(self, name, readonly(value))  # noqa: E731
        for name in ("albedo_chw", "transport_chw", "skin", "network_mask", "network_image"):
            put(name, np.ascontiguousarray(getattr(self, name), dtype=np.float32))
        put("light", np.array(self.light, dtype=np.float32))
        put("mask", np.asarray(self.mask, dtype=np.float32))
        put("image", np.asarray(self.image, dtype=np.float32))
        if self.face_meshes is not None:
            object.__setattr__(self, "face_meshes", tuple(readonly(np.asarray(m)) for m in self.face_meshes))
        if self.foreground is not None:  # F and B may be one array (a hard mask): kept as one
            object.__setattr__(self, "foreground", tuple(readonly(np.asarray(a)) for a in self.foreground))
        object.__setattr__(self, "people", tuple(self.people))
        object.__setattr__(self, "origin", (int(self.origin[0]), int(self.origin[1])))
        if self.edge is not None:
            put("edge", np.asarray(self.edge, dtype=np.float32))
        if self.skin_views is not None:
            put("skin_views", np.ascontiguousarray(self.skin_views, dtype=np.float32))

    def __reduce__(self):  # unpickled through the constructor, so the arrays come back read-only
        return (type(self), tuple(getattr(self, f.name) for f in fields(self)))

    @property
    def albedo(self) -> np.ndarray:
        """(R, R, 3) albedo, RGB in [0, 1] (a view)."""
        return self.albedo_chw.transpose(1, 2, 0)

    @property
    def transport(self) -> np.ndarray:
        """(R, R, 9) light transport (a view)."""
        return self.transport_chw.transpose(1, 2, 0)

    @property
    def resolution(self) -> int:
        """R, the network's square size."""
        return self.geometry.resolution

    @property
    def white_light(self) -> np.ndarray:
        """(9, 3) the photo's own light taken as white: each colour column is the Rec. 709 luminance of ``light``.

        The runtime divides by the shading under this light (a white-balanced photo's colours are its
        albedo's), so an error in the estimate's colour cannot tint the result.
        """
        lum = self.light.astype(np.float64) @ REC709.astype(np.float64)
        return np.repeat(lum[:, None], 3, axis=1).astype(np.float32)

    def shading(self, light: np.ndarray | None = None) -> np.ndarray:
        """(R, R, 3) float32 shading max(0, T·L) under ``light`` (default: the photo's own light, white)."""
        return sh.shading(self.transport, self.white_light if light is None else light)

    def to_input(self, layer: np.ndarray) -> np.ndarray:
        """Map a network-frame layer (R, R[, C]) to the input frame (H, W[, C]), zero outside the crop."""
        return self.geometry.to_input(layer)

    def __repr__(self) -> str:
        h, w = self.geometry.frame
        return f"Decomposition(input {h}x{w}, box {self.geometry.box}, resolution {self.resolution})"


@dataclass(frozen=True)
class RelightResult:
    """What ``relight_layers`` returns: the relit photo and the layers that made it.

    Attributes:
        image: (H, W, 3) RGB or (H, W, 4) RGBA float32 in [0, 1], the relit photo.
        layers: input-frame float32 layers: "albedo" (H, W, 3), "shading" (H, W, 3, not clipped),
            "diffuse" (H, W, 3), "residual" (H, W, 3, zero when diffuse-only), "relit" (H, W, 3 network
            output, upsampled without detail transfer), "mask" (H, W).
        light: (9, 3) the light used, RGB.
        diffuse_only: True when no stage-2 model was available: no residual (specular etc.) was added.
    """

    image: np.ndarray
    layers: dict
    light: np.ndarray
    diffuse_only: bool


def diffuse_batch(albedo_chw: np.ndarray, transport_chw: np.ndarray, lights: np.ndarray) -> np.ndarray:
    """Diffuse images clip(albedo ⊙ max(0, T·L_k), 0, 1) for K lights at once, channel-first.

    ``sh.shading_chw`` with the albedo (the one shading formula, in blocks of pixels).

    Args:
        albedo_chw: (3, R, R) float32.
        transport_chw: (9, R, R) float32.
        lights: (K, 9, 3) float RGB lights.

    Returns:
        (K, 3, R, R) float32 in [0, 1], ready for stage 2.
    """
    return sh.shading_chw(transport_chw, lights, albedo_chw)


class Memo:
    """What a Relighter computes once per Decomposition, weakly keyed to it (dropped with it), under one lock.

    Only what follows from the Decomposition's fields and the Relighter's models (device copies, the
    reconstruction under the photo's own light, the full-resolution guide, ...): a cache, not state; a
    Decomposition relit by a Relighter that never saw it gives the same picture."""

    def __init__(self) -> None:
        self._dicts: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
        self.lock = threading.Lock()

    def __call__(self, dec: Decomposition) -> dict:
        """``dec``'s entries (created on first use)."""
        with self.lock:
            state = self._dicts.get(dec)
            if state is None:
                state = self._dicts[dec] = {}
            return state


def intrinsic_layers(dec: Decomposition, shading: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """The photo's intrinsic layers at its own resolution, with its own detail (input frame).

    The network's shading under the photo's own light is smooth (it comes from the transport), so it
    is upsampled plainly; the photo's high frequencies (clothing pattern, hair, skin texture) then go
    into the albedo: albedo = photo / shading, where the shading is large enough for the ratio to be
    stable, blending into the network's upsampled albedo where it is dark (below 0.1). The skin map is
    upsampled edge-aware, guided by the photo. Outside the person every layer is 0; each is multiplied
    by the (soft) mask, as the network's outputs are.

    Returns:
        {"albedo": (H, W, 3), "shading": (H, W, 3) not clipped, "skin": (H, W), "mask": (H, W)},
        float32, albedo and skin in [0, 1].

    ``shading``: the (R, R, 3) network-frame shading the albedo is taken over, masked as
    ``Decomposition.shading`` is (default: that, the photo's own light through stage 1's transport). The
    studio's preview gives the shading the relighting factor divides by (bands restored), so that its albedo
    under the photo's own light is the photo again.
    """
    geom = dec.geometry
    alpha = dec.network_mask
    inner = alpha > 0.5
    albedo_net = extend_outward(unpremultiply(np.ascontiguousarray(dec.albedo), alpha), inner)
    skin_net = extend_outward(unpremultiply(np.repeat(dec.skin[..., None], 3, axis=2), alpha), inner)
    photo = np.ascontiguousarray(geom.crop(dec.image))
    shading = _shading_crop(dec, shading)
    albedo_up = np.clip(geom.to_crop(albedo_net), 0, 1)
    if geom.side > geom.resolution:
        y0, y1, x0, x1 = window(alpha)
        skin = guided_upsample(geom, skin_net[y0:y1, x0:x1], dec.network_image[y0:y1, x0:x1], photo, (y0, x0))
    else:
        skin = geom.to_crop(skin_net)
    ratio = np.clip(photo / np.maximum(shading, _SHADING_MIN), 0, 1)
    trust = np.clip(shading / _SHADING_TRUST, 0, 1)  # dark pixels: the ratio amplifies noise; trust the network
    albedo = albedo_up + (ratio - albedo_up) * trust
    m = geom.crop(dec.mask)[..., None]
    h, w = geom.frame
    y0, y1, x0, x1 = geom.box
    out = {"albedo": np.zeros((h, w, 3), np.float32), "shading": np.zeros((h, w, 3), np.float32),
           "skin": np.zeros((h, w), np.float32), "mask": np.array(dec.mask)}
    out["albedo"][y0:y1, x0:x1] = albedo * m
    out["shading"][y0:y1, x0:x1] = shading * m
    out["skin"][y0:y1, x0:x1] = np.clip(skin[..., 0], 0, 1) * m[..., 0]
    return out


def _shading_crop(dec: Decomposition, shading: np.ndarray | None) -> np.ndarray:
    """``intrinsic_layers``' shading in the crop box, straight (upsampled plainly, not below 0)."""
    alpha = dec.network_mask
    net = extend_outward(unpremultiply(dec.shading() if shading is None else shading, alpha), alpha > 0.5)
    return np.maximum(dec.geometry.to_crop(net), 0)


def shading_layer(dec: Decomposition, shading: np.ndarray | None = None) -> np.ndarray:
    """``intrinsic_layers(dec, shading)["shading"]`` alone (H, W, 3), without the albedo and skin it also makes
    (relight_rt.apps.render_passes takes the shading under two lights and the albedo once)."""
    geom = dec.geometry
    y0, y1, x0, x1 = geom.box
    out = np.zeros(geom.frame + (3,), np.float32)
    out[y0:y1, x0:x1] = _shading_crop(dec, shading) * geom.crop(dec.mask)[..., None]
    return out
