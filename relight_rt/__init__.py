"""relight_rt: monocular full-body human relighting as a lean ONNX runtime.

After Tajima, Kanamori & Endo, "Relighting Humans in the Wild: Monocular Full-Body Human
Relighting with Domain Adaptation" (Pacific Graphics 2021). Conventions (SH order, frame,
colour order) are those of DESIGN.md §3: RGB, real orthonormal degree-2 SH, +x toward the camera.
"""

from typing import TYPE_CHECKING

from ._version import __version__

if TYPE_CHECKING:  # what the lazy loading below provides, for type checkers and readers
    from . import color, compositing, config, contract, envmap, lightfile, lights, lightspec, masks, sh
    from ._errors import RelightError
    from .builder import open
    from .color import linear_to_srgb, srgb_to_linear
    from .compositing import Background, parse_background
    from .config import RuntimeConfig
    from .contract import KindSpec, ModelConfig, TensorSpec, register_kind
    from .envmap import directions_envmap, envmap_from_light, load_envmap, project_envmap, solid_angles_envmap
    from .lightfile import load_light, save_light
    from .lights import ambient, directional, interpolate, list_presets, preset, rotation_sequence, sky
    from .lightspec import LightSpec, parse_light
    from .masks import Matter, resolve_mask
    from .relighter import Decomposition, Relighter, RelightResult
    from .session import Model, create_session, find_models, load_model
    from .sh import (
        basis,
        check_light,
        cosine_lobe,
        irradiance,
        render_sphere,
        rotate,
        rotate_z,
        rotation_matrix,
        shading,
    )
    from .transport_file import load_transport


__all__ = [
    "RelightError",
    "__version__",
    # relighting
    "Decomposition",
    "Relighter",
    "RelightResult",
    "open",
    "RuntimeConfig",
    "create_session",
    "find_models",
    "load_model",
    "Model",
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
    "envmap",
    "lightfile",
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
    # decompose's files
    "load_transport",
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

# The public names are loaded at their first use, not at ``import relight_rt``: the command line must install
# its signal handling before numpy, OpenCV and onnxruntime load (~0.3 s in which Ctrl-C gave a traceback and
# SIGTERM no message; issue 35 item 16). The first access of any name imports these modules, in this order, and
# takes each name of ``__all__`` from the first of them that defines it (``__all__`` is the one list).
_HOMES = ("_errors", "color", "compositing", "config", "contract", "envmap", "lightfile", "lights", "lightspec",
          "masks", "sh", "relighter", "builder", "session", "transport_file")
_state = {"loading": False}
# the public names that are modules (tests/runtime/test_api_surface.py checks the list)
_MODULES = frozenset(
    ("color", "compositing", "config", "contract", "envmap", "lightfile", "lights", "lightspec", "masks", "sh")
)


def _load_public_names() -> None:
    import importlib

    if _state["loading"]:  # a module being loaded asks for a sibling: the import system fetches it itself
        return
    _state["loading"] = True
    try:
        homes = [vars(importlib.import_module(f"{__name__}.{module}")) for module in _HOMES]
        for name in __all__:  # the modules of __all__ are attributes of the package once imported
            found = [home[name] for home in homes if name in home]
            if name not in globals() and found:
                globals()[name] = found[0]
    finally:
        _state["loading"] = False


def __getattr__(name: str):
    # Only the public names load the homes. Any other name (``from . import _faces`` inside a module asks the
    # package first) and a public module (``from . import sh``) is left to the import system, which imports just
    # that submodule: loading every home there would run into the module still being imported (a circle).
    if name not in __all__:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    if name in _MODULES:
        import importlib

        return importlib.import_module(f"{__name__}.{name}")
    _load_public_names()
    try:
        return globals()[name]
    except KeyError:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None


def __dir__() -> list[str]:
    _load_public_names()
    return sorted(globals())
