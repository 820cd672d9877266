"""A stage-1 graph made of two: one graph's albedo and skin with another's transport and light.

    PYTHONPATH=. python benchmarks/stage1_mix.py --albedo relight_rt/models/stage1.onnx \
        --transport runs/gpu_3/stage1.onnx --out /tmp/mix_models/stage1.onnx

Both graphs run side by side on the same inputs inside one ONNX graph (each one's names prefixed apart), and the
outputs keep the stage-1 contract's names: ``albedo`` and ``skin`` from ``--albedo``, ``transport`` and ``light``
from ``--transport``. The metadata is the albedo graph's, its ``relight_rt.source`` saying what was mixed. Put the
result beside the bundled models (a copy of relight_rt/models with this stage1.onnx) and run the usual benchmarks
(``heldout_change.py measure --models``, ``yale_eval.py --models``): it says which part of a trained stage 1 wins
or loses there (docs/RESULTS.md, "Stage 1 at scale"). A benchmark tool, not a model to ship.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

FROM_ALBEDO = ("albedo", "skin")
FROM_TRANSPORT = ("transport", "light")


def mix(albedo_graph, transport_graph):
    """The mixed model (module docstring) of two loaded stage-1 ``onnx.ModelProto``; raises ValueError where the two
    do not share their inputs and the four outputs."""
    import onnx
    from onnx import compose, helper

    graphs = (albedo_graph, transport_graph)
    inputs = [[i.name for i in g.graph.input] for g in graphs]
    outputs = [sorted(o.name for o in g.graph.output) for g in graphs]
    if inputs[0] != inputs[1] or outputs[0] != outputs[1] or outputs[0] != sorted(FROM_ALBEDO + FROM_TRANSPORT):
        raise ValueError(f"expected two stage-1 graphs with the same inputs and outputs, got inputs {inputs} and "
                         f"outputs {outputs}")
    a, t = compose.add_prefix(albedo_graph, "a_"), compose.add_prefix(transport_graph, "t_")
    nodes = [helper.make_node("Identity", [name], [p + name]) for name in inputs[0] for p in ("a_", "t_")]
    nodes += list(a.graph.node) + list(t.graph.node)
    nodes += [helper.make_node("Identity", [("a_" if o.name in FROM_ALBEDO else "t_") + o.name], [o.name])
              for o in albedo_graph.graph.output]
    graph = helper.make_graph(nodes, "stage1_mix", list(albedo_graph.graph.input), list(albedo_graph.graph.output),
                              initializer=list(a.graph.initializer) + list(t.graph.initializer))
    model = helper.make_model(graph, opset_imports=albedo_graph.opset_import, ir_version=albedo_graph.ir_version)
    mixed = " (mixed: transport and light from another graph)"
    for p in albedo_graph.metadata_props:
        model.metadata_props.add(key=p.key, value=p.value + (mixed if p.key == "relight_rt.source" else ""))
    onnx.checker.check_model(model)
    return model


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--albedo", type=Path, required=True, help="stage1.onnx whose albedo and skin are kept")
    p.add_argument("--transport", type=Path, required=True, help="stage1.onnx whose transport and light are kept")
    p.add_argument("--out", type=Path, required=True, help="the mixed stage1.onnx")
    args = p.parse_args(argv)
    import onnx

    for path in (args.albedo, args.transport):
        if not path.is_file():
            p.error(f"expected a stage-1 graph, got {path} (no such file)")
    try:
        model = mix(onnx.load(str(args.albedo)), onnx.load(str(args.transport)))
    except ValueError as exc:
        p.error(str(exc))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    onnx.save(model, str(args.out))
    print(f"wrote {args.out}: albedo and skin of {args.albedo}, transport and light of {args.transport}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
