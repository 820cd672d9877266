"""The old module name relight_rt.background still imports, warns, and is relight_rt.scene_light itself."""

import importlib
import sys

import pytest


def test_background_module_is_scene_light_with_a_warning():
    sys.modules.pop("relight_rt.background", None)
    with pytest.warns(DeprecationWarning, match="scene_light"):
        old = importlib.import_module("relight_rt.background")
    import relight_rt.scene_light as new

    assert old is new
    assert old.light_from_background is new.light_from_background
