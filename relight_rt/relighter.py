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

import logging
import os
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import lights, sh
from ._chain import DeviceChain
from ._detail import extend_outward, guided_upsample, unpremultiply, window
from ._errors import RelightError
from ._geometry import CropGeometry
from ._io import IMAGE_SUFFIXES, read_image, read_mask, sibling_mask
from .session import Model, check_finite, find_models, load_model

log = logging.getLogger(__name__)

ImageLike = str | os.PathLike | np.ndarray
_RATIO_EPS = np.float32(0.02)  # keeps relit/reconstruction stable in dark pixels
_ALPHA_MIN = np.float32(1e-3)
_ENVMAP_SUFFIXES = (".hdr", ".pic", ".exr")
PRECISIONS = ("fp32", "fp16", "int8")
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


class Decomposition:
    """Stage 1's answer for one photo, with what is needed to put results back into the photo.

    Network-frame arrays are R x R views of the crop/pad/resize square (see ``geometry``); input-frame
    arrays have the photo's (H, W). All arrays are float32 and read-only; colours are RGB.

    Attributes:
        albedo: (R, R, 3) in [0, 1], masked.
        skin: (R, R) skin probability in [0, 1], masked.
        transport: (R, R, 9) SH light transport (DESIGN.md §3 order), masked.
        light: (9, 3) the photo's estimated SH light, RGB columns.
        network_mask: (R, R) the mask in the network frame, in [0, 1].
        network_image: (R, R, 3) the input photo in the network frame (what stage 1 saw, before masking).
        mask: (H, W) the person mask in the input frame, in [0, 1].
        image: (H, W, 3) the input photo, RGB in [0, 1].
        geometry: the CropGeometry mapping network pixels to input pixels.
    """

    def __init__(
        self,
        albedo_chw: np.ndarray,
        skin: np.ndarray,
        transport_chw: np.ndarray,
        light: np.ndarray,
        network_mask: np.ndarray,
        network_image: np.ndarray,
        mask: np.ndarray,
        image: np.ndarray,
        geometry: CropGeometry,
    ) -> None:
        self._albedo = _readonly(np.ascontiguousarray(albedo_chw, dtype=np.float32))  # (3, R, R)
        self._transport = _readonly(np.ascontiguousarray(transport_chw, dtype=np.float32))  # (9, R, R)
        self.skin = _readonly(np.ascontiguousarray(skin, dtype=np.float32))
        self.light = _readonly(np.array(light, dtype=np.float32))
        self.network_mask = _readonly(np.ascontiguousarray(network_mask, dtype=np.float32))
        self.network_image = _readonly(np.ascontiguousarray(network_image, dtype=np.float32))
        self.mask = _readonly(mask)
        self.image = _readonly(image)
        self.geometry = geometry
        self._cache: dict = {}

    @property
    def albedo(self) -> np.ndarray:
        """(R, R, 3) albedo, RGB in [0, 1] (a view)."""
        return self._albedo.transpose(1, 2, 0)

    @property
    def transport(self) -> np.ndarray:
        """(R, R, 9) light transport (a view)."""
        return self._transport.transpose(1, 2, 0)

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
    """What ``relight(..., return_layers=True)`` returns.

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

    Raises:
        RelightError: no models found, a model file unreadable or breaking the contract, unknown precision.
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
    ) -> None:
        if precision not in PRECISIONS:
            raise RelightError(f"precision is {precision!r}, expected one of {list(PRECISIONS)}")
        self._token = object()  # keys this Relighter's entries in a Decomposition's cache
        self.models_dir = find_models(models)
        self.precision = precision
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
        self._chain = None  # CUDA: stage 1 → shading → stage 2 without host round trips
        if self.stage1.on_cuda and (self.stage2 is None or self.stage2.on_cuda):
            self._chain = DeviceChain(self.stage1, self.stage2, "cuda", device_id)
        self.preprocess = preprocess
        self.detail = bool(detail)
        CropGeometry.from_mask(np.ones((1, 1), np.float32), self.resolution, preprocess)  # checks the mode

    def _graph(self, kind: str) -> Path:
        """The file of ``kind`` in this Relighter's precision, falling back to fp32 (logged) when absent."""
        fp32 = self.models_dir / f"{kind}.onnx"
        if self.precision == "fp32":
            return fp32
        path = self.models_dir / f"{kind}_{self.precision}.onnx"
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
        path = self.models_dir / "dvp.onnx"
        if self._dvp is None and path.is_file():
            self._dvp = load_model(path, "dvp", warmup=False, **self._session_args)
        return self._dvp

    # ------------------------------------------------------------------------------------ stage 1

    def decompose(self, image: ImageLike, mask: ImageLike | None = None) -> Decomposition:
        """Run stage 1 on a photo.

        Args:
            image: a path or an array (H, W, 3) RGB / (H, W, 4) RGBA, uint8 or float in [0, 1].
            mask: a path or an array (H, W), (H, W, 1) or (H, W, 3), binary or soft, same H x W as the
                image. None: the image's alpha channel.

        Raises:
            RelightError: bad image or mask (see relight_rt._io.read_image / read_mask), no mask at all.
        """
        img = read_image(image, "image")
        shape = img.shape[:2]
        if mask is not None:
            m = read_mask(mask, shape, "mask")
        elif img.shape[2] == 4:
            m = read_mask(img[..., 3], shape, "image alpha (used as the mask)")
        else:
            raise RelightError(
                "image: no mask given and the image has no alpha channel; give a mask (--mask FILE, or NAME_mask.png "
                "beside the image; mask= in Python)"
            )
        rgb = np.ascontiguousarray(img[..., :3]) if img.shape[2] == 4 else img
        geom = CropGeometry.from_mask(m, self.resolution, self.preprocess)
        net_img = geom.to_network(rgb)
        net_mask = geom.to_network(m)
        feeds = {"image": net_img.transpose(2, 0, 1)[None], "mask": net_mask[None, None]}
        if self._chain is not None:
            out, on_device = self._chain.run_stage1(feeds["image"], feeds["mask"])
            check_finite(out, self.stage1.name)
        else:
            out = self.stage1.run(feeds)
        light = out["light"][0]
        if not np.isfinite(light).all():
            raise RelightError(f"{self.stage1.name}: stage 1 estimated a non-finite light for this image")
        albedo, skin, transport = out["albedo"][0], out["skin"][0, 0], out["transport"][0]
        dec = Decomposition(albedo, skin, transport, light, net_mask, net_img, m, rgb, geom)
        if self._chain is not None:
            dec._cache[("device", self._token)] = on_device
        return dec

    # ------------------------------------------------------------------------------------ lights

    def resolve_light(self, light) -> np.ndarray:
        """Any accepted light argument → (9, 3) float32 RGB SH light.

        Accepted: an array (9, 3); a ``Decomposition`` (its estimated light: "light me like that photo");
        a light file (.npy / .json, RGB); an HDR environment map (.hdr / .pic / .exr, projected to SH);
        a photo (.png / .jpg / ...) of a person, whose light is estimated (its mask: its alpha channel
        or NAME_mask.png beside it); otherwise a preset name (relight_rt.lights).
        """
        if isinstance(light, Decomposition):
            return np.array(light.light, dtype=np.float32)
        if isinstance(light, (str, os.PathLike)):
            p = Path(light)
            suffix = p.suffix.lower()
            if p.is_file():
                if suffix in (".npy", ".json"):
                    value = sh.load_light(p)
                elif suffix in _ENVMAP_SUFFIXES:
                    value = sh.project_envmap(sh.load_envmap(p))
                elif suffix in IMAGE_SUFFIXES:
                    return np.array(self.decompose(p, sibling_mask(p)).light, dtype=np.float32)
                else:
                    raise RelightError(f"light: {p} is neither a light file (.npy/.json), an HDR map nor a photo")
                return _float32_light(value, f"light {p}")
            if suffix or os.sep in str(light):
                raise RelightError(f"light: file {p} not found")
            return _float32_light(lights.preset(str(light)), "light")
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
            diffuse = diffuse_batch(dec._albedo, dec._transport, lights[start : start + batch_size])
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
        key = ("device", self._token)
        if key not in dec._cache:  # a decomposition made elsewhere: upload its stage-1 outputs once
            dec._cache[key] = {
                "albedo": chain.upload(dec._albedo[None]),
                "transport": chain.upload(dec._transport[None]),
            }
        for start in range(0, lights.shape[0], batch_size):
            batch = lights[start : start + batch_size]
            mask_key = ("device-mask", self._token, batch.shape[0])
            if mask_key not in dec._cache:
                shape = (batch.shape[0], 1) + dec.network_mask.shape
                dec._cache[mask_key] = chain.upload(np.broadcast_to(dec.network_mask, shape))
            for diffuse, residual, relit in chain.relit(dec._cache[key], dec._cache[mask_key], batch, want_layers):
                check_finite({"relit": relit}, self.stage2.name if self.stage2 is not None else "shading")
                yield diffuse, residual, relit

    def _reconstruction(self, dec: Decomposition) -> np.ndarray:
        """(R, R, 3) straight colour of the pipeline's output under the photo's own light (cached)."""
        key = ("reconstruction", self._token)
        if key not in dec._cache:
            _, _, relit = next(self._network_relit(dec, dec.light[None], 1, want_layers=False))
            dec._cache[key] = _readonly(unpremultiply(relit.transpose(1, 2, 0), dec.network_mask))
        return dec._cache[key]

    def _background(self, background, dec: Decomposition) -> np.ndarray | None:
        if isinstance(background, str) and background == "original":
            return dec.image
        if isinstance(background, str) and background == "transparent":
            return None
        if not isinstance(background, (str, os.PathLike, np.ndarray)):
            raise RelightError(
                "background: expected 'original', 'transparent', a path or an image array, "
                f"got {type(background).__name__}"
            )
        bg = read_image(background, "background")
        if bg.shape[:2] != dec.image.shape[:2]:
            raise RelightError(
                f"background: is {bg.shape[0]}x{bg.shape[1]} (HxW), expected the input's size "
                f"{dec.image.shape[0]}x{dec.image.shape[1]}"
            )
        return bg[..., :3]

    def _person_colour(self, dec: Decomposition, relit: np.ndarray) -> np.ndarray:
        """(h, w, 3) straight (not premultiplied) colour of the relit person inside the crop box."""
        geom = dec.geometry
        relit_hwc = relit.transpose(1, 2, 0)
        if self.detail and geom.side > geom.resolution:
            if "window" not in dec._cache:
                dec._cache["window"] = window(dec.network_mask)
            y0, y1, x0, x1 = dec._cache["window"]  # the network pixels near the person; the rest is padding
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

    def _compose(self, dec: Decomposition, relit: np.ndarray, background: np.ndarray | None) -> np.ndarray:
        geom = dec.geometry
        y0, y1, x0, x1 = geom.box
        colour = self._person_colour(dec, relit)
        m = geom.crop(dec.mask)[..., None]
        if background is None:  # RGBA, straight alpha
            out = np.zeros(geom.frame + (4,), np.float32)
            out[y0:y1, x0:x1, :3] = np.where(m > 0, colour, 0)
            out[..., 3] = dec.mask
            return out
        out = np.array(background, dtype=np.float32)  # the result: one full-size copy
        region = out[y0:y1, x0:x1]
        region += (colour - region) * m
        return out

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
        background="original",
        return_layers: bool = False,
    ) -> np.ndarray | RelightResult:
        """Relight a photo (or a Decomposition) under a new light.

        Args:
            image: a photo (see ``decompose``) or a ``Decomposition`` (no stage-1 pass).
            light: see ``resolve_light``: (9, 3) array, light file, HDR map, photo, Decomposition or preset.
            mask: the photo's mask (None: its alpha channel); not with a Decomposition.
            background: "original" (the photo), "transparent" (RGBA output, alpha = mask) or an image
                (path or array) of the photo's size.
            return_layers: return a ``RelightResult`` with the layers instead of the image alone.

        Returns:
            (H, W, 3) float32 RGB in [0, 1] at the input's size ((H, W, 4) RGBA for "transparent"); pixels
            where the mask is 0 are the background's, untouched. With ``return_layers``, a RelightResult.
        """
        dec = self._prepare(image, mask)
        lit = self.resolve_light(light)
        bg = self._background(background, dec)
        diffuse, residual, relit = next(self._network_relit(dec, lit[None], 1, want_layers=return_layers))
        out = self._compose(dec, relit, bg)
        if not return_layers:
            return out
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
        background="original",
        batch_size: int = 4,
    ) -> Iterator[np.ndarray]:
        """Like ``relight_many`` but yields one (H, W, 3|4) result at a time (for long sweeps and video)."""
        if not isinstance(batch_size, int) or batch_size < 1:
            raise RelightError(f"batch_size: expected a whole number >= 1, got {batch_size!r}")
        dec = self._prepare(image, mask)
        lits = self._resolve_lights(lights)
        bg = self._background(background, dec)
        for _, _, relit in self._network_relit(dec, lits, batch_size, want_layers=False):
            yield self._compose(dec, relit, bg)

    def relight_many(
        self,
        image: ImageLike | Decomposition,
        lights,
        *,
        mask: ImageLike | None = None,
        background="original",
        batch_size: int = 4,
    ) -> np.ndarray:
        """One stage-1 pass, then K relights through stage 2 in batches of ``batch_size``.

        Args:
            image: a photo or a Decomposition (as for ``relight``).
            lights: (K, 9, 3) array or a list of anything ``resolve_light`` accepts.
            mask, background: as for ``relight``.
            batch_size: lights per stage-2 run.

        Returns:
            (K, H, W, 3) float32 RGB ((K, H, W, 4) for "transparent"); K full-size images are held in memory,
            use ``iter_relight`` for long sweeps.
        """
        dec = self._prepare(image, mask)
        lits = self._resolve_lights(lights)
        channels = 4 if isinstance(background, str) and background == "transparent" else 3
        out = np.empty((lits.shape[0],) + dec.geometry.frame + (channels,), np.float32)
        for i, img in enumerate(self.iter_relight(dec, lits, background=background, batch_size=batch_size)):
            out[i] = img
        return out

