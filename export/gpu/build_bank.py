"""``python -m export gpu-bank``: build the compact bank of posed people that ``gpu-train`` renders from.

Each subject is built here exactly as ``python -m export render`` builds it (anny people from the
``render`` extra, or the sphere figures of export.render.shapes), then stored compactly
(:mod:`export.gpu.bank`). Subjects already in the folder are kept (the build resumes); ``bank.json`` is
rewritten at the end. The training lights are copied in as one RGB array (``lights.npy``); the people do not
depend on them (gpu-train shades each sample under a light drawn at batch time), so ``--lights-only`` swaps the
lights of a built bank in seconds, without building anyone (nor needing the ``render`` extra).

Example (the bank docs/GPU.md carries to the device)::

    python -m export lights --out data/lights_dir --kinds sun_sky lamps window softbox sun_sky lamps overcast \
        --white-balance 0.6
    python -m export gpu-bank --out data/gpu_bank --lights data/lights_dir --n 96 --seed 300000 --texture-size 256
    python -m export gpu-bank --out data/gpu_bank --lights data/lights_new --lights-only   # other lights, same people
"""

from __future__ import annotations

import argparse
import logging
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from relight_rt import RelightError

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class GpuBankConfig:
    """Settings of one ``gpu-bank`` run."""

    out: Path
    lights: Path
    n: int = 60
    seed: int = 300000
    subject: str = "anny"
    texture_size: int = 512
    lights_only: bool = False


def add_arguments(parser: argparse.ArgumentParser) -> None:
    d = GpuBankConfig(out=Path(), lights=Path())
    parser.add_argument("--out", type=Path, required=True, help="bank folder (created; existing subjects kept)")
    parser.add_argument("--lights", type=Path, required=True,
                        help="folder of training lights (NAME.npy, BGR; python -m export lights)")
    parser.add_argument("--n", type=int, default=d.n, help="number of people (default %(default)s)")
    parser.add_argument("--seed", type=int, default=d.seed,
                        help="person i is subject seed SEED + i (default %(default)s: clear of the seeds the "
                             "render commands of models/README.md use)")
    parser.add_argument("--subject", choices=("anny", "shapes"), default=d.subject,
                        help="anny: clothed people (needs the render extra); shapes: sphere figures (tests)")
    parser.add_argument("--texture-size", type=int, default=d.texture_size,
                        help="longest side of a stored texture (default %(default)s)")
    parser.add_argument("--lights-only", action="store_true",
                        help="replace the lights of the bank already in --out and build no one (--n, --seed, "
                             "--subject and --texture-size are not used)")


def config_from_args(args: argparse.Namespace) -> GpuBankConfig:
    return GpuBankConfig(out=Path(args.out), lights=Path(args.lights), n=args.n, seed=args.seed,
                         subject=args.subject, texture_size=args.texture_size, lights_only=args.lights_only)


def _make(kind: str, seed: int):
    from export.render.cli import make_subject

    return make_subject({"kind": kind, "seed": seed, "clothing": True})


def run(config: GpuBankConfig) -> int:
    """Build (or complete) the bank; returns 0."""
    from export import dataset

    from . import bank

    if config.n < 1 or not 1 <= config.texture_size <= bank.TEXTURE_MAX_SIDE:
        raise RelightError(f"expected --n >= 1 and 1 <= --texture-size <= {bank.TEXTURE_MAX_SIDE}, got {config.n} and "
                           f"{config.texture_size}")
    if not 0 <= config.seed <= 2**32 - config.n:
        raise RelightError(f"--seed: expected 0 to 2**32 - --n, got {config.seed}")
    out, lights_dir = Path(config.out), Path(config.lights)
    if out.exists() and not out.is_dir():
        raise RelightError(f"--out {out}: a file, not a bank folder")
    if out.resolve() == lights_dir.resolve():
        raise RelightError(f"--out {out}: the --lights folder itself; give the bank a folder of its own")
    if config.lights_only:
        return _swap_lights(out, dataset.read_lights(config.lights))
    lights = dataset.read_lights(config.lights)
    out.mkdir(parents=True, exist_ok=True)
    bank._atomic_bytes(out / "lights.npy", lambda tmp: np.save(tmp, lights.astype(np.float32)))
    template = None
    if config.subject == "anny":
        from export.render import bodies

        t = bodies.get_template()
        bank.write_template(out, t.faces, t.uv)
        template = bank._TemplateIndex(t.faces, t.uv)
    t0 = time.monotonic()
    made = 0
    for i in range(config.n):
        seed = config.seed + i
        name = f"{config.subject}_{seed:06d}"
        if (out / f"{name}.npz").is_file():
            continue
        subject = _make(config.subject, seed)
        path = bank.write_subject(out, subject, texture_size=config.texture_size, template=template)
        made += 1
        log.info("%s: %d parts, %.0f kB (%.1f s per person so far)", name, len(subject.parts),
                 path.stat().st_size / 1e3, (time.monotonic() - t0) / made)
    index = bank.write_index(out)
    log.info("bank %s: %d people, %d lights, %.1f MB (%.0f kB per person)", out, len(index["subjects"]),
             len(lights), index["bytes"] / 1e6, index["mean_subject_bytes"] / 1e3)
    return 0


def _swap_lights(out: Path, lights: np.ndarray) -> int:
    """Replace the lights of the built bank ``out`` (its bank.json and people kept as they are); returns 0."""
    from . import bank

    old = bank.read_index(out)  # refuses a folder that holds no bank
    before = len(bank.read_lights(out, old)) if (out / old["lights"]).is_file() else 0
    bank._atomic_bytes(out / "lights.npy", lambda tmp: np.save(tmp, lights.astype(np.float32)))
    index = bank.write_index(out)
    log.info("bank %s: %d lights replaced by %d; its %d people kept", out, before, len(lights), len(index["subjects"]))
    return 0
