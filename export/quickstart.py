"""``python -m export quickstart``: render a small data set, train tiny models on the CPU, export, relight.

Everything lands in ``--out`` (default ``models/quickstart``)::

    data/samples  data/lights  data/photos     the rendered data set
    stage1/  stage2/                           training runs (checkpoints, log.jsonl)
    stage1.onnx  stage2.onnx                   the exported graphs (DESIGN.md §5 contract)
    eval/results.md                            the evaluation tables on the rendered data
    relit.png  relit_side_by_side.png          a rendered subject relit under a preset light

Data: ``--data-source render`` runs the renderer (``python -m export lights``, ``render`` and
``render-photos``; needs the ``render`` extra: trimesh, embreex, and anny for people): stage-1
samples of ``--samples`` subjects, and photos of ``--photo-subjects`` other subjects under
``--photo-lights`` environment maps each. ``--subject auto`` renders anny people when anny and the
body code import, else the renderer's sphere figures. ``toy`` writes sphere samples
(:mod:`export.toy_data`, no extra needed); ``auto`` (default) renders when the renderer is
importable and falls back to toy data with a warning otherwise.

Each step is a command's ``run`` called with the config this module builds (render → ``RenderConfig``,
train → ``TrainStage1Config`` / ``TrainStage2Config``, ``EvaluateConfig``), so the data can be followed from
the renders to the graphs; the demo relights through :class:`relight_rt.Relighter`, as a user would.

Budgets (defaults sized for ≤ 20 minutes on a 2-core CPU): ``--stage1-minutes`` and
``--stage2-minutes`` bound the training loops; the data size is set by ``--samples``,
``--photo-subjects`` and ``--photo-lights``. A second call with the same ``--out`` reuses the data
and continues the training runs (``--fresh`` starts over).
"""

from __future__ import annotations

import importlib
import logging
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from relight_rt import RelightError

from .config import reader

log = logging.getLogger(__name__)


def add_arguments(parser) -> None:
    parser.add_argument("--out", default="models/quickstart", help="output folder (default %(default)s)")
    parser.add_argument("--data-source", choices=("auto", "render", "toy"), default="auto",
                        help="renderer or toy spheres (default %(default)s)")
    parser.add_argument("--subject", choices=("auto", "anny", "shapes"), default="auto",
                        help="rendered subjects: anny people when available, else sphere figures (default %(default)s)")
    parser.add_argument("--dirs", type=int, default=128, help="transport directions per pixel (default %(default)s)")
    parser.add_argument("--samples", type=int, default=32, help="stage-1 samples to render (default %(default)s)")
    parser.add_argument("--photo-subjects", type=int, default=6, help="subjects for photos (default %(default)s)")
    parser.add_argument("--photo-lights", type=int, default=3, help="lights per photo subject (default %(default)s)")
    parser.add_argument("--n-lights", type=int, default=60,
                        help="training lights, rounded up to maps × 10 rotations (default %(default)s)")
    parser.add_argument("--resolution", type=int, default=128, help="network resolution (default %(default)s)")
    parser.add_argument("--width", type=int, default=8, help="network width (default %(default)s)")
    parser.add_argument("--norm", choices=("batch", "instance"), default="instance",
                        help="normalisation (default %(default)s: batch size 1)")
    parser.add_argument("--sf-scale", type=float, default=0.1,
                        help="factor on the SF loss weights (0.1 suits ≤ 256²; default %(default)s)")
    parser.add_argument("--stage1-minutes", type=float, default=11.0, help="stage-1 budget (default %(default)s)")
    parser.add_argument("--stage2-minutes", type=float, default=4.0, help="stage-2 budget (default %(default)s)")
    parser.add_argument("--stage2-epochs", type=int, default=40,
                        help="stage-2 epochs (its cosine schedule spans them; default %(default)s)")
    parser.add_argument("--light", default="golden-hour", help="preset light of the relighting demo")
    parser.add_argument("--threads", type=int, default=2, help="torch CPU threads (default %(default)s)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--fresh", action="store_true", help="delete --out's data and runs first")


@dataclass(frozen=True, kw_only=True)
class QuickstartConfig:
    """The settings of ``quickstart`` (one field per flag; see :func:`add_arguments`)."""

    out: Path = Path("models/quickstart")
    data_source: str = "auto"
    subject: str = "auto"
    dirs: int = 128
    samples: int = 32
    photo_subjects: int = 6
    photo_lights: int = 3
    n_lights: int = 60
    resolution: int = 128
    width: int = 8
    norm: str = "instance"
    sf_scale: float = 0.1
    stage1_minutes: float = 11.0
    stage2_minutes: float = 4.0
    stage2_epochs: int = 40
    light: str = "golden-hour"
    threads: int = 2
    seed: int = 0
    fresh: bool = False


config_from_args = reader(QuickstartConfig)


# ------------------------------------------------------------------------------------------ data


def _check(name: str, code: int) -> None:
    """A command's exit status: a non-zero one stops the quickstart with one clear error."""
    if code:
        raise RelightError(f"quickstart: the {name} step failed with exit code {code}")


def renderer_available() -> bool:
    """True when the renderer's commands and their extras (trimesh, embreex) import."""
    try:
        for module in ("export.render.cli", "export.render.lights_cli", "export.render.photos_cli",
                       "export.render.raycast"):
            importlib.import_module(module)
    except ImportError as exc:
        log.info("renderer not available (%s)", exc)
        return False
    return True


def anny_available() -> bool:
    """True when random clothed anny people can be rendered (``export.render.subjects`` and anny import)."""
    try:
        importlib.import_module("export.render.subjects")
        importlib.import_module("anny")
    except ImportError as exc:
        log.info("anny subjects not available (%s)", exc)
        return False
    return True


def render_data(data: Path, config: QuickstartConfig) -> None:
    """Render lights, stage-1 samples, and photos of other subjects, with the renderer's commands."""
    from .render import cli as render_cli
    from .render import lights_cli, photos_cli

    subject = config.subject if config.subject != "auto" else ("anny" if anny_available() else "shapes")
    if subject == "shapes":
        log.warning("rendering sphere figures (--subject shapes): anny people are not available")
    maps = max(1, -(-config.n_lights // 10))
    _check("lights", lights_cli.run(lights_cli.LightsConfig(out=data / "lights", n=maps, rotations=10,
                                                            seed=config.seed)))

    def render(out: Path, n: int, seed: int) -> None:
        _check("render", render_cli.run(render_cli.RenderConfig(
            out=out, n=n, seed=seed, resolution=config.resolution, dirs=config.dirs, subject=subject,
            workers=config.threads)))

    render(data / "samples", config.samples, config.seed)
    # photo subjects are other people than the stage-1 samples (seeds after them)
    render(data / "photo_subjects", config.photo_subjects, config.seed + config.samples)
    _check("render-photos", photos_cli.run(photos_cli.RenderPhotosConfig(
        data=data / "photo_subjects", envmaps=data / "lights", out=data / "photos", k=config.photo_lights,
        seed=config.seed, workers=config.threads)))


def toy_data(data: Path, config: QuickstartConfig) -> None:
    """Sphere samples, random lights and photos with a highlight (:mod:`export.toy_data`)."""
    from . import toy_data as toy

    toy.make_lights(data / "lights", config.n_lights, seed=config.seed + 1)
    toy.make_samples(data / "samples", config.samples, config.resolution, seed=config.seed)
    toy.make_photos(data / "photos", config.photo_subjects, config.photo_lights, config.resolution,
                    seed=config.seed + 2)


def make_data(data: Path, config: QuickstartConfig) -> str:
    """Write the data set unless it is there already; returns the source used."""
    marker = data / "SOURCE"
    if marker.exists():
        log.info("reusing the data in %s", data)
        return marker.read_text().strip()
    source = config.data_source
    if source == "auto":
        source = "render" if renderer_available() else "toy"
        if source == "toy":
            log.warning("the renderer is not available: using toy sphere data (install the 'render' extra)")
    (render_data if source == "render" else toy_data)(data, config)
    marker.write_text(source + "\n")
    return source


# ------------------------------------------------------------------------------------------ relighting


def _write_png(path: Path, rgb: np.ndarray) -> None:
    img = (np.clip(rgb, 0, 1) * 255 + 0.5).astype(np.uint8)[:, :, ::-1]
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".png", dir=path.parent)
    os.close(fd)
    if not cv2.imwrite(tmp, img):
        os.remove(tmp)
        raise RelightError(f"could not write {path}")
    os.replace(tmp, path)


def demo_relight(out: Path, photos: Path, resolution: int, light_name: str) -> Path:
    """Relight the first photo of ``photos`` under a preset light with the exported graphs in ``out``, through
    the runtime's public API (:class:`relight_rt.Relighter`); writes relit.png and a side-by-side."""
    from relight_rt import Relighter, RuntimeConfig

    from . import dataset
    from .torch_data import fit_square

    names = dataset.list_photos(photos)
    p = dataset.read_photo(photos, names[0])
    photo, mask = fit_square(p["photo"], resolution), fit_square(p["mask"], resolution)
    relighter = Relighter(RuntimeConfig(models=str(out), device="cpu", matting="off"))
    relit = relighter.relight(photo, light_name, mask=mask, background="black")
    _write_png(out / "relit.png", relit)
    _write_png(out / "relit_side_by_side.png", np.concatenate([photo * mask[..., None], relit], axis=1))
    log.info("relit %s under %r: %s", names[0], light_name, out / "relit.png")
    return out / "relit.png"


# ------------------------------------------------------------------------------------------ main


def run(config: QuickstartConfig) -> int:
    import torch

    if config.threads:
        torch.set_num_threads(config.threads)
    out = Path(config.out)
    if config.fresh and out.exists():
        for sub in ("data", "stage1", "stage2", "eval"):
            shutil.rmtree(out / sub, ignore_errors=True)
    out.mkdir(parents=True, exist_ok=True)
    data = out / "data"
    source = make_data(data, config)
    log.info("quickstart data (%s) in %s", source, data)

    from .evaluate import EvaluateConfig
    from .evaluate import run as evaluate
    from .train_stage1 import TrainStage1Config
    from .train_stage1 import run as train_stage1
    from .train_stage2 import TrainStage2Config
    from .train_stage2 import run as train_stage2

    s1, s2 = out / "stage1", out / "stage2"
    loop = {"width": config.width, "norm": config.norm, "seed": config.seed, "threads": config.threads,
            "log_every": 20, "export_onnx": True}
    _check("train-stage1", train_stage1(TrainStage1Config(
        data=data / "samples", lights=data / "lights", out=s1, resolution=config.resolution, epochs=1000,
        restart_epochs=20, max_minutes=config.stage1_minutes, sf_scale=config.sf_scale,
        resume=(s1 / "last.pt").exists(), **loop)))
    _check("train-stage2", train_stage2(TrainStage2Config(
        photos=data / "photos", stage1=s1 / "best.pt", out=s2, epochs=config.stage2_epochs,
        max_minutes=config.stage2_minutes, resume=(s2 / "last.pt").exists(), **loop)))
    for kind, run_dir in (("stage1", s1), ("stage2", s2)):
        shutil.copyfile(run_dir / f"{kind}.onnx", out / f"{kind}.onnx")
    _check("evaluate", evaluate(EvaluateConfig(
        stage1=s1 / "best.pt", stage2=s2 / "best.pt", data=data / "samples", lights=data / "lights",
        photos=data / "photos", out=out / "eval", max_samples=16, max_pairs=24)))
    demo_relight(out, data / "photos", config.resolution, config.light)
    log.info("quickstart done: %s", out)
    return 0
