"""The two networks run on a Decomposition's arrays: stage 1 on a batch of network-frame photos, stage 2 on the
diffuse images of K lights (on CUDA through the DeviceChain, stage 1's outputs kept on the device)."""

from __future__ import annotations

import logging
from collections.abc import Iterator

import numpy as np

from ..engine.device_chain import DeviceChain
from ..engine.errors import RelightError
from ..engine.session import Model, check_finite
from ..image.crop import CropGeometry
from .decomposition import Decomposition, Memo, diffuse_batch, readonly
from .face_pass import FacePass
from .upright import STAGE1_IMAGES, UprightTurn, mirror_averaged, mirror_picture, turn_picture, turned_back

log = logging.getLogger(__name__)

# stage 1 also sees each picture mirrored left-right (in the same batch), its answers mapped back and averaged with
# the first (relight_rt.relight.upright ``mirror_averaged``): a photo and its mirror image decompose to each other's
# mirror image, up to the crop (below). Without it stage 1 read Extended Yale B's frontal lamp 3.5 deg toward the
# image's right on a photo and on its mirror alike (face31). With the face mesh's MESH_FLIP alone it failed mirror31's
# criterion: a mirrored photo still relit up to 38 levels (p99) from the result mirrored, since CropGeometry placed a
# mirror's crop a pixel apart and stage 2 was not averaged. With crop.SYMMETRIC_CROP and STAGE2_MIRROR (below) too,
# within 1 level (benchmarks/mirror_equivariance.py). On since mirror34, the four parts together: c751cea's criterion
# met (Yale photos + mirrors pooled relight relerr 0.519 -> 0.499, de-light 0.401 -> 0.389; held-out renders' RMSE
# within 0.0005 of before on every framing, three of five better; docs/RESULTS.md). Costs a second stage-1
# run per picture (~15 ms on the CPU); on CUDA the averaged answers are uploaded again on first use (the
# DeviceChain's copies are of one run's).
STAGE1_MIRROR = True
# stage 2 also sees each shaded picture mirrored left-right (in the same batch; on CUDA a second run of the chain on
# the decomposition mirrored), its answers mirrored back and averaged with the first, so a photo and its mirror image
# relight to each other's result mirrored (with STAGE1_MIRROR, face_mesh.MESH_FLIP and crop.SYMMETRIC_CROP; DPR's
# portrait p99 5 -> 1 level). Its own switch, not STAGE1_MIRROR's: stage 1 runs once per decomposition, stage 2 once
# per light, so this one is paid on every relight (a second stage-2 run: +5-18 ms on a 2.5 MP relight, mirror32).
# On since mirror34 with the other three (docs/RESULTS.md).
STAGE2_MIRROR = True


class Network:
    """A Relighter's sessions run: ``stage1``, ``stage2`` (None: diffuse-only), ``chain`` (CUDA, or None); stage 1
    sees a person lying or tilted upright (``upright``)."""

    def __init__(self, stage1: Model, stage2: Model | None, chain: DeviceChain | None, memo: Memo,
                 faces: FacePass) -> None:
        self.stage1, self.stage2, self.chain, self.memo = stage1, stage2, chain, memo
        self.upright = UprightTurn(faces)  # which way a photo's person stands (the faces it finds: ``faces``)

    def stage1_outputs(self, net_imgs: list[np.ndarray], net_masks: list[np.ndarray]) -> tuple[dict, list]:
        """Stage 1 on (R, R, 3) photos and (R, R) masks: its outputs batched, and per image the device copies
        (CUDA) or None."""
        on_device: list = [None] * len(net_imgs)
        if self.chain is not None:
            outs = []
            for i, (ni, nm) in enumerate(zip(net_imgs, net_masks, strict=True)):
                out, on_device[i] = self.chain.run_stage1(ni.transpose(2, 0, 1)[None], nm[None, None])
                check_finite(out, self.stage1.name)
                outs.append(out)
            out = {k: np.concatenate([o[k] for o in outs]) for k in outs[0]}
        else:
            out = self.stage1.run({"image": np.stack(net_imgs).transpose(0, 3, 1, 2),
                                   "mask": np.stack(net_masks)[:, None]})
        return out, on_device

    def run_stage1(self, rgbs: list[np.ndarray], masks: list[np.ndarray], geoms: list[CropGeometry],
                   net_imgs: list[np.ndarray], net_masks: list[np.ndarray], meshes: list, alone: list[bool]
                   ) -> tuple[list[dict], list]:
        """Stage 1 on a batch of photos cropped to the network's square, a person lying or tilted seen turned upright
        (relight_rt.relight.upright; ``alone[i]``: photo i may be, one person's), the answers in the photos' frames.

        Args:
            rgbs, masks, geoms: the photos (H, W, 3), their mattes (H, W) and crops.
            net_imgs, net_masks: the same in the network frame, (R, R, 3) and (R, R).
            meshes: per photo the face meshes found upright in its crop, or None (not looked for).
            alone: per photo whether its person may be seen turned (one person of a photo: not a video frame, not a
                group's joint matte).

        Returns:
            Per photo the Decomposition's fields stage 1 gives: "albedo_chw" (3, R, R), "skin" (R, R),
            "transport_chw" (9, R, R), "light" (9, 3), "upright" (the quarter turns it was seen in) and "skin_views"
            ((2, R, R) the skin on the picture and on its mirror, mapped back; None unmirrored or turned); per photo its
            device copies (CUDA; None for a turned one, whose copies are the turned outputs: uploaded again on first
            use) or None.

        Raises:
            RelightError: stage 1 estimated a non-finite light.
        """
        turns = [self.upright.quarters(*args[:5]) if args[5] else 0
                 for args in zip(rgbs, masks, geoms, net_masks, meshes, alone, strict=True)]
        imgs, msks = ([turn_picture(a, q) for a, q in zip(arrays, turns, strict=True)]
                      for arrays in (net_imgs, net_masks))
        n, mirror = len(imgs), STAGE1_MIRROR
        if mirror:  # each picture (as seen: turned upright) and its mirror image in one batch
            imgs, msks = imgs + [mirror_picture(a) for a in imgs], msks + [mirror_picture(a) for a in msks]
        out, on_device = self.stage1_outputs(imgs, msks)
        fields = []
        for i, q in enumerate(turns):
            seen = {k: out[k][i] for k in (*STAGE1_IMAGES, "light")}
            views = None
            if mirror:
                other = {k: out[k][n + i] for k in (*STAGE1_IMAGES, "light")}
                # both skin maps kept: the head pass's search thresholds each, not their mean (face_pass)
                views = np.concatenate([seen["skin"], mirror_picture(other["skin"], 2)])
                seen = mirror_averaged(seen, other)
                on_device[i] = None
            if q:
                seen, on_device[i], views = turned_back(seen, q), None, None  # a turned person gets no head pass
                log.debug("stage 1 saw the person turned %d degrees counter-clockwise (upright)", 90 * q)
            if not np.isfinite(seen["light"]).all():
                raise RelightError(f"{self.stage1.name}: stage 1 estimated a non-finite light for this image")
            fields.append({"albedo_chw": seen["albedo"], "skin": seen["skin"][0], "transport_chw": seen["transport"],
                           "light": seen["light"], "upright": q, "skin_views": views})
        return fields, on_device[:n]

    def relit(
        self, dec: Decomposition, lights: np.ndarray, batch_size: int, want_layers: bool = True
    ) -> Iterator[tuple]:
        """Yield (diffuse, residual, relit), each (3, R, R) float32, per light, in batches.

        residual is None when diffuse-only; on CUDA diffuse and residual are None unless ``want_layers``.
        """
        net_mask = dec.network_mask[None, None]
        if self.chain is not None:
            yield from self.device_relit(dec, lights, batch_size, want_layers)
            return
        for start in range(0, lights.shape[0], batch_size):
            diffuse = diffuse_batch(dec.albedo_chw, dec.transport_chw, lights[start : start + batch_size])
            if not np.isfinite(diffuse).all():  # a NaN here is the light's or stage 1's, not stage 2's
                raise RelightError(f"light: shading under this light is not finite (stage 1: {self.stage1.name})")
            if self.stage2 is None:
                for d in diffuse:
                    yield d, None, d
                continue
            n = diffuse.shape[0]
            feeds = {"diffuse": diffuse, "mask": np.broadcast_to(net_mask, (n,) + net_mask.shape[1:])}
            if STAGE2_MIRROR:  # each shaded picture and its mirror image in one batch
                feeds = {k: np.concatenate([v, v[..., ::-1]]) for k, v in feeds.items()}
            out = self.stage2.run(feeds)
            if STAGE2_MIRROR:
                out = {k: (v[:n] + v[n:, ..., ::-1]) * np.float32(0.5) for k, v in out.items()}
            for i in range(n):
                yield diffuse[i], out["residual"][i], out["relit"][i]

    def device_relit(self, dec: Decomposition, lights: np.ndarray, batch_size: int, want_layers: bool) -> Iterator:
        """``relit`` on CUDA through the DeviceChain (stage-1 outputs stay on the device)."""
        chain = self.chain
        state = self.memo(dec)
        if "device" not in state:  # a decomposition made elsewhere: upload its stage-1 outputs once
            state["device"] = {"albedo": chain.upload(dec.albedo_chw[None]),
                               "transport": chain.upload(dec.transport_chw[None])}
        for start in range(0, lights.shape[0], batch_size):
            batch = lights[start : start + batch_size]
            mask_key = ("device-mask", batch.shape[0])
            if mask_key not in state:
                shape = (batch.shape[0], 1) + dec.network_mask.shape
                state[mask_key] = chain.upload(np.broadcast_to(dec.network_mask, shape))
            runs = chain.relit(state["device"], state[mask_key], batch, want_layers)
            if STAGE2_MIRROR and self.stage2 is not None:  # the decomposition mirrored shades to the shading mirrored
                if "device-mirror" not in state:
                    state["device-mirror"] = {
                        "albedo": chain.upload(np.ascontiguousarray(dec.albedo_chw[None, ..., ::-1])),
                        "transport": chain.upload(np.ascontiguousarray(dec.transport_chw[None, ..., ::-1]))}
                mirror_key = ("device-mask-mirror", batch.shape[0])
                if mirror_key not in state:
                    shape = (batch.shape[0], 1) + dec.network_mask.shape
                    state[mirror_key] = chain.upload(np.broadcast_to(dec.network_mask[:, ::-1], shape))
                mirrored = chain.relit(state["device-mirror"], state[mirror_key], batch, want_layers)
                runs = [(d, None if r is None else (r + rm[..., ::-1]) * np.float32(0.5),
                         (x + xm[..., ::-1]) * np.float32(0.5))
                        for (d, r, x), (_, rm, xm) in zip(runs, mirrored, strict=True)]
            for diffuse, residual, relit in runs:
                check_finite({"relit": relit}, self.stage2.name if self.stage2 is not None else "shading")
                yield diffuse, residual, relit

    def own_residual(self, dec: Decomposition) -> np.ndarray | None:
        """(3, R, R) stage 2's residual under the photo's own (white) light, cached; None when diffuse-only."""
        if self.stage2 is None:
            return None
        state = self.memo(dec)
        if "own_residual" not in state:
            _, residual, _ = next(self.relit(dec, dec.white_light[None], 1, want_layers=True))
            state["own_residual"] = readonly(np.array(residual, np.float32))
        return state["own_residual"]
