"""``python -m export evaluate``: the paper's tables on a held-out synthetic split, plus relighting error.

Table 1 (synthetic samples, ``--data`` + ``--lights``): each sample i is rendered under a fixed
light (drawn from the seed: ``lights[rng(seed, i)]``), decomposed by stage 1, and compared with
its ground truth: RMSE inside the mask (albedo, transport, shading, reconstruction) and of the 27
light coefficients, SSIM inside the mask's bounding box (albedo, shading, reconstruction; data
range 1). Shading is max(0, T·L); reconstruction is clip(albedo ⊙ shading, 0, 1) ⊙ mask.

Table 2 (photos, ``--photos``): reconstruction of each photo by stage 1 alone (its diffuse
reconstruction under its own estimated light) and by stage 1 + 2; relighting: photo i of a
subject is decomposed and re-rendered under the light of photo j of the same subject (the
ground-truth SH light stored with it), then compared with photo j — the ground-truth relit photo.

Rows: the trained network(s) and baselines:
- ``trivial``: a constant decomposition that needs no network: transport of a camera-facing
  normal (n = +x, unoccluded: A_l · Y_k(+x)) at every pixel, the mean of the evaluation lights as
  light, and a constant albedo = the image's mean colour inside the mask divided by that shading
  (so its reconstruction is the flat mean colour). Relighting keeps the albedo and swaps the light.
- ``stage 1 (no SF)``: a network trained with ``--no-sf`` when ``--nosf`` gives its checkpoint.
- ``oracle: true diffuse`` (Table 2, reconstruction only): the renderer's own diffuse image of the
  photo, i.e. the size of the non-diffuse part; ``+ stage 2``: stage 2 applied to it, which shows
  whether stage 2 learned the non-diffuse residual independently of stage 1's errors.
- ``oracle: stage 1 + true residual`` (Table 2, relighting only): stage 1's relit diffuse image plus
  the renderer's own non-diffuse part of the target photo (photo j minus its diffuse image), i.e.
  what a perfect stage 2 would give on top of this stage 1: the ceiling of stage 2's relighting gain.

Stage 2's effect (Table 2 with ``--stage2``): the differences are small, so each photo and each pair
is compared with itself: mean change of RMSE (stage 1 + 2 minus stage 1; negative = stage 2 helps),
a 95 % bootstrap interval that resamples whole subjects (the photos and pairs of one person are not
independent), and the share of photos / pairs that stage 2 improves. With pairs, the same for the
oracle row ("a perfect stage 2"): if even that change is within noise, a stage 2 that adds the
non-diffuse part cannot show a relighting gain on these photos (only one that also repairs stage 1's
errors could).

Writes ``OUT/results.md`` (markdown tables) and ``OUT/results.json``. Metrics are means over samples.
"""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from relight_rt import RelightError
from relight_rt.light.sh import basis as sh_basis
from relight_rt.light.sh import cosine_lobe

from .config import as_record, reader
from .frozen import apply_stage2, load_frozen
from .metrics_img import masked_rmse, masked_ssim
from .shading import render_diffuse, shading
from .torch_data import PhotoDataset, Stage1Dataset, decompose, subject_of
from .training import collate, pick_device, write_json

log = logging.getLogger(__name__)

# unoccluded transport of a camera-facing normal n = +x: A_l · Y_k(+x), (9,)
FRONT_TRANSPORT = (cosine_lobe() * sh_basis(np.array([1.0, 0.0, 0.0]))).astype(np.float32)


def add_arguments(parser) -> None:
    parser.add_argument("--stage1", required=True, help="stage-1 checkpoint (.pt) or ONNX graph (.onnx)")
    parser.add_argument("--stage2", default=None, help="stage-2 checkpoint or ONNX graph (photo tables)")
    parser.add_argument("--baseline", help="another stage-1 checkpoint or graph (e.g. the bundled one): its rows, and "
                                           "the paired change from it to --stage1 per subject")
    parser.add_argument("--nosf", default=None, help="stage-1 network trained with --no-sf (baseline row)")
    parser.add_argument("--data", default=None, help="held-out stage-1 samples (Table 1)")
    parser.add_argument("--lights", default=None, help="lights to render the samples under (Table 1)")
    parser.add_argument("--photos", default=None, help="held-out photos SUBJECT__L{j} (Table 2, relighting)")
    parser.add_argument("--out", required=True, help="folder for results.md and results.json")
    parser.add_argument("--max-samples", type=int, default=None, help="evaluate at most this many samples/photos")
    parser.add_argument("--max-pairs", type=int, default=200, help="at most this many relighting pairs")
    parser.add_argument("--seed", type=int, default=0, help="seed of the per-sample lights")
    parser.add_argument("--device", default="auto")
    parser.add_argument("--threads", type=int, default=None, help="torch CPU threads")


def _hwc(t: torch.Tensor) -> np.ndarray:
    return t.detach().cpu().numpy().transpose(1, 2, 0).astype(np.float64)


def _mean(rows: list[dict]) -> dict:
    keys = rows[0].keys() if rows else []
    return {k: float(np.nanmean([r[k] for r in rows])) for k in keys}


def trivial_decomposition(image: torch.Tensor, mask: torch.Tensor, mean_light: torch.Tensor) -> dict:
    """The constant baseline (module docstring) for a batch (N,3,R,R), (N,1,R,R) and a (9,3) light."""
    n, _, h, w = image.shape
    t = torch.as_tensor(FRONT_TRANSPORT, dtype=image.dtype, device=image.device)
    transport = t.reshape(1, 9, 1, 1).expand(n, 9, h, w) * mask
    light = mean_light.to(image).expand(n, 9, 3)
    shading = (t[:, None] * light[0]).sum(0).clamp_min(1e-3)  # (3,)
    mean_colour = (image * mask).sum((2, 3)) / mask.sum((2, 3)).clamp_min(1e-6)  # (N,3)
    albedo = (mean_colour / shading)[:, :, None, None].expand(n, 3, h, w) * mask
    return {"transport": transport, "albedo": albedo, "skin": torch.zeros_like(mask), "light": light}


def _synthetic_metrics(pred: dict, true: dict, image: torch.Tensor) -> list[dict]:
    rows = []
    s_pred = shading(pred["transport"], pred["light"]) * true["mask"]
    s_true = shading(true["transport"], true["light"]) * true["mask"]
    recon = render_diffuse(pred["albedo"], pred["transport"], pred["light"], true["mask"])
    for i in range(image.shape[0]):
        m = true["mask"][i, 0].cpu().numpy().astype(np.float64)
        a_p, a_t = _hwc(pred["albedo"][i]), _hwc(true["albedo"][i])
        s_p, s_t = _hwc(s_pred[i]), _hwc(s_true[i])
        r_p, r_t = _hwc(recon[i]), _hwc(image[i])
        rows.append({
            "albedo_rmse": masked_rmse(a_p, a_t, m), "albedo_ssim": masked_ssim(a_p, a_t, m),
            "light_rmse": float((pred["light"][i] - true["light"][i]).square().mean().sqrt()),
            "transport_rmse": masked_rmse(_hwc(pred["transport"][i]), _hwc(true["transport"][i]), m),
            "shading_rmse": masked_rmse(s_p, s_t, m), "shading_ssim": masked_ssim(s_p, s_t, m),
            "recon_rmse": masked_rmse(r_p, r_t, m), "recon_ssim": masked_ssim(r_p, r_t, m),
        })
    return rows


def evaluate_synthetic(models: dict[str, torch.nn.Module], data: Path, lights: np.ndarray, seed: int,
                       max_samples: int | None, device: torch.device) -> dict[str, dict]:
    """Table 1: mean metrics per method over the samples of ``data`` (see the module docstring)."""
    resolution = next(iter(models.values())).resolution
    ds = Stage1Dataset(data, lights, resolution, augment=False, seed=seed, cache=False)
    n = len(ds) if max_samples is None else min(len(ds), max_samples)
    mean_light = torch.as_tensor(np.asarray(lights, np.float32).mean(0), device=device)
    rows: dict[str, list[dict]] = {name: [] for name in [*models, "trivial"]}
    for i in range(n):
        true = {k: v.to(device) if isinstance(v, torch.Tensor) else v for k, v in collate([ds[i]]).items()}
        image = render_diffuse(true["albedo"], true["transport"], true["light"], true["mask"])
        for name, model in models.items():
            rows[name] += _synthetic_metrics(decompose(model, image, true["mask"]), true, image)
        rows["trivial"] += _synthetic_metrics(trivial_decomposition(image, true["mask"], mean_light), true, image)
    return {name: {"n": len(r), **_mean(r)} for name, r in rows.items()}


def _photo_rows(pred: torch.Tensor, true: torch.Tensor, mask: torch.Tensor, prefix: str) -> dict:
    m = mask[0].cpu().numpy().astype(np.float64)
    p, t = _hwc(pred), _hwc(true)
    return {f"{prefix}_rmse": masked_rmse(p, t, m), f"{prefix}_ssim": masked_ssim(p, t, m)}


def evaluate_photos(stage1: torch.nn.Module, stage2: torch.nn.Module | None, photos: Path, lights_mean: torch.Tensor,
                    max_samples: int | None, max_pairs: int, device: torch.device,
                    extra_stage1: dict[str, torch.nn.Module] | None = None) -> tuple[dict[str, dict], dict[str, dict]]:
    """Table 2: reconstruction and relighting of photos, and stage 2's paired effect (module docstring).

    Returns:
        (mean metrics per method, {"recon_rmse": ..., "relight_rmse": ...} from :func:`paired_change`;
        empty without stage 2).
    """
    ds = PhotoDataset(photos, stage1.resolution, cache=True)
    n = len(ds) if max_samples is None else min(len(ds), max_samples)
    items = [{k: v.to(device) if isinstance(v, torch.Tensor) else v for k, v in collate([ds[i]]).items()}
             for i in range(n)]

    def residual(d: torch.Tensor, m: torch.Tensor) -> torch.Tensor:
        return apply_stage2(stage2, d, m)

    decomposers: dict[str, object] = {"trivial": lambda img, m: trivial_decomposition(img, m, lights_mean),
                                      "stage 1": lambda img, m: decompose(stage1, img, m)}
    for name, model in (extra_stage1 or {}).items():
        decomposers[name] = lambda img, m, model=model: decompose(model, img, m)
    recon: dict[str, list[dict]] = {}
    relight: dict[str, list[dict]] = {}
    decomps: dict[str, list[dict]] = {name: [] for name in decomposers}
    for it in items:
        photo, m = it["photo"] * it["mask"], it["mask"]
        gt_diffuse = it["diffuse"] * m  # the renderer's diffuse part: how far a perfect stage 1 gets
        recon.setdefault("oracle: true diffuse", []).append(_photo_rows(gt_diffuse[0], photo[0], m[0], "recon"))
        if stage2 is not None:
            recon.setdefault("oracle: true diffuse + stage 2", []).append(
                _photo_rows(residual(gt_diffuse, m)[0], photo[0], m[0], "recon"))
        for name, fn in decomposers.items():
            d = fn(photo, m)
            decomps[name].append(d)
            diffuse = render_diffuse(d["albedo"], d["transport"], d["light"], m)
            recon.setdefault(name, []).append(_photo_rows(diffuse[0], photo[0], m[0], "recon"))
            if stage2 is not None and name == "stage 1":
                recon.setdefault("stage 1 + 2", []).append(_photo_rows(residual(diffuse, m)[0], photo[0], m[0],
                                                                       "recon"))
    pairs = [(i, j) for i in range(n) for j in range(n)
             if i != j and subject_of(ds.names[i]) == subject_of(ds.names[j])][:max_pairs]
    for i, j in pairs:
        target, m = items[j]["photo"] * items[j]["mask"], items[i]["mask"] * items[j]["mask"]
        for name in decomposers:
            d = decomps[name][i]
            diffuse = render_diffuse(d["albedo"], d["transport"], items[j]["light"], m)
            relight.setdefault(name, []).append(_photo_rows(diffuse[0], target[0], m[0], "relight"))
            if name != "stage 1":
                continue
            true_residual = (items[j]["photo"] - items[j]["diffuse"]) * m
            relight.setdefault("oracle: stage 1 + true residual", []).append(
                _photo_rows((diffuse + true_residual).clamp(0, 1)[0], target[0], m[0], "relight"))
            if stage2 is not None:
                relight.setdefault("stage 1 + 2", []).append(_photo_rows(residual(diffuse, m)[0], target[0],
                                                                         m[0], "relight"))
    results = {}
    for name in [*recon, *(k for k in relight if k not in recon)]:
        results[name] = {"n_photos": len(recon[name]), **_mean(recon[name])} if name in recon else {}
        if relight.get(name):
            results[name].update({"n_pairs": len(relight[name]), **_mean(relight[name])})
    effect = {}
    subjects = [subject_of(name) for name in ds.names[:n]]
    if BASELINE in decomposers:
        effect["vs_baseline_recon_rmse"] = paired_change(recon[BASELINE], recon["stage 1"], "recon_rmse", subjects)
        if pairs:
            effect["vs_baseline_relight_rmse"] = paired_change(relight[BASELINE], relight["stage 1"], "relight_rmse",
                                                               [subjects[i] for i, _ in pairs])
    if stage2 is not None:
        effect["recon_rmse"] = paired_change(recon["stage 1"], recon["stage 1 + 2"], "recon_rmse", subjects)
        if pairs:
            pair_subjects = [subjects[i] for i, _ in pairs]
            effect["relight_rmse"] = paired_change(relight["stage 1"], relight["stage 1 + 2"], "relight_rmse",
                                                   pair_subjects)
            effect["relight_ceiling"] = paired_change(relight["stage 1"], relight["oracle: stage 1 + true residual"],
                                                      "relight_rmse", pair_subjects)
    return results, effect


BASELINE = "baseline stage 1"


def paired_change(base: list[dict], new: list[dict], key: str, groups: list[str], resamples: int = 2000,
                  seed: int = 0) -> dict:
    """Paired change of ``key`` from ``base`` to ``new`` (item by item): mean, 95 % subject-bootstrap interval,
    share of items that got lower.

    Args:
        base, new: rows of the same items in the same order.
        key: the metric, e.g. "relight_rmse".
        groups: the subject of each item; the bootstrap resamples subjects, keeping each one's items together.
    """
    diff = np.array([n[key] - b[key] for b, n in zip(base, new, strict=True)], np.float64)
    labels, index = np.unique(np.asarray(groups), return_inverse=True)
    sums = np.bincount(index, weights=diff, minlength=len(labels))
    counts = np.bincount(index, minlength=len(labels)).astype(np.float64)
    draws = np.random.default_rng(seed).integers(0, len(labels), (resamples, len(labels)))
    means = sums[draws].sum(1) / counts[draws].sum(1)
    low, high = np.percentile(means, [2.5, 97.5])
    return {"mean": float(diff.mean()), "ci95": [float(low), float(high)], "improved": float((diff < 0).mean()),
            "n": int(diff.size), "subjects": int(len(labels))}


def markdown(results: dict) -> str:
    """The results as markdown tables (one per section)."""
    lines = []
    titles = {"synthetic": "Table 1: decomposition of held-out synthetic samples (RMSE in mask, SSIM in bbox)",
              "photos": "Table 2: photos: reconstruction and relighting against ground-truth relit photos"}
    for section, rows in results.items():
        if section not in titles or not rows:
            continue
        cols = [k for k in next(iter(rows.values())) if k not in ("n", "n_photos", "n_pairs")]
        for r in rows.values():
            cols += [k for k in r if k not in cols and k not in ("n", "n_photos", "n_pairs")]
        counts = {k: max(r.get(k, 0) for r in rows.values()) for k in ("n", "n_photos", "n_pairs")}
        count_text = ", ".join(f"{k} = {v}" for k, v in counts.items() if v)
        lines += [f"### {titles[section]} ({count_text})", "",
                  "| method | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
        for name, r in rows.items():
            cells = [f"{r[c]:.4f}" if c in r and r[c] == r[c] else "–" for c in cols]
            lines.append(f"| {name} | " + " | ".join(cells) + " |")
        lines.append("")
        if section == "photos" and results.get("stage2_effect"):
            lines += ["Stage 2's effect, photo by photo and pair by pair (stage 1 + 2 minus stage 1; negative: stage 2 "
                      "helps; 95 % interval resampling subjects):", "",
                      "| RMSE | mean change | 95 % interval | improved | n (subjects) |", "|---|---|---|---|---|"]
            labels = {"recon_rmse": "recon", "relight_rmse": "relight",
                      "relight_ceiling": "relight, a perfect stage 2 (oracle)"}
            for key, e in results["stage2_effect"].items():
                low, high = e["ci95"]
                lines.append(f"| {labels.get(key, key)} | {e['mean']:+.4f} | [{low:+.4f}, {high:+.4f}] "
                             f"| {100 * e['improved']:.0f} % | {e['n']} ({e['subjects']}) |")
            lines.append("")
        if section == "photos" and results.get("baseline_effect"):
            lines += ["Stage 1 against the baseline stage 1, photo by photo and pair by pair (stage 1 minus baseline; "
                      "negative: --stage1 is better; 95 % interval resampling subjects):", "",
                      "| RMSE | mean change | 95 % interval | improved | n (subjects) |", "|---|---|---|---|---|"]
            for key, e in results["baseline_effect"].items():
                low, high = e["ci95"]
                lines.append(f"| {key.removesuffix('_rmse')} | {e['mean']:+.4f} | [{low:+.4f}, {high:+.4f}] "
                             f"| {100 * e['improved']:.0f} % | {e['n']} ({e['subjects']}) |")
            lines.append("")
    return "\n".join(lines)


@dataclass(frozen=True, kw_only=True)
class EvaluateConfig:
    """The settings of ``evaluate`` (one field per flag; see :func:`add_arguments`)."""

    stage1: Path
    out: Path
    stage2: Path | None = None
    baseline: Path | None = None
    nosf: Path | None = None
    data: Path | None = None
    lights: Path | None = None
    photos: Path | None = None
    max_samples: int | None = None
    max_pairs: int = 200
    seed: int = 0
    device: str = "auto"
    threads: int | None = None


config_from_args = reader(EvaluateConfig)


def run(config: EvaluateConfig) -> int:
    from . import dataset

    if config.threads:
        torch.set_num_threads(config.threads)
    if config.data is None and config.photos is None:
        raise RelightError("evaluate: give --data (with --lights) and/or --photos")
    if config.data is not None and config.lights is None:
        raise RelightError("evaluate: --data needs --lights (the lights the samples are rendered under)")
    device = pick_device(config.device)
    stage1 = load_frozen(config.stage1, "stage1", device, threads=config.threads)
    stage2 = load_frozen(config.stage2, "stage2", device, threads=config.threads) if config.stage2 else None
    extra = {}
    if config.nosf:
        extra["stage 1 (no SF)"] = load_frozen(config.nosf, "stage1", device, threads=config.threads)
    if config.baseline:
        extra[BASELINE] = load_frozen(config.baseline, "stage1", device, threads=config.threads)
    lights = dataset.read_lights(config.lights) if config.lights else None
    results: dict = {"args": as_record(config)}
    if config.data is not None:
        models = {"stage 1": stage1, **extra}
        results["synthetic"] = evaluate_synthetic(models, Path(config.data), lights, config.seed, config.max_samples,
                                                  device)
    if config.photos is not None:
        if lights is not None:
            mean_light = torch.as_tensor(lights.mean(0), device=device)
        else:  # the mean of the photos' own lights
            names = dataset.list_photos(config.photos)
            mean_light = torch.as_tensor(np.mean([dataset.read_photo(config.photos, n)["light"] for n in names], 0),
                                         device=device)
        results["photos"], effect = evaluate_photos(stage1, stage2, Path(config.photos), mean_light, config.max_samples,
                                                    config.max_pairs, device, extra)
        base = {k.removeprefix("vs_baseline_"): v for k, v in effect.items() if k.startswith("vs_baseline_")}
        stage2_effect = {k: v for k, v in effect.items() if not k.startswith("vs_baseline_")}
        if stage2_effect:
            results["stage2_effect"] = stage2_effect
        if base:
            results["baseline_effect"] = base
    out = Path(config.out)
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "results.json", results)
    text = markdown(results)
    tmp = out / ".results.md.tmp"
    tmp.write_text(text)
    tmp.replace(out / "results.md")
    log.info("%s", text)
    log.info("wrote %s and %s", out / "results.md", out / "results.json")
    return 0


def load_results(path: Path) -> dict:
    """Read a results.json written by :func:`run`."""
    return json.loads(Path(path).read_text())
