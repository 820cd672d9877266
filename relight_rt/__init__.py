"""relight_rt: monocular full-body human relighting as a lean ONNX runtime.

After Tajima, Kanamori & Endo, "Relighting Humans in the Wild: Monocular Full-Body Human
Relighting with Domain Adaptation" (Pacific Graphics 2021). Conventions (SH order, frame,
colour order) are those of DESIGN.md §3: RGB, real orthonormal degree-2 SH, +x toward the camera.
"""

from . import color, compositing, config, contract, lights, lightspec, masks, sh
from ._errors import RelightError
from ._version import __version__
from .color import linear_to_srgb, srgb_to_linear
from .compositing import Background, parse_background
from .config import RuntimeConfig
from .contract import KindSpec, ModelConfig, TensorSpec, register_kind
from .lights import ambient, directional, interpolate, list_presets, preset, rotation_sequence, sky
from .lightspec import LightSpec, parse_light
from .masks import Matter, resolve_mask
from .relighter import Decomposition, Relighter, RelightResult
from .session import Model, create_session, find_models, load_model
from .sh import (
    basis,
    check_light,
    cosine_lobe,
    directions_envmap,
    envmap_from_light,
    irradiance,
    load_envmap,
    load_light,
    project_envmap,
    render_sphere,
    rotate,
    rotate_z,
    rotation_matrix,
    save_light,
    shading,
    solid_angles_envmap,
)
from .transport_file import load_transport

__all__ = [
    "RelightError",
    "__version__",
    # relighting
    "Decomposition",
    "Relighter",
    "RelightResult",
    "RuntimeConfig",
    "create_session",
    "find_models",
    "load_model",
    "Model",
    "load_transport",
    # the model contract
    "KindSpec",
    "ModelConfig",
    "TensorSpec",
    "register_kind",
    # lights, masks and backgrounds
    "LightSpec",
    "parse_light",
    "Matter",
    "resolve_mask",
    "Background",
    "parse_background",
    # modules
    "color",
    "compositing",
    "config",
    "contract",
    "lights",
    "lightspec",
    "masks",
    "sh",
    # spherical harmonics and environment maps
    "basis",
    "check_light",
    "cosine_lobe",
    "directions_envmap",
    "envmap_from_light",
    "irradiance",
    "load_envmap",
    "load_light",
    "project_envmap",
    "render_sphere",
    "rotate",
    "rotate_z",
    "rotation_matrix",
    "save_light",
    "shading",
    "solid_angles_envmap",
    # colour
    "linear_to_srgb",
    "srgb_to_linear",
    # parametric lights
    "ambient",
    "directional",
    "interpolate",
    "list_presets",
    "preset",
    "rotation_sequence",
    "sky",
]
