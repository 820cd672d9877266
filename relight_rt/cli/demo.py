"""``relight-rt demo``: relight the bundled example person under a preset and show the light beside the result.

The example is a person rendered by this project's own renderer (``python -m export render`` and
``render-photos``; see models/README.md), shipped as an RGBA PNG whose alpha is the mask, so the
demo needs no file of the user's and nothing from the network.
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import numpy as np

from ..engine.errors import RelightError
from ..image.io import read_image, write_image
from ..light import presets, sh
from .options import add_runtime_options, runtime_config

log = logging.getLogger(__name__)

EXAMPLE = Path(__file__).resolve().parents[1] / "data" / "example.png"


def example_path() -> Path:
    """Path of the bundled example photo: RGBA PNG, alpha = the person's mask."""
    if not EXAMPLE.is_file():
        raise RelightError(f"the bundled example {EXAMPLE} is missing; reinstall relight-rt")
    return EXAMPLE


def side_by_side(photo: np.ndarray, relit: np.ndarray, light: np.ndarray) -> np.ndarray:
    """One float32 RGB image: the photo, the relit photo and the light on a diffuse sphere.

    Args:
        photo: (H, W, 3) float RGB in [0, 1].
        relit: (H, W, 3) float RGB in [0, 1], same size.
        light: (9, 3) RGB SH light, shown on a sphere of height H/2 at the bottom of the third panel.
    """
    h, w = photo.shape[:2]
    size = max(16, min(h, w) // 2)
    sphere = np.clip(sh.render_sphere(light, size=size), 0.0, 1.0)
    panel = np.zeros((h, size, 3), np.float32)
    panel[h - size :, :] = sphere
    gap = np.ones((h, max(2, w // 64), 3), np.float32)
    return np.concatenate([photo[..., :3], gap, relit[..., :3], gap, panel], axis=1)


def run_demo(output: str | Path, preset: str = "golden-hour", models=None, device: str = "auto", *,
             config=None) -> Path:
    """Relight the bundled example under ``preset`` and write photo | relit | light preview to ``output``.

    ``config``: a relight_rt.engine.config.RuntimeConfig (wins over ``models`` and ``device``)."""
    from ..builder import open as open_relighter
    from ..engine.config import RuntimeConfig

    light = presets.preset(preset)
    photo = read_image(example_path(), "example")
    relighter = open_relighter(config if config is not None else RuntimeConfig(models=models, device=device))
    relit = relighter.relight(photo, light, background=np.zeros(photo.shape[:2] + (3,), np.float32))
    image = side_by_side(photo[..., :3] * photo[..., 3:], relit, light)
    return write_image(output, image, protect=[example_path()])


def add_parser(subparsers) -> None:
    p = subparsers.add_parser(
        "demo",
        help="relight the bundled example person under a preset",
        description="Relight the bundled example (a rendered person) and write the photo, the relit photo and "
        "the light on a sphere side by side.",
    )
    p.add_argument("--preset", default="golden-hour", metavar="NAME",
                   help=f"one of {', '.join(presets.list_presets())}")
    p.add_argument("-o", "--output", default="demo.png", metavar="OUT", help="image to write (default demo.png)")
    add_runtime_options(p)
    p.set_defaults(func=cmd_demo)


def cmd_demo(args: argparse.Namespace) -> int:
    path = run_demo(args.output, args.preset, config=runtime_config(args))  # every runtime option, as relight
    log.info("wrote %s (photo | relit under %s | the light on a sphere)", path, args.preset)
    return 0
