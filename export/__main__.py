"""``python -m export COMMAND ...``: one entry point for every training-side tool.

Each command lives in its own module, imported only when that command runs, so a missing
optional dependency (torch, anny, embreex) breaks only the commands that need it. A command
module provides ``add_arguments(parser)``, a frozen config dataclass of its settings,
``config_from_args(args) -> config`` and ``run(config) -> int`` (:mod:`export.config`); code calls
``run`` with a config it builds (:mod:`export.quickstart` does).
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys

# command name -> (module, one-line help)
COMMANDS: dict[str, tuple[str, str]] = {
    "convert-reference": ("export.convert", "convert the reference checkpoints (model_1st/2nd.pth) to ONNX"),
    "onnx": ("export.onnx_export", "export one of our own checkpoints to ONNX"),
    "render": ("export.render.cli", "render stage-1 training samples (albedo, mask, skin, transport)"),
    "lights": ("export.render.lights_cli", "make procedural HDR environment maps and their SH training lights"),
    "render-photos": ("export.render.photos_cli", "render non-diffuse 'photos' of rendered samples for stage 2"),
    "train-stage1": ("export.train_stage1", "train the stage-1 inverse-rendering network"),
    "train-stage2": ("export.train_stage2", "train the stage-2 residual network"),
    "average": ("export.average", "the weighted mean of checkpoints of one network (a model soup)"),
    "evaluate": ("export.evaluate", "evaluate trained networks on a held-out synthetic split"),
    "quickstart": ("export.quickstart", "render, train tiny models on the CPU, export and relight"),
    "fit-dvp": ("export.dvp", "fit an illumination-conditioned deep video prior to one video"),
    "mask-models": ("export.mask_models", "convert MediaPipe's person segmentation to the bundled matting graphs"),
    "face-mesh": ("export.face_mesh", "convert MediaPipe's face landmarker (face normals for relighting)"),
    "gpu-bank": ("export.gpu.build_bank", "build the compact bank of posed people that gpu-train renders from"),
    "gpu-train": ("export.gpu.train", "render samples from a bank and train stage 1 on a GPU until a deadline"),
    "gpu-check": ("export.gpu.check", "the torch renderer's transport against the embree renderer's, on bank people"),
}


def _load(module: str):
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as exc:
        missing = exc.name or "a module"
        if missing.startswith("export"):
            raise SystemExit(f"python -m export: {module} is not available in this checkout") from None
        raise SystemExit(
            f"python -m export: this command needs {missing!r}; install the extras: "
            f"pip install torch==2.13.0 && pip install -e '.[export,render]'"
        ) from None


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = argparse.ArgumentParser(prog="python -m export", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, (_, help_text) in COMMANDS.items():
        sub.add_parser(name, help=help_text, add_help=False)
    if not argv or argv[0] in ("-h", "--help") or argv[0] not in COMMANDS:
        parser.parse_args(argv[:1] or ["--help"])
        return 2
    name = argv[0]
    module = _load(COMMANDS[name][0])
    cmd_parser = argparse.ArgumentParser(prog=f"python -m export {name}", description=COMMANDS[name][1])
    module.add_arguments(cmd_parser)
    args = cmd_parser.parse_args(argv[1:])
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    from relight_rt import RelightError

    try:
        return int(module.run(module.config_from_args(args)) or 0)
    except RelightError as exc:
        print(f"python -m export {name}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
