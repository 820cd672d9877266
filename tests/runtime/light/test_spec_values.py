"""LightSpec's own values (rotate, a photo's mask) and parse_light on names no file system takes: one RelightError
each (fuzz9 found TypeError, ValueError, OverflowError and OSError)."""

import numpy as np
import pytest

from relight_rt import LightSpec, RelightError
from relight_rt.light.spec import parse_light


@pytest.mark.parametrize("rotate", ["x", None, 10**400, np.array([1.0, 2.0]), 1j, float("nan"), float("inf")])
def test_a_rotation_that_is_no_angle_is_refused(rotate):
    with pytest.raises(RelightError, match="^rotate: expected"):
        LightSpec.preset("studio", rotate=rotate)
    with pytest.raises(RelightError, match="^rotate: expected"):
        LightSpec.preset("studio").rotated(rotate)


def test_rotations_that_are_angles_still_add():
    spec = LightSpec.preset("studio", rotate="30").rotated(np.float32(60))
    assert spec.rotate == 90.0 and isinstance(spec.rotate, float)
    with pytest.raises(RelightError, match="finite"):
        LightSpec.preset("studio", rotate=1e308).rotated(1e308)  # the sum overflows


def test_a_photo_mask_must_be_a_path(tmp_path):
    with pytest.raises(RelightError, match="light mask: expected a path, got int"):
        LightSpec.photo(tmp_path / "a.png", mask=3)
    with pytest.raises(RelightError, match="light mask: expected a path, got list"):
        LightSpec("photo", str(tmp_path / "a.png"), mask=["m.png"])
    assert LightSpec.photo(tmp_path / "a.png", mask=tmp_path / "m.png").mask == str(tmp_path / "m.png")


def test_a_name_longer_than_the_system_allows_is_no_file():
    with pytest.raises(RelightError, match="unknown light preset"):
        parse_light("a" * 5000)
    with pytest.raises(RelightError, match="not found"):
        parse_light("a" * 5000 + ".npy")
