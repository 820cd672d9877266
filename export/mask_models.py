"""``python -m export mask-models``: convert MediaPipe's person-segmentation and face models to relight_rt graphs.

Runs in its OWN virtual environment (mediapipe 0.10.21 pins numpy<2; the runtime never imports it)::

    python3 -m venv /work/mpvenv
    /work/mpvenv/bin/pip install mediapipe==0.10.21 tf2onnx tensorflow-cpu onnxruntime "numpy<2"
    /work/mpvenv/bin/python -m export mask-models --out relight_rt/models

It reads three TFLite models from the ``mediapipe==0.10.21`` wheel (the last release that bundles them;
Google, Apache-2.0) and writes:

- ``matte_pose.onnx`` (kind ``matte_pose``) from ``modules/pose_landmark/pose_landmark_full.tflite``:
  input ``image`` [1,3,256,256] RGB in [0,1] (a square region around the person); outputs
  ``segmentation`` [1,1,256,256] (person logits) and ``presence`` [1,1] (the pose flag, a probability
  that a person is in the region). The landmark, heat-map and world-landmark heads are pruned.
- ``matte_roi.onnx`` (kind ``matte_roi``) from ``modules/selfie_segmentation/selfie_segmentation.tflite``:
  input ``image`` [1,3,256,256] RGB in [0,1] (the whole image, letterboxed); output ``segmentation``
  [1,1,256,256], a person probability (sigmoid applied). Its MediaPipe custom op
  Convolution2DTransposeBias (tf2onnx leaves it as is) is rewritten as an ONNX ConvTranspose with bias.
- ``matte_face.onnx`` (kind ``matte_face``, issue 33) from
  ``modules/face_detection/face_detection_full_range_sparse.tflite`` (BlazeFace, full range): input ``image``
  [1,3,192,192] RGB in [0,1] (the graph maps it to the [-1, 1] the model reads); outputs ``boxes``
  [1,16,48,48] and ``scores`` [1,1,48,48] (logits): one anchor per cell of a 48x48 grid (cell centre
  ((j + 0.5) / 48, (i + 0.5) / 48), anchor size 1), channels 0-3 the box centre offset and size in input
  pixels, 4-15 six (x, y) key points (eyes, nose, mouth, ears). relight_rt.person.matting decodes them.

All: converted with tf2onnx, NHWC I/O turned to NCHW by a Transpose at each end (onnxruntime folds
them), weights stored as float16 with a Cast to float32 (fp16 storage, fp32 compute) where every
weight survives the round trip exactly (MediaPipe ships these weights in fp16 already, so nothing is
lost), the format-1 metadata of DESIGN.md §5, and a check against the TFLite interpreter on a
few inputs before the file is written (atomically). It also writes NOTICE-mediapipe.txt (attribution,
the changes made, and the Apache-2.0 text), which ships beside the graphs.
"""

from __future__ import annotations

import argparse
import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .config import reader

log = logging.getLogger(__name__)

MEDIAPIPE_VERSION = "0.10.21"


@dataclass(frozen=True)
class Source:
    """One converted graph: where it comes from and how its inputs and outputs are laid out."""

    tflite: str  # path inside mediapipe/
    kind: str
    outputs: dict[str, str]  # tflite output -> ours
    size: int = 256  # square input side
    signed_input: bool = False  # the TFLite model reads [-1, 1]: the graph maps our [0, 1] input to it
    grid: int = 0  # > 0: (1, grid*grid, C) anchor outputs reshaped to (1, C, grid, grid) maps


SOURCES = {
    "matte_pose.onnx": Source(
        "modules/pose_landmark/pose_landmark_full.tflite",
        "matte_pose",
        {"Identity_2": "segmentation", "Identity_1": "presence"},
    ),
    "matte_roi.onnx": Source(
        "modules/selfie_segmentation/selfie_segmentation.tflite",
        "matte_roi",
        {"activation_10": "segmentation"},
    ),
    # issue 33: faces, where the pose graph finds nobody (close portraits) and to tell people in a group apart
    "matte_face.onnx": Source(
        "modules/face_detection/face_detection_full_range_sparse.tflite",
        "matte_face",
        {"Identity": "boxes", "Identity_1": "scores"},
        size=192,
        signed_input=True,
        grid=48,
    ),
}
LICENCE = (
    "converted from Google MediaPipe {version} {path} (Copyright Google LLC, Apache License 2.0, "
    "https://github.com/google-ai-edge/mediapipe) by python -m export mask-models"
)
PARITY_TOL = 1e-2  # max |onnx - tflite| on the output probabilities (measured 4e-3: fp32 summation order)
LOGITS = ("segmentation", "scores")  # compared after a sigmoid (the selfie model's output is one already: unchanged)
PIXELS = ("boxes",)  # face-box regressions, in input pixels: compared as fractions of the input side


def _sigmoid(x: np.ndarray) -> np.ndarray:
    return 1.0 / (1.0 + np.exp(-np.clip(x.astype(np.float64), -60, 60)))


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", default="relight_rt/models", help="folder for matte_pose.onnx and matte_roi.onnx")
    p.add_argument("--fp32", action="store_true", help="store the weights as float32 (twice the size)")
    p.add_argument("--no-verify", action="store_true", help="skip the check against the TFLite interpreter")


def mediapipe_root() -> Path:
    """The installed mediapipe package folder (it must be 0.10.21: later wheels hold no .tflite)."""
    try:
        import mediapipe
    except ModuleNotFoundError:
        raise SystemExit(
            "python -m export mask-models needs mediapipe==0.10.21 in a separate venv (it pins numpy<2): "
            'pip install mediapipe==0.10.21 tf2onnx tensorflow-cpu onnxruntime "numpy<2"'
        ) from None
    if getattr(mediapipe, "__version__", "") != MEDIAPIPE_VERSION:
        log.warning("mediapipe %s installed; the models were checked with %s", mediapipe.__version__, MEDIAPIPE_VERSION)
    return Path(mediapipe.__file__).resolve().parent


# ------------------------------------------------------------------------------------------ graph edits


def _to_onnx(tflite: Path):
    import tempfile

    import tf2onnx

    dense = densify_tflite(tflite)
    if dense is None:
        model, _ = tf2onnx.convert.from_tflite(str(tflite), opset=17)
        return model
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / tflite.name
        path.write_bytes(dense)
        model, _ = tf2onnx.convert.from_tflite(str(path), opset=17)
    return model


def densify_tflite(tflite: Path) -> bytes | None:
    """A TFLite model whose sparse weights (DENSIFY ops: the face detector's) are stored dense, for tf2onnx,
    which cannot read sparse tensors; None when the model has none.

    Each sparse constant is decoded (:func:`_dense_values`) and loses its sparsity, the readers of the DENSIFY
    op's output read that constant instead, and the op goes. (The TFLite interpreter's own DENSIFY output is
    not readable from Python: it shows zeros.) verify() checks the result against the sparse original."""
    import flatbuffers
    from tensorflow.lite.python import schema_py_generated as schema

    buf = tflite.read_bytes()
    model = schema.ModelT.InitFromObj(schema.Model.GetRootAsModel(buf, 0))
    densify = {
        i for i, c in enumerate(model.operatorCodes)
        if max(c.builtinCode, c.deprecatedBuiltinCode) == schema.BuiltinOperator.DENSIFY
    }  # fmt: skip
    g = model.subgraphs[0]
    ops = [op for op in g.operators if op.opcodeIndex in densify]
    if not ops:
        return None
    replace = {}
    for op in ops:
        src, dst = int(op.inputs[0]), int(op.outputs[0])
        t = g.tensors[src]
        dtype = {schema.TensorType.FLOAT16: np.float16, schema.TensorType.FLOAT32: np.float32}[t.type]
        values = np.frombuffer(bytes(model.buffers[t.buffer].data), dtype)
        dense = _dense_values(values, [int(d) for d in t.shape], t.sparsity, schema, t.name)
        t.sparsity = None
        t.shapeSignature = None
        model.buffers[t.buffer].data = np.frombuffer(dense.tobytes(), np.uint8)
        replace[dst] = src
    g.operators = [op for op in g.operators if op.opcodeIndex not in densify]
    for op in g.operators:
        op.inputs = np.array([replace.get(int(i), int(i)) for i in op.inputs], np.int32)
    builder = flatbuffers.Builder(len(buf) * 2)
    builder.Finish(model.Pack(builder), file_identifier=b"TFL3")
    log.info("%s: %d sparse weight tensors stored dense", tflite.name, len(ops))
    return bytes(builder.Output())


def _dense_values(values: np.ndarray, shape: list[int], sparsity, schema, name) -> np.ndarray:
    """Decode TFLite sparse storage (identity traversal order, no blocks; each dimension DENSE or SPARSE_CSR):
    walking the dimensions in order, a DENSE one repeats every position ``dense_size`` times, a CSR one keeps,
    for position p, the coordinates ``indices[segments[p]:segments[p + 1]]``; the stored values follow the
    positions of the last dimension."""
    order = [int(v) for v in sparsity.traversalOrder]
    if order != list(range(len(shape))) or (sparsity.blockMap is not None and len(sparsity.blockMap)):
        raise RuntimeError(f"{name}: sparse layout with traversal {order} / blocks not supported")
    coords = np.zeros((1, 0), np.int64)
    for axis, dm in enumerate(sparsity.dimMetadata):
        if dm.format == schema.DimensionType.DENSE:
            n = int(dm.denseSize)
            coords = np.concatenate([np.repeat(coords, n, 0), np.tile(np.arange(n), len(coords))[:, None]], 1)
        else:
            seg = np.asarray(dm.arraySegments.values, np.int64)
            idx = np.asarray(dm.arrayIndices.values, np.int64)
            if len(seg) != len(coords) + 1:
                raise RuntimeError(f"{name}: axis {axis}: {len(seg)} segments for {len(coords)} positions")
            counts = np.diff(seg)
            coords = np.concatenate([np.repeat(coords, counts, 0), idx[:, None]], 1)
    if len(coords) != values.size:
        raise RuntimeError(f"{name}: {values.size} stored values for {len(coords)} positions")
    dense = np.zeros(shape, values.dtype)
    dense[tuple(coords.T)] = values
    return dense


def rewrite_transpose_conv_bias(model) -> int:
    """Replace MediaPipe's Convolution2DTransposeBias (NHWC, OHWI weights, bias) by ONNX ConvTranspose.

    tf2onnx feeds the custom op through a Transpose NCHW->NHWC; the ConvTranspose takes the NCHW tensor
    before it, and a Transpose NCHW->NHWC after it restores what the rest of the graph expects. The
    kernel size is read from the weights and the stride from the input/output shapes (the custom
    options, a packed C struct, are not readable by tf2onnx). Returns how many nodes were rewritten.
    """
    import onnx
    from onnx import helper, numpy_helper

    g = model.graph
    inits = {t.name: t for t in g.initializer}
    producer = {o: n for n in g.node for o in n.output}
    count = 0
    for index, node in enumerate(list(g.node)):
        if node.op_type != "TFL_Convolution2DTransposeBias":
            continue
        x, w_name, b_name = node.input
        w = numpy_helper.to_array(inits[w_name])  # (out, kh, kw, in)
        b = numpy_helper.to_array(inits[b_name]).reshape(-1)
        pre = producer.get(x)
        perm = [a.ints for a in pre.attribute if a.name == "perm"] if pre is not None else []
        if pre is None or pre.op_type != "Transpose" or list(perm[0]) != [0, 2, 3, 1]:
            raise RuntimeError(f"{node.name}: expected its input from a Transpose NCHW->NHWC, got {pre}")
        kh, kw = int(w.shape[1]), int(w.shape[2])
        stride = (kh, kw)  # MediaPipe's decoders upsample exactly x2 with 2x2 kernels; checked by verify()
        w_onnx = np.ascontiguousarray(w.transpose(3, 0, 1, 2))  # (in, out, kh, kw)
        w_new, b_new, y_nchw = f"{node.name}_W_iokk", f"{node.name}_B", f"{node.name}_nchw"
        g.initializer.extend([numpy_helper.from_array(w_onnx, w_new), numpy_helper.from_array(b, b_new)])
        conv = helper.make_node(
            "ConvTranspose", [pre.input[0], w_new, b_new], [y_nchw], name=f"{node.name}_convT",
            kernel_shape=[kh, kw], strides=list(stride), pads=[0, 0, 0, 0],
        )  # fmt: skip
        back = helper.make_node(
            "Transpose", [y_nchw], list(node.output), name=f"{node.name}_to_nhwc", perm=[0, 2, 3, 1]
        )
        g.node.remove(node)
        g.node.insert(index, back)
        g.node.insert(index, conv)
        count += 1
    # drop initializers nobody reads any more
    used = {i for n in g.node for i in n.input}
    for t in [t for t in g.initializer if t.name not in used]:
        g.initializer.remove(t)
    onnx.checker.check_model(model)
    return count


def nchw_io(model, outputs: dict[str, str], size: int = 256, signed_input: bool = False, grid: int = 0):
    """One NCHW input ``image`` [1,3,size,size] in [0, 1] and the named ``outputs`` (old -> new), NCHW, others
    pruned. ``signed_input``: the model reads [-1, 1] (2x - 1 is added to the graph). ``grid``: outputs of
    shape (1, grid*grid, C) (one anchor per cell, row-major) become (1, C, grid, grid) maps."""
    import onnx
    from onnx import TensorProto, helper, numpy_helper

    g = model.graph
    if len(g.input) != 1:
        raise RuntimeError(f"expected one graph input, got {[i.name for i in g.input]}")
    old_in = g.input[0]
    dims = [d.dim_value for d in old_in.type.tensor_type.shape.dim]
    if dims[1:] != [size, size, 3]:
        raise RuntimeError(f"expected an NHWC [1,{size},{size},3] input, got {dims}")
    first = [helper.make_node("Transpose", ["image"], ["image_nhwc" if signed_input else old_in.name],
                              name="image_to_nhwc", perm=[0, 2, 3, 1])]  # fmt: skip
    if signed_input:
        g.initializer.extend([numpy_helper.from_array(np.array(2.0, np.float32), "image_scale"),
                              numpy_helper.from_array(np.array(-1.0, np.float32), "image_shift")])  # fmt: skip
        first += [helper.make_node("Mul", ["image_nhwc", "image_scale"], ["image_x2"], name="image_x2"),
                  helper.make_node("Add", ["image_x2", "image_shift"], [old_in.name], name="image_signed")]  # fmt: skip
    for node in reversed(first):
        g.node.insert(0, node)
    g.input.remove(old_in)
    g.input.append(helper.make_tensor_value_info("image", TensorProto.FLOAT, [1, 3, size, size]))
    old_out = {o.name: o for o in g.output}
    missing = sorted(set(outputs) - set(old_out))
    if missing:
        raise RuntimeError(f"outputs {missing} not in the graph (it has {sorted(old_out)})")
    for o in list(g.output):
        g.output.remove(o)
    for old, new in outputs.items():
        dims = [d.dim_value for d in old_out[old].type.tensor_type.shape.dim]
        if grid and len(dims) == 3:  # (1, grid*grid, C) -> (1, grid, grid, C) -> NCHW
            if dims[1] != grid * grid:
                raise RuntimeError(f"{old}: expected {grid * grid} anchors, got {dims}")
            g.initializer.append(numpy_helper.from_array(np.array([1, grid, grid, dims[2]], np.int64), f"{new}_grid"))
            g.node.append(helper.make_node("Reshape", [old, f"{new}_grid"], [f"{new}_nhwc"], name=f"{new}_grid"))
            g.node.append(
                helper.make_node("Transpose", [f"{new}_nhwc"], [new], name=f"{new}_to_nchw", perm=[0, 3, 1, 2])
            )
            shape = [1, dims[2], grid, grid]
        elif len(dims) == 4:  # NHWC -> NCHW
            g.node.append(helper.make_node("Transpose", [old], [new], name=f"{new}_to_nchw", perm=[0, 3, 1, 2]))
            shape = [dims[0], dims[3], dims[1], dims[2]]
        else:
            g.node.append(helper.make_node("Identity", [old], [new], name=f"{new}_out"))
            shape = dims
        g.output.append(helper.make_tensor_value_info(new, TensorProto.FLOAT, shape))
    # prune every node no output depends on
    needed = {o.name for o in g.output}
    keep = []
    for node in reversed(list(g.node)):
        if any(o in needed for o in node.output):
            keep.append(node)
            needed.update(node.input)
    keep.reverse()
    del g.node[:]
    g.node.extend(keep)
    for t in [t for t in g.initializer if t.name not in needed]:
        g.initializer.remove(t)
    for v in [v for v in g.value_info if v.name not in needed]:
        g.value_info.remove(v)
    onnx.checker.check_model(model)
    return model


def fp16_storage(model) -> int:
    """Store float32 weights that round-trip exactly through float16 as float16 + Cast; returns how many."""
    from onnx import TensorProto, helper, numpy_helper

    g = model.graph
    casts, count = [], 0
    for t in list(g.initializer):
        if t.data_type != TensorProto.FLOAT:
            continue
        a = numpy_helper.to_array(t)
        if a.size < 16:
            continue
        h = a.astype(np.float16)
        if not np.array_equal(h.astype(np.float32), a):
            log.info("%s: kept in float32 (not exact in float16)", t.name)
            continue
        name16 = f"{t.name}__fp16"
        g.initializer.remove(t)
        g.initializer.append(numpy_helper.from_array(h, name16))
        casts.append(helper.make_node("Cast", [name16], [t.name], name=f"{t.name}__cast", to=TensorProto.FLOAT))
        count += 1
    for c in reversed(casts):
        g.node.insert(0, c)
    return count


def set_metadata(model, kind: str, source: str, size: int = 256) -> None:
    from relight_rt.engine.contract import ModelConfig

    # "batch": normalisation (folded into the convolutions) uses fixed statistics, none per sample
    meta = ModelConfig(kind=kind, resolution=size, norm="batch", source=source).metadata()
    del model.metadata_props[:]
    for k, v in meta.items():
        entry = model.metadata_props.add()
        entry.key, entry.value = k, v
    model.producer_name = "relight_rt export.mask_models"


def convert(tflite: Path, spec: Source, source: str, fp16: bool = True):
    """Convert one MediaPipe TFLite model into a relight_rt graph (an onnx.ModelProto)."""
    model = _to_onnx(tflite)
    n = rewrite_transpose_conv_bias(model)
    if n:
        log.info("%s: %d Convolution2DTransposeBias -> ConvTranspose", tflite.name, n)
    nchw_io(model, spec.outputs, spec.size, spec.signed_input, spec.grid)
    if fp16:
        log.info("%s: %d weight tensors stored as float16", tflite.name, fp16_storage(model))
    set_metadata(model, spec.kind, source, spec.size)
    import onnx

    onnx.checker.check_model(model)
    return model


# ---------------------------------------------------------------------------------------------- checks


def test_inputs(seed: int = 0, size: int = 256) -> list[np.ndarray]:
    """NHWC [1,size,size,3] float32 inputs in [0, 1]: noise, a flat gray, a smooth blob, and the bundled example
    person (relight_rt/data/example.png, a rendered person) letterboxed, and its head enlarged (a face for the
    face detector)."""
    import cv2

    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:size, 0:size] / (size - 1.0)
    blob = np.exp(-(((xx - 0.5) / 0.15) ** 2 + ((yy - 0.55) / 0.35) ** 2))
    blob = np.stack([blob * 0.8, blob * 0.5 + 0.2, 1 - blob], -1)
    example = Path(__file__).resolve().parents[1] / "relight_rt" / "data" / "example.png"
    person = []
    if example.is_file():
        rgba = cv2.imread(str(example), cv2.IMREAD_UNCHANGED)
        img = cv2.cvtColor(rgba[..., :3], cv2.COLOR_BGR2RGB)
        for crop in (img, _head(img, rgba[..., 3])):
            h, w = crop.shape[:2]
            s = size / max(h, w)
            small = cv2.resize(crop, (max(1, round(w * s)), max(1, round(h * s))), interpolation=cv2.INTER_AREA)
            canvas = np.zeros((size, size, 3), np.uint8)
            canvas[: small.shape[0], : small.shape[1]] = small
            person.append(canvas[None].astype(np.float32) / 255.0)
    return [
        *person,
        rng.random((1, size, size, 3), dtype=np.float32),
        np.full((1, size, size, 3), 0.5, np.float32),
        blob[None].astype(np.float32),
    ]


def _head(img: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """A square crop around the top of the person (their head), from the alpha channel's rows and columns."""
    ys, xs = np.nonzero(alpha > 127)
    if ys.size == 0:
        return img
    y0 = int(ys.min())
    top = xs[ys < y0 + max(2, (ys.max() - y0) // 8)]
    side = max(8, int((ys.max() - y0) // 5))
    cx = int(top.mean())
    x0 = max(cx - side // 2, 0)
    return img[max(y0 - side // 8, 0) : y0 + side, x0 : x0 + side]


def run_tflite(tflite: Path, x_nhwc: np.ndarray) -> dict[str, np.ndarray]:
    """Outputs of the TFLite interpreter (tensorflow's) on one NHWC input, by tensor name."""
    import tensorflow as tf

    interp = tf.lite.Interpreter(model_path=str(tflite))
    interp.allocate_tensors()
    interp.set_tensor(interp.get_input_details()[0]["index"], x_nhwc)
    interp.invoke()
    return {d["name"]: interp.get_tensor(d["index"]) for d in interp.get_output_details()}


def verify(onnx_bytes: bytes, tflite: Path, spec: Source, inputs: list[np.ndarray]) -> float:
    """Largest |onnxruntime - TFLite| over ``inputs`` (NHWC, [0, 1]) and the spec's outputs: probabilities for
    logits, fractions of the input side for box regressions."""
    import onnxruntime as ort

    sess = ort.InferenceSession(onnx_bytes, providers=["CPUExecutionProvider"])
    names = [o.name for o in sess.get_outputs()]
    worst = 0.0
    for x in inputs:
        ref = run_tflite(tflite, 2 * x - 1 if spec.signed_input else x)
        got = dict(zip(names, sess.run(None, {"image": x.transpose(0, 3, 1, 2)}), strict=True))
        for old, new in spec.outputs.items():
            g = got[new]
            if g.ndim == 4:
                g = g.transpose(0, 2, 3, 1)
            r = ref[old].reshape(g.shape)  # anchor lists (1, grid*grid, C) are row-major (1, grid, grid, C)
            if new in LOGITS:  # logits reach +-2000 on flat regions: compare what is used, the probability
                g, r = _sigmoid(g), _sigmoid(r)
            elif new in PIXELS:
                g, r = g / spec.size, r / spec.size
            worst = max(worst, float(np.abs(g - r).max()))
    return worst


NOTICE_FILE = "NOTICE-mediapipe.txt"
NOTICE_HEAD = """relight_rt/models/matte_pose.onnx, matte_roi.onnx, matte_face.onnx, face_mesh.onnx and
face_mesh_triangles.txt

These files are derived from models of Google MediaPipe {version}
(https://github.com/google-ai-edge/mediapipe), Copyright The MediaPipe Authors / Google LLC,
licensed under the Apache License, Version 2.0 (the text follows):

- matte_pose.onnx from mediapipe/modules/pose_landmark/pose_landmark_full.tflite
- matte_roi.onnx from mediapipe/modules/selfie_segmentation/selfie_segmentation.tflite
- matte_face.onnx from mediapipe/modules/face_detection/face_detection_full_range_sparse.tflite
- face_mesh.onnx from mediapipe/modules/face_landmark/face_landmark.tflite
- face_mesh_triangles.txt from mediapipe/python/solutions/face_mesh_connections.py (FACEMESH_TESSELATION)

Changes made by relight_rt (python -m export mask-models, export/mask_models.py): converted from
TFLite to ONNX with tf2onnx; the custom op Convolution2DTransposeBias rewritten as ConvTranspose;
inputs and outputs renamed and turned from NHWC to NCHW; the landmark, heat-map and world-landmark
outputs of the pose model removed; the face detector's sparse weights stored dense, its input
mapped from [0, 1] to the [-1, 1] it reads, and its per-anchor outputs laid out as 48x48 maps;
weights stored as float16 (exactly the values MediaPipe ships); relight_rt metadata added. The
weights themselves are unchanged. face_mesh.onnx and face_mesh_triangles.txt (python -m export face-mesh,
export/face_mesh.py): the landmarker converted the same way, its outputs flattened; the triangles are the
3-cliques of the tessellation's edge list.

"""


def notice_text(root: Path) -> str:
    """NOTICE for the converted graphs: attribution, changes, and the Apache-2.0 text from the wheel."""
    dist = sorted(root.parent.glob("mediapipe-*.dist-info"))
    licence = (dist[-1] / "LICENSE").read_text(encoding="utf-8") if dist else ""
    marker = "=" * 20  # the wheel's LICENSE appends third-party notices (for code we do not use) after the Apache text
    licence = licence.split(marker)[0].rstrip() + "\n"
    if "Apache License" not in licence:
        raise SystemExit(f"could not read the Apache-2.0 text from the mediapipe wheel ({dist})")
    return NOTICE_HEAD.format(version=MEDIAPIPE_VERSION) + licence


@dataclass(frozen=True, kw_only=True)
class MaskModelsConfig:
    """The settings of ``mask-models`` (one field per flag; see :func:`add_arguments`)."""

    out: Path = Path("relight_rt/models")
    fp32: bool = False
    no_verify: bool = False


config_from_args = reader(MaskModelsConfig)


def run(config: MaskModelsConfig) -> int:
    from relight_rt.engine.files import atomic_path

    root = mediapipe_root()
    out = Path(config.out)
    out.mkdir(parents=True, exist_ok=True)
    for name, spec in SOURCES.items():
        rel = spec.tflite
        tflite = root / rel
        if not tflite.is_file():
            raise SystemExit(
                f"{tflite} not found: install mediapipe=={MEDIAPIPE_VERSION} (later wheels hold no .tflite)"
            )
        source = LICENCE.format(version=MEDIAPIPE_VERSION, path=f"mediapipe/{rel}")
        model = convert(tflite, spec, source, fp16=not config.fp32)
        data = model.SerializeToString()
        if not config.no_verify:
            err = verify(data, tflite, spec, test_inputs(size=spec.size))
            log.info("%s: max |onnx - tflite| = %.2e", name, err)
            if err > PARITY_TOL:
                raise SystemExit(f"{name}: converted graph differs from the TFLite model by {err:.3g} > {PARITY_TOL}")
        with atomic_path(out / name) as tmp:
            tmp.write_bytes(data)
        log.info("wrote %s (%.2f MB, kind %s)", out / name, len(data) / 1e6, spec.kind)
    with atomic_path(out / NOTICE_FILE) as tmp:
        tmp.write_text(notice_text(root), encoding="utf-8")
    log.info("wrote %s", out / NOTICE_FILE)
    return 0
