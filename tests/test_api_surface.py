"""The public names of relight_rt: a name that disappears breaks users, so it breaks this test."""

import relight_rt

PUBLIC = {
    "RelightError",
    "__version__",
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
