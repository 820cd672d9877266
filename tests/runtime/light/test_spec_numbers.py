"""LightSpec.from_numbers: a light as 27 numbers (a request, a text field), the one parser the studio uses."""

import numpy as np
import pytest

from relight_rt import LightSpec, RelightError


def test_27_numbers_are_coefficient_major_rgb():
    spec = LightSpec.from_numbers(list(range(27)), rotate=0.0)
    assert spec.source == "sh"
    light = spec.resolve()
    assert light.shape == (9, 3) and light.dtype == np.float32
    assert light[1, 0] == 3 and light[8, 2] == 26  # index 3k + c
    np.testing.assert_array_equal(LightSpec.from_numbers(np.arange(27).reshape(9, 3)).resolve(), light)


@pytest.mark.parametrize(
    ("value", "match"),
    [([1.0] * 26, "27 numbers"), ("studio", "27 numbers"), ([[1, 2], [3]], "27 numbers"),
     ([10**400] * 27, "27 numbers"),
     ([float("inf")] * 27, "finite"), ([2e4] * 27, r"\|value\| <= 10000")],
)
def test_bad_numbers_are_refused(value, match):
    with pytest.raises(RelightError, match=match):
        LightSpec.from_numbers(value)
