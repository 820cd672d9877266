"""relight_rt.image.crop: the reference's crop/pad/resize, exactly, and its inverse."""

import cv2
import numpy as np
import pytest

from relight_rt import RelightError
from relight_rt.image import crop as crop_module
from relight_rt.image.crop import CropGeometry


def reference_square(img, mask, size):
    """The reference path written out plainly (Tajima et al.'s published preprocessing, DESIGN.md §4):
    bbox of mask > 0, rows [min-5, max+5) clipped, zero-pad the short side centred ((long-short)//2
    before), cv2.resize with its default INTER_LINEAR."""
    ys, xs = np.nonzero(mask > 0)
    y0, y1 = max(ys.min() - 5, 0), min(ys.max() + 5, img.shape[0])
    x0, x1 = max(xs.min() - 5, 0), min(xs.max() + 5, img.shape[1])
    crop = img[y0:y1, x0:x1]
    h, w = crop.shape[:2]
    side = max(h, w)
    pad = (side - min(h, w)) // 2
    sq = np.zeros((side, side) + img.shape[2:], np.float32)
    if h > w:
        sq[:, pad : pad + w] = crop
    else:
        sq[pad : pad + h, :] = crop
    return cv2.resize(sq, (size, size)), (y0, y1, x0, x1)


def blob(h, w, box):
    m = np.zeros((h, w), np.float32)
    y0, y1, x0, x1 = box
    m[y0:y1, x0:x1] = 1
    return m


@pytest.mark.parametrize(
    ("shape", "box"),
    [
        ((200, 120), (30, 170, 40, 90)),
        ((90, 300), (10, 60, 20, 280)),
        ((64, 64), (0, 64, 3, 50)),
        ((50, 50), (0, 50, 0, 50)),
    ],
)
def test_reference_mode_matches_the_reference_path_exactly(shape, box):
    rng = np.random.default_rng(1)
    img = rng.random(shape + (3,)).astype(np.float32)
    mask = blob(*shape, box)
    want, want_box = reference_square(img, mask, 64)
    geom = CropGeometry.from_mask(mask, 64, mode="reference")
    assert geom.box == tuple(int(v) for v in want_box)
    np.testing.assert_array_equal(geom.to_network(img), want)
    want_m, _ = reference_square(mask, mask, 64)
    np.testing.assert_array_equal(geom.to_network(mask), want_m)


def test_margin_is_5_before_and_4_after_like_the_reference(monkeypatch):
    geom = CropGeometry.from_mask(blob(100, 100, (40, 60, 30, 50)), 64, mode="reference")
    assert geom.box == (35, 64, 25, 54)  # last mask row 59 → exclusive end 64
    monkeypatch.setattr(crop_module, "SYMMETRIC_CROP", False)
    assert CropGeometry.from_mask(blob(100, 100, (40, 60, 30, 50)), 64).box == (35, 64, 25, 54)
    monkeypatch.setattr(crop_module, "SYMMETRIC_CROP", True)  # quality: 5 px on both sides
    assert CropGeometry.from_mask(blob(100, 100, (40, 60, 30, 50)), 64).box == (35, 65, 25, 55)
    assert CropGeometry.from_mask(blob(100, 100, (40, 60, 30, 50)), 64, mode="reference").box == (35, 64, 25, 54)


@pytest.mark.parametrize("shape", [(200, 120), (201, 97), (90, 300), (64, 64), (120, 77)])
@pytest.mark.parametrize("symmetric", [False, True])
def test_a_mirrored_mask_is_cropped_to_the_mirrored_square(shape, symmetric, monkeypatch):
    """SYMMETRIC_CROP: a photo's mirror image reaches the network as the photo's square mirrored, to float rounding
    (the margin alike on both sides, left-right padding equal); the reference's crop sits a pixel apart on some."""
    monkeypatch.setattr(crop_module, "SYMMETRIC_CROP", symmetric)
    rng = np.random.default_rng(shape[0] * shape[1])
    exact = []
    for _ in range(12):
        h, w = shape
        y0, x0 = int(rng.integers(0, h // 3)), int(rng.integers(0, w // 3))
        box = (y0, int(rng.integers(y0 + 5, h + 1)), x0, int(rng.integers(x0 + 5, w + 1)))
        img = rng.random(shape + (3,)).astype(np.float32)
        mask = blob(h, w, box)
        geom = CropGeometry.from_mask(mask, 64)
        mir = CropGeometry.from_mask(mask[:, ::-1], 64)
        same = np.abs(mir.to_network(img[:, ::-1]) - geom.to_network(img)[:, ::-1]).max() < 1e-5
        exact.append(same)
    if symmetric:
        assert all(exact)
    else:
        assert not all(exact) or shape == (64, 64)


def test_padding_is_centred_on_the_short_side(monkeypatch):
    monkeypatch.setattr(crop_module, "SYMMETRIC_CROP", False)
    tall = CropGeometry.from_mask(blob(300, 300, (10, 210, 100, 150)), 64)  # crop 209 x 59
    assert tall.crop_shape == (209, 59) and tall.side == 209 and tall.offset == (0, 75)
    wide = CropGeometry.from_mask(blob(300, 300, (100, 150, 10, 210)), 64)
    assert wide.offset == (75, 0)


def test_a_body_cut_by_the_photo_border_stays_cut_by_the_square_border():
    # a waist-up crop wider than tall, cut by the bottom border: the padding goes on top only
    wide = CropGeometry.from_mask(blob(200, 300, (80, 200, 20, 280)), 64)  # crop rows 75-200, cols 15-284
    h, w = wide.crop_shape
    assert wide.offset == (w - h, 0)
    square = wide.to_network(np.ones((200, 300), np.float32))
    assert square[-1].min() > 0.99 and square[0].max() == 0  # the person reaches the square's bottom edge
    # cut at the top (a person entering from above), and at the left / right of a tall crop
    assert CropGeometry.from_mask(blob(200, 300, (0, 120, 20, 280)), 64).offset == (0, 0)
    left = CropGeometry.from_mask(blob(300, 200, (20, 280, 0, 100)), 64)
    right = CropGeometry.from_mask(blob(300, 200, (20, 280, 100, 200)), 64)
    assert left.offset == (0, 0) and right.offset == (0, right.side - right.crop_shape[1])
    # cut on both sides, or on neither: centred; the reference path is always centred
    both = CropGeometry.from_mask(blob(200, 300, (0, 200, 100, 150)), 64)
    assert both.offset == (0, (both.side - both.crop_shape[1]) // 2)
    ref = CropGeometry.from_mask(blob(200, 300, (80, 200, 20, 280)), 64, mode="reference")
    assert ref.offset == ((ref.side - ref.crop_shape[0]) // 2, 0)


def test_quality_mode_uses_area_when_shrinking():
    rng = np.random.default_rng(2)
    img = rng.random((256, 256, 3)).astype(np.float32)
    mask = blob(256, 256, (5, 252, 5, 252))
    geom = CropGeometry.from_mask(mask, 64)
    assert geom.side == 256
    np.testing.assert_allclose(geom.to_network(img), cv2.resize(img, (64, 64), interpolation=cv2.INTER_AREA), atol=1e-6)


@pytest.mark.parametrize("channels", [None, 1, 3, 4, 9])
@pytest.mark.parametrize("shape", [(150, 100), (60, 40), (64, 64)])
def test_round_trip_of_a_smooth_image(shape, channels):
    h, w = shape
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    base = 0.5 + 0.25 * np.sin(yy / 17) * np.cos(xx / 13)
    img = base if channels is None else np.repeat(base[..., None], channels, axis=2)
    mask = blob(h, w, (5, h - 5, 6, w - 6))
    geom = CropGeometry.from_mask(mask, 64)
    net = geom.to_network(img)
    assert net.shape == (64, 64) + img.shape[2:]
    back = geom.to_input(net)
    assert back.shape == img.shape and back.dtype == np.float32
    inner = (slice(10, h - 10), slice(10, w - 10))
    np.testing.assert_allclose(back[inner], img[inner], atol=0.02)
    outside = mask == 0
    outside[geom.box[0] : geom.box[1], geom.box[2] : geom.box[3]] = False
    assert not back[outside].any()


def test_enlarging_samples_like_a_full_resize():
    """to_crop samples only the crop box; it must agree with resizing the whole square and cutting."""
    mask = blob(300, 200, (10, 290, 40, 160))
    geom = CropGeometry.from_mask(mask, 64)
    net = np.random.default_rng(3).random((64, 64, 9)).astype(np.float32)
    oy, ox = geom.offset
    h, w = geom.crop_shape
    full = np.concatenate([cv2.resize(net[..., i : i + 3], (geom.side, geom.side)) for i in (0, 3, 6)], axis=2)
    np.testing.assert_allclose(geom.to_crop(net), full[oy : oy + h, ox : ox + w], atol=1e-3)


def test_functions_return_new_arrays():
    img = np.random.default_rng(4).random((80, 80, 3)).astype(np.float32)
    keep = img.copy()
    geom = CropGeometry.from_mask(blob(80, 80, (10, 70, 20, 60)), 64)
    geom.to_input(geom.to_network(img))
    np.testing.assert_array_equal(img, keep)


def test_bad_mode_and_empty_mask():
    with pytest.raises(RelightError, match="mode"):
        CropGeometry.from_mask(blob(10, 10, (2, 8, 2, 8)), 64, mode="bicubic")
    with pytest.raises(RelightError, match="empty"):
        CropGeometry.from_mask(np.zeros((10, 10), np.float32), 64)


def test_window_origin_matches_the_whole_frame():
    mask = blob(300, 200, (10, 290, 40, 160))
    geom = CropGeometry.from_mask(mask, 64)
    net = np.random.default_rng(5).random((64, 64, 3)).astype(np.float32)
    whole = geom.to_crop(net)
    part = geom.to_crop(net[:, 10:54], origin=(0, 10))  # the crop covers network columns ~11..52
    np.testing.assert_allclose(part, whole, atol=1e-4)  # warpAffine works in fixed point
    small = CropGeometry.from_mask(blob(40, 40, (10, 30, 10, 30)), 64)
    with pytest.raises(RelightError, match="origin"):
        small.to_crop(net, origin=(1, 1))


def test_crop_to_network_is_to_network_of_the_crop_box():
    """What lies in the crop box, given as the box's array, goes to the network frame as the whole image does; an
    array of another size is refused."""
    rng = np.random.default_rng(4)
    img = rng.random((120, 90, 3)).astype(np.float32)
    for mode, size in (("quality", 32), ("reference", 64), ("quality", 200)):  # shrinking, equal-ish, enlarging
        geom = CropGeometry.from_mask(blob(120, 90, (20, 110, 10, 70)), size, mode=mode)
        np.testing.assert_array_equal(geom.crop_to_network(geom.crop(img)), geom.to_network(img))
    with pytest.raises(RelightError, match="crop box"):
        geom.crop_to_network(img)
