"""Patch a format-1 stage-2 graph to the reference's rule for ``relit`` (issue 34, DESIGN.md §5).

Graphs exported before the fix computed ``relit = clip(diffuse + r ⊙ mask, 0, 1) ⊙ mask``; the reference
(and our training, ``export/train_stage2.py``) adds the raw residual r and masks the sum,
``relit = clip(diffuse + r, 0, 1) ⊙ mask``. The two agree wherever mask is 0 or 1 and differ at soft
mask edges. Re-exporting needs the training checkpoint; this rewires the graph instead: the ``Add`` that
reads ``residual`` (= Mul(r, mask)) is made to read r, the Mul's other input. Nothing else changes (the
``residual`` output, the weights, the metadata).

    python -m export.patch_stage2_relit relight_rt/models/stage2.onnx [--out PATCHED.onnx]

Before writing, the patched graph is run beside the original on a random input with a soft mask: the
``residual`` output and ``relit`` where mask is 0 or 1 must agree to 1e-6, and ``relit`` must equal
``clip(diffuse + r, 0, 1) ⊙ mask`` (r recovered as residual / mask where mask > 0) everywhere. It prints
how many pixels changed and by how much. A graph already in the new form is left as it is.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np


def _producers(graph) -> dict:
    return {out: node for node in graph.node for out in node.output}


def patch_model(model):
    """The stage-2 ``onnx.ModelProto`` with ``relit`` built from the raw residual; returns (model, changed)."""
    import copy

    model = copy.deepcopy(model)
    graph = model.graph
    prod = _producers(graph)
    residual = prod.get("residual")
    if residual is None or residual.op_type != "Mul" or "mask" not in residual.input:
        raise ValueError("expected 'residual' = Mul(r, mask) in a stage-2 graph")
    raw = next(i for i in residual.input if i != "mask")
    readers = [n for n in graph.node if "residual" in n.input]
    adds = [n for n in readers if n.op_type == "Add" and "diffuse" in n.input]
    if not adds:
        uses_raw = [n for n in graph.node if n.op_type == "Add" and "diffuse" in n.input and raw in n.input]
        if uses_raw:
            return model, False  # already the reference's rule
        raise ValueError("expected an Add(diffuse, residual) feeding 'relit'")
    if len(adds) != 1:
        raise ValueError(f"expected one Add(diffuse, residual), found {len(adds)}")
    add = adds[0]
    add.input[list(add.input).index("residual")] = raw
    return model, True


def _run(model_bytes: bytes, feeds: dict) -> dict:
    import onnxruntime as ort

    sess = ort.InferenceSession(model_bytes, providers=["CPUExecutionProvider"])
    return dict(zip([o.name for o in sess.get_outputs()], sess.run(None, feeds), strict=True))


def check(before, after, size: int = 128, seed: int = 0) -> dict:
    """Run both graphs on a random diffuse image with a soft elliptic mask; raise when the patch changed
    anything but ``relit`` at soft edges or ``relit`` does not follow the new rule. Returns figures."""
    from relight_rt.engine.contract import config_from_metadata

    meta = {p.key: p.value for p in before.metadata_props}
    res = config_from_metadata(meta).resolution or size
    rng = np.random.default_rng(seed)
    yy, xx = np.meshgrid(np.linspace(-1, 1, res), np.linspace(-1, 1, res), indexing="ij")
    mask = np.clip((1 - (xx / 0.7) ** 2 - (yy / 0.9) ** 2) * 8, 0, 1).astype(np.float32)[None, None]
    feeds = {"diffuse": rng.random((1, 3, res, res), dtype=np.float32), "mask": mask}
    old, new = _run(before.SerializeToString(), feeds), _run(after.SerializeToString(), feeds)
    hard = np.broadcast_to((mask == 0) | (mask == 1), old["relit"].shape)
    soft = ~hard
    figures = {
        "residual max |diff|": float(np.abs(new["residual"] - old["residual"]).max()),
        "relit max |diff| where mask is 0 or 1": float(np.abs(new["relit"] - old["relit"])[hard].max()),
        "relit max |diff| at soft edges": float(np.abs(new["relit"] - old["relit"])[soft].max(initial=0)),
        "soft-edge pixels": int(soft[0, 0].sum()),
    }
    m = np.broadcast_to(mask, old["residual"].shape)
    r = np.divide(new["residual"], m, out=np.zeros_like(new["residual"]), where=m > 0)
    want = np.clip(feeds["diffuse"] + r, 0, 1) * mask
    figures["relit vs clip(diffuse + r) * mask, max |diff|"] = float(np.abs(new["relit"] - want).max())
    if figures["residual max |diff|"] > 1e-6 or figures["relit max |diff| where mask is 0 or 1"] > 1e-6:
        raise ValueError(f"the patch changed more than relit at soft edges: {figures}")
    if figures["relit vs clip(diffuse + r) * mask, max |diff|"] > 1e-5:
        raise ValueError(f"the patched relit does not follow clip(diffuse + r, 0, 1) * mask: {figures}")
    return figures


def main(argv: list[str] | None = None) -> int:
    import onnx

    from relight_rt.engine.files import atomic_path

    parser = argparse.ArgumentParser(prog="python -m export.patch_stage2_relit", description=__doc__.splitlines()[0])
    parser.add_argument("model", type=Path, help="a stage-2 .onnx file")
    parser.add_argument("--out", type=Path, help="where to write the patched graph (default: in place)")
    args = parser.parse_args(argv)
    before = onnx.load(str(args.model))
    try:
        after, changed = patch_model(before)
    except ValueError as exc:
        print(f"patch_stage2_relit: error: {args.model}: {exc}", file=sys.stderr)
        return 2
    if not changed:
        print(f"{args.model}: already clip(diffuse + r, 0, 1) * mask; left as it is")
        return 0
    onnx.checker.check_model(after, full_check=True)
    for name, value in check(before, after).items():
        print(f"{name}: {value:.3g}" if isinstance(value, float) else f"{name}: {value}")
    out = args.out or args.model
    with atomic_path(out) as tmp:
        onnx.save(after, str(tmp))
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
