"""``python -m export render``: render stage-1 training samples (albedo, mask, skin, transport).

Writes, per sample, the reference's layout (``NAME_tex.png``, ``NAME_mask.png``, ``NAME_parsing.png``,
``NAME_transport.npz``; see export.dataset) plus ``NAME_meta.json`` (how to re-create the subject and
the camera; ``render-photos`` reads it). Samples are rendered in parallel worker processes; the same
``--seed`` gives identical files.
"""

from __future__ import annotations

import argparse
import json
import logging
import multiprocessing
import os
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from relight_rt.engine.errors import RelightError

from ..config import reader

log = logging.getLogger(__name__)

META_FORMAT = "relight_rt.sample/1"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", required=True, type=Path, help="output folder")
    parser.add_argument("--n", type=int, default=8, help="number of random subjects (ignored with --mesh)")
    parser.add_argument("--seed", type=int, default=0, help="sample i renders subject seed SEED + i")
    parser.add_argument("--resolution", type=int, default=1024, help="square image size")
    parser.add_argument("--dirs", type=int, default=256, help="Monte Carlo directions per pixel for the transport")
    parser.add_argument(
        "--subject", choices=("anny", "shapes"), default="anny",
        help="anny: random clothed people (export.render.subjects); shapes: a sphere figure (no body model)",
    )
    parser.add_argument("--no-clothing", action="store_true", help="anny bodies without garments")
    parser.add_argument(
        "--views", type=int, default=1,
        help="samples per subject: view 0 faces the camera, the others turn the subject about +z by a random "
             "angle within --max-yaw (building a body costs far more than ray casting it)",
    )
    parser.add_argument("--max-yaw", type=float, default=45.0, help="largest turn of the extra views, degrees")
    parser.add_argument("--mesh", type=Path, nargs="+",
                        help="render these textured .obj meshes instead (skin labels: NAME_skin.png beside NAME.obj)")
    parser.add_argument("--camera", choices=("orthographic", "perspective"), default="orthographic")
    parser.add_argument("--fov", type=float, default=20.0, help="perspective field of view, degrees")
    parser.add_argument("--margin", type=float, default=0.05, help="free border, fraction of the image side")
    parser.add_argument(
        "--framings", default="full", type=parse_framings,
        help="camera framings and their weights, drawn per subject: e.g. full=0.4,knees-up=0.15,waist-up=0.15,"
             "head-shoulders=0.15,face=0.15 (names: full, knees-up, waist-up, head-shoulders, face; default full)",
    )
    parser.add_argument("--workers", type=int, default=2, help="parallel processes")
    parser.add_argument("--preview", action="store_true", help="also write OUT/contact_sheet.png")
    parser.add_argument("--overwrite", action="store_true", help="re-render samples that already exist")


def parse_framings(text: str) -> dict[str, float]:
    """``name[=weight],...`` -> {framing: probability}; weights default to 1 and are normalised."""
    from .camera import FRAMINGS

    out: dict[str, float] = {}
    for item in (t.strip() for t in text.split(",") if t.strip()):
        name, _, weight = item.partition("=")
        if name not in FRAMINGS:
            raise argparse.ArgumentTypeError(f"framing {name!r}: expected one of {list(FRAMINGS)}")
        try:
            w = float(weight) if weight else 1.0
        except ValueError:
            raise argparse.ArgumentTypeError(f"framing {name}: weight {weight!r} is not a number") from None
        if not (w >= 0 and np.isfinite(w)):
            raise argparse.ArgumentTypeError(f"framing {name}: weight must be >= 0, got {weight}")
        out[name] = out.get(name, 0.0) + w
    total = sum(out.values())
    if not out or total <= 0:
        raise argparse.ArgumentTypeError(f"--framings {text!r}: expected at least one framing with a weight > 0")
    return {k: v / total for k, v in out.items()}


def pick_framing(framings: dict[str, float], seed: int) -> str:
    """The framing of subject ``seed`` (deterministic: the same seed, the same framing)."""
    names = sorted(framings)
    rng = np.random.default_rng([seed, 0xF4A3])
    return str(rng.choice(names, p=[framings[n] for n in names]))


def make_subject(source: dict):
    """Re-create a subject from its ``NAME_meta.json`` ``source`` entry."""
    kind = source.get("kind")
    from .scene import Subject

    if kind == "anny":
        from .subjects import random_subject

        subject = random_subject(int(source["seed"]), clothing=bool(source.get("clothing", True)))
        return turn_subject(subject, float(source.get("yaw", 0.0)))
    if kind == "shapes":
        from .shapes import random_scene

        return Subject(random_scene(int(source["seed"])), name=f"shapes_{int(source['seed']):06d}")
    if kind == "mesh":
        from .subjects import load_subject

        return load_subject(source["path"], source.get("skin"))
    raise RelightError(f"subject source {source!r}: expected kind 'anny', 'shapes' or 'mesh'")


def turn_subject(subject, yaw_deg: float):
    """The subject turned about +z (its vertical axis through the centre of its bounds) by ``yaw_deg``;
    positive turns carry +x (toward the camera) toward +y. Returns a new Subject."""
    from dataclasses import replace

    if yaw_deg == 0.0:
        return subject
    from relight_rt.light.sh import rotation_matrix

    rot = rotation_matrix(yaw=yaw_deg, degrees=True).astype(np.float32)
    lo, hi = subject.bounds()
    centre = ((lo + hi) / 2).astype(np.float32)
    centre[2] = 0.0
    parts = [replace(p, vertices=((p.vertices - centre) @ rot.T + centre).astype(np.float32)) for p in subject.parts]
    return replace(subject, parts=parts)


def render_views(job: dict) -> list[dict]:
    """Build one subject and render each of its views (``job['views']``: a list of (name, yaw)).
    Runs in a worker process; returns timing statistics per view."""
    t0 = time.perf_counter()
    base = make_subject({**job["source"], "yaw": 0.0})
    build_s = time.perf_counter() - t0
    stats = []
    for name, yaw in job["views"]:
        view = {**job, "name": name, "source": {**job["source"], "yaw": yaw}}
        stats.append(render_one(view, turn_subject(base, yaw), build_s / len(job["views"])))
    return stats


def render_one(job: dict, subject=None, build_s: float | None = None) -> dict:
    """Render and write one sample (runs in a worker process). Returns timing statistics."""
    from .. import dataset
    from .camera import fit_camera
    from .raycast import Tracer
    from .transport import render_gbuffer, transport

    t0 = time.perf_counter()
    if subject is None:
        subject = make_subject(job["source"])
    t1 = time.perf_counter()
    if build_s is not None:
        t0 = t1 - build_s
    cam = fit_camera(subject, job["resolution"], margin=job["margin"], kind=job["camera"], fov_deg=job["fov"],
                     framing=job.get("framing", "full"))
    tracer = Tracer(subject)
    g = render_gbuffer(subject, cam, tracer)
    rng = np.random.default_rng([job["seed"], 0x5A17])
    t = transport(tracer, g, job["dirs"], rng=rng)
    t2 = time.perf_counter()
    out = Path(job["out"])
    name = job["name"]
    dataset.write_sample(out, name, g.image(g.albedo), g.mask, g.image(g.skin), g.image(t))
    meta = {
        "format": META_FORMAT,
        "name": name,
        "source": job["source"],
        "seed": job["seed"],
        "camera": cam.to_dict(),
        "framing": job.get("framing", "full"),
        "dirs": job["dirs"],
        "pixels": int(len(g.index)),
        "triangles": int(len(tracer.faces)),
    }
    text = json.dumps(meta, indent=1)
    dataset.atomic_write(out / f"{name}_meta.json", lambda tmp: Path(tmp).write_text(text))
    return {"name": name, "build_s": t1 - t0, "render_s": t2 - t1, "write_s": time.perf_counter() - t2,
            "rays": len(g.index) * job["dirs"] + cam.resolution**2}


def _jobs(config: RenderConfig) -> list[dict]:
    common = {"resolution": config.resolution, "dirs": config.dirs, "margin": config.margin, "camera": config.camera,
              "fov": config.fov, "out": str(config.out)}
    if config.mesh:
        jobs = []
        for i, p in enumerate(config.mesh):
            skin = p.with_name(f"{p.stem}_skin.png")  # optional skin-label texture beside the mesh
            source = {"kind": "mesh", "path": str(p.resolve()), "skin": str(skin.resolve()) if skin.is_file() else None}
            jobs.append({**common, "name": p.stem, "seed": config.seed + i, "source": source,
                         "framing": pick_framing(config.framings, config.seed + i)})
        return jobs
    jobs = []
    for i in range(config.n):
        seed = config.seed + i
        source = {"kind": config.subject, "seed": seed}
        if config.subject == "anny":
            source["clothing"] = not config.no_clothing
        name = f"{config.subject}_{seed:06d}"
        views = [(name, 0.0)]
        if config.views > 1 and config.subject == "anny":
            rng = np.random.default_rng([seed, 0x7E35])
            yaws = rng.uniform(-config.max_yaw, config.max_yaw, config.views - 1)
            views += [(f"{name}_v{v}", round(float(y), 3)) for v, y in enumerate(yaws, start=1)]
        jobs.append({**common, "name": name, "seed": seed, "source": source, "views": views,
                     "framing": pick_framing(config.framings, seed)})
    return jobs


def run_pool(func, jobs: list, workers: int, desc: str):
    """Run ``func`` over ``jobs`` in ``workers`` processes (in this one when 1) with a progress bar;
    yields (job, result or exception)."""
    from tqdm import tqdm

    bar = tqdm(total=len(jobs), desc=desc, unit="sample")
    try:
        if workers <= 1 or len(jobs) <= 1:
            for job in jobs:
                yield job, _guard(func, job)
                bar.update()
            return
        ctx = multiprocessing.get_context("spawn")
        with ctx.Pool(min(workers, len(jobs)), initializer=_init_worker) as pool:
            futures = [(job, pool.apply_async(_guard, (func, job))) for job in jobs]
            for job, fut in futures:
                yield job, fut.get()
                bar.update()
    finally:
        bar.close()


def _init_worker() -> None:
    """One thread per worker process: the workers already fill the cores (torch, used by the body model,
    would otherwise start a thread per core in every worker)."""
    for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ[var] = "1"


def _guard(func, job):
    try:
        return func(job)
    except (RelightError, OSError, ValueError) as exc:  # reported per sample, the batch goes on
        return exc


@dataclass(frozen=True, kw_only=True)
class RenderConfig:
    """The settings of ``render`` (one field per flag; see :func:`add_arguments`)."""

    out: Path
    n: int = 8
    seed: int = 0
    resolution: int = 1024
    dirs: int = 256
    subject: str = "anny"
    no_clothing: bool = False
    views: int = 1
    max_yaw: float = 45.0
    mesh: tuple[Path, ...] | None = None
    camera: str = "orthographic"
    fov: float = 20.0
    margin: float = 0.05
    framings: Mapping[str, float] = field(default_factory=lambda: {"full": 1.0})
    workers: int = 2
    preview: bool = False
    overwrite: bool = False

    def __post_init__(self) -> None:
        if self.resolution < 8 or self.dirs < 1 or self.n < 0 or self.workers < 1:
            raise RelightError("expected --resolution >= 8, --dirs >= 1, --n >= 0 and --workers >= 1")
        if self.views < 1:
            raise RelightError(f"expected --views >= 1, got {self.views}")


config_from_args = reader(RenderConfig)


def run(config: RenderConfig) -> int:
    from .. import dataset

    config.out.mkdir(parents=True, exist_ok=True)
    jobs = _jobs(config)
    if not config.overwrite:
        done = set(dataset.list_samples(config.out))

        def exists(name: str) -> bool:
            return name in done and (config.out / f"{name}_meta.json").is_file()

        skipped = [j["name"] for j in jobs if all(exists(n) for n, _ in j.get("views", [(j["name"], 0.0)]))]
        if skipped:
            log.info("%d subjects already rendered (use --overwrite to re-render)", len(skipped))
        jobs = [j for j in jobs if j["name"] not in skipped]
    start = time.perf_counter()
    failures, stats = [], []
    views = [j for j in jobs if "views" in j]
    singles = [j for j in jobs if "views" not in j]
    results = list(run_pool(render_views, views, config.workers, "render")) if views else []
    results += list(run_pool(render_one, singles, config.workers, "render")) if singles else []
    for job, res in results:
        if isinstance(res, Exception):
            failures.append(f"{job['name']}: {res}")
        else:
            stats.extend(res if isinstance(res, list) else [res])
    wall = time.perf_counter() - start
    if stats:
        render_s = sum(s["render_s"] for s in stats)
        rays = sum(s["rays"] for s in stats)
        log.info(
            "%d samples in %.1f s (%d workers): subject %.1f s, ray casting + transport %.1f s and writing %.1f s "
            "per sample; %.2f M rays/s per process", len(stats), wall, config.workers,
            np.mean([s["build_s"] for s in stats]), render_s / len(stats), np.mean([s["write_s"] for s in stats]),
            rays / max(render_s, 1e-9) / 1e6,
        )
    if config.preview:
        from .contact_sheet import sample_row, write_sheet

        names = dataset.list_samples(config.out)[:16]
        if names:
            write_sheet(config.out / "contact_sheet.png", [sample_row(config.out, n) for n in names])
            log.info("contact sheet: %s", config.out / "contact_sheet.png")
    for f in failures:
        log.error("failed: %s", f)
    return 1 if failures else 0
