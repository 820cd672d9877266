"""``python -m export mask-models``: convert MediaPipe's person-segmentation models to relight_rt graphs.

Runs in its OWN virtual environment (mediapipe 0.10.21 pins numpy<2; the runtime never imports it)::

    python3 -m venv /work/mpvenv
    /work/mpvenv/bin/pip install mediapipe==0.10.21 tf2onnx tensorflow-cpu onnxruntime "numpy<2"
    /work/mpvenv/bin/python -m export mask-models --out relight_rt/models

It reads two TFLite models from the ``mediapipe==0.10.21`` wheel (the last release that bundles them;
Google, Apache-2.0) and writes:

- ``matte_pose.onnx`` (kind ``matte_pose``) from ``modules/pose_landmark/pose_landmark_full.tflite``:
  input ``image`` [1,3,256,256] RGB in [0,1] (a square region around the person); outputs
  ``segmentation`` [1,1,256,256] (person logits) and ``presence`` [1,1] (the pose flag, a probability
  that a person is in the region). The landmark, heat-map and world-landmark heads are pruned.
- ``matte_roi.onnx`` (kind ``matte_roi``) from ``modules/selfie_segmentation/selfie_segmentation.tflite``:
  input ``image`` [1,3,256,256] RGB in [0,1] (the whole image, letterboxed); output ``segmentation``
  [1,1,256,256], a person probability (sigmoid applied). Its MediaPipe custom op
  Convolution2DTransposeBias (tf2onnx leaves it as is) is rewritten as an ONNX ConvTranspose with bias.

Both: converted with tf2onnx, NHWC I/O turned to NCHW by a Transpose at each end (onnxruntime folds
them), weights stored as float16 with a Cast to float32 (fp16 storage, fp32 compute) where every
weight survives the round trip exactly (MediaPipe ships these weights in fp16 already, so nothing is
lost), the format-1 metadata of DESIGN.md §5, and a check against the TFLite interpreter on a
few inputs before the file is written (atomically). It also writes NOTICE-mediapipe.txt (attribution,
the changes made, and the Apache-2.0 text), which ships beside the graphs.
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)

MEDIAPIPE_VERSION = "0.10.21"
SOURCES = {
    # file name -> (tflite path inside mediapipe/, kind, {tflite output: our output})
    "matte_pose.onnx": (
        "modules/pose_landmark/pose_landmark_full.tflite",
        "matte_pose",
        {"Identity_2": "segmentation", "Identity_1": "presence"},
    ),
    "matte_roi.onnx": (
        "modules/selfie_segmentation/selfie_segmentation.tflite",
        "matte_roi",
        {"activation_10": "segmentation"},
    ),
}
LICENCE = (
    "converted from Google MediaPipe {version} {path} (Copyright Google LLC, Apache License 2.0, "
    "https://github.com/google-ai-edge/mediapipe) by python -m export mask-models"
)
PARITY_TOL = 1e-2  # max |onnx - tflite| on the output probabilities (measured 4e-3: fp32 summation order)
LOGITS = ("segmentation",)  # compared after a sigmoid (the selfie model's output is one already: unchanged)


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
    import tf2onnx

    model, _ = tf2onnx.convert.from_tflite(str(tflite), opset=17)
    return model


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


def nchw_io(model, outputs: dict[str, str]):
    """One NCHW input ``image`` [1,3,256,256] and the named ``outputs`` (old -> new), NCHW, others pruned."""
    import onnx
    from onnx import TensorProto, helper

    g = model.graph
    if len(g.input) != 1:
        raise RuntimeError(f"expected one graph input, got {[i.name for i in g.input]}")
    old_in = g.input[0]
    dims = [d.dim_value for d in old_in.type.tensor_type.shape.dim]
    if dims[1:] != [256, 256, 3]:
        raise RuntimeError(f"expected an NHWC [1,256,256,3] input, got {dims}")
    g.node.insert(0, helper.make_node("Transpose", ["image"], [old_in.name], name="image_to_nhwc", perm=[0, 2, 3, 1]))
    g.input.remove(old_in)
    g.input.append(helper.make_tensor_value_info("image", TensorProto.FLOAT, [1, 3, 256, 256]))
    old_out = {o.name: o for o in g.output}
    missing = sorted(set(outputs) - set(old_out))
    if missing:
        raise RuntimeError(f"outputs {missing} not in the graph (it has {sorted(old_out)})")
    for o in list(g.output):
        g.output.remove(o)
    for old, new in outputs.items():
        dims = [d.dim_value for d in old_out[old].type.tensor_type.shape.dim]
        if len(dims) == 4:  # NHWC -> NCHW
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


def set_metadata(model, kind: str, source: str) -> None:
    from relight_rt.contract import ModelConfig

    # "batch": normalisation (folded into the convolutions) uses fixed statistics, none per sample
    meta = ModelConfig(kind=kind, resolution=256, norm="batch", source=source).metadata()
    del model.metadata_props[:]
    for k, v in meta.items():
        entry = model.metadata_props.add()
        entry.key, entry.value = k, v
    model.producer_name = "relight_rt export.mask_models"


def convert(tflite: Path, kind: str, outputs: dict[str, str], source: str, fp16: bool = True):
    """Convert one MediaPipe TFLite model into a relight_rt graph (an onnx.ModelProto)."""
    model = _to_onnx(tflite)
    n = rewrite_transpose_conv_bias(model)
    if n:
        log.info("%s: %d Convolution2DTransposeBias -> ConvTranspose", tflite.name, n)
    nchw_io(model, outputs)
    if fp16:
        log.info("%s: %d weight tensors stored as float16", tflite.name, fp16_storage(model))
    set_metadata(model, kind, source)
    import onnx

    onnx.checker.check_model(model)
    return model


# ---------------------------------------------------------------------------------------------- checks


def test_inputs(seed: int = 0) -> list[np.ndarray]:
    """NHWC [1,256,256,3] float32 inputs: noise, a flat gray, a smooth blob, and the bundled example person
    (relight_rt/data/example.png, a rendered person) letterboxed to 256x256."""
    import cv2

    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:256, 0:256] / 255.0
    blob = np.exp(-(((xx - 0.5) / 0.15) ** 2 + ((yy - 0.55) / 0.35) ** 2))
    blob = np.stack([blob * 0.8, blob * 0.5 + 0.2, 1 - blob], -1)
    example = Path(__file__).resolve().parents[1] / "relight_rt" / "data" / "example.png"
    person = []
    if example.is_file():
        img = cv2.cvtColor(cv2.imread(str(example), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
        h, w = img.shape[:2]
        s = 256 / max(h, w)
        small = cv2.resize(img, (max(1, round(w * s)), max(1, round(h * s))), interpolation=cv2.INTER_AREA)
        canvas = np.zeros((256, 256, 3), np.uint8)
        canvas[: small.shape[0], : small.shape[1]] = small
        person = [canvas[None].astype(np.float32) / 255.0]
    return [
        *person,
        rng.random((1, 256, 256, 3), dtype=np.float32),
        np.full((1, 256, 256, 3), 0.5, np.float32),
        blob[None].astype(np.float32),
    ]


def run_tflite(tflite: Path, x_nhwc: np.ndarray) -> dict[str, np.ndarray]:
    """Outputs of the TFLite interpreter (tensorflow's) on one NHWC input, by tensor name."""
    import tensorflow as tf

    interp = tf.lite.Interpreter(model_path=str(tflite))
    interp.allocate_tensors()
    interp.set_tensor(interp.get_input_details()[0]["index"], x_nhwc)
    interp.invoke()
    return {d["name"]: interp.get_tensor(d["index"]) for d in interp.get_output_details()}


def verify(onnx_bytes: bytes, tflite: Path, outputs: dict[str, str], inputs: list[np.ndarray]) -> float:
    """Largest |onnxruntime - TFLite| over ``inputs`` and the named ``outputs`` (TFLite name -> ours)."""
    import onnxruntime as ort

    sess = ort.InferenceSession(onnx_bytes, providers=["CPUExecutionProvider"])
    names = [o.name for o in sess.get_outputs()]
    worst = 0.0
    for x in inputs:
        ref = run_tflite(tflite, x)
        got = dict(zip(names, sess.run(None, {"image": x.transpose(0, 3, 1, 2)}), strict=True))
        for old, new in outputs.items():
            g = got[new]
            if g.ndim == 4:
                g = g.transpose(0, 2, 3, 1)
            r = ref[old]
            if new in LOGITS:  # logits reach +-2000 on flat regions: compare what is used, the probability
                g, r = _sigmoid(g), _sigmoid(r)
            worst = max(worst, float(np.abs(g - r).max()))
    return worst


NOTICE_FILE = "NOTICE-mediapipe.txt"
NOTICE_HEAD = """relight_rt/models/matte_pose.onnx and relight_rt/models/matte_roi.onnx

These two files are derived from models of Google MediaPipe {version}
(https://github.com/google-ai-edge/mediapipe), Copyright The MediaPipe Authors / Google LLC,
licensed under the Apache License, Version 2.0 (the text follows):

- matte_pose.onnx from mediapipe/modules/pose_landmark/pose_landmark_full.tflite
- matte_roi.onnx from mediapipe/modules/selfie_segmentation/selfie_segmentation.tflite

Changes made by relight_rt (python -m export mask-models, export/mask_models.py): converted from
TFLite to ONNX with tf2onnx; the custom op Convolution2DTransposeBias rewritten as ConvTranspose;
inputs and outputs renamed and turned from NHWC to NCHW; the landmark, heat-map and world-landmark
outputs of the pose model removed; weights stored as float16 (exactly the values MediaPipe ships);
relight_rt metadata added. The weights themselves are unchanged.

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


def run(args: argparse.Namespace) -> int:
    from relight_rt._io import atomic_path

    root = mediapipe_root()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for name, (rel, kind, outputs) in SOURCES.items():
        tflite = root / rel
        if not tflite.is_file():
            raise SystemExit(
                f"{tflite} not found: install mediapipe=={MEDIAPIPE_VERSION} (later wheels hold no .tflite)"
            )
        source = LICENCE.format(version=MEDIAPIPE_VERSION, path=f"mediapipe/{rel}")
        model = convert(tflite, kind, outputs, source, fp16=not args.fp32)
        data = model.SerializeToString()
        if not args.no_verify:
            err = verify(data, tflite, outputs, test_inputs())
            log.info("%s: max |onnx - tflite| = %.2e", name, err)
            if err > PARITY_TOL:
                raise SystemExit(f"{name}: converted graph differs from the TFLite model by {err:.3g} > {PARITY_TOL}")
        with atomic_path(out / name) as tmp:
            tmp.write_bytes(data)
        log.info("wrote %s (%.2f MB, kind %s)", out / name, len(data) / 1e6, kind)
    with atomic_path(out / NOTICE_FILE) as tmp:
        tmp.write_text(notice_text(root), encoding="utf-8")
    log.info("wrote %s", out / NOTICE_FILE)
    return 0
