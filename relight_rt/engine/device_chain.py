"""CUDA: stage 1 → shading → stage 2 kept on the GPU with onnxruntime IO binding.

On CPU the Relighter does the shading with numpy (``sh.shading_chw``, through ``relighter.diffuse_batch``:
the one CPU shading formula). On CUDA the same formula stays a tiny ONNX graph, on purpose (built here
without the ``onnx`` package: a few protobuf fields written by hand), so transport and albedo stay on the
device between stage 1 and stage 2 and only the (K, 9, 3) lights go up and the relit images come down.

The shading graph: inputs ``albedo`` [1, 3, H, W], ``transport`` [1, 9, H, W], ``light`` [K, 9, 3];
output ``diffuse`` [K, 3, H, W] = clip(albedo ⊙ max(0, Σ_k transport_k · light[:, k, c]), 0, 1).
"""

from __future__ import annotations

import struct
from functools import lru_cache

import numpy as np
import onnxruntime as ort

from .session import CPU, CUDA, Model

# ------------------------------------------------------------------------------ protobuf, by hand


def _varint(n: int) -> bytes:
    out = bytearray()
    while True:
        byte = n & 0x7F
        n >>= 7
        if n:
            out.append(byte | 0x80)
        else:
            out.append(byte)
            return bytes(out)


def _field(number: int, value) -> bytes:
    """One protobuf field: int → varint, bytes/str → length-delimited."""
    if isinstance(value, int):
        return _varint(number << 3) + _varint(value)
    data = value.encode() if isinstance(value, str) else value
    return _varint(number << 3 | 2) + _varint(len(data)) + data


def _value_info(name: str, dims: list) -> bytes:
    shape = b"".join(_field(1, _field(1, d) if isinstance(d, int) else _field(2, d)) for d in dims)
    tensor_type = _field(1, 1) + _field(2, shape)  # elem_type FLOAT, shape
    return _field(1, name) + _field(2, _field(1, tensor_type))


def _scalar(name: str, value: float) -> bytes:
    return _field(2, 1) + _field(8, name) + _field(9, struct.pack("<f", value))  # FLOAT, name, raw_data


def _node(op: str, inputs: list[str], outputs: list[str], attrs: bytes = b"") -> bytes:
    return b"".join(_field(1, i) for i in inputs) + b"".join(_field(2, o) for o in outputs) + _field(4, op) + attrs


@lru_cache(maxsize=1)
def shade_graph() -> bytes:
    """The serialized ONNX model of the shading step (see the module docstring)."""
    equation = _field(1, "equation") + _field(4, "nkhw,bkc->bchw") + _field(20, 3)  # AttributeProto STRING
    nodes = [
        _node("Einsum", ["transport", "light"], ["s0"], _field(5, equation)),
        _node("Relu", ["s0"], ["shading"]),
        _node("Mul", ["albedo", "shading"], ["d0"]),
        _node("Clip", ["d0", "zero", "one"], ["diffuse"]),
    ]
    graph = b"".join(_field(1, n) for n in nodes) + _field(2, "relight_rt_shade")
    graph += _field(5, _scalar("zero", 0.0)) + _field(5, _scalar("one", 1.0))
    graph += _field(11, _value_info("albedo", [1, 3, "H", "W"]))
    graph += _field(11, _value_info("transport", [1, 9, "H", "W"]))
    graph += _field(11, _value_info("light", ["K", 9, 3]))
    graph += _field(12, _value_info("diffuse", ["K", 3, "H", "W"]))
    opset = _field(1, "") + _field(2, 17)
    return _field(1, 8) + _field(2, "relight_rt") + _field(7, graph) + _field(8, opset)


# ------------------------------------------------------------------------------ the device chain


class DeviceChain:
    """Stage 1 and stage 2 (and the shading between them) with device-resident intermediates.

    Args:
        stage1, stage2: the checked models, both running on CUDA (stage2 may be None: diffuse-only).
        device: where intermediates live: "cuda", or "cpu" (the same binding logic, for tests without a GPU).
        device_id: the CUDA device they run on.
    """

    def __init__(self, stage1: Model, stage2: Model | None, device: str = "cuda", device_id: int = 0) -> None:
        self.stage1, self.stage2 = stage1, stage2
        self.device, self.device_id = device, int(device_id) if device == "cuda" else 0
        providers = [(CUDA, {"device_id": self.device_id}), CPU] if device == "cuda" else [CPU]
        self.shade = ort.InferenceSession(shade_graph(), ort.SessionOptions(), providers=providers)

    def upload(self, array: np.ndarray) -> ort.OrtValue:
        """A host array → an OrtValue on the device (one copy)."""
        array = np.ascontiguousarray(array, np.float32)
        return ort.OrtValue.ortvalue_from_numpy(array, self.device, self.device_id)

    def run_stage1(self, image: np.ndarray, mask: np.ndarray) -> tuple[dict, dict]:
        """Stage 1 on (1, 3, R, R) / (1, 1, R, R) host arrays.

        Returns:
            (host outputs by name, {"albedo", "transport"} as device OrtValues for ``relit``).
        """
        session = self.stage1.session
        binding = session.io_binding()
        binding.bind_cpu_input("image", np.ascontiguousarray(image, np.float32))
        binding.bind_cpu_input("mask", np.ascontiguousarray(mask, np.float32))
        names = [o.name for o in session.get_outputs()]
        for name in names:
            binding.bind_output(name, self.device, self.device_id)
        session.run_with_iobinding(binding)
        values = dict(zip(names, binding.get_outputs(), strict=True))
        host = {name: value.numpy() for name, value in values.items()}  # the Decomposition's arrays
        return host, {"albedo": values["albedo"], "transport": values["transport"]}

    def relit(self, device: dict, mask: ort.OrtValue, lights: np.ndarray, want_layers: bool) -> list[tuple]:
        """Shading and stage 2 for a batch of lights, on the device.

        Args:
            device: {"albedo", "transport"} device OrtValues of one decomposition (batch 1).
            mask: device OrtValue (K, 1, R, R), the network mask repeated K times.
            lights: (K, 9, 3) float32 host array.
            want_layers: also copy diffuse and residual to the host.

        Returns:
            K tuples (diffuse or None, residual or None, relit), each (3, R, R) host float32.
        """
        binding = self.shade.io_binding()
        binding.bind_ortvalue_input("albedo", device["albedo"])
        binding.bind_ortvalue_input("transport", device["transport"])
        binding.bind_cpu_input("light", np.ascontiguousarray(lights, np.float32))
        binding.bind_output("diffuse", self.device, self.device_id)
        self.shade.run_with_iobinding(binding)
        diffuse = binding.get_outputs()[0]
        if self.stage2 is None:
            d = diffuse.numpy()
            return [(x, None, x) for x in d]
        s2 = self.stage2.session.io_binding()
        s2.bind_ortvalue_input("diffuse", diffuse)
        s2.bind_ortvalue_input("mask", mask)
        s2.bind_output("relit")  # to the host
        if want_layers:
            s2.bind_output("residual")
        else:
            s2.bind_output("residual", self.device, self.device_id)  # not needed: leave it on the device
        self.stage2.session.run_with_iobinding(s2)
        outs = dict(zip(["relit", "residual"], s2.get_outputs(), strict=True))  # in the order bound
        relit = outs["relit"].numpy()
        if not want_layers:
            return [(None, None, x) for x in relit]
        d, res = diffuse.numpy(), outs["residual"].numpy()
        return list(zip(d, res, relit, strict=True))
