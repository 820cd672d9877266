"""relight_rt: monocular full-body human relighting as a lean ONNX runtime.

After Tajima, Kanamori & Endo, "Relighting Humans in the Wild: Monocular Full-Body Human
Relighting with Domain Adaptation" (Pacific Graphics 2021). Conventions (SH order, frame,
colour order) are those of DESIGN.md §3: RGB, real orthonormal degree-2 SH, +x toward the camera.

``relight_rt.open(config)`` gives a :class:`Relighter`; everything else lives in the modules listed below
(``relight_rt.sh.rotate``, ``relight_rt.engine.session.load_model``, ...).
"""

from ._version import __version__

# The public names, each with its home ("module:attribute"; "module" for a name that is a module): the one
# list. ``__all__`` is read from it, and so is the loader below: a name is imported at its first use, not at
# ``import relight_rt``
# (the command line must install its signal handling before numpy, OpenCV and onnxruntime load: ~0.3 s in which
# Ctrl-C gave a traceback and SIGTERM no message; issue 35 item 16), and only its own module is imported.
_PUBLIC = {
    "RelightError": "engine.errors:RelightError",
    "open": "builder:open",
    "Relighter": "relight.relighter:Relighter",
    "Decomposition": "relight.decomposition:Decomposition",
    "RelightResult": "relight.decomposition:RelightResult",
    "RuntimeConfig": "engine.config:RuntimeConfig",
    "LightSpec": "light.spec:LightSpec",
    "Background": "image.compositing:Background",
    "Matter": "person.masks:Matter",
    "preset": "light.presets:preset",
    "load_light": "light.files:load_light",
    "save_light": "light.files:save_light",
    "color": "image.color",
    "compositing": "image.compositing",
    "config": "engine.config",
    "contract": "engine.contract",
    "envmap": "light.envmap",
    "lightfile": "light.files",
    "lights": "light.presets",
    "lightspec": "light.spec",
    "masks": "person.masks",
    "scene": "apps.scene",
    "sh": "light.sh",
}

__all__ = ["__version__", *_PUBLIC]


def __getattr__(name: str):
    # Only the public names are loaded here. Any other name (``from . import _faces`` inside a module asks the
    # package first) is left to the import system, which imports just that submodule.
    if name not in _PUBLIC:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import importlib

    module, _, attribute = _PUBLIC[name].partition(":")
    value = importlib.import_module(f"{__name__}.{module}")
    if attribute:
        value = getattr(value, attribute)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
