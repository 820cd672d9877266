"""export.dataset: the reference's stage-1 layout, light folders and stage-2 photos round-trip."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from export import dataset
from relight_rt import RelightError


def _sample(h: int = 6, w: int = 5, seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    return {
        "albedo": rng.integers(0, 256, (h, w, 3)).astype(np.float32) / 255.0,
        "mask": (rng.random((h, w)) > 0.3).astype(np.float32),
        "skin": (rng.random((h, w)) > 0.5).astype(np.float32),
        "transport": rng.normal(size=(h, w, 9)).astype(np.float32),
    }


@pytest.mark.parametrize("shape", [(6, 5), (16, 16)])
def test_sample_round_trip(tmp_path, shape):
    s = _sample(*shape)
    dataset.write_sample(tmp_path, "s0", **s)
    assert dataset.list_samples(tmp_path) == ["s0"]
    back = dataset.read_sample(tmp_path, "s0")
    np.testing.assert_array_equal(back["albedo"], s["albedo"])
    np.testing.assert_array_equal(back["mask"], s["mask"])
    np.testing.assert_array_equal(back["skin"], s["skin"])
    np.testing.assert_array_equal(back["transport"], s["transport"])
    assert back["transport"].dtype == np.float32


def test_sample_is_bgr_on_disk(tmp_path):
    albedo = np.zeros((4, 4, 3), np.float32)
    albedo[..., 0] = 1.0  # pure red in RGB
    dataset.write_sample(tmp_path, "red", albedo, np.ones((4, 4)), np.zeros((4, 4)), np.zeros((4, 4, 9)))
    raw = cv2.imread(str(tmp_path / "red_tex.png"), cv2.IMREAD_UNCHANGED)
    assert raw.shape == (4, 4, 3)
    assert (raw[..., 2] == 255).all() and (raw[..., :2] == 0).all()  # red lives in OpenCV's last channel
    mask = cv2.imread(str(tmp_path / "red_mask.png"), cv2.IMREAD_UNCHANGED)
    assert mask.shape == (4, 4) and mask.dtype == np.uint8 and (mask == 255).all()
    with np.load(tmp_path / "red_transport.npz", allow_pickle=False) as z:
        assert list(z.keys()) == ["T"]


def test_reads_reference_sample_layout(reference_dir, tmp_path):
    """The reference's own sample (BGR tex, 1-channel masks) reads with the same RGB meaning."""
    src = reference_dir / "train_human_1st"
    for suffix in ("tex", "mask", "parsing"):
        img = cv2.imread(str(src / f"sample000_{suffix}.png"), cv2.IMREAD_UNCHANGED)
        cv2.imwrite(str(tmp_path / f"ref_{suffix}.png"), img[::8, ::8])
    np.savez(tmp_path / "ref_transport.npz", T=np.zeros((128, 128, 9), np.float32))
    back = dataset.read_sample(tmp_path, "ref")
    raw = cv2.imread(str(src / "sample000_tex.png"))[::8, ::8]
    np.testing.assert_array_equal(back["albedo"], raw[:, :, ::-1] / np.float32(255))
    assert set(np.unique(back["mask"])) <= {0.0, 1.0}


def test_incomplete_samples_are_not_listed(tmp_path):
    dataset.write_sample(tmp_path, "a", **_sample())
    dataset.write_sample(tmp_path, "b", **_sample())
    (tmp_path / "b_transport.npz").unlink()
    assert dataset.list_samples(tmp_path) == ["a"]
    with pytest.raises(RelightError, match="missing file"):
        dataset.read_sample(tmp_path, "b")


def test_write_sample_rejects_bad_shapes(tmp_path):
    s = _sample()
    with pytest.raises(RelightError, match=r"expected \(H, W, 3\)"):
        dataset.write_sample(tmp_path, "x", s["albedo"][..., :2], s["mask"], s["skin"], s["transport"])
    with pytest.raises(RelightError, match="transport"):
        dataset.write_sample(tmp_path, "x", s["albedo"], s["mask"], s["skin"], s["transport"][..., :4])
    with pytest.raises(RelightError, match="mask"):
        dataset.write_sample(tmp_path, "x", s["albedo"], s["mask"][:2], s["skin"], s["transport"])
    assert list(tmp_path.iterdir()) == []


def test_lights_round_trip_bgr(tmp_path):
    rgb = np.arange(27, dtype=np.float32).reshape(9, 3)
    dataset.write_light(tmp_path, "a", rgb)
    dataset.write_light(tmp_path, "b", -rgb)
    np.testing.assert_array_equal(np.load(tmp_path / "a.npy"), rgb[:, ::-1])
    lights = dataset.read_lights(tmp_path)
    assert lights.shape == (2, 9, 3) and lights.dtype == np.float32
    np.testing.assert_array_equal(lights[0], rgb)
    np.testing.assert_array_equal(dataset.read_light(tmp_path, "b"), -rgb)


def test_reads_reference_lights(reference_dir):
    lights = dataset.read_lights(reference_dir / "lights")
    raw = np.load(reference_dir / "lights" / "cluster08.npy")
    assert lights.shape == (10, 9, 3)
    np.testing.assert_allclose(lights[0], raw[:, ::-1])


def test_bad_lights(tmp_path):
    with pytest.raises(RelightError, match=r"\(9, 3\)"):
        dataset.write_light(tmp_path, "x", np.zeros((9, 4)))
    with pytest.raises(RelightError, match="NaN"):
        dataset.write_light(tmp_path, "x", np.full((9, 3), np.nan))
    np.save(tmp_path / "bad.npy", np.zeros(5))
    with pytest.raises(RelightError, match=r"\(9, 3\)"):
        dataset.read_lights(tmp_path)


def test_photo_round_trip(tmp_path):
    rng = np.random.default_rng(1)
    photo = rng.integers(0, 256, (8, 7, 3)).astype(np.uint8)
    diffuse = rng.random((8, 7, 3)).astype(np.float32)
    mask = np.ones((8, 7), np.float32)
    light = rng.normal(size=(9, 3)).astype(np.float32)
    for j in (0, 1):
        dataset.write_photo(tmp_path, dataset.photo_name("s0001", j), photo, diffuse, mask, light)
    assert dataset.list_photos(tmp_path) == ["s0001__L0", "s0001__L1"]
    back = dataset.read_photo(tmp_path, "s0001__L1")
    np.testing.assert_array_equal(back["photo"], photo / np.float32(255))
    np.testing.assert_allclose(back["diffuse"], diffuse, atol=0.5 / 255 + 1e-6)
    np.testing.assert_array_equal(back["light"], light)
    np.testing.assert_array_equal(np.load(tmp_path / "s0001__L1_light.npy"), light[:, ::-1])
    assert dataset.split_photo_name("s0001__L1") == ("s0001", 1)
    with pytest.raises(RelightError, match="SUBJECT__L"):
        dataset.write_photo(tmp_path, "nolight", photo, diffuse, mask, light)
