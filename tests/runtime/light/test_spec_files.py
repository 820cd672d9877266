"""relight_rt.light.spec: which kind of light an image file is (an equirectangular map or a photo of a person)."""

import cv2
import numpy as np
import pytest

from relight_rt.light.spec import parse_light


@pytest.mark.parametrize(
    ("name", "width", "height", "source"),
    [
        ("pano.png", 64, 32, "envmap"),  # exactly 2:1
        ("odd.png", 63, 32, "envmap"),  # within a pixel of 2:1
        ("wide.jpg", 65, 32, "envmap"),
        # these passed for panoramas when the kind was read from a 1/8 decode (rounded to 3 x 2, 7 x 4, 7 x 4)
        ("small.png", 30, 20, "photo"),
        ("mid.png", 60, 35, "photo"),
        ("small.jpg", 50, 30, "photo"),
        ("photo.png", 48, 64, "photo"),
    ],
)
def test_kind_from_the_header_size(tmp_path, name, width, height, source):
    path = tmp_path / name
    cv2.imwrite(str(path), np.full((height, width, 3), 128, np.uint8))
    assert parse_light(str(path)).source == source
