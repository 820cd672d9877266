"""``relight-rt doctor``: what is installed, which providers run the models, and known install problems."""

from __future__ import annotations

import argparse
import importlib.metadata as md
import platform
import sys
from pathlib import Path

import cv2
import numpy as np
import onnxruntime as ort

from .. import __version__
from ..engine.errors import RelightError
from ..engine.session import CUDA, create_session, find_models
from .options import add_runtime_options

_ORT_DISTS = ("onnxruntime", "onnxruntime-gpu", "onnxruntime-directml", "onnxruntime-openvino", "onnxruntime-silicon",
              "ort-nightly", "ort-nightly-gpu")  # fmt: skip
_CV_DISTS = ("opencv-python", "opencv-python-headless", "opencv-contrib-python", "opencv-contrib-python-headless")


def installed(names: tuple[str, ...]) -> list[str]:
    """'name version' for each of ``names`` that is installed."""
    found = []
    for name in names:
        try:
            found.append(f"{name} {md.version(name)}")
        except md.PackageNotFoundError:
            pass
    return found


def report(models: str | Path | None = None, device: str = "auto") -> tuple[list[str], list[str]]:
    """Lines describing the installation, and the problems found (empty when all is well)."""
    lines = [
        f"relight_rt {__version__} ({Path(__file__).resolve().parents[1]})",
        f"python {platform.python_version()} ({sys.executable})",
        f"numpy {np.__version__}, onnxruntime {ort.__version__}, opencv {cv2.__version__}",
    ]
    problems = []
    ort_dists, cv_dists = installed(_ORT_DISTS), installed(_CV_DISTS)
    lines.append(f"onnxruntime packages: {', '.join(ort_dists) or 'none found by pip metadata'}")
    lines.append(f"opencv packages: {', '.join(cv_dists) or 'none found by pip metadata'}")
    if len(ort_dists) > 1:
        problems.append(
            f"several onnxruntime packages are installed ({', '.join(ort_dists)}); they overwrite each other: "
            "uninstall all of them, then install exactly one (onnxruntime-gpu for CUDA)"
        )
    if len(cv_dists) > 1:
        problems.append(
            f"several OpenCV packages are installed ({', '.join(cv_dists)}); uninstall all of them, then install "
            "opencv-contrib-python-headless only"
        )
    if not hasattr(cv2, "ximgproc"):
        problems.append(
            "cv2.ximgproc is missing: the cv2 that Python imports is not the opencv-contrib-python-headless build "
            "relight_rt depends on (another OpenCV package shadows it); uninstall the others"
        )
    available = ort.get_available_providers()
    lines.append(f"onnxruntime providers available: {', '.join(available)}")
    try:
        folder = find_models(models)
    except RelightError as exc:
        lines.append("models: none")
        problems.append(str(exc))  # nothing can be relit without them
        return lines, problems
    lines.append(f"models: {folder}")
    for name in ("stage1", "stage2", "dvp"):
        path = folder / f"{name}.onnx"
        if not path.is_file():
            lines.append(f"  {name}: absent")
            continue
        try:
            session = create_session(path, device=device, warmup=False, kind=name)
        except RelightError as exc:
            problems.append(str(exc))
            continue
        meta = session.get_modelmeta().custom_metadata_map
        active = session.get_providers()
        lines.append(
            f"  {name}: resolution {meta.get('relight_rt.resolution')}, norm {meta.get('relight_rt.norm')}, "
            f"source {meta.get('relight_rt.source', '')!r}, running on {', '.join(active)}"
        )
        if CUDA in available and active[0] != CUDA and device != "cpu":
            problems.append(f"{path}: CUDA is offered but the model runs on {active[0]}")
    return lines, problems


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("doctor", help="versions, providers, models and install problems")
    add_runtime_options(p)
    p.set_defaults(func=cmd_doctor)


def cmd_doctor(args: argparse.Namespace) -> int:
    """Print the report; exit 1 when it found problems."""
    lines, problems = report(args.models, args.device)
    for line in lines:
        print(line)
    for problem in problems:
        print(f"problem: {problem}")
    print("ok" if not problems else f"{len(problems)} problem(s) found")
    return 1 if problems else 0
