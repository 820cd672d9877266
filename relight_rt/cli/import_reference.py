"""``relight-rt import-reference``: the authors' checkpoints to ONNX graphs, without torch
(relight_rt.apps.reference_checkpoints)."""

from __future__ import annotations

import argparse


def add_parser(subparsers) -> None:
    p = subparsers.add_parser(
        "import-reference",
        help="convert the authors' checkpoints to ONNX graphs (no torch needed)",
        description="Convert the reference implementation's checkpoints (model_1st.pth, model_2nd.pth, a DVP "
        "network) to this runtime's ONNX graphs without torch: the pickle is read by a restricted unpickler "
        "that accepts tensor records only. Needs the onnx package (pip install \"relight-rt[import]\").",
    )
    p.add_argument("--stage1", metavar="PTH", help="the reference's model_1st.pth")
    p.add_argument("--stage2", metavar="PTH", help="the reference's model_2nd.pth")
    p.add_argument("--dvp", metavar="PTH", help="a reference deep-video-prior network (state_dict)")
    p.add_argument("--out", required=True, metavar="DIR", help="folder for stage1.onnx / stage2.onnx / dvp.onnx")
    p.add_argument("--width", type=int, default=64, help="base width (64 = reference)")
    p.add_argument("--resolution", type=int, default=1024, help="network resolution (1024 = reference)")
    p.set_defaults(func=cmd_import_reference)


def cmd_import_reference(args: argparse.Namespace) -> int:
    from ..apps.reference_checkpoints import import_reference

    done = import_reference(
        args.out, stage1=args.stage1, stage2=args.stage2, dvp=args.dvp, width=args.width, resolution=args.resolution
    )
    for item in done:
        print(f"wrote {item['path']} ({item['kind']}, {item['bytes'] / 1e6:.1f} MB): {item['source']}")
    return 0
