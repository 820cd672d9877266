"""``python -m export lights``: environment maps and their SH training lights.

Writes into OUT:
- ``NAME.npy``: (9, 3) float32 SH light with columns B, G, R (the reference's layout; read with
  ``export.dataset.read_lights``), one per map and rotation: NAME = ``BASE_rNN``, the map turned about
  +z by NN × 360°/ROTATIONS (carrying +x toward +y, like ``relight_rt.sh.rotate_z``);
- ``hdr/BASE.hdr``: the (unrotated) map as Radiance HDR, linear RGB;
- ``lights.json``: for every light name, its map file and rotation step (``render-photos`` reads it); a map
  of a kind fixed to the camera (``envmaps.CAMERA_BOUND``: "flash") is turned instead through
  ±``--camera-turn`` degrees in ROTATIONS even steps, its entries saying by how many map columns
  (``"columns"``), so that its key light stays near the camera.

Maps are procedural (``export.render.envmaps``) or, with ``--hdr DIR``, every .hdr/.exr/.png/.jpg
map in DIR (resized to ``--height``); both are scaled so the brightest irradiance of a map lies in
``--target`` (default 0.9–2.6, like the reference's test lights) unless ``--keep-scale``. With
``--white-balance S`` each map (and so its light and the photos rendered under it) loses the fraction S of
its colour cast, as photos from a camera with automatic white balance do. ``--ground-albedo LO HI`` lights
the ground of "sun_sky" maps by the sky and sun with an albedo in [LO, HI] (the bounce from below a dark
ground leaves out). At the end the set's directions are logged (:func:`direction_figures`).
"""

from __future__ import annotations

import argparse
import json
import logging
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from relight_rt.engine.errors import RelightError

from ..config import check_fraction, reader

log = logging.getLogger(__name__)

INDEX = "lights.json"
INDEX_FORMAT = "relight_rt.lights/1"
MAP_EXTS = (".hdr", ".exr", ".png", ".jpg", ".jpeg")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", required=True, type=Path, help="output folder")
    parser.add_argument("--n", type=int, default=276, help="number of procedural maps (the paper used 276)")
    parser.add_argument("--rotations", type=int, default=10, help="rotations about the vertical per map (36° steps)")
    parser.add_argument("--height", type=int, default=90, help="map height H (width 2H, divisible by --rotations)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--kinds", nargs="+",
                        help="procedural kinds to draw from, in turn (default: sun_sky overcast softbox window lamps "
                             "night; flash and low_lamp only when named)")
    parser.add_argument("--hdr", type=Path, help="use the environment maps in this folder instead of procedural ones")
    parser.add_argument("--keep-scale", action="store_true", help="do not rescale --hdr maps")
    parser.add_argument("--target", type=float, nargs=2, default=None, metavar=("LO", "HI"),
                        help="range of the brightest irradiance after scaling (log-uniform)")
    parser.add_argument("--white-balance", type=float, default=0.0, metavar="S",
                        help="remove this fraction (0-1) of each map's colour cast, as a camera's automatic "
                             "white balance would (default 0: the maps as drawn)")
    parser.add_argument("--ground-albedo", type=float, nargs=2, default=None, metavar=("LO", "HI"),
                        help="sun_sky maps: a ground of this albedo range lit by the sky and sun (real ground "
                             "0.1-0.4) instead of the default dim one")
    parser.add_argument("--camera-turn", type=float, default=30.0, metavar="DEG",
                        help="maps of kinds fixed to the camera (flash) turn through +-DEG about the vertical "
                             "instead of a whole circle (default %(default)s)")


def _maps(config: LightsConfig):
    """Yield (base name, procedural kind or None for a --hdr map, (H, 2H, 3) map)."""
    from relight_rt.light.envmap import load_envmap

    from . import envmaps

    rng = np.random.default_rng(config.seed)
    lo, hi = config.target or envmaps.TARGET_RANGE

    def target():
        return math.exp(rng.uniform(math.log(lo), math.log(hi)))

    if config.hdr is not None:
        if not Path(config.hdr).is_dir():
            raise RelightError(f"--hdr {config.hdr}: folder does not exist")
        files = sorted(p for p in Path(config.hdr).iterdir() if p.suffix.lower() in MAP_EXTS)
        if not files:
            raise RelightError(f"--hdr {config.hdr}: no environment maps (.hdr, .exr, .png, .jpg) found")
        for p in files:
            env = envmaps.resize_envmap(load_envmap(p), config.height)
            yield p.stem, None, env if config.keep_scale else envmaps.normalize_envmap(env, target())
        return
    kinds = config.kinds or list(envmaps.DEFAULT_KINDS)
    bad = [k for k in kinds if k not in envmaps.KINDS]
    if bad:
        raise RelightError(f"--kinds {bad}: expected some of {envmaps.KINDS}")
    for i in range(config.n):
        kind = kinds[i % len(kinds)]
        yield f"env{i:04d}_{kind}", kind, envmaps.procedural_envmap(kind, rng, config.height, target=target(),
                                                                    ground_albedo=config.ground_albedo)


def turn_columns(config: LightsConfig, kind: str | None, width: int) -> list[int] | None:
    """How many columns each of the ``rotations`` lights of a map of ``kind`` turns it (carrying +x toward +y),
    for a camera-bound kind (``envmaps.CAMERA_BOUND``): even steps through ±``camera_turn`` degrees, rounded to
    whole columns of a map ``width`` wide. None for every other map (whole-circle turns, ``rotation`` ×
    360°/``rotations``)."""
    from .envmaps import CAMERA_BOUND

    if kind not in CAMERA_BOUND:
        return None
    r = config.rotations
    steps = np.linspace(-1.0, 1.0, r) if r > 1 else np.zeros(1)
    return [int(round(a / 360.0 * width)) for a in config.camera_turn * steps]


@dataclass(frozen=True, kw_only=True)
class LightsConfig:
    """The settings of ``lights`` (one field per flag; see :func:`add_arguments`)."""

    out: Path
    n: int = 276
    rotations: int = 10
    height: int = 90
    seed: int = 0
    kinds: tuple[str, ...] | None = None
    hdr: Path | None = None
    keep_scale: bool = False
    target: tuple[float, float] | None = None
    white_balance: float = 0.0
    ground_albedo: tuple[float, float] | None = None
    camera_turn: float = 30.0

    def __post_init__(self) -> None:
        if self.rotations < 1 or self.height < 2 or self.n < 0:
            raise RelightError("expected --rotations >= 1, --height >= 2 and --n >= 0")
        check_fraction("--white-balance", self.white_balance)
        if self.ground_albedo is not None and not 0.0 <= self.ground_albedo[0] <= self.ground_albedo[1] <= 1.0:
            raise RelightError(f"--ground-albedo: expected 0 <= LO <= HI <= 1, got {self.ground_albedo}")
        if not 0.0 <= self.camera_turn <= 180.0:
            raise RelightError(f"--camera-turn: expected 0 to 180 degrees, got {self.camera_turn}")
        if (2 * self.height) % self.rotations:
            raise RelightError(f"--height {self.height}: the width {2 * self.height} must be divisible by --rotations")


config_from_args = reader(LightsConfig)


def run(config: LightsConfig) -> int:
    from tqdm import tqdm

    from relight_rt.light.envmap import project_envmap
    from relight_rt.light.sh import rotate_z

    from .. import dataset
    from . import envmaps

    out = Path(config.out)
    (out / "hdr").mkdir(parents=True, exist_ok=True)
    index = {"format": INDEX_FORMAT, "rotations": config.rotations, "lights": {}}
    coeff0, lights = [], []
    total = config.n if config.hdr is None else None
    for base, kind, env in tqdm(_maps(config), total=total, desc="lights", unit="map"):
        if config.white_balance > 0:
            env = envmaps.white_balance(env, config.white_balance)
        envmaps.write_hdr(out / "hdr" / f"{base}.hdr", env)
        light = project_envmap(env)
        columns = turn_columns(config, kind, env.shape[1])
        for r in range(config.rotations):
            name = f"{base}_r{r:02d}"
            entry = {"envmap": f"hdr/{base}.hdr", "rotation": r}
            if columns is None:
                angle = 2 * math.pi * r / config.rotations
            else:
                angle = 2 * math.pi * columns[r] / env.shape[1]
                entry["columns"] = columns[r]
            written = rotate_z(light, angle)
            dataset.write_light(out, name, written)
            lights.append(written)
            index["lights"][name] = entry
        coeff0.append(light[0])
    text = json.dumps(index, indent=1)
    dataset.atomic_write(out / INDEX, lambda tmp: Path(tmp).write_text(text))
    if coeff0:
        c = np.asarray(coeff0)
        log.info("%d maps × %d rotations = %d lights in %s", len(c), config.rotations, len(index["lights"]), out)
        log.info("SH coefficient 0 per channel: min %.2f, median %.2f, max %.2f (reference test lights: 0.22–1.42, "
                 "median 0.63)", c.min(), np.median(c), c.max())
        log.info("directions: %s", format_direction_figures(direction_figures(np.asarray(lights))))
    return 0


def direction_figures(lights: np.ndarray) -> dict:
    """Where a set of lights comes from: the direction of each light's luminance (Rec. 709) by its degree-1 band
    (``relight_rt.light.sh.dominant_direction``), summarised.

    Args:
        lights: (N, 9, 3) RGB lights (DESIGN.md §3), N >= 1.

    Returns:
        ``n``; ``elevation_quantiles``: elevation in degrees (above the horizon > 0) at 5, 25, 50, 75 and 95 %;
        ``below_10`` and ``below_0``: the share below +10° and below 0°; ``frontal_horizon``: the share from near
        the camera at about the face's height (toward the camera, x > 0.7, and |elevation| < 20°);
        ``directionality_median``: the median of ``dominant_direction``'s second value (0 uniform, 1 one direction).
        A light without a direction counts as elevation 90° and not frontal.
    """
    from relight_rt.image.color import REC709
    from relight_rt.light.sh import dominant_direction

    lights = np.asarray(lights, np.float64)
    if lights.ndim != 3 or lights.shape[1:] != (9, 3) or not len(lights):
        raise RelightError(f"lights: expected (N, 9, 3) RGB lights, got {lights.shape}")
    el, toward, strength = [], [], []
    for light in lights:
        d, s = dominant_direction(light @ np.asarray(REC709))
        el.append(90.0 if d is None else math.degrees(math.asin(float(np.clip(d[2], -1.0, 1.0)))))
        toward.append(-1.0 if d is None else float(d[0]))
        strength.append(s)
    el, toward = np.asarray(el), np.asarray(toward)
    quantiles = (5, 25, 50, 75, 95)
    return {
        "n": len(lights),
        "elevation_quantiles": {str(q): round(float(np.percentile(el, q)), 1) for q in quantiles},
        "below_10": round(float((el < 10).mean()), 4),
        "below_0": round(float((el < 0).mean()), 4),
        "frontal_horizon": round(float(((toward > 0.7) & (np.abs(el) < 20)).mean()), 4),
        "directionality_median": round(float(np.median(strength)), 3),
    }


def format_direction_figures(f: dict) -> str:
    """:func:`direction_figures` as one line."""
    q = "/".join(f"{v:+.0f}" for v in f["elevation_quantiles"].values())
    return (f"{f['n']} lights, elevation 5/25/50/75/95 % {q} deg, below +10 {100 * f['below_10']:.1f} %, below 0 "
            f"{100 * f['below_0']:.1f} %, frontal at face height (x > 0.7, |el| < 20) {100 * f['frontal_horizon']:.1f} "
            f"%, directionality median {f['directionality_median']:.2f}")


def environment(root: str | Path, name: str) -> np.ndarray:
    """The (H, 2H, 3) linear RGB map behind light ``name`` of a folder written by this command."""
    from relight_rt.light.envmap import load_envmap

    from .envmaps import rotate_envmap

    root = Path(root)
    index = json.loads((root / INDEX).read_text())
    if index.get("format") != INDEX_FORMAT:
        raise RelightError(f"{root / INDEX}: expected format {INDEX_FORMAT!r}, got {index.get('format')!r}")
    entry = index["lights"].get(name)
    if entry is None:
        raise RelightError(f"{root / INDEX}: no light named {name!r}")
    env = load_envmap(root / entry["envmap"])
    if "columns" in entry:  # a camera-bound map, turned by whole columns (turn_columns)
        return rotate_envmap(env, int(entry["columns"]), env.shape[1])
    return rotate_envmap(env, int(entry["rotation"]), int(index["rotations"]))


def list_environments(root: str | Path) -> list[str]:
    """Names of the environments of a folder: the lights of ``lights.json`` when present, else the stems of
    every environment map file (.hdr, .exr, .png, .jpg) in it."""
    root = Path(root)
    if not root.is_dir():
        raise RelightError(f"environment folder {root} does not exist")
    if (root / INDEX).is_file():
        return sorted(json.loads((root / INDEX).read_text())["lights"])
    return sorted(p.name for p in root.iterdir() if p.suffix.lower() in MAP_EXTS)


def load_environment(root: str | Path, name: str, height: int | None = None) -> np.ndarray:
    """A map from :func:`list_environments`'s list, optionally resized to ``height``."""
    from relight_rt.light.envmap import load_envmap

    from .envmaps import resize_envmap

    root = Path(root)
    env = environment(root, name) if (root / INDEX).is_file() else load_envmap(root / name)
    return env if height is None else resize_envmap(env, height)
