"""relight_rt: monocular full-body human relighting as a lean ONNX runtime.

After Tajima, Kanamori & Endo, "Relighting Humans in the Wild: Monocular Full-Body Human
Relighting with Domain Adaptation" (Pacific Graphics 2021). Conventions (SH order, frame,
colour order) are those of DESIGN.md §3: RGB, real orthonormal degree-2 SH, +x toward the camera.
"""

from . import color, lights, sh
from ._errors import RelightError
from ._version import __version__
from .color import linear_to_srgb, srgb_to_linear
from .lights import ambient, directional, interpolate, list_presets, preset, rotation_sequence, sky
from .relighter import Decomposition, Relighter, RelightResult
from .session import create_session, find_models, load_model
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

__all__ = [
    "RelightError",
    "__version__",
    # relighting
    "Decomposition",
    "Relighter",
    "RelightResult",
    "create_session",
    "find_models",
    "load_model",
    # modules
    "color",
    "lights",
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
