"""``python -m export gpu-check``: the torch renderer's samples against the embree renderer's, on bank people.

Each of ``--n`` bank subjects from ``--start`` on is rendered, unturned, in one framing of the training mix (in
turn: full, knees-up, waist-up, head-shoulders, face), by both renderers from the very same meshes and
textures (:func:`export.gpu.bank.to_subject`): the torch one (:mod:`export.gpu.render`, shadow maps over
``--dirs`` directions) and the embree one (:mod:`export.render.transport`, ray-cast visibility over
``--reference-dirs`` cosine-weighted directions, the reference). Per sample, inside the pixels both masks
cover: the Pearson correlation of the transport (all nine coefficients together, and each on its own),
and of the shading under ten training lights of the bank; the masks' IoU and the largest albedo
difference. The same figures for embree at ``--embree-dirs`` directions (what the CPU training data
uses) against the reference give the noise floor of today's samples. Needs the ``render`` extra (embreex).

Example::

    python -m export gpu-check --bank data/gpu_bank --n 5 --out runs/gpu_check.json
"""

from __future__ import annotations

import argparse
import json
import logging
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from relight_rt import RelightError

log = logging.getLogger(__name__)

ORDER = ("full", "knees-up", "waist-up", "head-shoulders", "face")


@dataclass(frozen=True)
class GpuCheckConfig:
    bank: Path = Path("data/gpu_bank")
    out: Path | None = None
    n: int = 5
    start: int = 0
    resolution: int = 256
    dirs: int = 128
    shadow_size: int = 256
    reference_dirs: int = 1024
    embree_dirs: int = 128
    seed: int = 0


MAX_EMBREE_DIRS = 65536  # the embree renderer's directions per pixel (the reference uses 1024)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    d = GpuCheckConfig()
    parser.add_argument("--bank", type=Path, default=d.bank, help="bank folder (default %(default)s)")
    parser.add_argument("--out", type=Path, help="also write the figures to this JSON file")
    parser.add_argument("--n", type=int, default=d.n, help="people to compare (default %(default)s)")
    parser.add_argument("--start", type=int, default=d.start,
                        help="the first of them, in the bank's order (default %(default)s)")
    parser.add_argument("--resolution", type=int, default=d.resolution)
    parser.add_argument("--dirs", type=int, default=d.dirs, help="torch renderer: visibility directions")
    parser.add_argument("--shadow-size", type=int, default=d.shadow_size, help="torch renderer: depth-map side")
    parser.add_argument("--reference-dirs", type=int, default=d.reference_dirs,
                        help="embree directions of the reference (default %(default)s)")
    parser.add_argument("--embree-dirs", type=int, default=d.embree_dirs,
                        help="embree directions of the noise-floor comparison (default %(default)s, as the "
                             "training renders of models/README.md)")
    parser.add_argument("--seed", type=int, default=d.seed)


def config_from_args(args: argparse.Namespace) -> GpuCheckConfig:
    return GpuCheckConfig(bank=Path(args.bank), out=args.out, n=args.n, start=args.start,
                          resolution=args.resolution, dirs=args.dirs, shadow_size=args.shadow_size,
                          reference_dirs=args.reference_dirs, embree_dirs=args.embree_dirs, seed=args.seed)


def _corr(a: np.ndarray, b: np.ndarray) -> float:
    a, b = a.ravel().astype(np.float64), b.ravel().astype(np.float64)
    if a.std() < 1e-12 or b.std() < 1e-12:
        return float("nan")
    return float(np.corrcoef(a, b)[0, 1])


def compare(candidate: dict[str, np.ndarray], reference: dict[str, np.ndarray], lights: np.ndarray) -> dict:
    """Figures of one sample pair (dicts of export.render.transport.render_sample's (R, R, C) arrays)."""
    both = (candidate["mask"] > 0.5) & (reference["mask"] > 0.5)
    either = (candidate["mask"] > 0.5) | (reference["mask"] > 0.5)
    tc, tr = candidate["transport"][both], reference["transport"][both]  # (M, 9)
    shading_c = np.einsum("mk,lkc->lmc", tc, lights).mean(-1)
    shading_r = np.einsum("mk,lkc->lmc", tr, lights).mean(-1)
    return {
        "pixels": int(both.sum()),
        "mask_iou": float(both.sum() / max(either.sum(), 1)),
        "albedo_max_diff": float(np.abs(candidate["albedo"][both] - reference["albedo"][both]).max()),
        "transport_corr": _corr(tc, tr),
        "coefficient_corr": [_corr(tc[:, k], tr[:, k]) for k in range(9)],
        "shading_corr": float(np.mean([_corr(shading_c[i], shading_r[i]) for i in range(len(lights))])),
        "transport_mae": float(np.abs(tc - tr).mean()),
    }


def run(config: GpuCheckConfig) -> int:
    import torch

    from export.render.camera import fit_camera
    from export.render.raycast import Tracer
    from export.render.transport import render_gbuffer, transport

    from . import bank
    from .render import DeviceSubject, RenderSettings, render_sample

    if config.n < 1 or config.start < 0:
        raise RelightError(f"expected --n >= 1 and --start >= 0, got {config.n} and {config.start}")
    for name in ("reference_dirs", "embree_dirs"):
        if not 1 <= getattr(config, name) <= MAX_EMBREE_DIRS:
            raise RelightError(f"--{name.replace('_', '-')}: expected 1 to {MAX_EMBREE_DIRS}, got "
                               f"{getattr(config, name)}")
    settings = RenderSettings(resolution=config.resolution, dirs=config.dirs, shadow_size=config.shadow_size)
    index = bank.read_index(config.bank)
    if config.out is not None:  # before the work: the figures never replace a file of the bank
        from relight_rt.engine.files import check_target

        bank_files = [Path(config.bank) / n for n in ("bank.json", "template.npz", index["lights"])]
        check_target(config.out, [*bank_files, *(Path(config.bank) / f"{n}.npz" for n in index["subjects"])])
    template = bank.read_template(config.bank)
    lights_all = bank.read_lights(config.bank, index)
    lights = lights_all[np.random.default_rng(config.seed).choice(len(lights_all), min(10, len(lights_all)),
                                                                  replace=False)]
    rows = []
    names = index["subjects"][config.start : config.start + config.n]
    if not names:
        raise RelightError(f"--start {config.start}: the bank has {len(index['subjects'])} people")
    for i, name in enumerate(names):
        framing = ORDER[i % len(ORDER)]
        data = bank.read_subject(Path(config.bank) / f"{name}.npz", template)
        t0 = time.monotonic()
        sample = render_sample(DeviceSubject.from_data(data, torch.device("cpu")), settings, framing=framing,
                               generator=torch.Generator().manual_seed(config.seed + i))
        torch_s = time.monotonic() - t0
        ours = {k: v.numpy().transpose(1, 2, 0) for k, v in sample.items()}
        ours["mask"] = ours["mask"][..., 0]
        subject = bank.to_subject(data)
        cam = fit_camera(subject, config.resolution, framing=framing)
        tracer = Tracer(subject)
        g = render_gbuffer(subject, cam, tracer)
        t0 = time.monotonic()
        t_ref = transport(tracer, g, config.reference_dirs, rng=np.random.default_rng([config.seed, i, 1]))
        embree_s = time.monotonic() - t0
        t_cpu = transport(tracer, g, config.embree_dirs, rng=np.random.default_rng([config.seed, i, 2]))
        reference = {"albedo": g.image(g.albedo), "mask": g.mask, "transport": g.image(t_ref)}
        floor = {"albedo": g.image(g.albedo), "mask": g.mask, "transport": g.image(t_cpu)}
        row = {"subject": name, "framing": framing, "torch_s": round(torch_s, 2),
               "embree_reference_s": round(embree_s, 2), "torch": compare(ours, reference, lights),
               "embree_at_training_dirs": compare(floor, reference, lights)}
        rows.append(row)
        log.info("%s (%s): torch vs embree corr %.4f (per coefficient min %.4f, shading %.4f, mask IoU %.4f); "
                 "embree %d dirs vs reference %.4f", name, framing, row["torch"]["transport_corr"],
                 min(row["torch"]["coefficient_corr"]), row["torch"]["shading_corr"], row["torch"]["mask_iou"],
                 config.embree_dirs, row["embree_at_training_dirs"]["transport_corr"])
    result = {"config": {k: str(v) for k, v in vars(config).items()}, "samples": rows,
              "min_transport_corr": min(r["torch"]["transport_corr"] for r in rows),
              "mean_transport_corr": float(np.mean([r["torch"]["transport_corr"] for r in rows])),
              "min_shading_corr": min(r["torch"]["shading_corr"] for r in rows)}
    print(json.dumps({k: v for k, v in result.items() if k != "samples"}, indent=1))
    if config.out is not None:
        from export.training import write_json

        write_json(Path(config.out), result)
    return 0
