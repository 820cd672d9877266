"""``python -m export face-mesh``: MediaPipe's face landmarker as a relight_rt graph, and its triangle table.

Runs in the mediapipe venv of ``export.mask_models`` (mediapipe 0.10.21 pins numpy<2; the runtime never imports it)::

    /work/mpvenv/bin/python -m export face-mesh --out relight_rt/models

Writes, from the ``mediapipe==0.10.21`` wheel (Google, Apache-2.0; the attribution is in NOTICE-mediapipe.txt,
which ``mask-models`` writes):

- ``face_mesh.onnx`` from ``modules/face_landmark/face_landmark.tflite``: input ``image`` [1,3,192,192] RGB in
  [0,1] (a square around a face, upright); outputs ``landmarks`` [1,1404] (468 points x (x, y, z): x, y in input
  pixels of the 192 square, z depth in the same units, smaller = nearer the camera) and ``face_flag`` [1,1] (logit
  that a face is in the square). Converted as the matting graphs are (tf2onnx, NCHW input, float16 storage).
- ``face_mesh_triangles.txt`` ((T, 3) vertex indices, one triangle a line): the mesh's triangles, recovered
  from the wheel's tessellation edge list (``FACEMESH_TESSELATION`` in
  ``mediapipe.python.solutions.face_mesh_connections``) as its 3-cliques. Not wound: every triangle seen from the
  camera faces it, so the runtime turns each normal toward the camera.

relight_rt.person.face_mesh uses both: normals of the face for the relighting factor.
"""

from __future__ import annotations

import argparse
import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from export.config import reader
from export.mask_models import LICENCE, MEDIAPIPE_VERSION, NOTICE_FILE, _to_onnx, fp16_storage, mediapipe_root, nchw_io

log = logging.getLogger(__name__)

TFLITE = "modules/face_landmark/face_landmark.tflite"
OUTPUTS = {"conv2d_21": "landmarks", "conv2d_31": "face_flag"}
SIZE = 192


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", default="relight_rt/models", help="folder for face_mesh.onnx and its triangles")


def triangles_from_edges(edges) -> np.ndarray:
    """(T, 3) int array: every 3-clique of an undirected edge list (vertex triples joined pairwise), sorted."""
    adj: dict[int, set[int]] = {}
    for a, b in edges:
        adj.setdefault(int(a), set()).add(int(b))
        adj.setdefault(int(b), set()).add(int(a))
    tris = set()
    for a, nbrs in adj.items():
        for b in nbrs:
            if b <= a:
                continue
            for c in nbrs & adj[b]:
                if c > b:
                    tris.add((a, b, c))
    return np.array(sorted(tris), np.int64).reshape(-1, 3)


def convert(root: Path):
    import onnx
    from onnx import helper

    model = _to_onnx(root / TFLITE)
    nchw_io(model, OUTPUTS, SIZE)
    g = model.graph  # the outputs are (1, 1, 1, C) NHWC -> (1, C, 1, 1) after nchw_io: flatten them
    for o in list(g.output):
        flat = f"{o.name}_flat"
        for node in g.node:
            node.output[:] = [flat if x == o.name else x for x in node.output]
        g.node.append(helper.make_node("Flatten", [flat], [o.name], name=f"{o.name}_flatten", axis=1))
        dims = [d.dim_value for d in o.type.tensor_type.shape.dim]
        g.output.remove(o)
        g.output.append(helper.make_tensor_value_info(o.name, onnx.TensorProto.FLOAT, [1, int(np.prod(dims[1:]))]))
    log.info("face_mesh: %d weight tensors stored as float16", fp16_storage(model))
    meta = {"relight_rt.kind": "face_mesh", "relight_rt.resolution": str(SIZE),
            "relight_rt.source": LICENCE.format(version=MEDIAPIPE_VERSION, path=TFLITE)}
    del model.metadata_props[:]
    for k, v in meta.items():
        e = model.metadata_props.add()
        e.key, e.value = k, v
    model.producer_name = "relight_rt export.face_mesh"
    onnx.checker.check_model(model)
    return model


@dataclass(frozen=True, kw_only=True)
class FaceMeshConfig:
    """The settings of ``face-mesh`` (one field per flag; see :func:`add_arguments`)."""

    out: Path = Path("relight_rt/models")


config_from_args = reader(FaceMeshConfig)


def run(config: FaceMeshConfig) -> int:
    import onnxruntime as ort
    import tensorflow as tf
    from mediapipe.python.solutions.face_mesh_connections import FACEMESH_TESSELATION

    from relight_rt.engine.files import atomic_path

    root = mediapipe_root()
    out = Path(config.out)
    out.mkdir(parents=True, exist_ok=True)
    model = convert(root)
    # parity with the TFLite interpreter on a smooth random image
    rng = np.random.default_rng(0)
    x = cv2_free_blur(rng.random((1, SIZE, SIZE, 3)).astype(np.float32))
    interp = tf.lite.Interpreter(model_path=str(root / TFLITE))
    interp.allocate_tensors()
    interp.set_tensor(interp.get_input_details()[0]["index"], x)
    interp.invoke()
    want = {d["name"]: interp.get_tensor(d["index"]).reshape(1, -1) for d in interp.get_output_details()}
    sess = ort.InferenceSession(model.SerializeToString(), providers=["CPUExecutionProvider"])
    got = dict(zip(["landmarks", "face_flag"], sess.run(["landmarks", "face_flag"],
                                                        {"image": x.transpose(0, 3, 1, 2).copy()}), strict=True))
    err = float(np.abs(got["landmarks"] - want["conv2d_21"]).max())
    log.info("face_mesh: max |onnx - tflite| landmarks %.2e px", err)
    if err > 0.05:
        raise SystemExit(f"face_mesh.onnx differs from the TFLite model by {err} px")
    with atomic_path(out / "face_mesh.onnx") as tmp:
        tmp.write_bytes(model.SerializeToString())
    tris = triangles_from_edges(FACEMESH_TESSELATION)
    with atomic_path(out / "face_mesh_triangles.txt") as tmp:
        np.savetxt(tmp, tris, fmt="%d", header=f"{len(tris)} triangles of MediaPipe's face mesh (see {NOTICE_FILE})")
    log.info("face_mesh: %d triangles from %d edges", len(tris), len(FACEMESH_TESSELATION))
    return 0


def cv2_free_blur(x: np.ndarray, k: int = 9) -> np.ndarray:
    """A box blur along both image axes (numpy only), so the test image has structure at a face's scale."""
    for axis in (1, 2):
        x = np.mean([np.roll(x, s, axis=axis) for s in range(-k, k + 1)], axis=0)
    return x.astype(np.float32)
