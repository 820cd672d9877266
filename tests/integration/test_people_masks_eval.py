"""benchmarks/people_masks_eval.py: outline_offset (where a mask's outline cuts the photo's own, blurred, edge), the
sheets, and the options it refuses."""

from __future__ import annotations

import cv2
import numpy as np
import pytest


def disc_photo(radius: float = 40.0, blur: float = 1.2, size: int = 160):
    """A red disc on a blue backdrop, its edge blurred as a lens and JPEG blur it; the disc's true outline is the
    circle ``radius`` (the edge's half mix)."""
    yy, xx = np.mgrid[:size, :size].astype(np.float32)
    r = np.hypot(yy - size / 2 + 0.5, xx - size / 2 + 0.5)
    sharp = np.clip(radius + 0.5 - r, 0.0, 1.0)  # area coverage, about
    alpha = cv2.GaussianBlur(sharp, (0, 0), blur)
    rgb = alpha[..., None] * np.float32([0.8, 0.2, 0.1]) + (1 - alpha[..., None]) * np.float32([0.1, 0.3, 0.8])
    return rgb.astype(np.float32), r


def test_an_outline_through_the_edges_half_mix_is_at_zero_and_a_generous_one_is_not(load_benchmark):
    pme = load_benchmark("people_masks_eval")
    rgb, r = disc_photo()
    on = pme.outline_offset(rgb, r < 40.0)
    wide = pme.outline_offset(rgb, r < 41.0)
    tight = pme.outline_offset(rgb, r < 39.0)
    assert abs(on) < 0.3  # measured 0.02 (41 px: +0.89, 39 px: -0.81)
    assert 0.6 < wide - on < 1.4 and 0.6 < on - tight < 1.4  # one pixel more or less of the edge's backdrop side
    grey = np.full_like(rgb, 0.5)  # no edge to measure against
    assert np.isnan(pme.outline_offset(grey, r < 40.0))


def test_the_below_sheet_shows_each_method_beside_the_reference(load_benchmark, tmp_path):
    pme = load_benchmark("people_masks_eval")
    (tmp_path / "photos").mkdir()
    h, w = 120, 160
    photo = np.full((h, w, 3), 200, np.uint8)
    gt = np.zeros((h, w), bool)
    gt[30:90, 40:100] = True
    cv2.imwrite(str(tmp_path / "photos" / "x.jpg"), photo)
    cv2.imwrite(str(tmp_path / "photos" / "x_mask.png"), gt.astype(np.uint8) * 255)
    ours = gt.copy()
    ours[30:90, 100:130] = True  # ours adds a strip the selfie graph leaves out
    keep = {("ours", "x"): ours, ("selfie", "x"): gt.copy()}
    out = tmp_path / "sheet.png"
    pme.sheet(tmp_path, ["x"], keep, out, "ours", height=h, beside="selfie")
    sheet = cv2.imread(str(out), cv2.IMREAD_COLOR)
    assert sheet.shape[1] == 4 * w  # photo | reference | ours | selfie
    strip = (60, 115)  # a pixel of the added strip, in each panel
    ours_px = sheet[strip[0], 2 * w + strip[1]].astype(int)
    selfie_px = sheet[strip[0], 3 * w + strip[1]].astype(int)
    assert ours_px[2] > ours_px[1] + 100  # red: ours adds here
    assert abs(selfie_px[2] - selfie_px[1]) < 10  # grey: the selfie graph agrees with the mask (background)
    pme.sheet(tmp_path, ["x"], keep, out, "ours", height=h)
    assert cv2.imread(str(out), cv2.IMREAD_COLOR).shape[1] == 3 * w  # without beside: three panels


def test_grow_and_below_sheet_refuse_what_they_cannot_do(load_benchmark):
    pme = load_benchmark("people_masks_eval")
    with pytest.raises(SystemExit):
        pme.main(["--grow", "9"])
    with pytest.raises(SystemExit):
        pme.main(["--methods", "ours", "--below-sheet", "/tmp/x.png"])


def test_below_by_half_lists_each_halfs_photos_below_the_selfie_graph_and_those_far_below(load_benchmark):
    pme = load_benchmark("people_masks_eval")
    ours = {"a": 0.90, "b": 0.95, "c": 0.80, "d": 0.99}
    selfie = {"a": 0.95, "b": 0.955, "c": 0.70, "d": 0.99}
    halves = {"a": "A", "b": "A", "c": "B", "d": "B"}
    got = pme.below_by_half(ours, selfie, halves)
    assert got == {"A": (["a", "b"], ["a"]), "B": ([], [])}  # b: below by 0.005, not past 0.01; d: equal, not below
    assert pme.below_by_half(ours, selfie, halves, by=0.001)["A"] == (["a", "b"], ["a", "b"])
    assert set(pme.below_by_half({"c": 0.8}, selfie, halves)) == {"B"}  # --half B: only B is reported


def test_graphs_mirrored_shows_each_graph_its_crops_mirror_and_mirrors_its_answer_back(load_benchmark):
    from pathlib import Path

    from relight_rt.engine.session import Model
    from relight_rt.person import matting as M

    pme = load_benchmark("people_masks_eval")
    matter = M.PersonMatter()
    x = np.random.default_rng(38).random((1, 3, 256, 256)).astype(np.float32)
    roi = matter.roi.run({"image": np.ascontiguousarray(x[..., ::-1])})["segmentation"]
    pose = matter.pose.run({"image": np.ascontiguousarray(x[..., ::-1])})
    run = Model.run
    with pme.graphs_mirrored():
        assert np.array_equal(matter.roi.run({"image": x})["segmentation"], roi[..., ::-1])
        seen = matter.pose.run({"image": x})
        assert np.array_equal(seen["segmentation"], pose["segmentation"][..., ::-1])
        assert np.array_equal(seen["presence"], pose["presence"])
    assert Model.run is run  # (restored)
    # the face graph: the faces found on the example's mirror, its boxes mirrored back, are the example's
    example = Path(M.__file__).resolve().parents[2] / "data" / "example.png"
    rgb = cv2.cvtColor(cv2.imread(str(example)), cv2.COLOR_BGR2RGB).astype(np.float32) / 255
    w = rgb.shape[1]
    faces = matter.find_faces(rgb)
    assert faces
    with pme.graphs_mirrored():
        seen = matter.find_faces(np.ascontiguousarray(rgb[:, ::-1]))
    assert len(seen) == len(faces)
    for f, g in zip(faces, seen, strict=True):
        assert np.allclose([w - g.box[2], g.box[1], w - g.box[0], g.box[3]], f.box, atol=1e-3)
        assert abs(f.score - g.score) < 1e-6


def asymmetric_pair(folder):
    """photos/x.jpg: bright on its left third, dark elsewhere; x_mask.png: that left third."""
    (folder / "photos").mkdir(parents=True)
    photo = np.full((60, 90, 3), 20, np.uint8)
    photo[:, :30] = 230
    cv2.imwrite(str(folder / "photos" / "x.jpg"), photo)
    cv2.imwrite(str(folder / "photos" / "x_mask.png"), (photo[..., 0] > 128).astype(np.uint8) * 255)
    return folder / "photos" / "x.jpg", folder / "photos" / "x_mask.png"


def test_images_mirrored_mirrors_every_image_and_mask_read_and_puts_the_readers_back(load_benchmark, tmp_path):
    pme = load_benchmark("people_masks_eval")
    img, mask = asymmetric_pair(tmp_path)
    rgb, gt = pme.read_rgb(img), pme.read_mask(mask, (60, 90))
    assert gt[:, :30].all() and not gt[:, 30:].any()
    with pme.images_mirrored():
        np.testing.assert_array_equal(pme.read_rgb(img), rgb[:, ::-1])
        np.testing.assert_array_equal(pme.read_mask(mask, (60, 90)), gt[:, ::-1])
    np.testing.assert_array_equal(pme.read_rgb(img), rgb)
    np.testing.assert_array_equal(pme.read_mask(mask, (60, 90)), gt)


class _Fake:
    """A stand-in for PersonMatter: ``kind`` "bright" mattes the bright pixels (mirrors with the photo), "left" always
    the photo's left third (does not)."""

    kind = "bright"

    def __init__(self, **kwargs):
        self.roi = self.pose = None

    def __call__(self, rgb, name=""):
        if self.kind == "bright":
            return (rgb.mean(axis=2) > 0.5).astype(np.float32)
        alpha = np.zeros(rgb.shape[:2], np.float32)
        alpha[:, : rgb.shape[1] // 3] = 1.0
        return alpha


@pytest.mark.parametrize("kind", ["bright", "left"])
def test_run_methods_under_images_mirrored_scores_the_mirrors_against_their_mirrored_masks(
    load_benchmark, tmp_path, monkeypatch, kind
):
    pme = load_benchmark("people_masks_eval")
    asymmetric_pair(tmp_path)
    monkeypatch.setattr(pme.M, "PersonMatter", _Fake)
    monkeypatch.setattr(_Fake, "kind", kind)
    asis = pme.run_methods(tmp_path, "photos", ["ours"], None)["ours"]["x"]
    with pme.images_mirrored():
        mirrored = pme.run_methods(tmp_path, "photos", ["ours"], None)["ours"]["x"]
    assert asis == 1.0
    # a matte that mirrors with the photo scores alike; one fixed to a side of the frame loses the mirrored person
    assert mirrored == (1.0 if kind == "bright" else 0.0)


def test_mirrored_refuses_the_options_that_read_the_photos_as_they_come(load_benchmark):
    pme = load_benchmark("people_masks_eval")
    for extra in (["--sheet", "/tmp/x.png"], ["--outline"], ["--speed"]):
        with pytest.raises(SystemExit):
            pme.main(["--mirrored", *extra])
    with pytest.raises(SystemExit):
        pme.main(["--graphs-mirrored", "--speed"])
