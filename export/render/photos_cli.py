"""``python -m export render-photos``: non-diffuse "photos" of rendered samples under environment maps.

For every sample of ``--data`` (written by ``python -m export render``, which leaves ``NAME_meta.json``
beside it) the subject and camera are re-created, and K photos are rendered under K environment maps
drawn (deterministically, from ``--seed`` and the sample's name) from ``--envmaps``: a folder written
by ``python -m export lights`` (its ``lights.json``, with rotations) or any folder of .hdr maps.
Writes ``SUBJECT__L{j}_photo.png``, ``_diffuse.png``, ``_mask.png`` and ``_light.npy`` per photo
(see export.dataset), and ``SUBJECT__L{j}_env.txt`` naming the environment used. With ``--full-shading``
the photo's diffuse part is shaded by the full environment map (hard shadows, sharp terminators) rather
than by its SH projection, as a camera would record it; ``_diffuse.png`` stays stage 1's SH image.
``--gloss`` makes every surface shinier (:func:`export.render.photos.glossier`) for test and training
sets whose non-diffuse part is large.
"""

from __future__ import annotations

import argparse
import json
import logging
import time
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from relight_rt.engine.errors import RelightError

from ..config import check_fraction, reader

log = logging.getLogger(__name__)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--data", required=True, type=Path, help="folder of rendered samples (with NAME_meta.json)")
    parser.add_argument("--envmaps", required=True, type=Path, help="output of `lights`, or a folder of .hdr maps")
    parser.add_argument("--out", required=True, type=Path, help="output folder for the photos")
    parser.add_argument("--k", type=int, default=3, help="photos (environment maps) per sample")
    parser.add_argument("--samples", type=int, default=32, help="specular rays per pixel (lobe + map, each)")
    parser.add_argument("--full-shading", action="store_true",
                        help="shade with the full environment map (hard shadows; median cut into 256 point lights) "
                             "instead of its SH projection; _diffuse.png stays the SH image (export.render.photos)")
    parser.add_argument("--gloss", type=float, default=0.0,
                        help="0..1: make every surface shinier (specular x(1+4g), roughness x(1-g/2)) for photos "
                             "with a large non-diffuse part (export.render.photos.glossier; default 0)")
    parser.add_argument("--env-height", type=int, default=None, help="resize maps to this height (default: as stored)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--preview", action="store_true", help="also write OUT/contact_sheet.png")


def photo_one(job: dict) -> dict:
    """Render the K photos of one sample (runs in a worker process)."""
    from .. import dataset
    from .camera import Camera
    from .cli import make_subject
    from .lights_cli import load_environment
    from .photos import glossier, pixel_size, render_photo
    from .raycast import Tracer
    from .transport import render_gbuffer

    t0 = time.perf_counter()
    data, name = Path(job["data"]), job["name"]
    meta = json.loads((data / f"{name}_meta.json").read_text())
    sample = dataset.read_sample(data, name)
    subject = make_subject(meta["source"])
    cam = Camera.from_dict(meta["camera"])
    tracer = Tracer(subject)
    g = render_gbuffer(subject, cam, tracer)
    mismatch = float(np.abs(g.mask - sample["mask"]).mean())
    if mismatch > 1e-3:
        raise RelightError(
            f"sample {name}: the re-created subject covers other pixels than the stored mask ({mismatch:.2%} differ); "
            "was it rendered with another version of the subject generator?"
        )
    g = glossier(g, job["gloss"])
    flat = g.index
    albedo = sample["albedo"].reshape(-1, 3)[flat]
    transport = sample["transport"].reshape(-1, 9)[flat]
    for j, env_name in enumerate(job["envs"]):
        env = load_environment(job["envmaps"], env_name, job["env_height"])
        rng = np.random.default_rng([job["seed"], zlib.crc32(name.encode()), j])
        out = render_photo(tracer, g, transport, env, pixel_size=pixel_size(cam.half_extent, cam.resolution),
                           albedo=albedo, n_samples=job["samples"], full=job["full"], rng=rng)
        pname = dataset.photo_name(name, j)
        dataset.write_photo(job["out"], pname, out["photo"], out["diffuse"], out["mask"], out["light"])
        text = f"{env_name}\n"
        dataset.atomic_write(Path(job["out"]) / f"{pname}_env.txt", lambda tmp, t=text: Path(tmp).write_text(t))
    return {"name": name, "s": time.perf_counter() - t0}


@dataclass(frozen=True, kw_only=True)
class RenderPhotosConfig:
    """The settings of ``render-photos`` (one field per flag; see :func:`add_arguments`)."""

    data: Path
    envmaps: Path
    out: Path
    k: int = 3
    samples: int = 32
    full_shading: bool = False
    gloss: float = 0.0
    env_height: int | None = None
    seed: int = 0
    workers: int = 2
    preview: bool = False

    def __post_init__(self) -> None:
        if self.k < 1 or self.samples < 0 or self.workers < 1:
            raise RelightError("expected --k >= 1, --samples >= 0 and --workers >= 1")
        check_fraction("--gloss", self.gloss)


config_from_args = reader(RenderPhotosConfig)


def run(config: RenderPhotosConfig) -> int:
    from .. import dataset
    from .cli import run_pool
    from .lights_cli import list_environments

    names = [n for n in dataset.list_samples(config.data) if (config.data / f"{n}_meta.json").is_file()]
    if not names:
        raise RelightError(f"--data {config.data}: no rendered samples with NAME_meta.json found")
    envs = list_environments(config.envmaps)
    if len(envs) < config.k:
        raise RelightError(
            f"--envmaps {config.envmaps}: expected at least {config.k} environment maps, found {len(envs)}")
    jobs = []
    for name in names:
        rng = np.random.default_rng([config.seed, zlib.crc32(name.encode())])
        pick = rng.choice(len(envs), size=config.k, replace=False)
        jobs.append({"data": str(config.data), "name": name, "envmaps": str(config.envmaps),
                     "envs": [envs[i] for i in pick], "env_height": config.env_height, "samples": config.samples,
                     "full": config.full_shading, "gloss": config.gloss, "seed": config.seed, "out": str(config.out)})
    config.out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    failures, times = [], []
    for job, res in run_pool(photo_one, jobs, config.workers, "photos"):
        if isinstance(res, Exception):
            failures.append(f"{job['name']}: {res}")
        else:
            times.append(res["s"])
    if times:
        log.info("%d samples × %d photos in %.1f s (%.1f s per sample per process)", len(times), config.k,
                 time.perf_counter() - start, float(np.mean(times)))
    if config.preview:
        from .contact_sheet import photo_row, write_sheet

        photos = dataset.list_photos(config.out)[:16]
        if photos:
            write_sheet(config.out / "contact_sheet.png", [photo_row(config.out, p, config.data) for p in photos])
            log.info("contact sheet: %s", config.out / "contact_sheet.png")
    for f in failures:
        log.error("failed: %s", f)
    return 1 if failures else 0
