"""relight_rt.relight.transport_file: transport.npz at the network's resolution (float16) + crop geometry, and format
1."""

from __future__ import annotations

import numpy as np
import pytest

from relight_rt import RelightError
from relight_rt.image.crop import CropGeometry
from relight_rt.relight.transport_file import load_transport, save_transport


def geometry_and_transport(h=90, w=60, r=32, seed=0):
    mask = np.zeros((h, w), np.float32)
    mask[10:80, 15:45] = 1
    geo = CropGeometry.from_mask(mask, r)
    t = np.random.default_rng(seed).normal(0, 1, (r, r, 9)).astype(np.float32)
    return geo, t


def test_round_trip_at_the_network_size_and_the_photo_size(tmp_path):
    geo, t = geometry_and_transport()
    save_transport(tmp_path / "t.npz", t, geo)
    net = load_transport(tmp_path / "t.npz", network=True)
    np.testing.assert_allclose(net, t, rtol=2**-11, atol=0)  # float16 rounding, nothing else
    full = load_transport(tmp_path / "t.npz")
    assert full.shape == (90, 60, 9) and full.dtype == np.float32
    np.testing.assert_allclose(full, geo.to_input(t.astype(np.float16).astype(np.float32)), rtol=1e-6, atol=1e-7)


def test_format_1_files_are_still_read(tmp_path):
    old = np.random.default_rng(1).random((20, 30, 9)).astype(np.float32)
    np.savez_compressed(tmp_path / "old.npz", T=old)
    np.testing.assert_array_equal(load_transport(tmp_path / "old.npz"), old)
    with pytest.raises(RelightError, match="photo-size map only"):
        load_transport(tmp_path / "old.npz", network=True)


def test_bad_files(tmp_path):
    geo, t = geometry_and_transport()
    with pytest.raises(RelightError, match="not found"):
        load_transport(tmp_path / "none.npz")
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(RelightError, match="not a readable .npz"):
        load_transport(tmp_path / "junk.npz")
    np.savez(tmp_path / "other.npz", x=np.zeros(3))
    with pytest.raises(RelightError, match="expected the key 'transport'"):
        load_transport(tmp_path / "other.npz")
    save_transport(tmp_path / "t.npz", t, geo)
    with np.load(tmp_path / "t.npz") as z:
        parts = dict(z)
    np.savez(tmp_path / "box.npz", **{**parts, "box": np.array([0, 500, 0, 10])})
    with pytest.raises(RelightError, match="inconsistent crop geometry"):
        load_transport(tmp_path / "box.npz")
    np.savez(tmp_path / "nobox.npz", **{k: v for k, v in parts.items() if k != "box"})
    with pytest.raises(RelightError, match="incomplete crop geometry"):
        load_transport(tmp_path / "nobox.npz")
    with pytest.raises(RelightError, match=r"expected \(32, 32, 9\)"):
        save_transport(tmp_path / "x.npz", t[:16], geo)


def test_load_refuses_a_member_larger_than_the_npy_limit_before_inflating_it(tmp_path, monkeypatch):
    """A .npz is a zip: its members' sizes are checked before anything is decompressed (as load_npy does)."""
    import relight_rt.relight.transport_file as tf

    path = tmp_path / "t.npz"
    np.savez_compressed(path, T=np.zeros((64, 64, 9), np.float32))  # 147 KB inflated, a few hundred bytes stored
    assert tf.load_transport(path).shape == (64, 64, 9)
    monkeypatch.setattr(tf, "NPY_MAX_BYTES", 100_000)
    with pytest.raises(RelightError, match="larger than"):
        tf.load_transport(path)
