"""Optional int8 static quantisation of a contract graph, refused unless it stays close to fp32.

``python -m export.quantize --model models/stage1.onnx --data PHOTOS --out models/stage1_int8.onnx``

Static QDQ quantisation with onnxruntime's tools (``onnxruntime.quantization``): int8 weights per
output channel (symmetric), uint8 activations (asymmetric) whose ranges come from running the fp32
graph on calibration inputs (min/max). onnxruntime turns each QuantizeLinear → DequantizeLinear → Conv
group into an integer convolution (on x86 with AVX-512 VNNI / AVX-VNNI these run several times the
fp32 rate). Only convolutions are quantised; normalisation, resizing, activations and the contract's
scaling/masking/clipping stay float32, and so do the graph's inputs and outputs (float32, NCHW: the
runtime feeds the int8 graph exactly like the fp32 one).

Stage 1 keeps its encoder, its residual blocks, its light head and the decoders' first convs (``dc0a``,
``dc0b``, on the bottleneck) in fp32 (``KEEP_FP32``): the light (27 numbers from the bottleneck) is the
most sensitive output; with those in fp32 no quantised tensor reaches it, so it is exactly the fp32
light. Those convs are about 30 % of the work; the rest of the two decoders (about 70 %) is quantised.
Stage 2 and the DVP network keep their first conv (the image input) and their last conv (the output
residual) in fp32, about 5 % of their work: on random 1024² weights that lifts the residual from 34.9
to 36.2 dB; the rest is quantised.

**Quality gate.** On held-out inputs (never used for calibration) every output of the int8 graph must
reach ``MIN_PSNR`` (35 dB) against the fp32 graph (peak = the largest |value| of that fp32 output, as
``export.onnx_export.fp16_psnr``); otherwise nothing is written and RelightError says which output
failed. Calibration data: the stage-2 photos that ``python -m export render-photos`` writes
(``export.dataset.read_photo``: stage 1 is fed photo + mask, stage 2 diffuse + mask), resized to the
graph's resolution. Needs ``onnx`` and onnxruntime, not torch. The runtime never imports this module.
"""

from __future__ import annotations

import argparse
import logging
import math
import os
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import onnxruntime as ort

from relight_rt import RelightError
from relight_rt.engine.contract import KINDS, config_from_metadata

__all__ = ["KEEP_FP32", "MIN_PSNR", "psnr", "quantize", "photo_feeds", "main"]

log = logging.getLogger(__name__)

MIN_PSNR = 35.0
# Conv node-name fragments kept in fp32 per kind (names as torch's exporter writes them: /net/c3/Conv ...)
KEEP_FP32 = {
    "stage1": ("/net/c0/", "/net/c1/", "/net/c2/", "/net/c3/", "/net/c4/", "/net/c5/", "/net/ra/", "/net/rb/",
               "l/Conv", "/net/dc0a/", "/net/dc0b/"),  # fmt: skip
    "stage2": ("/net/c0/", "/net/dc5b/"),
    "dvp": ("/net/c0/", "/net/dc5b/"),
}


def psnr(reference: np.ndarray, candidate: np.ndarray) -> float:
    """PSNR in dB of ``candidate`` against ``reference``, peak = max |reference| (inf when equal)."""
    ref, got = reference.astype(np.float64), candidate.astype(np.float64)
    if ref.shape != got.shape or not np.isfinite(got).all():
        return -math.inf
    mse = float(np.mean((got - ref) ** 2))
    peak = float(np.abs(ref).max()) or 1.0
    return math.inf if mse == 0 else 10 * math.log10(peak**2 / mse)


def _session(path: str | os.PathLike) -> ort.InferenceSession:
    return ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])


class _Reader:
    """onnxruntime's CalibrationDataReader protocol over a list of feeds."""

    def __init__(self, feeds: Sequence[dict]) -> None:
        self._it = iter(feeds)

    def get_next(self) -> dict | None:
        return next(self._it, None)

    def rewind(self) -> None:  # some onnxruntime versions call it
        pass


def _check_feeds(feeds: Sequence[dict], kind: str, what: str) -> None:
    want = sorted(t.name for t in KINDS[kind].inputs)
    if not feeds:
        raise RelightError(f"{what}: expected at least one input, got none")
    for i, f in enumerate(feeds):
        if sorted(f) != want:
            raise RelightError(f"{what}[{i}]: expected inputs {want}, got {sorted(f)}")


def quantize(
    model: str | os.PathLike,
    out_path: str | os.PathLike,
    calibration: Sequence[dict],
    held_out: Sequence[dict],
    *,
    min_psnr: float = MIN_PSNR,
    keep_fp32: Sequence[str] | None = None,
) -> dict:
    """Write an int8 QDQ copy of a contract graph, only if it passes the quality gate.

    Args:
        model: the fp32 .onnx graph (contract metadata is checked and carried over).
        out_path: where to write the int8 graph (atomically).
        calibration: input feeds {name: float32 NCHW array} of the graph's kind, for activation ranges.
        held_out: other feeds, for the PSNR gate.
        min_psnr: the gate, dB, for every output.
        keep_fp32: Conv node-name fragments to leave in fp32; None: ``KEEP_FP32`` of the graph's kind.

    Returns:
        {"path", "kind", "psnr": {output: dB (worst held-out sample)}, "quantized_convs", "fp32_convs", "seconds"}.

    Raises:
        RelightError: not a contract graph, bad feeds, or an output under ``min_psnr`` (nothing written).
    """
    import onnx
    from onnxruntime.quantization import CalibrationMethod, QuantFormat, QuantType, quantize_static

    t0 = time.perf_counter()
    model, out_path = Path(model), Path(out_path)
    fp32 = _session(model)
    config = config_from_metadata(fp32.get_modelmeta().custom_metadata_map, str(model))
    _check_feeds(calibration, config.kind, "calibration")
    _check_feeds(held_out, config.kind, "held_out")
    graph = onnx.load(str(model))
    fragments = KEEP_FP32[config.kind] if keep_fp32 is None else tuple(keep_fp32)
    convs = [n.name for n in graph.graph.node if n.op_type == "Conv"]
    excluded = [n for n in convs if any(f in n for f in fragments)]
    del graph
    out_path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=out_path.name + ".", suffix=".tmp.onnx", dir=out_path.parent)
    os.close(fd)
    try:
        quantize_static(
            str(model),
            tmp,
            _Reader(calibration),
            quant_format=QuantFormat.QDQ,
            activation_type=QuantType.QUInt8,
            weight_type=QuantType.QInt8,
            per_channel=True,
            op_types_to_quantize=["Conv"],
            nodes_to_exclude=excluded,
            calibrate_method=CalibrationMethod.MinMax,
            extra_options={"ActivationSymmetric": False, "WeightSymmetric": True},
        )
        q = onnx.load(tmp)
        meta = {p.key: p.value for p in q.metadata_props}
        if config_from_metadata(meta, tmp) != config:  # quantize_static keeps metadata_props; be sure
            raise RelightError(f"{out_path}: the quantised graph lost its relight_rt metadata")
        for p in q.metadata_props:
            if p.key == "relight_rt.source":
                p.value += f"; int8 QDQ (onnxruntime {ort.__version__}, {len(calibration)} calibration inputs)"
        onnx.save(q, tmp)
        del q
        int8 = _session(tmp)
        names = [o.name for o in fp32.get_outputs()]
        worst = dict.fromkeys(names, math.inf)
        for feeds in held_out:
            for name, ref, got in zip(names, fp32.run(names, feeds), int8.run(names, feeds), strict=True):
                worst[name] = min(worst[name], psnr(ref, got))
        log.info("%s int8 PSNR vs fp32 (dB, worst of %d): %s", out_path.name, len(held_out), worst)
        bad = min(worst, key=worst.get)
        if not worst[bad] >= min_psnr:
            raise RelightError(
                f"{out_path}: int8 output {bad!r} has PSNR {worst[bad]:.1f} dB against fp32, under {min_psnr:g} dB; "
                "nothing written"
            )
        os.chmod(tmp, 0o644)
        os.replace(tmp, out_path)
    finally:
        Path(tmp).unlink(missing_ok=True)
        Path(tmp + ".data").unlink(missing_ok=True)
    return {"path": str(out_path), "kind": config.kind, "psnr": worst, "quantized_convs": len(convs) - len(excluded),
            "fp32_convs": len(excluded), "seconds": time.perf_counter() - t0}  # fmt: skip


def photo_feeds(root: str | os.PathLike, kind: str, resolution: int, names: Sequence[str]) -> list[dict]:
    """Graph inputs from rendered stage-2 photos (``export.dataset``): stage1 ← photo + mask, stage2 ← diffuse + mask.

    Each photo is resized (INTER_AREA) to ``resolution`` squared; batch 1, float32 NCHW.
    """
    import cv2

    from .dataset import read_photo

    if kind not in ("stage1", "stage2"):
        raise RelightError(f"calibration from photos: kind {kind!r} is not supported (stage1, stage2)")
    feeds = []
    for name in names:
        p = read_photo(root, name)
        size = (resolution, resolution)
        image = cv2.resize(p["photo" if kind == "stage1" else "diffuse"], size, interpolation=cv2.INTER_AREA)
        mask = cv2.resize(p["mask"], size, interpolation=cv2.INTER_AREA)
        first = "image" if kind == "stage1" else "diffuse"
        feeds.append({first: np.ascontiguousarray(image.transpose(2, 0, 1)[None], np.float32),
                      "mask": np.ascontiguousarray(mask[None, None], np.float32)})  # fmt: skip
    return feeds


def main(argv: list[str] | None = None) -> int:
    """``python -m export.quantize``: calibrate on rendered photos, gate, write."""
    parser = argparse.ArgumentParser(prog="python -m export.quantize", description=__doc__.splitlines()[0])
    parser.add_argument("--model", required=True, help="fp32 stage1.onnx or stage2.onnx")
    parser.add_argument("--data", required=True, help="folder of rendered photos (python -m export render-photos)")
    parser.add_argument("--out", required=True, help="the int8 .onnx to write (e.g. models/stage1_int8.onnx)")
    parser.add_argument("--calibration", type=int, default=32, help="photos used for calibration (default 32)")
    parser.add_argument("--held-out", type=int, default=8, help="other photos for the PSNR gate (default 8)")
    parser.add_argument("--min-psnr", type=float, default=MIN_PSNR, help=f"gate in dB (default {MIN_PSNR:g})")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    try:
        from .dataset import list_photos

        config = config_from_metadata(_session(args.model).get_modelmeta().custom_metadata_map, args.model)
        names = list_photos(args.data)
        n_cal, n_held = args.calibration, args.held_out
        if n_cal < 1 or n_held < 1 or len(names) < n_cal + n_held:
            raise RelightError(f"{args.data}: {len(names)} photos, need {n_cal} + {n_held} (calibration + held out)")
        rng = np.random.default_rng(0)
        order = [names[i] for i in rng.permutation(len(names))]
        res = config.resolution or 256
        cal = photo_feeds(args.data, config.kind, res, order[:n_cal])
        held = photo_feeds(args.data, config.kind, res, order[n_cal : n_cal + n_held])
        summary = quantize(args.model, args.out, cal, held, min_psnr=args.min_psnr)
    except RelightError as exc:
        sys.stderr.write(f"export quantize: error: {exc}\n")
        return 2
    psnrs = ", ".join(f"{k} {v:.1f} dB" for k, v in summary["psnr"].items())
    print(f"wrote {summary['path']} ({summary['quantized_convs']} int8 convs, {summary['fp32_convs']} fp32); {psnrs}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
