"""relight_rt.person.matting: the bundled person-matting graphs, PersonMatter, VideoMatter, outline_flicker, and the
conversion (export/mask_models.py)."""

from __future__ import annotations

import copy
from pathlib import Path

import cv2
import numpy as np
import pytest

from relight_rt import RelightError
from relight_rt.engine.session import bundled_models_dir, load_model
from relight_rt.image import regions as _square
from relight_rt.image.io import read_image
from relight_rt.person import matting as M
from relight_rt.person.face_detector import FACE_SIZE, GRID
from relight_rt.person.matting import _detect

REPO = Path(__file__).resolve().parents[4]
EXAMPLE = REPO / "relight_rt" / "data" / "example.png"  # a rendered person; its alpha channel is the true mask


def iou(a: np.ndarray, b: np.ndarray) -> float:
    a, b = a >= 0.5, b >= 0.5
    return float((a & b).sum() / max((a | b).sum(), 1))


@pytest.fixture(scope="module")
def matter() -> M.PersonMatter:
    return M.PersonMatter()


@pytest.fixture(scope="module")
def example() -> tuple[np.ndarray, np.ndarray]:
    rgba = read_image(EXAMPLE)
    return np.ascontiguousarray(rgba[..., :3]), rgba[..., 3].copy()


def gradient(h: int = 240, w: int = 320) -> np.ndarray:
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    return np.stack([xx / w, yy / h, 1 - xx / w], -1).astype(np.float32)


# ------------------------------------------------------------------------------------------ bundled graphs


def test_bundled_graphs_follow_the_contract():
    folder = bundled_models_dir()
    for file, kind, size in ((M.POSE_FILE, "matte_pose", 256), (M.ROI_FILE, "matte_roi", 256),
                             (M.FACE_FILE, "matte_face", 192)):  # fmt: skip
        model = load_model(folder / file, kind, device="cpu", warmup=False)
        assert model.config.kind == kind and model.config.resolution == size
        assert "MediaPipe" in model.config.source and "Apache" in model.config.source
    pose = load_model(folder / M.POSE_FILE, "matte_pose", device="cpu", warmup=False)
    assert [o.name for o in pose.session.get_outputs()] == ["segmentation", "presence"]


def test_all_bundled_graphs_stay_within_40_mb():
    total = sum(p.stat().st_size for p in (REPO / "relight_rt").rglob("*.onnx"))
    assert total <= 40 * 1000 * 1000, f"bundled .onnx files total {total / 1e6:.1f} MB > 40 MB"


def test_converted_graphs_match_tflite():
    """Parity of the committed graphs with MediaPipe's TFLite models (only where mediapipe is installed:
    the conversion venv, see export/mask_models.py)."""
    mediapipe = pytest.importorskip("mediapipe")
    pytest.importorskip("tensorflow")
    from export import mask_models

    root = Path(mediapipe.__file__).resolve().parent
    for name, spec in mask_models.SOURCES.items():
        data = (bundled_models_dir() / name).read_bytes()
        err = mask_models.verify(data, root / spec.tflite, spec, mask_models.test_inputs(size=spec.size))
        assert err <= mask_models.PARITY_TOL, f"{name}: {err}"


def test_transpose_conv_bias_rewrite_matches_its_definition():
    """MediaPipe's Convolution2DTransposeBias (NHWC, OHWI weights, stride = kernel) -> ONNX ConvTranspose."""
    onnx = pytest.importorskip("onnx")
    import onnxruntime as ort
    from onnx import TensorProto, helper, numpy_helper

    from export.mask_models import rewrite_transpose_conv_bias

    rng = np.random.default_rng(0)
    w = rng.standard_normal((2, 2, 2, 4)).astype(np.float32)  # (out, kh, kw, in)
    b = rng.standard_normal(2).astype(np.float32)
    nodes = [
        helper.make_node("Transpose", ["x"], ["x_nhwc"], perm=[0, 2, 3, 1]),
        helper.make_node("TFL_Convolution2DTransposeBias", ["x_nhwc", "w", "b"], ["y"], name="up"),
    ]
    graph = helper.make_graph(
        nodes, "g", [helper.make_tensor_value_info("x", TensorProto.FLOAT, [1, 4, 3, 3])],
        [helper.make_tensor_value_info("y", TensorProto.FLOAT, [1, 6, 6, 2])],
        [numpy_helper.from_array(w, "w"), numpy_helper.from_array(b, "b")],
    )  # fmt: skip
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    assert rewrite_transpose_conv_bias(model) == 1
    assert not any(n.op_type.startswith("TFL_") for n in model.graph.node)
    x = rng.standard_normal((1, 4, 3, 3)).astype(np.float32)
    y = ort.InferenceSession(model.SerializeToString(), providers=["CPUExecutionProvider"]).run(None, {"x": x})[0]
    want = np.zeros((1, 6, 6, 2), np.float32)
    for di in range(2):
        for dj in range(2):
            want[0, di::2, dj::2, :] = np.einsum("cij,oc->ijo", x[0], w[:, di, dj, :]) + b
    np.testing.assert_allclose(y, want, atol=1e-5)
    assert onnx is not None


# ---------------------------------------------------------------------------------------------- geometry


def test_crop_region_of_the_whole_square_image_is_the_image():
    rng = np.random.default_rng(1)
    img = rng.random((256, 256, 3), dtype=np.float32)
    out = M.crop_region(img, M.Region(128.0, 128.0, 256.0))
    np.testing.assert_allclose(out, img, atol=1e-5)
    big = cv2.resize(img, (1024, 1024), interpolation=cv2.INTER_NEAREST)  # 4x4 blocks: area-averaging is exact
    np.testing.assert_allclose(M.crop_region(big, M.Region(512.0, 512.0, 1024.0)), img, atol=1e-4)


def test_crop_region_pads_with_zeros_past_the_border():
    img = np.ones((100, 100, 3), np.float32)
    out = M.crop_region(img, M.Region(0.0, 50.0, 200.0))  # left half of the region is outside
    assert out[:, :120].max() == 0.0 and out[:60].max() == 0.0 and out[70:186, 134:250].min() > 0.99


def _ramp(h: int, w: int) -> np.ndarray:
    """x / w, y / h and a mix: area averaging and bilinear resampling reproduce a linear image exactly."""
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32) + 0.5  # pixel centres
    return np.dstack([xx / w, yy / h, (xx + 2 * yy) / (w + 2 * h)]).astype(np.float32)


@pytest.mark.parametrize("shape", [(1155, 1733), (1302, 1950), (517, 1001)])
@pytest.mark.parametrize("side", [700.0, 1275.36, 2900.0])
def test_crop_region_of_a_large_region_samples_the_image_where_grid_of_region_says(shape, side):
    # a large region is reduced (by a power of 2) before the warp; on a linear image every canvas pixel
    # whose footprint lies inside the image must hold the image's value at that pixel's centre
    h, w = shape
    img = _ramp(h, w)
    region = M.Region(0.37 * w, 0.55 * h, side)
    out = M.crop_region(img, region)
    k, bx, by = _square.grid_of_region(region)
    cx = (np.arange(256) - bx) / k  # image x of each canvas column's centre
    cy = (np.arange(256) - by) / k
    margin = 3 / k  # the canvas pixel's footprint, reduction and warp included
    ix, iy = (cx > margin) & (cx < w - margin), (cy > margin) & (cy < h - margin)
    want_x = np.broadcast_to(cx[None, :] / w, out.shape[:2])
    want_y = np.broadcast_to(cy[:, None] / h, out.shape[:2])
    inside = iy[:, None] & ix[None, :]
    assert inside.sum() > 1000
    np.testing.assert_allclose(out[..., 0][inside], want_x[inside], atol=2e-4)
    np.testing.assert_allclose(out[..., 1][inside], want_y[inside], atol=2e-4)


def test_crops_inside_reductions_shared_are_the_same_and_reduce_the_photo_once(monkeypatch):
    rng = np.random.default_rng(3)
    img = rng.random((1155, 1733, 3), dtype=np.float32)
    regions = [M.Region(866.0, 577.0, 1733.0), M.Region(575.1, 655.3, 1057.1), M.Region(573.0, 688.3, 1135.6)]
    alone = [M.crop_region(img, r) for r in regions]
    calls = []
    blocks = _square._blocks
    monkeypatch.setattr(_square, "_blocks", lambda a, n, b: calls.append(a.shape) or blocks(a, n, b))
    with _square.reductions_shared(img):
        shared = [M.crop_region(img, r) for r in regions]
        again = M.crop_region(img, regions[1])
    for a, b in zip(alone, shared, strict=True):
        np.testing.assert_array_equal(a, b)  # one maths in and out of the block
    assert again is shared[1] and not again.flags.writeable  # the same region is cropped once
    assert calls.count(img.shape) == 1  # the photo itself is halved once; smaller reductions come from that


def test_crop_region_of_a_large_region_keeps_the_dtype():
    img = np.full((900, 1300, 3), 200, np.uint8)
    out = M.crop_region(img, M.Region(650.0, 450.0, 1300.0))  # reduced before the warp
    assert out.dtype == np.uint8 and out[100:150, 100:150].min() == 200


def test_reductions_shared_keeps_only_the_last_few_crops():
    img = np.zeros((600, 900, 3), np.float32)
    with _square.reductions_shared(img) as pyr:
        crops = [M.crop_region(img, M.Region(300.0 + 10 * i, 300.0, 600.0)) for i in range(10)]
        assert len(pyr._crops) <= _square._KEEP_CROPS  # person="all" crops 66 tiles: they are not all kept
        assert M.crop_region(img, M.Region(390.0, 300.0, 600.0)) is crops[-1]


def test_reductions_shared_keeps_nothing_after_the_block():
    img = np.zeros((900, 1400, 3), np.float32)
    region = M.Region(700.0, 450.0, 1400.0)
    with _square.reductions_shared(img):
        assert M.crop_region(img, region).max() == 0.0
    img[:] = 1.0  # a caller may reuse its buffer for the next frame
    assert M.crop_region(img, region)[100:150, 100:150].min() > 0.99


class CountedGraph:
    """A graph whose runs are counted (it answers as the graph it wraps)."""

    def __init__(self, model):
        self.model, self.runs = model, 0

    def run(self, feeds):
        self.runs += 1
        return self.model.run(feeds)


def test_the_face_graph_answers_once_per_window_inside_reductions_shared(matter):
    head = cv2.resize(head_crop(read_image(EXAMPLE))[0], None, fx=2.0, fy=2.0)
    photo = np.full((600, 800, 3), 0.4, np.float32)
    photo[: head.shape[0], 100 : 100 + head.shape[1]] = head  # a face seen whole
    ways = 2 if _detect.FACE_BOTH_WAYS else 1  # the whole photo is asked as it comes and mirrored
    counted = copy.copy(matter)  # (the module's matter is left as it is)
    counted.face = CountedGraph(matter.face)
    alone = counted.find_faces(photo)
    assert alone and counted.find_faces(photo) == alone and counted.face.runs == 2 * ways  # outside: every time
    every = counted.find_faces(photo, every=True)
    windows = counted.face.runs - 2 * ways  # the whole photo and its tiles
    assert windows > ways + 1
    counted.face.runs = 0
    with _square.reductions_shared(photo):
        assert counted.find_faces(photo) == alone and counted.find_faces(photo) == alone  # the same answer ...
        assert counted.face.runs == ways  # ... from one run each way
        assert counted.find_faces(photo, every=True) == every  # the whole photo's window is among the tiles'
        assert counted.face.runs == windows
        counted.find_faces(photo, every=True)
        assert counted.face.runs == windows
    counted.find_faces(photo)
    assert counted.face.runs == windows + ways  # nothing kept after the block


class _LeftFace:
    """A stand-in for the face graph: one face, sure, at the canvas's left quarter, and only where that quarter is
    brighter than the right one (MediaPipe's graph scores a face and its mirror image apart)."""

    def run(self, feeds):
        canvas = feeds["image"][0]
        side = canvas.shape[-1]
        scores = np.full((1, GRID, GRID), -20.0, np.float32)
        if canvas[:, :, : side // 4].mean() > canvas[:, :, -side // 4 :].mean():
            i, j = GRID // 2, GRID // 8  # the anchor at x 0.135, y 0.51 of the canvas
            scores[0, i, j] = 10.0
            return {"boxes": self._boxes(i, j), "scores": scores}
        return {"boxes": np.zeros((1, 16, GRID, GRID), np.float32), "scores": scores}

    @staticmethod
    def _boxes(i, j):
        out = np.zeros((1, 16, GRID, GRID), np.float32)
        out[0, 2:4, i, j] = 0.2 * FACE_SIZE  # 0.2 of the canvas wide and tall, on the anchor
        return out


@pytest.mark.parametrize("both", [True, False])
def test_a_face_the_graph_sees_only_mirrored_is_found_in_its_place(monkeypatch, both):
    """The whole photo is asked both ways (faceflip44): a face the graph scores under its threshold as the photo
    comes and over it mirrored is found, at its own place in the photo (not the mirror's)."""
    monkeypatch.setattr(_detect, "FACE_BOTH_WAYS", both)
    photo = np.full((400, 400, 3), 0.2, np.float32)
    photo[:, 300:] = 0.9  # bright on the right: the stand-in sees its face only in the mirror image
    faces = _detect.find_faces(_LeftFace(), photo)
    if not both:
        assert faces == []
        return
    assert len(faces) == 1
    x0, y0, x1, y1 = faces[0].box
    assert 300 < (x0 + x1) / 2 < 360 and abs((x1 - x0) - 80) < 2  # the right quarter: 1 - 0.135 of the width


def test_blocks_average_and_treat_the_image_as_zero_past_its_edge():
    img = np.arange(5 * 7 * 3, dtype=np.float32).reshape(5, 7, 3)
    out = _square._blocks(img, 2, (0, 0, 4, 3))
    padded = np.zeros((6, 8, 3), np.float32)
    padded[:5, :7] = img
    want = padded.reshape(3, 2, 4, 2, 3).mean(axis=(1, 3))
    np.testing.assert_allclose(out, want, rtol=1e-6)


# ----------------------------------------------------------------------------------------------- photos


def test_example_person_is_found_at_full_resolution(matter, example):
    rgb, truth = example
    alpha = matter(rgb)
    assert alpha.shape == rgb.shape[:2] and alpha.dtype == np.float32
    assert 0.0 <= alpha.min() and alpha.max() <= 1.0
    assert iou(alpha, truth) > 0.93  # measured 0.958


@pytest.mark.parametrize(
    ("crop", "floor"),
    [((slice(None), slice(110, None)), 0.88), ((slice(0, 300), slice(None)), 0.90)],
    ids=["cut-left", "cut-bottom"],
)  # fmt: skip
def test_person_cut_by_the_border(matter, example, crop, floor):
    rgb, truth = example
    alpha = matter(np.ascontiguousarray(rgb[crop]))
    assert iou(alpha, truth[crop]) > floor  # measured 0.913 and 0.935


def test_small_person_in_a_big_photo(matter, example):
    """200 px high in 2400x1800 (11 % of the height): the whole-image pass misses them, the tiles find them."""
    rgb, truth = example
    big = np.full((1800, 2400, 3), (0.35, 0.35, 0.45), np.float32)
    small = cv2.resize(rgb, (114, 200), interpolation=cv2.INTER_AREA)
    alpha = cv2.resize(truth, (114, 200), interpolation=cv2.INTER_AREA)[..., None]
    big[1200:1400, 1700:1814] = small * alpha + big[1200:1400, 1700:1814] * (1 - alpha)
    want = np.zeros(big.shape[:2], np.float32)
    want[1200:1400, 1700:1814] = alpha[..., 0]
    assert iou(matter(big), want) > 0.9  # measured 0.973


def test_uint8_rgba_and_grayscale_inputs(matter, example):
    rgb, truth = example
    ref = matter(rgb)
    np.testing.assert_allclose(matter((rgb * 255 + 0.5).astype(np.uint8)), ref, atol=0.02)
    rgba = np.dstack([rgb, np.zeros_like(truth)])  # an empty alpha channel is ignored: matting looks at the picture
    np.testing.assert_array_equal(matter(rgba), ref)
    gray = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
    assert iou(matter(gray), truth) > 0.9 and iou(matter(gray[..., None]), truth) > 0.9  # measured 0.940


def test_the_matter_only_reads_a_float32_photo(matter, example):
    """The matters take a float32 photo in [0, 1] without copying it (a 12-megapixel copy cost ~200 ms), so
    nothing in them may write into it."""
    rgb, _ = example
    mine = rgb.copy()
    matter(mine)
    video = M.VideoMatter(matter)
    video(mine)
    video(mine)
    np.testing.assert_array_equal(mine, rgb)


def test_no_person_raises(matter):
    with pytest.raises(RelightError, match="no person found in gradient.png"):
        matter(gradient(), "gradient.png")
    with pytest.raises(RelightError, match="no person found"):
        matter(np.zeros((64, 80, 3), np.float32))


@pytest.mark.parametrize(
    ("bad", "words"),
    [
        (np.zeros((1, 1, 3), np.float32), "too small"),
        (np.zeros((8, 300, 3), np.float32), "too small"),
        (np.full((32, 32, 3), np.nan, np.float32), "NaN"),
        (np.full((32, 32, 3), 2.0, np.float32), r"\[0, 1\]"),
        (np.zeros((32, 32, 2), np.float32), "shape"),
        (np.zeros((32, 32, 3), np.int32), "uint8, uint16 or float"),  # the one intake (_io) words it
        ("photo.jpg", "array"),
    ],
)
def test_bad_inputs_raise_relight_error(matter, bad, words):
    with pytest.raises(RelightError, match=words):
        matter(bad, "photo")


def test_largest_or_all_people(matter, example):
    rgb, truth = example
    small = cv2.resize(rgb, None, fx=0.6, fy=0.6, interpolation=cv2.INTER_AREA)
    canvas = np.zeros((508, 620, 3), np.float32)
    canvas[:, :290] = rgb
    canvas[100 : 100 + small.shape[0], 330 : 330 + small.shape[1]] = small
    largest = matter(canvas)
    assert (largest[:, :290] >= 0.5).sum() > 0.9 * (truth >= 0.5).sum() and not (largest[:, 320:] >= 0.5).any()
    everyone = M.PersonMatter(person="all")(canvas)
    assert (everyone[:, 320:] >= 0.5).sum() > 0.5 * (0.36 * (truth >= 0.5).sum())
    with pytest.raises(RelightError, match="person"):
        M.PersonMatter(person="tallest")


def test_shared_matter_is_loaded_once(example):
    a = M.shared_matter()
    assert M.shared_matter() is a and M.shared_matter(person="all") is not a
    rgb, truth = example
    assert iou(a(rgb), truth) > 0.93
    with pytest.raises(RelightError, match="not found"):
        M.shared_matter("/nonexistent/models")


def test_reference_photo_iou(matter, reference_dir):
    rgb = read_image(reference_dir / "photo" / "sample.jpg")
    truth = cv2.imread(str(reference_dir / "photo" / "sample_mask.png"), cv2.IMREAD_GRAYSCALE) / 255.0
    assert iou(matter(rgb), truth) > 0.95  # measured 0.970 (docs/RESULTS.md)


def head_crop(rgba: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A close head-and-shoulders crop of the example person (the top quarter of their height) and its alpha."""
    ys, xs = np.nonzero(rgba[..., 3] > 0.5)
    top, height = int(ys.min()), int(ys.max() - ys.min())
    cx = int(xs[ys < top + 0.1 * height].mean())
    half = int(0.15 * height)
    crop = rgba[max(top - 20, 0) : top + height // 4, cx - half : cx + half]
    return np.ascontiguousarray(crop[..., :3]), crop[..., 3].copy()


def test_close_portrait_is_found_by_its_face(matter):
    """Issue 33: the pose graph's presence flag says nobody in a close head-and-shoulders crop (0.00 here), so
    before the face detector such portraits gave "no person found"."""
    crop, truth = head_crop(read_image(EXAMPLE))
    blobs = matter.find_people(crop)
    assert blobs and all(matter.segment(crop, M.Region.around(*b)).presence < 0.5 for _, b in blobs)
    faces = matter.find_faces(crop)
    assert len(faces) == 1 and faces[0].score > 0.6
    fx0, fy0, fx1, fy1 = faces[0].box
    assert 0 < fx0 < fx1 < crop.shape[1] and 0 < fy0 < fy1 < crop.shape[0]
    assert iou(matter(crop), truth) > 0.85


def test_models_folder_without_the_face_graph_still_mattes(tmp_path, example):
    for name in (M.POSE_FILE, M.ROI_FILE):
        (tmp_path / name).write_bytes((bundled_models_dir() / name).read_bytes())
    m = M.PersonMatter(tmp_path)
    assert m.face is None and m.find_faces(example[0]) == []
    assert iou(m(example[0]), example[1]) > 0.93


def test_no_person_message_says_what_was_looked_for(matter):
    with pytest.raises(RelightError, match="no person found in flat.png .no body or face"):
        matter(np.full((200, 300, 3), 0.4, np.float32), "flat.png")


def test_face_decoding_and_weighted_nms():
    from relight_rt.person import face_detector as F

    boxes = np.zeros((16, F.GRID, F.GRID), np.float32)
    scores = np.full((1, F.GRID, F.GRID), -10.0, np.float32)
    scores[0, 10, 20] = 3.0  # one face: cell (row 10, column 20), centre moved 4 px right, 40 x 48 px
    boxes[:4, 10, 20] = (4.0, 0.0, 40.0, 48.0)
    scores[0, 10, 21] = 2.0  # the same face seen from the next cell
    boxes[:4, 10, 21] = (0.0, 0.0, 40.0, 48.0)
    scores[0, 40, 5] = 0.1  # below the threshold
    found = F.decode(boxes, scores)
    assert len(found) == 2
    cx, cy = (20.5 / F.GRID) + 4 / F.FACE_SIZE, 10.5 / F.GRID
    np.testing.assert_allclose(found[0][0] if found[0][1] > found[1][1] else found[1][0],
                               [cx - 20 / 192, cy - 24 / 192, cx + 20 / 192, cy + 24 / 192], atol=1e-6)  # fmt: skip
    merged = F.weighted_nms(found)
    assert len(merged) == 1 and merged[0][1] == pytest.approx(1 / (1 + np.exp(-3.0)))
    face = F.Face((100.0, 50.0, 140.0, 98.0), 0.9)
    assert face.body_box((200, 400)) == (120 - 1.75 * 48, 50 - 0.6 * 48, 120 + 1.75 * 48, 200.0)


def test_everyone_on_the_reference_street_photo(reference_dir):
    """Issue 33: --person all found only the main subject; passers-by stand about 140 px tall behind her."""
    rgb = read_image(reference_dir / "photo" / "sample.jpg")
    matter = M.PersonMatter(person="all")
    people = matter.people(rgb)
    boxes = [M.person_box(p, rgb.shape[:2]) for p in people]
    assert len(people) >= 4  # measured 6: the subject and five passers-by
    assert all(b[3] - b[1] >= M.MIN_PERSON_FRACTION * rgb.shape[0] for b in boxes)
    tall = max(boxes, key=lambda b: b[3] - b[1])
    assert tall[3] - tall[1] > 0.7 * rgb.shape[0]


def test_sparse_weights_are_decoded():
    """export/mask_models._dense_values: TFLite's CSR layout (rows dense, the last axis sparse)."""
    from types import SimpleNamespace as NS

    from export.mask_models import _dense_values

    want = np.zeros((2, 1, 1, 5), np.float16)
    want[0, 0, 0, [1, 4]] = (0.5, -1.0)
    want[1, 0, 0, [0]] = 2.0
    dense, sparse = 0, 1
    schema = NS(DimensionType=NS(DENSE=dense, SPARSE_CSR=sparse))
    dims = [NS(format=dense, denseSize=2), NS(format=dense, denseSize=1), NS(format=dense, denseSize=1),
            NS(format=sparse, arraySegments=NS(values=[0, 2, 3]), arrayIndices=NS(values=[1, 4, 0]))]  # fmt: skip
    sparsity = NS(traversalOrder=[0, 1, 2, 3], blockMap=None, dimMetadata=dims)
    values = np.array([0.5, -1.0, 2.0], np.float16)
    np.testing.assert_array_equal(_dense_values(values, [2, 1, 1, 5], sparsity, schema, "w"), want)
    with pytest.raises(RuntimeError, match="traversal"):
        _dense_values(values, [2, 1, 1, 5], NS(traversalOrder=[1, 0, 2, 3], blockMap=None, dimMetadata=dims),
                      schema, "w")  # fmt: skip


# ------------------------------------------------------------------------------------------------ video


def test_video_matter_follows_and_survives_empty_frames(matter, example):
    rgb, truth = example
    vm = M.VideoMatter(matter, smoothing=0.7)
    frames = [np.roll(rgb, 3 * t, axis=1) for t in range(4)]
    alphas = [vm(f) for f in frames]
    for t, a in enumerate(alphas):
        assert iou(a, np.roll(truth, 3 * t, axis=1)) > 0.9
    assert vm(np.zeros_like(rgb)).max() == 0.0  # nobody: an empty matte, no error
    assert iou(vm(rgb), truth) > 0.9  # found again
    with pytest.raises(RelightError, match="previous frames"):
        vm(rgb[:200])
    flicker = M.outline_flicker(alphas, frames)
    assert 0.0 <= flicker < 0.05


def test_outline_flicker_measures_edge_change(matter):
    a = np.zeros((64, 64), np.float32)
    a[16:48, 16:48] = 1.0
    assert M.outline_flicker([a, a, a]) == 0.0
    b = a.copy()
    b[16:48, 46:48] = 0.0  # the right edge moves by 2 pixels
    assert M.outline_flicker([a, b]) > 0.05
    with pytest.raises(RelightError, match="at least 2"):
        M.outline_flicker([a])
    with pytest.raises(RelightError):
        M.VideoMatter(matter, smoothing=1.0)
