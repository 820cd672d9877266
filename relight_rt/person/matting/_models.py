"""The matting graphs: where they are found, and the images they accept."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ...engine import environment
from ...engine.contract import KINDS
from ...engine.errors import RelightError
from ...engine.limits import check_array_pixels
from ...engine.session import bundled_models_dir
from ...image.io import read_image
from ...image.regions import SIZE as SIZE  # both graphs' input side

POSE_FILE = KINDS["matte_pose"].filename  # the kinds are declared in relight_rt.engine.contract
ROI_FILE = KINDS["matte_roi"].filename
FACE_FILE = KINDS["matte_face"].filename  # optional: a models folder without it finds people by body only
MIN_SIDE = 16  # smaller images cannot show a person to these models


def find_matting_models(models: str | os.PathLike | None = None) -> Path:
    """The folder holding matte_pose.onnx and matte_roi.onnx: ``models`` if given, else $RELIGHT_RT_MODELS
    when it holds them, else the bundled models.

    Raises:
        RelightError: the folder lacks one of the two graphs.
    """
    if models is not None:
        place = Path(models)
    else:
        env = environment.models()
        place = Path(env) if env and (Path(env) / POSE_FILE).is_file() else bundled_models_dir()
    for f in (POSE_FILE, ROI_FILE):
        if not (place / f).is_file():
            raise RelightError(
                f"person matting: {place / f} not found (the bundled graphs come with the package; "
                f"rebuild them with python -m export mask-models)"
            )
    return place


def as_rgb(image: np.ndarray, name: str = "image", *, copy: bool = True) -> np.ndarray:
    """Check and convert an image for matting: a new float32 (H, W, 3) RGB array in [0, 1] (with
    ``copy=False``, the matters' own intake, the image itself when it already is one: they only read it).

    Accepts (H, W, 3) RGB, (H, W, 4) RGBA (the alpha is ignored: matting looks at the picture), and
    grayscale (H, W) or (H, W, 1) (repeated into three channels); uint8 (0-255), uint16 (0-65535) or float
    (0-1). The conversion is the runtime's one image intake (relight_rt.image.io.read_image); matting adds that
    the image is an array (not a path) at least 16x16.

    Raises:
        RelightError: not an array, another shape, another dtype, NaN/Inf, values outside [0, 1], or an
            image smaller than 16x16.
    """
    if not isinstance(image, np.ndarray):
        raise RelightError(f"{name}: expected an (H, W, 3) RGB array, got {type(image).__name__}")
    check_array_pixels(image, name)  # before anything converts it
    if not (image.ndim == 2 or (image.ndim == 3 and image.shape[2] in (1, 3, 4))):
        raise RelightError(f"{name}: expected an (H, W, 3) RGB image, got shape {tuple(image.shape)}")
    if image.shape[0] < MIN_SIDE or image.shape[1] < MIN_SIDE:
        raise RelightError(
            f"{name}: image is {image.shape[0]}x{image.shape[1]} (HxW), too small to find a person in "
            f"(expected at least {MIN_SIDE}x{MIN_SIDE})"
        )
    rgb = read_image(image, name, copy=copy)
    return rgb if rgb.shape[2] == 3 else np.ascontiguousarray(rgb[..., :3])
