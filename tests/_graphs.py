"""Hand-made ONNX graphs that follow (or deliberately break) the relight_rt contract, for runtime tests.

The "analytic" stage 1 has outputs that are simple functions of its input, so results can be checked
exactly: albedo = image ⊙ mask, skin = mask / 2, transport = mask ⊙ LOBE (the unoccluded transport of a
normal facing the camera, +x), light = OWN_LIGHT, a white light with LOBE · OWN_LIGHT[:, c] = 1, so the
photo's own shading is 1 everywhere and its reconstruction is the masked input itself.
Needs the ``onnx`` package (tests only; the runtime never imports it). No torch.
"""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest

onnx = pytest.importorskip("onnx", reason='builds test graphs; pip install "relight-rt[test]"')
from onnx import TensorProto, helper, numpy_helper  # noqa: E402

from relight_rt.engine.contract import ModelConfig  # noqa: E402

# unoccluded transport of normal +x: A_l * Y_k(1, 0, 0) (DESIGN.md §3)
LOBE = np.array(
    [
        math.pi * 0.5 / math.sqrt(math.pi),
        0.0,
        0.0,
        2 * math.pi / 3 * math.sqrt(3 / (4 * math.pi)),
        0.0,
        0.0,
        math.pi / 4 * math.sqrt(5 / (16 * math.pi)) * -1.0,
        0.0,
        math.pi / 4 * math.sqrt(15 / (16 * math.pi)),
    ],
    dtype=np.float32,
)
OWN_LIGHT = np.repeat((LOBE / float(LOBE @ LOBE))[:, None], 3, axis=1).astype(np.float32)  # LOBE · L = 1


def _value(name, shape, elem=TensorProto.FLOAT):
    return helper.make_tensor_value_info(name, elem, shape)


def _model(nodes, inputs, outputs, inits, meta, opset=17) -> onnx.ModelProto:
    graph = helper.make_graph(nodes, "g", inputs, outputs, initializer=inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", opset)])
    model.ir_version = 8
    for k, v in meta.items():
        entry = model.metadata_props.add()
        entry.key, entry.value = k, v
    return model


def meta_for(kind_: str, resolution: int, **overrides) -> dict[str, str]:
    """Good metadata for a graph of kind ``kind_``; overrides set relight_rt.KEY (None removes it)."""
    meta = ModelConfig(kind=kind_, resolution=resolution, norm="instance", source="tests/_graphs.py").metadata()
    for key, value in overrides.items():
        full = f"relight_rt.{key}"
        if value is None:
            meta.pop(full, None)
        else:
            meta[full] = value
    return meta


def stage1_model(resolution=64, *, meta=None, image_name="image", elem=TensorProto.FLOAT, rank=4, size=None,
                 light=OWN_LIGHT) -> onnx.ModelProto:  # fmt: skip
    """The analytic stage 1 (see the module docstring); keyword arguments break the contract on purpose."""
    r = resolution if size is None else size
    img_shape = ["N", 3, r, r] if rank == 4 else ["N", 3 * r * r]  # rank != 4: flat, reshaped inside
    inits = [
        numpy_helper.from_array(LOBE.reshape(1, 9, 1, 1), "lobe"),
        numpy_helper.from_array(np.asarray(light, np.float32).reshape(1, 9, 3), "own_light"),
        numpy_helper.from_array(np.array(0.5, np.float32), "half"),
        numpy_helper.from_array(np.array(0.0, np.float32), "zero"),
        numpy_helper.from_array(np.array([-1, 1, 1], np.int64), "shape3"),
    ]
    if rank != 4:
        inits.append(numpy_helper.from_array(np.array([-1, 3, r, r], np.int64), "shape4"))
    nodes = [
        helper.make_node("Identity", [image_name], ["img"]),
        helper.make_node("Mul", ["img", "mask"], ["albedo"]),
        helper.make_node("Mul", ["mask", "half"], ["skin"]),
        helper.make_node("Mul", ["mask", "lobe"], ["transport"]),
        helper.make_node("ReduceMean", ["mask"], ["m_mean"], keepdims=1),
        helper.make_node("Reshape", ["m_mean", "shape3"], ["m3"]),
        helper.make_node("Mul", ["m3", "zero"], ["z3"]),
        helper.make_node("Add", ["z3", "own_light"], ["light"]),
    ]
    if elem != TensorProto.FLOAT:
        nodes[0] = helper.make_node("Cast", [image_name], ["img"], to=TensorProto.FLOAT)
    if rank != 4:
        nodes[0] = helper.make_node("Reshape", [image_name, "shape4"], ["img"])
    # ReduceMean without axes reduces everything; per-sample mean over C,H,W instead:
    nodes[4] = helper.make_node("ReduceMean", ["mask"], ["m_mean"], keepdims=1, axes=[1, 2, 3])
    inputs = [_value(image_name, img_shape, elem), _value("mask", ["N", 1, r, r])]
    outputs = [
        _value("albedo", ["N", 3, r, r]),
        _value("skin", ["N", 1, r, r]),
        _value("transport", ["N", 9, r, r]),
        _value("light", ["N", 9, 3]),
    ]
    return _model(nodes, inputs, outputs, inits, meta if meta is not None else meta_for("stage1", resolution), opset=13)


def unoccluded_transport(normal) -> np.ndarray:
    """(9,) float32 transport A_l * Y_k(n) of an unoccluded unit normal ``n`` (DESIGN.md §3 order)."""
    x, y, z = (float(v) for v in normal)
    c0, c1 = 0.5 / math.sqrt(math.pi), math.sqrt(3 / (4 * math.pi))
    c2, c20, c22 = math.sqrt(15 / (4 * math.pi)), math.sqrt(5 / (16 * math.pi)), math.sqrt(15 / (16 * math.pi))
    y_k = [c0, c1 * y, c1 * z, c1 * x, c2 * x * y, c2 * y * z, c20 * (3 * z * z - 1), c2 * x * z, c22 * (x * x - y * y)]
    a_l = [math.pi] + [2 * math.pi / 3] * 3 + [math.pi / 4] * 5
    return np.array([a * v for a, v in zip(a_l, y_k, strict=True)], np.float32)


def stage1_sides_model(resolution=64, *, light=OWN_LIGHT) -> onnx.ModelProto:
    """The analytic stage 1 with normals that are NOT all +x: the network square's left half faces -y,
    its right half +y (DESIGN.md §3: +y is toward the image's right), so a light from +y brightens the
    person's right side and dims the left. albedo = image ⊙ mask, skin = mask / 2, light = ``light``."""
    r = resolution
    tmap = np.empty((1, 9, r, r), np.float32)
    tmap[0, :, :, : r // 2] = unoccluded_transport((0, -1, 0))[:, None, None]
    tmap[0, :, :, r // 2 :] = unoccluded_transport((0, 1, 0))[:, None, None]
    inits = [
        numpy_helper.from_array(tmap, "tmap"),
        numpy_helper.from_array(np.asarray(light, np.float32).reshape(1, 9, 3), "own_light"),
        numpy_helper.from_array(np.array(0.5, np.float32), "half"),
        numpy_helper.from_array(np.array(0.0, np.float32), "zero"),
        numpy_helper.from_array(np.array([-1, 1, 1], np.int64), "shape3"),
    ]
    nodes = [
        helper.make_node("Mul", ["image", "mask"], ["albedo"]),
        helper.make_node("Mul", ["mask", "half"], ["skin"]),
        helper.make_node("Mul", ["mask", "tmap"], ["transport"]),
        helper.make_node("ReduceMean", ["mask"], ["m_mean"], keepdims=1, axes=[1, 2, 3]),
        helper.make_node("Reshape", ["m_mean", "shape3"], ["m3"]),
        helper.make_node("Mul", ["m3", "zero"], ["z3"]),
        helper.make_node("Add", ["z3", "own_light"], ["light"]),
    ]
    inputs = [_value("image", ["N", 3, r, r]), _value("mask", ["N", 1, r, r])]
    outputs = [
        _value("albedo", ["N", 3, r, r]),
        _value("skin", ["N", 1, r, r]),
        _value("transport", ["N", 9, r, r]),
        _value("light", ["N", 9, 3]),
    ]
    return _model(nodes, inputs, outputs, inits, meta_for("stage1", resolution), opset=13)


def stage2_model(resolution=0, *, meta=None, gain=0.1) -> onnx.ModelProto:
    """r = gain * (diffuse - 0.5); residual = r ⊙ mask; relit = clip(diffuse + r, 0, 1) ⊙ mask (DESIGN.md §5)."""
    inits = [
        numpy_helper.from_array(np.array(gain, np.float32), "gain"),
        numpy_helper.from_array(np.array(0.5, np.float32), "half"),
        numpy_helper.from_array(np.array(0.0, np.float32), "lo"),
        numpy_helper.from_array(np.array(1.0, np.float32), "hi"),
    ]
    nodes = [
        helper.make_node("Sub", ["diffuse", "half"], ["d0"]),
        helper.make_node("Mul", ["d0", "gain"], ["d1"]),
        helper.make_node("Mul", ["d1", "mask"], ["residual"]),
        helper.make_node("Add", ["diffuse", "d1"], ["s"]),
        helper.make_node("Clip", ["s", "lo", "hi"], ["c"]),
        helper.make_node("Mul", ["c", "mask"], ["relit"]),
    ]
    inputs = [_value("diffuse", ["N", 3, "H", "W"]), _value("mask", ["N", 1, "H", "W"])]
    outputs = [_value("residual", ["N", 3, "H", "W"]), _value("relit", ["N", 3, "H", "W"])]
    return _model(nodes, inputs, outputs, inits, meta if meta is not None else meta_for("stage2", resolution))


def dvp_model(resolution=0) -> onnx.ModelProto:
    """relit = frame ⊙ mask (ignores the light)."""
    nodes = [
        helper.make_node("Mul", ["frame", "mask"], ["relit0"]),
        helper.make_node("ReduceMean", ["light"], ["ls"], keepdims=0, axes=[1, 2]),
        helper.make_node("Mul", ["ls", "zero"], ["lz"]),
        helper.make_node("Add", ["relit0", "lz4"], ["relit"]),
        helper.make_node("Reshape", ["lz", "shape4"], ["lz4"]),
    ]
    nodes = nodes[:3] + [nodes[4], nodes[3]]
    inits = [
        numpy_helper.from_array(np.array(0.0, np.float32), "zero"),
        numpy_helper.from_array(np.array([-1, 1, 1, 1], np.int64), "shape4"),
    ]
    inputs = [_value("frame", ["N", 3, "H", "W"]), _value("mask", ["N", 1, "H", "W"]), _value("light", ["N", 9, 3])]
    return _model(nodes, inputs, [_value("relit", ["N", 3, "H", "W"])], inits, meta_for("dvp", resolution), opset=13)


def save(model: onnx.ModelProto, path: Path) -> Path:
    onnx.checker.check_model(model)
    onnx.save(model, str(path))
    return path


def assert_batch_is_per_sample(session, inputs: dict[str, np.ndarray]) -> None:
    """A batch's outputs equal its items run one by one (DESIGN.md §5: batch items are independent), within
    float32 rounding; ``session`` an onnxruntime InferenceSession, ``inputs`` its feed with N >= 2."""
    both = session.run(None, inputs)
    n = next(iter(inputs.values())).shape[0]
    for i in range(n):
        single = session.run(None, {k: v[i : i + 1] for k, v in inputs.items()})
        for b, s in zip(both, single, strict=True):
            np.testing.assert_allclose(b[i : i + 1], s, rtol=1e-5, atol=1e-6)


def make_models_dir(folder: Path, resolution=64, stage2=True, dvp=False, stage1=None) -> Path:
    """A models folder with the analytic stage1 (or the graph ``stage1``) and the toy stage2/dvp."""
    folder.mkdir(parents=True, exist_ok=True)
    save(stage1 if stage1 is not None else stage1_model(resolution), folder / "stage1.onnx")
    if stage2:
        save(stage2_model(), folder / "stage2.onnx")
    if dvp:
        save(dvp_model(), folder / "dvp.onnx")
    return folder


# ------------------------------------------------------------------------------ shared test fixtures
# (imported by the runtime test modules: ``from _graphs import models_dir, ...``)



@pytest.fixture(scope="session")
def models_dir(tmp_path_factory) -> Path:
    """Analytic stage1 (R = 64) + toy stage2 + toy dvp."""
    return make_models_dir(tmp_path_factory.mktemp("models"), 64, stage2=True, dvp=True)


@pytest.fixture(scope="session")
def diffuse_models_dir(tmp_path_factory) -> Path:
    """Analytic stage1 only: results are diffuse-only."""
    return make_models_dir(tmp_path_factory.mktemp("models_s1"), 64, stage2=False)


def person(h=150, w=100, seed=0, box=(20, 140, 30, 80)):
    """A textured float RGB image and a binary mask with a rectangle "person" (y0, y1, x0, x1)."""
    rng = np.random.default_rng(seed)
    img = (0.2 + 0.6 * rng.random((h, w, 3))).astype(np.float32)
    mask = np.zeros((h, w), np.float32)
    y0, y1, x0, x1 = box
    mask[y0:y1, x0:x1] = 1.0
    return img, mask


def write_person(folder: Path, name: str = "p", seed: int = 0, *, mask_folder: Path | None = None,
                 **shape) -> Path:
    """``person(**shape, seed=seed)`` written as ``folder/NAME.png`` (8-bit) and its ``NAME_mask.png`` (beside it,
    or in ``mask_folder``); returns the photo's path."""
    img, mask = person(seed=seed, **shape)
    cv2.imwrite(str(folder / f"{name}.png"), (img[..., ::-1] * 255).round().astype(np.uint8))
    cv2.imwrite(str((mask_folder or folder) / f"{name}_mask.png"), (mask * 255).astype(np.uint8))
    return folder / f"{name}.png"
