"""The public names of relight_rt: a name that disappears breaks users, so it breaks this test."""

import relight_rt

PUBLIC = {
    "RelightError",
    "__version__",
    "Decomposition",
    "Relighter",
    "RelightResult",
    "open",
    "create_session",
    "find_models",
    "load_model",
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
    "linear_to_srgb",
    "srgb_to_linear",
    "ambient",
    "directional",
    "interpolate",
    "list_presets",
    "preset",
    "rotation_sequence",
    "sky",
    "color",
    "lights",
    "sh",
    "envmap",
    "lightfile",
    # the typed spine (docs/ARCHITECTURE.md)
    "Background",
    "KindSpec",
    "LightSpec",
    "Matter",
    "Model",
    "ModelConfig",
    "RuntimeConfig",
    "TensorSpec",
    "parse_background",
    "parse_light",
    "register_kind",
    "resolve_mask",
    "compositing",
    "config",
    "contract",
    "lightspec",
    "masks",
    "load_transport",
}


def test_public_names_are_exported():
    missing = PUBLIC - set(relight_rt.__all__)
    assert not missing, f"public names missing from relight_rt.__all__: {sorted(missing)}"
    unguarded = set(relight_rt.__all__) - PUBLIC
    assert not unguarded, f"new public names: add them to PUBLIC so their removal is caught: {sorted(unguarded)}"
    for name in relight_rt.__all__:
        assert hasattr(relight_rt, name), name


def test_relight_error_is_value_error():
    assert issubclass(relight_rt.RelightError, ValueError)


def test_version_is_a_string():
    parts = relight_rt.__version__.split(".")
    assert len(parts) >= 2 and all(p.isdigit() for p in parts[:2])


# The public modules' own surfaces: names users import from them (a rename breaks them, so it breaks this).
MODULE_SURFACE = {
    "relight_rt.video": {"FrameSource", "FrameSink", "LightSchedule", "RelighterEngine", "DVPModel", "Engine",
                         "FrameLayers", "VideoReport", "composite", "relight_frames", "relight_video", "resolve_light"},
    "relight_rt.contract": {"KINDS", "KindSpec", "ModelConfig", "TensorSpec", "config_from_metadata", "kind_spec",
                            "register_kind", "FORMAT_VERSION"},
    "relight_rt.lights": {"ambient", "directional", "interpolate", "list_presets", "preset", "rotation_sequence",
                          "sky"},
    "relight_rt.lightspec": {"LightSpec", "parse_light"},
    "relight_rt.compositing": {"Background", "parse_background", "fit_image", "over_box", "over_premultiplied"},
    "relight_rt.masks": {"Matter", "resolve_mask", "find_mask_file"},
    "relight_rt.config": {"RuntimeConfig"},
    "relight_rt.relighter": {"Decomposition", "Relighter", "RelightResult", "diffuse_batch"},
    "relight_rt.session": {"Model", "create_session", "load_model", "find_models", "validate_session"},
}


def test_public_modules_keep_their_names():
    import importlib

    for module, names in MODULE_SURFACE.items():
        mod = importlib.import_module(module)
        missing = sorted(n for n in names if not hasattr(mod, n))
        assert not missing, f"{module} lost {missing}"


def test_what_public_functions_return_is_exported():
    """load_model returns a Model with a ModelConfig; both are importable from the package itself."""
    assert relight_rt.Model is relight_rt.session.Model
    assert relight_rt.ModelConfig is relight_rt.contract.ModelConfig
    assert "Model" in relight_rt.__all__ and "ModelConfig" in relight_rt.__all__


def test_relight_has_one_return_type():
    import inspect

    sig = inspect.signature(relight_rt.Relighter.relight)
    assert "return_layers" not in sig.parameters
    assert sig.return_annotation in ("np.ndarray", relight_rt.Relighter.relight.__annotations__["return"])


def test_the_public_modules_are_listed_as_modules():
    """relight_rt.__getattr__ imports a public module by itself (not every home): its list must be exact."""
    import types

    import relight_rt

    modules = {n for n in relight_rt.__all__ if isinstance(getattr(relight_rt, n), types.ModuleType)}
    assert modules == set(relight_rt._MODULES)
