"""benchmarks/heldout_steps.py (contrast27): its transport mixes, its switches of the product's steps, its figures."""

from types import SimpleNamespace

import numpy as np
import pytest


@pytest.fixture(scope="module")
def hs(load_benchmark):
    return load_benchmark("heldout_steps")


def _transports(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    true, est = rng.normal(size=(2, 5, 7, 9)).astype(np.float32)
    true[..., 0], est[..., 0] = rng.uniform(1, 3, (2, 5, 7))
    return true, est


def test_mixed_transport_takes_occlusion_from_one_and_shape_from_the_other(hs):
    true, est = _transports()
    np.testing.assert_array_equal(hs.mixed_transport(true, est, "true"), true)
    np.testing.assert_array_equal(hs.mixed_transport(true, est, "est"), est)
    occ = hs.mixed_transport(true, est, "occlusion")
    np.testing.assert_allclose(occ[..., 0], true[..., 0])
    np.testing.assert_allclose(occ[..., 1:] / occ[..., :1], est[..., 1:] / est[..., :1], rtol=1e-5)
    shape = hs.mixed_transport(true, est, "shape")
    np.testing.assert_allclose(shape[..., 0], est[..., 0])
    np.testing.assert_allclose(shape[..., 1:] / shape[..., :1], true[..., 1:] / true[..., :1], rtol=1e-5)


def test_every_step_is_switched_off_and_back(hs):
    from relight_rt.relight import compose, factor, shadow_fill, strength

    watched = [(strength, "BAND_GAIN"), (strength, "EXPLAIN_SHARE"), (strength, "EXPLAIN_SHADOW_SHARE"),
               (factor, "refit_light"), (factor, "face_refit"), (factor, "_OWN_FLOOR"), (factor, "shaded_skin"),
               (factor.Factor, "cast"), (shadow_fill.ShadowFill, "shadow_weight"), (compose, "steady_chroma"),
               (compose, "keep_neutral"), (compose, "shoulder")]
    before = [getattr(o, n) for o, n in watched]
    find = object()
    fake = SimpleNamespace(_network=SimpleNamespace(stage2="graph"), _faces=SimpleNamespace(find=find), face_pass=True)
    with hs.switched_off(fake, hs.STEPS):
        assert all(getattr(o, n) is not b for (o, n), b in zip(watched, before, strict=True))
        assert fake._network.stage2 is None and fake._faces.find is not find and fake.face_pass is False
        assert strength.BAND_GAIN == (1.0, 1.0, 1.0)
    assert all(getattr(o, n) is b for (o, n), b in zip(watched, before, strict=True))
    assert fake._network.stage2 == "graph" and fake._faces.find is find and fake.face_pass is True
    with hs.switched_off(fake, []):
        assert all(getattr(o, n) is b for (o, n), b in zip(watched, before, strict=True))
    with pytest.raises(ValueError, match="unknown steps"), hs.switched_off(fake, ["no such step"]):
        pass


def test_figures_read_the_truth_as_1_and_the_input_as_0(hs):
    rng = np.random.default_rng(1)
    mask = np.ones((16, 16), np.float32)
    img_i = rng.uniform(0.05, 0.9, (16, 16, 3)).astype(np.float32)
    img_j = rng.uniform(0.05, 0.9, (16, 16, 3)).astype(np.float32)
    src, dst = (img_i, mask, None), (img_j, mask, None)
    same = hs.figures(img_j, src, dst)
    assert same["slope"] == pytest.approx(1) and same["corr"] == pytest.approx(1) and same["rmse"] == 0
    assert same["slope_lit"] == pytest.approx(1) and same["dark_share"] == 0
    assert hs.figures(img_i, src, dst)["slope"] == pytest.approx(0, abs=1e-6)
    half = img_i * np.sqrt(img_j / img_i)  # half the log change
    assert hs.figures(half, src, dst)["slope"] == pytest.approx(0.5, abs=0.02)
