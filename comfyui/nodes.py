"""relight_rt as ComfyUI nodes: load the models, decompose a photo, make a light, relight, passes, composite.

Each class follows ComfyUI's node interface (``INPUT_TYPES``, ``RETURN_TYPES``, ``FUNCTION``, ``CATEGORY``).
IMAGE and MASK tensors are converted at the edge (``_convert``); everything else is relight_rt's public API
(``Relighter``, ``LightSpec``, ``lights``, ``sh``, ``scene_light``). The values that travel between these nodes
have their own ComfyUI types:

- ``RELIGHT_MODELS``: a ``relight_rt.Relighter`` (its ONNX sessions, loaded once and kept by ComfyUI's cache).
- ``RELIGHT_DECOMPOSITION``: a tuple of ``relight_rt.Decomposition``, one per image of the batch.
- ``RELIGHT_LIGHT``: a ``relight_rt.LightSpec`` (a preset keeps its name, so that its own exposure applies
  as on the command line; every other source is resolved to its (9, 3) SH array here).

A batch of B images gives B decompositions and B relit images; a batch of one broadcasts against any other.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

import relight_rt
from relight_rt import LightSpec, Relighter, RelightError, RuntimeConfig, lights, scene, sh
from relight_rt.engine.config import DEVICES, MATTING, PRECISIONS
from relight_rt.light.from_background import key_direction
from relight_rt.light.spec import parse_light
from relight_rt.relight.decomposition import intrinsic_layers

from ._convert import arrays_to_image, arrays_to_mask, batch_pairs, images_to_arrays, masks_to_arrays

CATEGORY = "relight_rt"
MODELS = "RELIGHT_MODELS"
DECOMPOSITION = "RELIGHT_DECOMPOSITION"
LIGHT = "RELIGHT_LIGHT"
LIGHT_SOURCES = ("preset", "sh_file", "hdr_panorama", "lamp", "photo", "background")
EXPOSURE_MODES = ("auto", "physical")


class _Steps:
    """ComfyUI's progress bar and interrupt check when running inside ComfyUI; nothing outside it."""

    def __init__(self, total: int):
        try:
            import comfy.model_management as management
            import comfy.utils
        except ImportError:  # unit tests, or any host without ComfyUI
            self._bar, self._management = None, None
        else:
            self._bar, self._management = comfy.utils.ProgressBar(total), management

    def check(self) -> None:
        if self._management is not None:
            self._management.throw_exception_if_processing_interrupted()

    def done(self) -> None:
        if self._bar is not None:
            self._bar.update(1)


def _input_path(text: str, what: str) -> str:
    """A file named in a node: an absolute path, else relative to ComfyUI's input folder (to the working folder
    outside ComfyUI)."""
    if not isinstance(text, str) or not text.strip():
        raise RelightError(f"{what}: expected a file name, got an empty field")
    path = Path(text.strip()).expanduser()
    if not path.is_absolute():
        try:
            import folder_paths
        except ImportError:
            pass
        else:
            path = Path(folder_paths.get_input_directory()) / path
    if not path.is_file():
        raise RelightError(f"{what}: file {path} not found")
    return os.fspath(path)


def _colour(text: str) -> np.ndarray:
    """'#RRGGBB' or 'r, g, b' (floats, each >= 0) → three floats."""
    s = str(text).strip()
    if s.startswith("#") and len(s) == 7:
        try:
            return np.array([int(s[i:i + 2], 16) / 255 for i in (1, 3, 5)])
        except ValueError:
            pass
    else:
        try:
            values = np.array([float(v) for v in s.split(",")])
        except ValueError:
            values = np.zeros(0)
        if values.shape == (3,) and np.all(np.isfinite(values)) and np.all(values >= 0):
            return values
    raise RelightError(f"lamp_color: expected '#RRGGBB' or three numbers 'r, g, b' (>= 0), got {text!r}")


def _exposure(mode: str, ev: float):
    """The node's (mode, EV) as relight_rt's one exposure parameter: "physical", "auto", or an EV offset."""
    if mode not in EXPOSURE_MODES:
        raise RelightError(f"exposure: expected one of {list(EXPOSURE_MODES)}, got {mode!r}")
    if mode == "physical":
        return "physical"
    return "auto" if float(ev) == 0.0 else float(ev)


def _lamp(azimuth: float, elevation: float, colour: str, intensity: float, size: float) -> np.ndarray:
    """A lamp at (azimuth, elevation) degrees: azimuth 0 is the camera's side, +90 the image's right, 180 behind
    the subject; elevation +90 straight above (subject frame, DESIGN.md §3). ``size``: the lamp disc's angular
    radius in degrees (0: a point)."""
    direction = key_direction(float(azimuth), float(elevation))
    return lights.directional(direction, _colour(colour), float(intensity), math.radians(float(size)))


# ----------------------------------------------------------------------------------------------- nodes


class LoadRelightModels:
    """Load relight_rt's ONNX models once (the bundled ones, or a folder with stage1.onnx [stage2.onnx])."""

    CATEGORY = CATEGORY
    RETURN_TYPES = (MODELS,)
    RETURN_NAMES = ("models",)
    FUNCTION = "load"

    @classmethod
    def INPUT_TYPES(cls):
        return {"required": {
            "models_folder": ("STRING", {"default": "", "tooltip": "empty: the bundled models ($RELIGHT_RT_MODELS)"}),
            "device": (list(DEVICES), {"default": "auto"}),
            "precision": (list(PRECISIONS), {"default": "fp32"}),
            "matting": (list(MATTING), {"default": "auto", "tooltip": "photos without a mask: the automatic "
                                        "matte of the largest person (auto), of everyone (all), or an error (off)"}),
            "detail": ("BOOLEAN", {"default": True, "tooltip": "keep the photo's full-resolution detail"}),
        }}

    def load(self, models_folder: str, device: str, precision: str, matting: str, detail: bool):
        folder = models_folder.strip() or None
        config = RuntimeConfig(models=folder, device=device, precision=precision, matting=matting, detail=bool(detail))
        return (relight_rt.open(config),)


class RelightDecompose:
    """Stage 1 on each image: the decomposition (for Relight), its albedo and shading, and the person's mask."""

    CATEGORY = CATEGORY
    RETURN_TYPES = (DECOMPOSITION, "IMAGE", "IMAGE", "MASK")
    RETURN_NAMES = ("decomposition", "albedo", "shading", "mask")
    FUNCTION = "decompose"

    @classmethod
    def INPUT_TYPES(cls):
        return {"required": {"models": (MODELS,), "image": ("IMAGE",)},
                "optional": {"mask": ("MASK", {"tooltip": "1 = the person; unconnected: the automatic matte"})}}

    def decompose(self, models: Relighter, image, mask=None):
        photos = images_to_arrays(image)
        masks = masks_to_arrays(mask, len(photos), photos[0].shape[:2])
        steps = _Steps(len(photos))
        decs, albedo, shading, alpha = [], [], [], []
        for photo, m in zip(photos, masks, strict=True):
            steps.check()
            dec = models.decompose(photo, m)
            layers = intrinsic_layers(dec)  # the photo's size, its detail in the albedo
            decs.append(dec)
            albedo.append(layers["albedo"])
            shading.append(layers["shading"])  # unclipped; IMAGE holds [0, 1] (the float passes keep the rest)
            alpha.append(layers["mask"])
            steps.done()
        return (tuple(decs), arrays_to_image(albedo), arrays_to_image(shading), arrays_to_mask(alpha))


class RelightLight:
    """A light: a preset, an SH light file, an HDR panorama, a lamp, the light of a photo, or of a background."""

    CATEGORY = CATEGORY
    RETURN_TYPES = (LIGHT, "IMAGE")
    RETURN_NAMES = ("light", "preview")
    FUNCTION = "make"

    @classmethod
    def INPUT_TYPES(cls):
        return {
            "required": {
                "source": (list(LIGHT_SOURCES), {"default": "preset"}),
                "preset": (lights.list_presets(), {"default": "studio"}),
                "file": ("STRING", {"default": "", "tooltip": "sh_file (.npy/.json), hdr_panorama (.hdr/.exr/"
                                    "equirectangular image), photo or background when no image is connected; "
                                    "relative to ComfyUI's input folder"}),
                "rotation": ("FLOAT", {"default": 0.0, "min": -360.0, "max": 360.0, "step": 1.0,
                                       "tooltip": "degrees about the vertical axis"}),
                "lamp_azimuth": ("FLOAT", {"default": 45.0, "min": -180.0, "max": 180.0, "step": 1.0,
                                           "tooltip": "0: from the camera, +90: from the image's right"}),
                "lamp_elevation": ("FLOAT", {"default": 30.0, "min": -90.0, "max": 90.0, "step": 1.0}),
                "lamp_color": ("STRING", {"default": "#ffffff"}),
                "lamp_intensity": ("FLOAT", {"default": 1.0, "min": 0.0, "max": 100.0, "step": 0.05}),
                "lamp_size": ("FLOAT", {"default": 10.0, "min": 0.0, "max": 180.0, "step": 1.0,
                                        "tooltip": "angular radius of the lamp in degrees (0: a point)"}),
                "fov": ("FLOAT", {"default": 60.0, "min": 11.0, "max": 169.0, "step": 1.0,
                                  "tooltip": "background: its horizontal field of view in degrees"}),
            },
            "optional": {
                "models": (MODELS, {"tooltip": "photo: stage 1 estimates its light"}),
                "image": ("IMAGE", {"tooltip": "photo or background (the first of a batch)"}),
                "mask": ("MASK", {"tooltip": "photo: its person (1); unconnected: the automatic matte"}),
            },
        }

    @classmethod
    def IS_CHANGED(cls, source="preset", file="", **other_inputs):  # noqa: N802 (ComfyUI's name)
        """ComfyUI runs the node again when this value changes: a light file's time of change and size (ComfyUI
        cannot see a file change on disk by itself); the other inputs it compares itself."""
        if source in ("sh_file", "hdr_panorama", "photo", "background") and str(file).strip():
            try:
                st = os.stat(_input_path(file, source))
            except (RelightError, OSError):
                return ""
            return f"{st.st_mtime_ns}:{st.st_size}"
        return ""

    def make(self, source, preset, file, rotation, lamp_azimuth, lamp_elevation, lamp_color, lamp_intensity,
             lamp_size, fov, models=None, image=None, mask=None):
        spec = self.spec(source, preset, file, rotation, lamp_azimuth, lamp_elevation, lamp_color, lamp_intensity,
                         lamp_size, fov, models, image, mask)
        preview = sh.render_sphere(spec.resolve(), 128)
        return (spec, arrays_to_image([preview / max(float(preview.max()), 1e-6)]))

    @staticmethod
    def spec(source, preset, file="", rotation=0.0, lamp_azimuth=45.0, lamp_elevation=30.0, lamp_color="#ffffff",
             lamp_intensity=1.0, lamp_size=10.0, fov=60.0, models=None, image=None, mask=None) -> LightSpec:
        """The node's inputs as a LightSpec (``make`` without the preview)."""
        if source == "preset":
            return LightSpec.preset(parse_light(preset, allow_paths=False).value, rotate=rotation)
        if source == "sh_file":
            return LightSpec.file(_input_path(file, "sh_file"), rotate=rotation)
        if source == "hdr_panorama":
            return LightSpec.envmap(_input_path(file, "hdr_panorama"), rotate=rotation)
        if source == "lamp":
            lamp = _lamp(lamp_azimuth, lamp_elevation, lamp_color, lamp_intensity, lamp_size)
            return LightSpec.from_array(lamp, rotate=rotation)
        if source == "photo":
            if models is None:
                raise RelightError("light of a photo: connect the models (stage 1 estimates its light)")
            if image is not None:
                photo = images_to_arrays(image)[0]
                m = masks_to_arrays(mask, 1, photo.shape[:2])[0]
                light = models.resolve_light(models.decompose(photo, m))
            else:
                light = models.resolve_light(LightSpec.photo(_input_path(file, "photo")))
            return LightSpec.from_array(light, rotate=rotation)
        if source == "background":
            from relight_rt.light.from_background import light_from_background

            backdrop = images_to_arrays(image)[0] if image is not None else _input_path(file, "background")
            light, _ = light_from_background(backdrop, fov)
            return LightSpec.from_array(light, rotate=rotation)
        raise RelightError(f"source: expected one of {list(LIGHT_SOURCES)}, got {source!r}")


class Relight:
    """Relight each decomposition under a light: the photo (or a new background) with the person relit."""

    CATEGORY = CATEGORY
    RETURN_TYPES = ("IMAGE", "MASK")
    RETURN_NAMES = ("image", "mask")
    FUNCTION = "relight"

    @classmethod
    def INPUT_TYPES(cls):
        return {
            "required": {
                "models": (MODELS,),
                "decomposition": (DECOMPOSITION,),
                "light": (LIGHT,),
                "exposure": (list(EXPOSURE_MODES), {"default": "auto", "tooltip": "auto: the person keeps its "
                                                    "brightness (a preset may ask for its own); physical: as given"}),
                "ev": ("FLOAT", {"default": 0.0, "min": -20.0, "max": 20.0, "step": 0.25,
                                 "tooltip": "stops brighter (+) or darker (-) than auto"}),
            },
            "optional": {"background": ("IMAGE", {"tooltip": "a new background (fitted by cover); "
                                                  "unconnected: the photo's own"})},
        }

    def relight(self, models: Relighter, decomposition, light: LightSpec, exposure: str, ev: float, background=None):
        mode = _exposure(exposure, ev)
        decs = _decompositions(decomposition)
        backs = images_to_arrays(background, "background") if background is not None else ["original"]
        steps = _Steps(max(len(decs), len(backs)))
        out, alpha = [], []
        for dec, back in batch_pairs(decs, backs, ("decomposition", "background")):
            steps.check()
            out.append(models.relight(dec, light, background=back, exposure=mode))
            alpha.append(dec.mask)
            steps.done()
        return (arrays_to_image(out), arrays_to_mask(alpha))


class RelightPasses:
    """The passes of each relit image (relight_rt.apps.render_passes, docs/PASSES.md) as ComfyUI images: a normal map
    read off the transport, the albedo, the shading under the light, the residual and the matte.

    IMAGE holds [0, 1], so: the normal map is 0.5 + 0.5 n (camera space: R right, G up, B toward the camera; grey
    off the person), the shading is clipped at 1, the residual is 0.5 + residual (clipped). The float passes
    themselves: ``relight-rt decompose --format exr``.
    """

    CATEGORY = CATEGORY
    RETURN_TYPES = ("IMAGE", "IMAGE", "IMAGE", "IMAGE", "MASK")
    RETURN_NAMES = ("normal", "albedo", "shading", "residual", "alpha")
    FUNCTION = "passes"

    @classmethod
    def INPUT_TYPES(cls):
        return {"required": {
            "models": (MODELS,),
            "decomposition": (DECOMPOSITION,),
            "light": (LIGHT,),
            "exposure": (list(EXPOSURE_MODES), {"default": "auto"}),
            "ev": ("FLOAT", {"default": 0.0, "min": -20.0, "max": 20.0, "step": 0.25}),
        }}

    def passes(self, models: Relighter, decomposition, light: LightSpec, exposure: str, ev: float):
        from relight_rt.apps.render_passes import compute_passes

        mode = _exposure(exposure, ev)
        decs = _decompositions(decomposition)
        steps = _Steps(len(decs))
        out = {"normal": [], "albedo": [], "shading": [], "residual": [], "alpha": []}
        for dec in decs:
            steps.check()
            layers = compute_passes(models, dec, light, exposure=mode).layers
            out["normal"].append(0.5 + 0.5 * layers["normal"])
            out["albedo"].append(layers["albedo"])
            out["shading"].append(layers["shading"])
            out["residual"].append(0.5 + layers["residual"])
            out["alpha"].append(layers["alpha"])
            steps.done()
        images = tuple(arrays_to_image(out[name]) for name in ("normal", "albedo", "shading", "residual"))
        return (*images, arrays_to_mask(out["alpha"]))


class RelightComposite:
    """Put the person of a photo into a background, relit by the background's light (or a given one)."""

    CATEGORY = CATEGORY
    RETURN_TYPES = ("IMAGE",)
    RETURN_NAMES = ("image",)
    FUNCTION = "composite"

    @classmethod
    def INPUT_TYPES(cls):
        return {
            "required": {
                "models": (MODELS,),
                "person": ("IMAGE",),
                "background": ("IMAGE",),
                "ev": ("FLOAT", {"default": 0.0, "min": -20.0, "max": 20.0, "step": 0.25}),
                "fov": ("FLOAT", {"default": 60.0, "min": 11.0, "max": 169.0, "step": 1.0}),
                "shadow": ("BOOLEAN", {"default": True}),
                "height": ("FLOAT", {"default": 0.0, "min": 0.0, "max": 1.0, "step": 0.01,
                                     "tooltip": "the person's height as a share of the background's; 0: automatic"}),
                "position_x": ("FLOAT", {"default": -1.0, "min": -1.0, "max": 1.0, "step": 0.01,
                                         "tooltip": "where the feet go, a share of the width; -1: automatic"}),
                "position_y": ("FLOAT", {"default": -1.0, "min": -1.0, "max": 1.0, "step": 0.01}),
            },
            "optional": {
                "mask": ("MASK", {"tooltip": "the person (1); unconnected: the automatic matte"}),
                "light": (LIGHT, {"tooltip": "unconnected: the background's own light"}),
            },
        }

    def composite(self, models: Relighter, person, background, ev, fov, shadow, height, position_x, position_y,
                  mask=None, light=None):
        people = images_to_arrays(person, "person")
        masks = masks_to_arrays(mask, len(people), people[0].shape[:2])
        backs = images_to_arrays(background, "background")
        if (position_x < 0) != (position_y < 0):
            raise RelightError("position: give both position_x and position_y in [0, 1], or both -1 (automatic)")
        position = None if position_x < 0 else (float(position_x), float(position_y))
        pairs = batch_pairs(list(zip(people, masks, strict=True)), backs, ("person", "background"))
        steps = _Steps(len(pairs))
        out = []
        for (photo, m), back in pairs:
            steps.check()
            out.append(scene.composite(models, photo, back, mask=m, light=light, position=position,
                                        height=float(height) or None, shadow=bool(shadow),
                                        exposure="auto" if float(ev) == 0.0 else float(ev), fov=float(fov)))
            steps.done()
        if len({o.shape for o in out}) > 1:
            raise RelightError("background: a batch of backgrounds of different sizes cannot make one IMAGE")
        return (arrays_to_image(out),)


def _decompositions(value) -> tuple:
    from relight_rt import Decomposition

    decs = tuple(value) if isinstance(value, (list, tuple)) else (value,)
    if not decs or not all(isinstance(d, Decomposition) for d in decs):
        raise RelightError("decomposition: expected the output of Relight Decompose")
    return decs


# ComfyUI keys every node class by one global name: these carry the package's prefix
NODES = {
    "RelightRTLoadModels": LoadRelightModels,
    "RelightRTDecompose": RelightDecompose,
    "RelightRTLight": RelightLight,
    "RelightRTRelight": Relight,
    "RelightRTPasses": RelightPasses,
    "RelightRTComposite": RelightComposite,
}
DISPLAY_NAMES = {
    "RelightRTLoadModels": "Load Relight Models (relight_rt)",
    "RelightRTDecompose": "Relight Decompose (relight_rt)",
    "RelightRTLight": "Relight Light (relight_rt)",
    "RelightRTRelight": "Relight (relight_rt)",
    "RelightRTPasses": "Relight Passes: normal map, albedo, shading (relight_rt)",
    "RelightRTComposite": "Relight Composite (relight_rt)",
}
