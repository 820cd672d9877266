"""The public names of relight_rt: a name that disappears, or one that appears without review, breaks this test,
and each is what its module defines (issue 47: about 20 names, from one name-to-module table)."""

import importlib
import inspect
import types

import numpy as np
from _graphs import OWN_LIGHT, models_dir, person  # noqa: F401  (models_dir: the fixture)

import relight_rt

# each public name and its home ("module:attribute"; "module": the name is that module)
PUBLIC = {
    "__version__": "_version:__version__",
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


def test_the_public_names_are_these_and_few():
    assert sorted(relight_rt.__all__) == sorted(PUBLIC)
    assert len(relight_rt.__all__) <= 25 and len(set(relight_rt.__all__)) == len(relight_rt.__all__)


def test_each_public_name_is_what_its_module_defines():
    for name, home in PUBLIC.items():
        value = getattr(relight_rt, name)
        module, _, attribute = home.partition(":")
        if not attribute:
            assert isinstance(value, types.ModuleType) and value is importlib.import_module(f"relight_rt.{module}")
        else:
            assert attribute == name
            assert value is getattr(importlib.import_module(f"relight_rt.{module}"), name), name
    assert set(PUBLIC) <= set(dir(relight_rt))


def test_other_names_are_not_reached_through_the_package():
    for gone in ("load_model", "rotate_z", "directional", "parse_light", "composite", "relight_layers"):
        assert not hasattr(relight_rt, gone), gone


def test_relight_error_is_value_error():
    assert issubclass(relight_rt.RelightError, ValueError)


def test_version_is_a_string():
    parts = relight_rt.__version__.split(".")
    assert len(parts) >= 2 and all(p.isdigit() for p in parts[:2])


def test_relight_returns_the_image_and_layers_gives_the_result(models_dir):  # noqa: F811
    r = relight_rt.Relighter(relight_rt.RuntimeConfig(models=models_dir, device="cpu"))
    img, mask = person(60, 40, box=(10, 50, 10, 30))
    assert "layers" not in inspect.signature(r.relight).parameters
    out = r.relight(img, OWN_LIGHT, mask=mask)
    assert isinstance(out, np.ndarray) and out.shape == img.shape
    result = r.layers(img, OWN_LIGHT, mask=mask)
    assert isinstance(result, relight_rt.RelightResult) and set(result.layers) >= {"albedo", "shading", "relit"}
    np.testing.assert_array_equal(result.image, out)


# The public modules' own surfaces: names users import from them (a rename breaks them, so it breaks this).
MODULE_SURFACE = {
    "relight_rt.video.job": {"FrameSource", "FrameSink", "LightSchedule", "RelighterEngine", "DVPModel", "Engine",
                             "FrameLayers", "VideoReport", "composite", "relight_frames", "relight_video",
                             "resolve_light", "relight_clip"},
    "relight_rt.contract": {"KINDS", "KindSpec", "ModelConfig", "TensorSpec", "config_from_metadata", "kind_spec",
                            "register_kind", "FORMAT_VERSION"},
    "relight_rt.lights": {"ambient", "directional", "interpolate", "list_presets", "preset", "rotation_sequence",
                          "sky"},
    "relight_rt.lightspec": {"LightSpec", "parse_light"},
    "relight_rt.compositing": {"Background", "parse_background", "fit_image", "over_box", "over_premultiplied"},
    "relight_rt.masks": {"Matter", "resolve_mask", "find_mask_file"},
    "relight_rt.config": {"RuntimeConfig"},
    "relight_rt.relight.relighter": {"Decomposition", "Relighter", "RelightResult", "diffuse_batch", "compose_step"},
    "relight_rt.builder": {"open", "person_matter", "video_matter"},
    "relight_rt.scene": {"composite", "scene_lighting", "relight_person", "place", "camera_match", "shadows",
                         "shade", "grade", "parse_position"},
    "relight_rt.relight.look": {"SKIN_CHROMA", "skin_chroma", "shaded_skin", "knee", "shoulder", "dark_colour",
                                "steady_chroma", "tint_range", "neutral_darks", "keep_neutral", "NeutralDarks"},
    "relight_rt.relight.decomposition": {"Decomposition", "RelightResult", "diffuse_batch", "intrinsic_layers"},
    "relight_rt.engine.session": {"Model", "create_session", "load_model", "find_models", "validate_session"},
    "relight_rt.sh": {"basis", "check_light", "cosine_lobe", "irradiance", "render_sphere", "rotate", "rotate_z",
                      "rotation_matrix", "shading"},
    "relight_rt.envmap": {"directions_envmap", "envmap_from_light", "load_envmap", "project_envmap",
                          "solid_angles_envmap"},
    "relight_rt.color": {"linear_to_srgb", "srgb_to_linear"},
    "relight_rt.relight.transport_file": {"load_transport"},
}


def test_public_modules_keep_their_names():
    for module, names in MODULE_SURFACE.items():
        public = module.removeprefix("relight_rt.")
        # a public module is reached as users reach it, through the package (relight_rt.sh is light/sh.py)
        mod = getattr(relight_rt, public) if public in relight_rt.__all__ else importlib.import_module(module)
        missing = sorted(n for n in names if not hasattr(mod, n))
        assert not missing, f"{module} lost {missing}"
