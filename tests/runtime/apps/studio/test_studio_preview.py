"""relight_rt.apps.studio.preview: the page's layers unpacked from bytes packed here by hand, in the layout
``Studio.layers_bytes`` writes (relight_rt/apps/studio/core.py), the area reduction against OpenCV's INTER_AREA, the
shadow plane and the preview picture against their formulas. No models: test_studio.py checks the same functions on a
Studio's real layers (what a Decomposition gives), this file their arithmetic on values chosen to show it.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from relight_rt import RelightError
from relight_rt.apps.studio.preview import (
    _area_weights,
    area_reduce,
    layers_in_box,
    preview_picture,
    shadow_plane,
    unpack_layers,
)
from relight_rt.image.color import REC709, linear_to_srgb, srgb_to_linear
from relight_rt.relight.look import SKIN_CHROMA

H, W = 5, 4
NS, NH, NG, NB = 6, 3, 4, 2  # samples: exposure, highlight guard, grade, the head pass's blend


def pack(rng: np.random.Generator, index=(1, 3), rim=(2, 7, 19), **counts) -> tuple[bytes, dict, dict]:
    """Random layers packed as ``Studio.layers_bytes`` packs them (9 uint16 planes of transport, 11 uint8 planes,
    padding to ``exposure_offset``, then the float32 samples, the head blend's int32 indices and planes, the kept
    rim's int32 pixels and planes) → (data, meta, the values packed)."""
    n = H * W
    ns, nh, ng = counts.get("ns", NS), counts.get("nh", NH), counts.get("ng", NG)
    v = {
        "q16": rng.integers(0, 65536, (9, H, W)).astype("<u2"),
        "q8": rng.integers(0, 256, (11, H, W)).astype(np.uint8),
        "off": rng.normal(size=9), "scale": rng.random(9) * 1e-3,
        "exposure": rng.normal(size=(13, ns)).astype("<f4"), "guard": rng.normal(size=(15, nh)).astype("<f4"),
        "grade": rng.normal(size=(21, ng)).astype("<f4"), "index": np.asarray(index, "<i4"),
    }
    v["blend"] = rng.normal(size=(15, len(index))).astype("<f4")
    v["rim_index"], v["rim"] = np.asarray(rim, "<i4"), rng.random((3, len(rim))).astype("<f4")
    head = v["q16"].tobytes() + v["q8"].tobytes()
    offset = 29 * n + 3  # the page's float planes start after some padding
    hoffset = offset + 52 * ns
    goffset = hoffset + 60 * nh
    boffset = goffset + 84 * ng
    data = (head + bytes(offset - len(head)) + v["exposure"].tobytes() + v["guard"].tobytes() + v["grade"].tobytes()
            + v["index"].tobytes() + v["blend"].tobytes() + v["rim_index"].tobytes() + v["rim"].tobytes())
    meta = {"height": H, "width": W, "transport_offset": v["off"].tolist(), "transport_scale": v["scale"].tolist(),
            "exposure_samples": ns, "exposure_offset": offset, "highlight_samples": nh, "highlight_offset": hoffset,
            "grade_samples": ng, "grade_offset": goffset, "grade_head_samples": len(index),
            "grade_head_offset": boffset, "rim_samples": len(rim), "rim_offset": boffset + 64 * len(index)}
    return data, meta, v


# ------------------------------------------------------------------------------------------------ unpack


def test_unpack_layers_reads_back_every_plane_and_sample():
    data, meta, v = pack(np.random.default_rng(0))
    got = unpack_layers(data, meta)
    q16, q8 = v["q16"].astype(np.float64), v["q8"].astype(np.float64)
    want = v["off"][:, None, None] + q16 * v["scale"][:, None, None]
    np.testing.assert_allclose(got["transport"], want, rtol=1e-6, atol=1e-6)
    for name, planes in (("albedo", q8[:3]), ("mask", q8[3]), ("background", q8[4:7]), ("skin", q8[10])):
        np.testing.assert_allclose(got[name], planes / 255, atol=1e-7)
    np.testing.assert_allclose(got["skin_chroma"], 2 * q8[7:10] / 255 - 1, atol=1e-6)
    e, g, b = v["exposure"], v["guard"], v["grade"]
    for name, want in (("transport", e[:9].T), ("albedo", e[9:12].T), ("mask", e[12])):
        np.testing.assert_array_equal(got["exposure"][name], want)
    for name, want in (("lit", g[:3].T), ("steady", g[3:6].T), ("transport", g[6:].T)):
        np.testing.assert_array_equal(got["highlight"][name], want)
    grade = got["grade"]
    for field, want in (("lit", b[:3].T), ("steady", b[3:6].T), ("transport", b[6:15].T), ("weight", b[15]),
                        ("knee", b[16]), ("own", b[17:20].T), ("neutral", b[20])):
        np.testing.assert_array_equal(getattr(grade, field), want)
    np.testing.assert_array_equal(grade.head.index, [1, 3])
    for i, field in enumerate(("weight", "skin", "body_scale", "body_stays", "scale", "stays")):
        np.testing.assert_array_equal(getattr(grade.head, field), v["blend"][i])
    np.testing.assert_array_equal(grade.head.transport, v["blend"][6:].T)
    assert all(a.dtype == np.float32 for a in (got["transport"], got["albedo"], grade.lit, grade.head.weight))
    assert grade.head.index.dtype == np.int32
    np.testing.assert_array_equal(got["rim"]["index"], [2, 7, 19])
    np.testing.assert_array_equal(got["rim"]["rim"], v["rim"].T)
    assert got["rim"]["index"].dtype == np.int32 and got["rim"]["rim"].dtype == np.float32


def test_unpack_layers_before_the_rim_reads_none():
    """A layout without the kept rim's keys (a server from before it) reads as no rim pixels."""
    data, meta, _ = pack(np.random.default_rng(10), rim=())
    old = {k: v for k, v in meta.items() if not k.startswith("rim_")}
    got = unpack_layers(data, old)
    assert got["rim"]["index"].size == 0 and got["rim"]["rim"].shape == (0, 3)


def test_unpack_layers_without_head_blend_or_samples():
    data, meta, _ = pack(np.random.default_rng(1), index=(), ns=0, nh=0, ng=0)
    got = unpack_layers(data, meta)
    assert got["exposure"]["transport"].shape == (0, 9) and got["grade"].head.index.size == 0
    assert got["transport"].shape == (9, H, W)


def test_unpack_layers_refuses_inconsistent_layouts():
    data, meta, _ = pack(np.random.default_rng(2))
    with pytest.raises(RelightError, match=r"layers: expected \d+ bytes for 5x4"):
        unpack_layers(data + b"\0", meta)
    with pytest.raises(RelightError, match="layers: expected"):
        unpack_layers(data, {**meta, "exposure_offset": 29 * H * W - 1})  # the float planes over the pixel planes
    with pytest.raises(RelightError, match="layers: expected"):  # more blended pixels than grade samples
        unpack_layers(*pack(np.random.default_rng(3), index=(0, 1, 2, 3, 4))[:2])
    for wrong in ((3, 1), (2, 2), (-1, 2)):
        with pytest.raises(RelightError, match=r"head pass's blend names grade samples outside 0\.\.3 or out of order"):
            unpack_layers(*pack(np.random.default_rng(4), index=wrong)[:2])
    for wrong in ((3, 1), (2, 2), (-1, 2), (0, H * W)):
        with pytest.raises(RelightError, match=r"the kept rim names pixels outside 0\.\.19 or out of order"):
            unpack_layers(*pack(np.random.default_rng(4), rim=wrong)[:2])
    with pytest.raises(RelightError, match="layers: expected"):  # the rim's pixels not where the layout says
        unpack_layers(data, {**meta, "rim_offset": meta["rim_offset"] + 4})


def test_layers_in_box_is_the_whole_frame_cut_to_the_box():
    data, meta, _ = pack(np.random.default_rng(5))
    whole = layers_in_box(data, meta, (slice(None), slice(None)))
    box = (slice(1, 4), slice(2, 4))
    part = layers_in_box(data, meta, box)
    for name, planes in whole.items():
        np.testing.assert_array_equal(part[name], planes[(Ellipsis, *box)])


# ------------------------------------------------------------------------------------------------ area


def test_area_weights_halving_and_rows_summing_to_one():
    cols, w = _area_weights(4, 2, 0, 2)  # each output pixel is the mean of two inputs
    assert cols == slice(0, 4)
    np.testing.assert_array_equal(w, [[0.5, 0.5, 0, 0], [0, 0, 0.5, 0.5]])
    cols, w = _area_weights(7, 3, 1, 3)  # a span of 7/3 input pixels, the output's middle and last
    assert cols == slice(2, 7) and w.dtype == np.float32
    np.testing.assert_allclose(w.sum(axis=1), 1, rtol=1e-6)
    np.testing.assert_allclose(w[0], np.array([2 / 3, 1, 2 / 3, 0, 0]) * 3 / 7, rtol=1e-6)  # 7/3..14/3 over 2..7


@pytest.mark.parametrize(("shape", "size"), [((37, 53), (10, 14)), ((20, 30), (10, 15)), ((9, 9), (9, 9))])
def test_area_reduce_is_opencv_inter_area(shape, size):
    """The whole box gives what cv2.resize(INTER_AREA) gives; a part gives that result's part (the docstring's
    promise: the cost follows the box, the values do not)."""
    rng = np.random.default_rng(6)
    planes = [rng.random(shape).astype(np.float32) for _ in range(2)]
    full = [cv2.resize(p, size[::-1], interpolation=cv2.INTER_AREA) for p in planes]
    out, got = area_reduce(planes, size, [0, shape[0], 0, shape[1]])
    assert out == [0, size[0], 0, size[1]]
    for g, f in zip(got, full, strict=True):
        np.testing.assert_allclose(g, f, rtol=1e-5, atol=1e-6)
    box = [shape[0] // 3, shape[0] // 2 + 1, shape[1] // 4, shape[1] - 2]
    out, got = area_reduce(planes, size, box)
    assert out == [box[0] * size[0] // shape[0], math.ceil(box[1] * size[0] / shape[0]),
                   box[2] * size[1] // shape[1], math.ceil(box[3] * size[1] / shape[1])]
    for g, f in zip(got, full, strict=True):
        np.testing.assert_allclose(g, f[out[0] : out[1], out[2] : out[3]], rtol=1e-5, atol=1e-6)


# ------------------------------------------------------------------------------------------------ shadows


def test_shadow_plane_from_its_boxes():
    assert (shadow_plane({"box": None}, 3, 4) == 1).all()
    depth = np.array([[0, 255], [51, 102]], np.uint8)
    answer = {"box": [1, 3, 1, 3], "depth": depth.tobytes()}
    plane = shadow_plane(answer, 3, 4)
    want = np.ones((3, 4), np.float32)
    want[1:3, 1:3] = 1 - depth / 255
    np.testing.assert_allclose(plane, want, atol=1e-7)
    head = np.array([[0.5, 2.0, 1.0]], "<f4")
    plane = shadow_plane({**answer, "head_box": [2, 3, 0, 3], "head": head.tobytes()}, 3, 4)
    want[2, 0:3] *= head[0]  # on the cast shadows' factor, both where they overlap
    np.testing.assert_allclose(plane, want, atol=1e-7)
    assert plane.dtype == np.float32


# ------------------------------------------------------------------------------------------------ picture


def _layers(rng, skin=0.0):
    t = rng.normal(size=(9, 3, 4)).astype(np.float32)
    t[0] = np.abs(t[0]) + 1  # mostly lit, a few pixels facing away
    return {"transport": t, "albedo": rng.random((3, 3, 4)).astype(np.float32),
            "skin_chroma": rng.uniform(-0.5, 0.5, (3, 3, 4)).astype(np.float32),
            "skin": np.full((3, 4), skin, np.float32)}


def test_preview_picture_off_the_skin_is_albedo_times_shading():
    """skin 0: albedo x max(0, T.L) x shadow, clipped to [0, 1] (the docstring's formula, DESIGN.md §3)."""
    rng = np.random.default_rng(7)
    layers = _layers(rng)
    light = rng.normal(size=(9, 3)).astype(np.float32) * 0.5
    meta = {"own_white": rng.random(9).tolist()}  # the own light's luminance column (9,)
    shading = np.maximum(np.einsum("khw,kc->hwc", layers["transport"].astype(np.float64), light), 0)
    want = np.clip(layers["albedo"].transpose(1, 2, 0) * shading, 0, 1)
    assert (shading == 0).any() and (want == 1).any() and ((want > 0) & (want < 1)).any()  # every case is seen
    got = preview_picture(layers, meta, light)
    assert got.shape == (3, 4, 3) and got.dtype == np.float32
    np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-6)
    shadow = rng.random((3, 4)).astype(np.float32)
    want = np.clip(layers["albedo"].transpose(1, 2, 0) * shading * shadow[..., None], 0, 1)
    np.testing.assert_allclose(preview_picture(layers, meta, light, shadow), want, rtol=1e-5, atol=1e-6)
    one = {**layers, "transport": np.zeros((9, 3, 4), np.float32), "albedo": np.full((3, 3, 4), 0.5, np.float32)}
    one["transport"][0] = math.sqrt(math.pi) / 2  # A_0 Y_00 = pi / (2 sqrt(pi)): a constant light's irradiance
    lit = np.zeros((9, 3), np.float32)
    lit[0] = [0.2, 0.4, 0.6] / np.float32(math.sqrt(math.pi) / 2)
    np.testing.assert_allclose(preview_picture(one, meta, lit), np.broadcast_to([0.1, 0.2, 0.3], (3, 4, 3)),
                               rtol=1e-6)


def test_preview_picture_skin_keeps_its_colour_only_where_the_light_darkens():
    """Under the photo's own white light (ratio 1) the skin rule changes nothing; under half of it the skin keeps
    more of its chroma: a gain of 1 + (0.5**(SKIN_CHROMA - 1) - 1) x chroma (relight_rt.relight.look.shaded_skin)."""
    rng = np.random.default_rng(8)
    plain = _layers(rng)
    own = np.zeros((9, 3), np.float32)
    own[0] = 1.0 / (math.sqrt(math.pi) / 2)
    meta = {"own_white": own[:, 0].tolist()}
    small = {k: v * (0.3 if k == "albedo" else 1) for k, v in plain.items()}  # nothing clipped
    small_skin = {**small, "skin": np.ones((3, 4), np.float32)}
    np.testing.assert_allclose(preview_picture(small_skin, meta, own), preview_picture(small, meta, own), rtol=1e-6)
    half = preview_picture(small_skin, meta, 0.5 * own)
    gain = np.clip(1 + (0.5 ** (SKIN_CHROMA - 1) - 1) * small["skin_chroma"].transpose(1, 2, 0), 0.25, 4)
    np.testing.assert_allclose(half, preview_picture(small, meta, 0.5 * own) * gain, rtol=1e-5, atol=1e-7)


def test_preview_picture_refuses_a_bad_light():
    layers = _layers(np.random.default_rng(9))
    meta = {"own_white": np.ones(9).tolist()}
    with pytest.raises(RelightError, match=r"\(9, 3\)"):
        preview_picture(layers, meta, np.ones((9, 4), np.float32))
    with pytest.raises(RelightError, match="NaN"):
        preview_picture(layers, meta, np.full((9, 3), np.nan, np.float32))


def _rim_layers(rng):
    """Layers of 3 x 4 pixels, none skin, with a mask, an own light (white, constant: its shading 1 everywhere) and
    a kept rim on four pixels, and that own light (9, 3)."""
    layers = _layers(rng)
    layers["transport"] = np.zeros((9, 3, 4), np.float32)
    layers["transport"][0] = 1
    layers["transport"][1] = np.where(np.add.outer(np.arange(3), np.arange(4)) % 2, 0.4, -0.4)  # a light with a
    # side (Y_1) darkens some pixels and brightens others
    mask = np.array([[1, 0.5, 0.25, 0], [1, 1, 0.6, 0.1], [1, 0.8, 0.4, 0]], np.float32)
    layers["albedo"] = (rng.uniform(0.1, 0.6, (3, 3, 4)) * mask).astype(np.float32)  # premultiplied
    layers["mask"] = mask
    layers["rim"] = {"index": np.array([1, 2, 6, 9], np.int32),
                     "rim": rng.uniform(0.02, 0.2, (4, 3)).astype(np.float32)}
    own = np.zeros((9, 3), np.float32)
    own[0] = 1
    return layers, own


def test_preview_rim_adds_what_the_light_took_of_it_in_linear_light():
    """On the rim's pixels, where the light leaves the straight colour's linear luminance at g x the own colour's
    (g < 1), rim x (1 - g) is added in linear light, then premultiplied again (relight_rt.relight.kept_rim
    ``with_kept_rim``); where it brightens (g >= 1), and off the rim, the picture is the one without it."""
    layers, own = _rim_layers(np.random.default_rng(11))
    meta = {"own_white": own[:, 0].tolist()}
    bare = {k: v for k, v in layers.items() if k != "rim"}
    light = own.copy()
    light[1] = 0.8
    got, plain = preview_picture(layers, meta, light), preview_picture(bare, meta, light)
    m = layers["mask"].reshape(-1)
    straight = lambda a: np.clip(a.reshape(-1, 3) / np.maximum(m, 1e-6)[:, None], 0, 1)  # noqa: E731
    own_colour = straight(np.clip(layers["albedo"].transpose(1, 2, 0), 0, 1))
    want = plain.reshape(-1, 3).copy()
    darker = 0
    for j, p in enumerate(layers["rim"]["index"]):
        g = (srgb_to_linear(straight(plain)[p]) @ REC709) / (srgb_to_linear(own_colour[p]) @ REC709)
        if g < 1:
            darker += 1
            lin = srgb_to_linear(straight(plain)[p]) + layers["rim"]["rim"][j] * (1 - g)
            want[p] = linear_to_srgb(np.clip(lin, 0, 1)) * m[p]
    assert 0 < darker < 4  # both cases seen
    np.testing.assert_allclose(got.reshape(-1, 3), want, rtol=1e-5, atol=1e-6)
    off = np.setdiff1d(np.arange(m.size), layers["rim"]["index"])
    np.testing.assert_array_equal(got.reshape(-1, 3)[off], plain.reshape(-1, 3)[off])
    assert (got.reshape(-1, 3) >= plain.reshape(-1, 3) - 1e-7).all()


def test_preview_rim_under_the_own_light_changes_nothing():
    """g = 1 under the photo's own light: the photo comes back, rim or not."""
    layers, own = _rim_layers(np.random.default_rng(12))
    meta = {"own_white": own[:, 0].tolist()}
    bare = {k: v for k, v in layers.items() if k != "rim"}
    np.testing.assert_array_equal(preview_picture(layers, meta, own), preview_picture(bare, meta, own))
    dark = preview_picture(layers, meta, 0.2 * own)  # a light that darkens every pixel: each rim pixel lifted
    lifted = dark.reshape(-1, 3)[layers["rim"]["index"]] - preview_picture(bare, meta, 0.2 * own).reshape(-1, 3)[
        layers["rim"]["index"]]
    assert (lifted[layers["mask"].reshape(-1)[layers["rim"]["index"]] > 0] > 1e-3).all()
