"""The Relighter: decompose a photo of a person, relight it, and put it back at full resolution.

Pipeline (DESIGN.md §1, §4, §5)::

    photo + mask ─► crop/pad/resize (CropGeometry) ─► stage 1 ─► albedo, skin, transport, light
    new light L' ─► diffuse D = clip(albedo ⊙ max(0, T·L'), 0, 1) ─► stage 2 ─► relit (network frame)
    relit ─► back to the input's size and position ─► composited over the background

Full-resolution detail: when the crop box is larger than the network's square (scale S/R > 1), the
network's relit image is not simply upsampled. The ratio relit / reconstruction (the reconstruction is
the same pipeline under the photo's own estimated light; both unpremultiplied, the ratio extended a few
pixels past the outline) is upsampled edge-aware with a fast guided filter (He & Sun 2015: the local
linear model ratio ≈ a·I + b is fitted at network resolution on the gray input, and a, b are upsampled
and applied with the full-resolution gray input I), then multiplied into the full-resolution input, so
the input's own high-frequency detail survives. Relighting with the photo's own light gives the input
back unchanged. (``cv2.ximgproc.guidedFilter`` at full resolution gives the same kind of result but
costs ~0.6 s per 2-megapixel crop with a colour guide; this costs ~30 ms.)

Without ``stage2.onnx`` the output is the diffuse image only: ``Relighter.diffuse_only`` is True, a
warning is logged at load, and ``RelightResult.diffuse_only`` says so.
"""

from __future__ import annotations

import importlib.util
import logging
import os
import threading
import weakref
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from . import exposure as _exposure
from . import sh
from ._chain import DeviceChain
from ._detail import extend_outward, guided_upsample, unpremultiply, window
from ._errors import RelightError
from ._geometry import CropGeometry
from ._io import read_image, sibling_mask
from .compositing import Background, clean_edge_colour, over_box, parse_background
from .config import RuntimeConfig
from .contract import kind_spec
from .lightspec import LightSpec, parse_light
from .masks import Matter, resolve_mask
from .session import Model, check_finite, find_models, load_model

log = logging.getLogger(__name__)

ImageLike = str | os.PathLike | np.ndarray
_RATIO_EPS = np.float32(0.02)  # keeps relit/reconstruction stable in dark pixels
_ALPHA_MIN = np.float32(1e-3)
_SHADING_MIN = np.float32(1e-3)  # full-resolution albedo: photo / shading, shading floored here
_SHADING_TRUST = np.float32(0.1)  # ... and trusted fully from this shading up (blended into the network's below)
_SHADE_BLOCK = 1 << 19  # multiply-adds per block of diffuse_batch (about 2 MB of float32 temporaries)


def _float32_light(light, name: str) -> np.ndarray:
    """A checked (9, 3) light in float32, the dtype it is used in (too large or non-finite there: RelightError)."""
    arr = sh.check_light(light, name).astype(np.float32)
    if not np.isfinite(arr).all():
        raise RelightError(f"{name}: SH light overflows float32 (|value| must be <= {sh.MAX_COEFF:g})")
    return arr


def _readonly(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


@dataclass(frozen=True, eq=False)
class Decomposition:
    """Stage 1's answer for one photo, with what is needed to put results back into the photo: plain data.

    Only arrays and the crop geometry: a Decomposition pickles (to another process, a Ray worker) and
    holds no session or device memory; a Relighter keeps whatever it prepares for one (device copies, the
    reconstruction) on its own side, keyed to it. Network-frame arrays are R x R views of the
    crop/pad/resize square (see ``geometry``); input-frame arrays have the photo's (H, W). All arrays are
    float32 and read-only; colours are RGB.

    Attributes:
        albedo_chw: (3, R, R) albedo in [0, 1], masked (``albedo`` is the (R, R, 3) view).
        skin: (R, R) skin probability in [0, 1], masked.
        transport_chw: (9, R, R) SH light transport (DESIGN.md §3 order), masked (``transport``: (R, R, 9)).
        light: (9, 3) the photo's estimated SH light, RGB columns.
        network_mask: (R, R) the mask in the network frame, in [0, 1].
        network_image: (R, R, 3) the input photo in the network frame (what stage 1 saw, before masking).
        mask: (H, W) the person mask in the input frame, in [0, 1].
        image: (H, W, 3) the input photo, RGB in [0, 1].
        geometry: the CropGeometry mapping network pixels to input pixels.
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

    def __post_init__(self) -> None:
        put = lambda name, value: object.__setattr__(self, name, _readonly(value))  # noqa: E731
        for name in ("albedo_chw", "transport_chw", "skin", "network_mask", "network_image"):
            put(name, np.ascontiguousarray(getattr(self, name), dtype=np.float32))
        put("light", np.array(self.light, dtype=np.float32))
        put("mask", np.asarray(self.mask, dtype=np.float32))
        put("image", np.asarray(self.image, dtype=np.float32))

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

    def shading(self, light: np.ndarray | None = None) -> np.ndarray:
        """(R, R, 3) float32 shading max(0, T·L) under ``light`` (default: the photo's own light)."""
        return sh.shading(self.transport, self.light if light is None else light)

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

    The formula of ``sh.shading`` on channel-first arrays, as one matrix product for every light.

    Args:
        albedo_chw: (3, R, R) float32.
        transport_chw: (9, R, R) float32.
        lights: (K, 9, 3) float RGB lights.

    Returns:
        (K, 3, R, R) float32 in [0, 1], ready for stage 2.
    """
    k = lights.shape[0]
    _, h, w = transport_chw.shape
    n = h * w
    coeffs = np.ascontiguousarray(lights.transpose(0, 2, 1).reshape(3 * k, 9), dtype=np.float32)
    transport = transport_chw.reshape(9, n)
    albedo = albedo_chw.reshape(1, 3, n)
    out = np.empty((k, 3, n), np.float32)
    # In pixel blocks of ~_SHADE_BLOCK multiply-adds: each block's product, ReLU, albedo product and clip run
    # while it is in cache (one pass over memory instead of four), and BLAS stays on one thread for such
    # small products (its threads only add start-up and contention for a 9-deep inner dimension).
    step = max(256, _SHADE_BLOCK // (27 * k))
    for s in range(0, n, step):
        e = min(s + step, n)
        block = (coeffs @ transport[:, s:e]).reshape(k, 3, e - s)
        np.maximum(block, 0, out=block)
        block *= albedo[:, :, s:e]
        np.clip(block, 0, 1, out=out[:, :, s:e])
    return out.reshape(k, 3, h, w)


class Relighter:
    """Relight photos of people with the relight_rt ONNX models.

    Args:
        models: folder with ``stage1.onnx`` and optionally ``stage2.onnx`` (without it results are
            diffuse-only) and ``dvp.onnx``; None: $RELIGHT_RT_MODELS, then the bundled models.
        device: "auto" (CUDA when available), "cuda" or "cpu".
        device_id: CUDA device index.
        providers: explicit onnxruntime providers (win over ``device``).
        preprocess: "quality" (INTER_AREA when shrinking) or "reference" (the reference's INTER_LINEAR
            resize, bit-for-bit; see relight_rt._geometry).
        detail: carry the input's full-resolution detail into the result when the person is larger
            than the network's square (see the module docstring); False: plain upsampling.
        warmup: run each graph once at load; None: only on CUDA.
        precision: which graphs of the folder to run: "fp32" (``stage1.onnx``, ``stage2.onnx``), "fp16"
            (``stage1_fp16.onnx``, ... as ``python -m export onnx --fp16`` writes them; for CUDA, slow on
            most CPUs) or "int8" (``stage1_int8.onnx``, ... from ``python -m export.quantize``; CPU). A
            graph missing in that precision is taken in fp32 (logged). The DVP graph is always fp32.
        matting: "auto": photos with neither a mask nor alpha get an automatic person matte when a
            matting model is installed; "off": they are an error.

    All of these but ``providers`` form the Relighter's :class:`relight_rt.config.RuntimeConfig`
    (``self.config``); ``Relighter.from_config(config)`` builds one from it.

    Raises:
        RelightError: no models found, a model file unreadable or breaking the contract, a bad setting.
    """

    def __init__(
        self,
        models: str | os.PathLike | None = None,
        *,
        device: str = "auto",
        device_id: int = 0,
        providers: list | None = None,
        preprocess: str = "quality",
        detail: bool = True,
        warmup: bool | None = None,
        precision: str = "fp32",
        matting: str = "auto",
    ) -> None:
        self.config = RuntimeConfig(models=models, device=device, device_id=device_id, precision=precision,
                                    preprocess=preprocess, detail=bool(detail), warmup=warmup, matting=matting)
        self.models_dir = find_models(models)
        self.precision = precision
        self.preprocess = preprocess
        self.detail = bool(detail)
        self._session_args = {"device": device, "device_id": device_id, "providers": providers}
        self.stage1: Model = load_model(self._graph("stage1"), "stage1", warmup=False, **self._session_args)
        if warmup is None:
            warmup = self.stage1.on_cuda
        if warmup:
            self.stage1.warm_up()
        self.stage2: Model | None = None
        stage2_path = self._graph("stage2")
        if stage2_path.is_file():
            self.stage2 = load_model(stage2_path, "stage2", warmup=warmup, **self._session_args)
            res2 = self.stage2.config.resolution
            if res2 not in (0, self.resolution):
                raise RelightError(
                    f"{stage2_path}: resolution {res2} does not match stage 1's {self.resolution} (or 0 for any size)"
                )
        else:
            log.warning("%s has no stage2.onnx: results are diffuse-only (no residual/specular)", self.models_dir)
        self._dvp: Model | None = None
        self._matter: Matter | None = None
        self._matter_loaded = False
        self._chain = None  # CUDA: stage 1 → shading → stage 2 without host round trips
        if self.stage1.on_cuda and (self.stage2 is None or self.stage2.on_cuda):
            self._chain = DeviceChain(self.stage1, self.stage2, "cuda", device_id)
        # What this Relighter prepares for a Decomposition (device copies, reconstruction, window), kept
        # here rather than on the (plain-data) Decomposition, and dropped with it.
        self._state: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
        self._state_lock = threading.Lock()
        CropGeometry.from_mask(np.ones((1, 1), np.float32), self.resolution, preprocess)  # checks the mode

    @classmethod
    def from_config(cls, config: RuntimeConfig, providers: list | None = None) -> Relighter:
        """A Relighter set up as ``config`` says (``providers``: explicit onnxruntime providers)."""
        if not isinstance(config, RuntimeConfig):
            raise RelightError(f"config: expected a RuntimeConfig, got {type(config).__name__}")
        return cls(config.models, device=config.device, device_id=config.device_id, providers=providers,
                   preprocess=config.preprocess, detail=config.detail, warmup=config.warmup,
                   precision=config.precision, matting=config.matting)

    def _graph(self, kind: str) -> Path:
        """The file of ``kind`` in this Relighter's precision, falling back to fp32 (logged) when absent."""
        fp32 = self.models_dir / kind_spec(kind).filename
        if self.precision == "fp32":
            return fp32
        path = fp32.with_name(f"{fp32.stem}_{self.precision}{fp32.suffix}")
        if path.is_file() or not fp32.is_file():
            return path
        log.warning("%s: no %s, running %s in fp32", self.models_dir, path.name, kind)
        return fp32

    @property
    def resolution(self) -> int:
        """R, stage 1's square input size."""
        return self.stage1.config.resolution

    @property
    def diffuse_only(self) -> bool:
        """True when there is no stage-2 model: results lack the residual (specular, etc.)."""
        return self.stage2 is None

    @property
    def dvp(self) -> Model | None:
        """The deep-video-prior graph (``dvp.onnx`` in the models folder), loaded on first use; None if absent."""
        path = self.models_dir / kind_spec("dvp").filename
        if self._dvp is None and path.is_file():
            self._dvp = load_model(path, "dvp", warmup=False, **self._session_args)
        return self._dvp

    @property
    def matter(self) -> Matter | None:
        """The automatic person matte (relight_rt.matting), loaded on first use; None when off or not installed."""
        if not self._matter_loaded:
            self._matter_loaded = True
            if self.config.matting == "auto" and importlib.util.find_spec(f"{__package__}.matting") is not None:
                from .matting import find_matting_models, shared_matter

                try:
                    find_matting_models()
                except RelightError as exc:  # the graphs are not installed: photos then need a mask or alpha
                    log.debug("no automatic matting: %s", exc)
                else:
                    self._matter = shared_matter(device=self.config.device)
        return self._matter

    def _prepared(self, dec: Decomposition) -> dict:
        """This Relighter's per-decomposition state (created on first use; freed with the Decomposition)."""
        with self._state_lock:
            state = self._state.get(dec)
            if state is None:
                state = self._state[dec] = {}
            return state

    # ------------------------------------------------------------------------------------ stage 1

    def decompose(self, image: ImageLike, mask: ImageLike | None = None) -> Decomposition:
        """Run stage 1 on a photo.

        Args:
            image: a path or an array (H, W, 3) RGB / (H, W, 4) RGBA, uint8 or float in [0, 1].
            mask: a path or an array (H, W), (H, W, 1) or (H, W, 3), binary or soft, same H x W as the
                image; ``"auto"``: the automatic matte; None: the image's alpha channel, else the automatic
                matte (relight_rt.masks.resolve_mask).

        Raises:
            RelightError: bad image or mask (see relight_rt._io.read_image / read_mask), no mask to be had.
        """
        return self.decompose_batch([image], [mask])[0]

    def decompose_batch(
        self, images: Sequence[ImageLike], masks: Sequence[ImageLike | None] | None = None, *,
        allow_full: bool = False,
    ) -> list[Decomposition]:
        """Run stage 1 on several photos in one batch (video frames, folders).

        Args:
            images: photos as for ``decompose`` (any sizes).
            masks: one per image (None entries: alpha, else the automatic matte); None: all None.
            allow_full: accept a mask that covers the whole image (a video frame filled by the person).

        Returns:
            One Decomposition per image, in order.
        """
        if masks is None:
            masks = [None] * len(images)
        if len(masks) != len(images):
            raise RelightError(f"masks: expected one per image ({len(images)}), got {len(masks)}")
        if not images:
            return []
        rgbs, ms, geoms = [], [], []
        for i, (image, mask) in enumerate(zip(images, masks, strict=True)):
            name = str(image) if isinstance(image, (str, os.PathLike)) else f"image {i}" if len(images) > 1 else "image"
            img = read_image(image, "image")
            m = resolve_mask(img, mask, matter=self.matter if mask is None or isinstance(mask, str) else None,
                             allow_empty=allow_full, name=name)
            rgbs.append(np.ascontiguousarray(img[..., :3]) if img.shape[2] == 4 else img)
            ms.append(m)
            geoms.append(CropGeometry.from_mask(m, self.resolution, self.preprocess))
        net_imgs = [g.to_network(rgb) for g, rgb in zip(geoms, rgbs, strict=True)]
        net_masks = [g.to_network(m) for g, m in zip(geoms, ms, strict=True)]
        on_device: list = [None] * len(images)
        if self._chain is not None:
            outs = []
            for i, (ni, nm) in enumerate(zip(net_imgs, net_masks, strict=True)):
                out, on_device[i] = self._chain.run_stage1(ni.transpose(2, 0, 1)[None], nm[None, None])
                check_finite(out, self.stage1.name)
                outs.append(out)
            out = {k: np.concatenate([o[k] for o in outs]) for k in outs[0]}
        else:
            out = self.stage1.run({"image": np.stack(net_imgs).transpose(0, 3, 1, 2),
                                   "mask": np.stack(net_masks)[:, None]})
        decs = []
        for i, geom in enumerate(geoms):
            light = out["light"][i]
            if not np.isfinite(light).all():
                raise RelightError(f"{self.stage1.name}: stage 1 estimated a non-finite light for this image")
            dec = Decomposition(out["albedo"][i], out["skin"][i, 0], out["transport"][i], light, net_masks[i],
                                net_imgs[i], ms[i], rgbs[i], geom)
            if on_device[i] is not None:
                self._prepared(dec)["device"] = on_device[i]
            decs.append(dec)
        return decs

    # ------------------------------------------------------------------------------------ lights

    def _estimate_light(self, photo: Path, mask: str | None) -> np.ndarray:
        return np.array(self.decompose(photo, mask if mask is not None else sibling_mask(photo)).light, np.float32)

    def resolve_light(self, light) -> np.ndarray:
        """Any accepted light argument → (9, 3) float32 RGB SH light.

        Accepted: an array (9, 3); a ``Decomposition`` (its estimated light: "light me like that photo");
        a :class:`relight_rt.lightspec.LightSpec`; a string or path, read by the one rule of
        relight_rt.lightspec (light file, environment map, photo of a person, or preset name).
        """
        if isinstance(light, Decomposition):
            return np.array(light.light, dtype=np.float32)
        if isinstance(light, (str, os.PathLike)):
            light = parse_light(light)
        if isinstance(light, LightSpec):
            return _float32_light(light.resolve(self._estimate_light, dtype=np.float64), "light")
        return _float32_light(light, "light")

    def _resolve_lights(self, values) -> np.ndarray:
        """A (K, 9, 3) array, or a list of anything ``resolve_light`` accepts → (K, 9, 3) float32, K >= 1."""
        if isinstance(values, np.ndarray):
            if values.ndim != 3 or values.shape[1:] != (9, 3):
                raise RelightError(f"lights: expected (K, 9, 3) SH lights, got {values.shape} {values.dtype}")
        elif not isinstance(values, (list, tuple)):
            raise RelightError(f"lights: expected a (K, 9, 3) array or a list of lights, got {type(values).__name__}")
        if len(values) == 0:
            raise RelightError("lights: expected at least one light, got none")
        return np.stack([self.resolve_light(v) for v in values])

    # ------------------------------------------------------------------------------------ relight

    def _network_relit(
        self, dec: Decomposition, lights: np.ndarray, batch_size: int, want_layers: bool = True
    ) -> Iterator[tuple]:
        """Yield (diffuse, residual, relit), each (3, R, R) float32, per light, in batches.

        residual is None when diffuse-only; on CUDA diffuse and residual are None unless ``want_layers``.
        """
        net_mask = dec.network_mask[None, None]
        if self._chain is not None:
            yield from self._device_relit(dec, lights, batch_size, want_layers)
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
            out = self.stage2.run({"diffuse": diffuse, "mask": np.broadcast_to(net_mask, (n,) + net_mask.shape[1:])})
            for i in range(n):
                yield diffuse[i], out["residual"][i], out["relit"][i]

    def _device_relit(self, dec: Decomposition, lights: np.ndarray, batch_size: int, want_layers: bool) -> Iterator:
        """``_network_relit`` on CUDA through the DeviceChain (stage-1 outputs stay on the device)."""
        chain = self._chain
        state = self._prepared(dec)
        if "device" not in state:  # a decomposition made elsewhere: upload its stage-1 outputs once
            state["device"] = {"albedo": chain.upload(dec.albedo_chw[None]),
                               "transport": chain.upload(dec.transport_chw[None])}
        for start in range(0, lights.shape[0], batch_size):
            batch = lights[start : start + batch_size]
            mask_key = ("device-mask", batch.shape[0])
            if mask_key not in state:
                shape = (batch.shape[0], 1) + dec.network_mask.shape
                state[mask_key] = chain.upload(np.broadcast_to(dec.network_mask, shape))
            for diffuse, residual, relit in chain.relit(state["device"], state[mask_key], batch, want_layers):
                check_finite({"relit": relit}, self.stage2.name if self.stage2 is not None else "shading")
                yield diffuse, residual, relit

    def _reconstruction(self, dec: Decomposition) -> np.ndarray:
        """(R, R, 3) straight colour of the pipeline's output under the photo's own light (cached)."""
        state = self._prepared(dec)
        if "reconstruction" not in state:
            _, _, relit = next(self._network_relit(dec, dec.light[None], 1, want_layers=False))
            state["reconstruction"] = _readonly(unpremultiply(relit.transpose(1, 2, 0), dec.network_mask))
        return state["reconstruction"]

    def _person_colour(self, dec: Decomposition, relit: np.ndarray) -> np.ndarray:
        """(h, w, 3) straight (not premultiplied) colour of the relit person inside the crop box."""
        geom = dec.geometry
        relit_hwc = relit.transpose(1, 2, 0)
        if self.detail and geom.side > geom.resolution:
            state = self._prepared(dec)
            if "window" not in state:
                state["window"] = window(dec.network_mask)
            y0, y1, x0, x1 = state["window"]  # the network pixels near the person; the rest is padding
            alpha = dec.network_mask[y0:y1, x0:x1]
            colour_net = unpremultiply(relit_hwc[y0:y1, x0:x1], alpha)
            ratio = (colour_net + _RATIO_EPS) / (self._reconstruction(dec)[y0:y1, x0:x1] + _RATIO_EPS)
            ratio = extend_outward(ratio, alpha > 0.5)
            image = np.ascontiguousarray(geom.crop(dec.image))
            colour = image * guided_upsample(geom, ratio, dec.network_image[y0:y1, x0:x1], image, (y0, x0))
        else:
            premult = geom.to_crop(relit_hwc)
            alpha = geom.to_crop(dec.network_mask)[..., None]
            colour = np.divide(premult, alpha, out=np.zeros_like(premult), where=alpha > _ALPHA_MIN)
        np.clip(colour, 0, 1, out=colour)
        return colour

    def layers(self, dec: Decomposition) -> dict[str, np.ndarray]:
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
        """
        geom = dec.geometry
        alpha = dec.network_mask
        inner = alpha > 0.5
        shading_net = extend_outward(unpremultiply(dec.shading(), alpha), inner)
        albedo_net = extend_outward(unpremultiply(np.ascontiguousarray(dec.albedo), alpha), inner)
        skin_net = extend_outward(unpremultiply(np.repeat(dec.skin[..., None], 3, axis=2), alpha), inner)
        photo = np.ascontiguousarray(geom.crop(dec.image))
        shading = np.maximum(geom.to_crop(shading_net), 0)
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

    def to_photo(self, dec: Decomposition, relit: np.ndarray, background="original") -> np.ndarray:
        """Put one relit network image (3, R, R) back into the photo, over ``background``.

        Returns:
            (H, W, 3) float32 RGB, or (H, W, 4) RGBA for a transparent background.
        """
        bg = parse_background(background)
        return self._compose(dec, relit, bg.backdrop(dec.image), clean=bg.kind != "original")

    def _compose(self, dec: Decomposition, relit: np.ndarray, backdrop: np.ndarray | None, clean: bool = False
                 ) -> np.ndarray:  # fmt: skip
        """The relit person over ``backdrop`` (None: RGBA); ``clean``: a new backdrop, so the soft edge loses
        the photo's old background first (relight_rt.compositing.clean_edge_colour)."""
        geom = dec.geometry
        colour = self._person_colour(dec, relit)
        alpha = geom.crop(dec.mask)
        if clean:
            photo = np.ascontiguousarray(geom.crop(dec.image)[..., :3])
            colour = clean_edge_colour(colour, photo, self._foreground(dec), alpha)
        return over_box(colour, alpha[..., None], geom.box, backdrop, dec.mask)

    def _foreground(self, dec: Decomposition) -> np.ndarray:
        """The person's decontaminated colour in the crop box (relight_rt.foreground), once per Decomposition."""
        state = self._prepared(dec)
        if "foreground" not in state:
            from .foreground import estimate_foreground

            geom = dec.geometry
            state["foreground"] = estimate_foreground(np.ascontiguousarray(geom.crop(dec.image)[..., :3]),
                                                      np.ascontiguousarray(geom.crop(dec.mask)))  # fmt: skip
        return state["foreground"]

    def _prepare(self, image, mask) -> Decomposition:
        if isinstance(image, Decomposition):
            if mask is not None:
                raise RelightError("mask: a Decomposition already has its mask; pass mask only with an image")
            return image
        return self.decompose(image, mask)

    def relight(
        self,
        image: ImageLike | Decomposition,
        light,
        *,
        mask: ImageLike | None = None,
        background: Background | str | os.PathLike | np.ndarray = "original",
        exposure="auto",
    ) -> np.ndarray:
        """Relight a photo (or a Decomposition) under a new light.

        Args:
            image: a photo (see ``decompose``) or a ``Decomposition`` (no stage-1 pass).
            light: see ``resolve_light``: (9, 3) array, LightSpec, light file, HDR map, photo, Decomposition or
                preset.
            mask: the photo's mask (see ``decompose``); not with a Decomposition.
            background: a :class:`relight_rt.compositing.Background`, or its shorthand: "original" (the
                photo), "transparent" (RGBA output, alpha = mask), a colour ("black", "#RRGGBB") or an image
                (path or array; fitted to the photo by "cover").
            exposure: "auto" (default: the light is scaled so the person keeps its mean luminance), an EV
                offset from auto (+1 twice as bright), or "physical" (the light as given); relight_rt.exposure.

        Returns:
            (H, W, 3) float32 RGB in [0, 1] at the input's size ((H, W, 4) RGBA for "transparent"); pixels
            where the mask is 0 are the background's, untouched. ``relight_layers`` also returns the layers.
        """
        dec = self._prepare(image, mask)
        lit = _exposure.expose(dec, self.resolve_light(light), exposure)
        bg = parse_background(background)
        _, _, relit = next(self._network_relit(dec, lit[None], 1, want_layers=False))
        return self._compose(dec, relit, bg.backdrop(dec.image), clean=bg.kind != "original")

    def relight_layers(
        self,
        image: ImageLike | Decomposition,
        light,
        *,
        mask: ImageLike | None = None,
        background: Background | str | os.PathLike | np.ndarray = "original",
        exposure="auto",
    ) -> RelightResult:
        """``relight`` plus the input-frame layers that made the picture (see :class:`RelightResult`)."""
        dec = self._prepare(image, mask)
        lit = _exposure.expose(dec, self.resolve_light(light), exposure)
        bg = parse_background(background)
        diffuse, residual, relit = next(self._network_relit(dec, lit[None], 1, want_layers=True))
        out = self._compose(dec, relit, bg.backdrop(dec.image), clean=bg.kind != "original")
        chw = lambda a: dec.to_input(np.ascontiguousarray(a.transpose(1, 2, 0)))  # noqa: E731
        layers = {
            "albedo": dec.to_input(np.ascontiguousarray(dec.albedo)),
            "shading": dec.to_input(dec.shading(lit)),
            "diffuse": chw(diffuse),
            "residual": chw(residual) if residual is not None else np.zeros(dec.image.shape, np.float32),
            "relit": chw(relit),
            "mask": np.array(dec.mask),
        }
        return RelightResult(out, layers, lit, self.diffuse_only)

    def iter_relight(
        self,
        image: ImageLike | Decomposition,
        lights,
        *,
        mask: ImageLike | None = None,
        background: Background | str | os.PathLike | np.ndarray = "original",
        batch_size: int = 4,
        exposure="auto",
    ) -> Iterator[np.ndarray]:
        """Like ``relight_many`` but yields one (H, W, 3|4) result at a time (for long sweeps and video)."""
        if not isinstance(batch_size, int) or batch_size < 1:
            raise RelightError(f"batch_size: expected a whole number >= 1, got {batch_size!r}")
        dec = self._prepare(image, mask)
        lits = _exposure.expose(dec, self._resolve_lights(lights), exposure)
        bg = parse_background(background)
        backdrop = bg.backdrop(dec.image)
        for _, _, relit in self._network_relit(dec, lits, batch_size, want_layers=False):
            yield self._compose(dec, relit, backdrop, clean=bg.kind != "original")

    def relight_many(
        self,
        image: ImageLike | Decomposition,
        lights,
        *,
        mask: ImageLike | None = None,
        background: Background | str | os.PathLike | np.ndarray = "original",
        batch_size: int = 4,
        exposure="auto",
    ) -> np.ndarray:
        """One stage-1 pass, then K relights through stage 2 in batches of ``batch_size``.

        Args:
            image: a photo or a Decomposition (as for ``relight``).
            lights: (K, 9, 3) array or a list of anything ``resolve_light`` accepts.
            mask, background: as for ``relight``.
            batch_size: lights per stage-2 run.
            exposure: as for ``relight``, for each light on its own.

        Returns:
            (K, H, W, 3) float32 RGB ((K, H, W, 4) for "transparent"); K full-size images are held in memory,
            use ``iter_relight`` for long sweeps.
        """
        dec = self._prepare(image, mask)
        lits = self._resolve_lights(lights)
        bg = parse_background(background)
        out = np.empty((lits.shape[0],) + dec.geometry.frame + (bg.channels,), np.float32)
        results = self.iter_relight(dec, lits, background=bg, batch_size=batch_size, exposure=exposure)
        for i, img in enumerate(results):
            out[i] = img
        return out

    def composite(
        self,
        image: ImageLike,
        background,
        *,
        mask: ImageLike | None = None,
        light=None,
        position=None,
        height: float | None = None,
        shadow: bool = False,
        exposure="auto",
        fov: float = 60.0,
        white_balance: bool = True,
    ) -> np.ndarray:
        """Relight the person of ``image`` for the scene of ``background`` and put it there.

        See ``relight_rt.scene.composite`` for the arguments. Returns (H_bg, W_bg, 3) float32 sRGB.
        """
        from .scene import composite

        return composite(self, image, background, mask=mask, light=light, position=position, height=height,
                         shadow=shadow, exposure=exposure, fov=fov, white_balance=white_balance)
