"""``python -m export lights``: environment maps and their SH training lights.

Writes into OUT:
- ``NAME.npy``: (9, 3) float32 SH light with columns B, G, R (the reference's layout; read with
  ``export.dataset.read_lights``), one per map and rotation: NAME = ``BASE_rNN``, the map turned about
  +z by NN × 360°/ROTATIONS (carrying +x toward +y, like ``relight_rt.sh.rotate_z``);
- ``hdr/BASE.hdr``: the (unrotated) map as Radiance HDR, linear RGB;
- ``lights.json``: for every light name, its map file and rotation step (``render-photos`` reads it).

Maps are procedural (``export.render.envmaps``) or, with ``--hdr DIR``, every .hdr/.exr/.png/.jpg
map in DIR (resized to ``--height``); both are scaled so the brightest irradiance of a map lies in
``--target`` (default 0.9–2.6, like the reference's test lights) unless ``--keep-scale``. With
``--white-balance S`` each map (and so its light and the photos rendered under it) loses the fraction S of
its colour cast, as photos from a camera with automatic white balance do.
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
    parser.add_argument("--kinds", nargs="+", help="procedural kinds to draw from (default: all)")
    parser.add_argument("--hdr", type=Path, help="use the environment maps in this folder instead of procedural ones")
    parser.add_argument("--keep-scale", action="store_true", help="do not rescale --hdr maps")
    parser.add_argument("--target", type=float, nargs=2, default=None, metavar=("LO", "HI"),
                        help="range of the brightest irradiance after scaling (log-uniform)")
    parser.add_argument("--white-balance", type=float, default=0.0, metavar="S",
                        help="remove this fraction (0-1) of each map's colour cast, as a camera's automatic "
                             "white balance would (default 0: the maps as drawn)")


def _maps(config: LightsConfig):
    """Yield (base name, (H, 2H, 3) map) pairs."""
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
            yield p.stem, env if config.keep_scale else envmaps.normalize_envmap(env, target())
        return
    kinds = config.kinds or list(envmaps.KINDS)
    bad = [k for k in kinds if k not in envmaps.KINDS]
    if bad:
        raise RelightError(f"--kinds {bad}: expected some of {envmaps.KINDS}")
    for i in range(config.n):
        kind = kinds[i % len(kinds)]
        yield f"env{i:04d}_{kind}", envmaps.procedural_envmap(kind, rng, config.height, target=target())


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

    def __post_init__(self) -> None:
        if self.rotations < 1 or self.height < 2 or self.n < 0:
            raise RelightError("expected --rotations >= 1, --height >= 2 and --n >= 0")
        check_fraction("--white-balance", self.white_balance)
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
    coeff0 = []
    total = config.n if config.hdr is None else None
    for base, env in tqdm(_maps(config), total=total, desc="lights", unit="map"):
        if config.white_balance > 0:
            env = envmaps.white_balance(env, config.white_balance)
        envmaps.write_hdr(out / "hdr" / f"{base}.hdr", env)
        light = project_envmap(env)
        for r in range(config.rotations):
            name = f"{base}_r{r:02d}"
            rotated = rotate_z(light, 2 * math.pi * r / config.rotations)
            dataset.write_light(out, name, rotated)
            index["lights"][name] = {"envmap": f"hdr/{base}.hdr", "rotation": r}
        coeff0.append(light[0])
    text = json.dumps(index, indent=1)
    dataset.atomic_write(out / INDEX, lambda tmp: Path(tmp).write_text(text))
    if coeff0:
        c = np.asarray(coeff0)
        log.info("%d maps × %d rotations = %d lights in %s", len(c), config.rotations, len(index["lights"]), out)
        log.info("SH coefficient 0 per channel: min %.2f, median %.2f, max %.2f (reference test lights: 0.22–1.42, "
                 "median 0.63)", c.min(), np.median(c), c.max())
    return 0


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
