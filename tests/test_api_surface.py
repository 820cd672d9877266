"""The public names of relight_rt: a name that disappears breaks users, so it breaks this test."""

import relight_rt

PUBLIC = {
    "RelightError",
    "__version__",
    "Decomposition",
    "Relighter",
    "RelightResult",
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
}


def test_public_names_are_exported():
    missing = PUBLIC - set(relight_rt.__all__)
    assert not missing, f"public names missing from relight_rt.__all__: {sorted(missing)}"
    for name in relight_rt.__all__:
        assert hasattr(relight_rt, name), name


def test_relight_error_is_value_error():
    assert issubclass(relight_rt.RelightError, ValueError)


def test_version_is_a_string():
    parts = relight_rt.__version__.split(".")
    assert len(parts) >= 2 and all(p.isdigit() for p in parts[:2])
