"""sh.py split along its concepts: env maps in relight_rt.envmap, light files in relight_rt.lightfile (their
old names in relight_rt.sh are gone)."""

import numpy as np
import pytest

from relight_rt import envmap, lightfile, lights, sh


def test_moved_names_are_gone_from_sh():
    for name in ("load_envmap", "project_envmap", "envmap_from_light", "load_light", "save_light"):
        assert not hasattr(sh, name), name
    with pytest.raises(AttributeError, match="nope"):
        sh.nope  # noqa: B018


def test_sh_norm_is_the_basis_constant_of_each_function():
    # Y_k at a direction where every monomial of the table is 1 except 3z² − 1 = 2 and x² − y² = 1 - 0 ...
    # checked directly instead: Y_k(ω) / monomial_k(ω) at a generic direction equals NORM[k].
    w = np.array([0.48, 0.6, 0.64])
    x, y, z = w
    mono = np.array([1, y, z, x, x * y, y * z, 3 * z * z - 1, x * z, x * x - y * y])
    np.testing.assert_allclose(sh.basis(w) / mono, sh.NORM, rtol=1e-12)


def test_light_file_round_trip_and_envmap_projection_from_new_homes(tmp_path):
    light = lights.preset("rim")
    lightfile.save_light(tmp_path / "l.json", light)
    np.testing.assert_allclose(lightfile.load_light(tmp_path / "l.json"), light, atol=1e-12)
    env = envmap.envmap_from_light(light, 64).astype(np.float64)
    np.testing.assert_allclose(envmap.project_envmap(env), light, atol=2e-3)
