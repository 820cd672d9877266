"""Why did gpu-train's first runs get worse on held-out people? Overfitting, or the torch renderer's samples?

Renders (once, cached in ``--cache``) stage-1 samples of three kinds and scores stage-1 graphs on them:

- ``bank/torch``: people of the training bank, torch renderer (export.gpu.render; what gpu-train trained on);
- ``new/torch``: people of another bank (other seeds, never trained on), torch renderer;
- ``new/embree-bank``: the same new people, same framing and turn, embree renderer (export.render.transport at
  ``--embree-dirs``) on the bank's meshes and 512-px textures: the renderer alone differs from ``new/torch``;
- ``new/embree``: the same, from the person rebuilt by ``python -m export render``'s own code (full-size textures):
  what the shipped stage 1's training data and the held-out renders are (needs anny; skipped without it);
- ``new256/torch`` (with ``--new256``): the same people from a bank of 256-px textures, torch renderer;
- ``heldout/embree`` and ``heldout/photo`` (with ``--heldout``): the people of benchmarks/heldout_change.py, their
  diffuse inputs, then their non-diffuse photos (render-photos) as the input (each under its own lamp).

Each sample is scored under fixed lights (``--bank-lights`` of the bank's training lights and the six lamps of
benchmarks/heldout_change.py, projected to SH): the input image is clip(a ⊙ max(0, t·l), 0, 1) ⊙ mask as in training,
and per graph: the stage-1 loss of the first lend's gpu-train (``Stage1Loss(sf_scale=0.2)``, no band or direction terms:
gpu-train adds them since), the transport's L1, the relit diffuse image's RMSE under another of the lights (Â ⊙ max(0,
T̂·l') against a ⊙ max(0, t·l')), and the transport's degree-2/0 band ratio (mean over the mask of |T₂|/|T₀|, the
truth's beside it). Means per set.

    PYTHONPATH=. python benchmarks/gpu_gap.py --bank data/gpu_bank --new /tmp/gpu17_new --cache /tmp/gpu17_cache \
        --new256 /tmp/gpu17_new256 --n-bank 10 --n-new 10 \
        --graphs shipped=relight_rt/models/stage1.onnx run1=runs/gpu_1/stage1.onnx --json runs/gpu_gap.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from benchmarks.heldout_change import FRAMINGS as ORDER  # noqa: E402  (the held-out set's framings, in its order)


def lamp_lights() -> np.ndarray:
    """(6, 9, 3) RGB SH of heldout_change.py's six lamps."""
    from benchmarks.heldout_change import LAMPS, lamp_envmap
    from relight_rt.light.envmap import project_envmap

    return np.stack([np.asarray(project_envmap(lamp_envmap(d)), np.float32) for d in LAMPS.values()])


def _views(names: list[str], seed: int) -> list[tuple[str, str, float]]:
    rng = np.random.default_rng(seed)
    return [(n, ORDER[i % len(ORDER)], float(rng.uniform(-45.0, 45.0))) for i, n in enumerate(names)]


def _embree(subject, framing: str, yaw: float, resolution: int, dirs: int, seed: int) -> dict:
    from export.render.camera import fit_camera
    from export.render.cli import turn_subject
    from export.render.raycast import Tracer
    from export.render.transport import render_gbuffer, transport

    subject = turn_subject(subject, yaw)
    cam = fit_camera(subject, resolution, framing=framing)
    tracer = Tracer(subject)
    g = render_gbuffer(subject, cam, tracer)
    t = transport(tracer, g, dirs, rng=np.random.default_rng([seed, 0x5A17]))
    return {"albedo": g.image(g.albedo), "mask": g.mask[..., None], "skin": g.image(g.skin)[..., None],
            "transport": g.image(t)}


def render_sets(args) -> dict[str, list[dict]]:
    """{set name: [sample dicts of (R, R, C) float32 arrays]}, rendered or read from the cache."""
    import torch

    from export.gpu import bank
    from export.gpu.render import DeviceSubject, RenderSettings, render_sample

    settings = RenderSettings(resolution=args.resolution, dirs=args.dirs, shadow_size=args.shadow_size)
    cache = Path(args.cache)
    cache.mkdir(parents=True, exist_ok=True)
    sets: dict[str, list[dict]] = {}
    plan = []
    train = bank.read_index(args.bank)["subjects"]
    train = train[: len(train) - args.held_out] if args.held_out else train  # (gpu-train's held-out people)
    picks = [train[int(i)] for i in np.linspace(0, len(train) - 1, args.n_bank).round()]
    plan += [("bank/torch", args.bank, v) for v in _views(picks, 1)]
    new = bank.read_index(args.new)["subjects"][: args.n_new]
    for kind in ("new/torch", "new/embree-bank", "new/embree"):
        plan += [(kind, args.new, v) for v in _views(new, 2)]
    if args.new256 is not None:  # the same people stored with smaller textures (gpu-bank --texture-size 256)
        plan += [("new256/torch", args.new256, v) for v in _views(new, 2)]
    for kind, root, (name, framing, yaw) in plan:
        path = cache / f"{kind.replace('/', '_')}_{name}_{framing}.npz"
        if not path.is_file():
            t0 = time.monotonic()
            template = bank.read_template(root)
            data = bank.read_subject(Path(root) / f"{name}.npz", template)
            if kind.endswith("torch"):
                s = render_sample(DeviceSubject.from_data(data, torch.device("cpu")), settings, framing=framing,
                                  yaw_deg=yaw, generator=torch.Generator().manual_seed(7))
                sample = {k: v.numpy().transpose(1, 2, 0) for k, v in s.items()}
            elif kind == "new/embree-bank":
                sample = _embree(bank.to_subject(data), framing, yaw, args.resolution, args.embree_dirs, 7)
            else:
                try:
                    from export.render.cli import make_subject
                except ImportError:
                    continue
                seed = int(name.rsplit("_", 1)[1])
                sample = _embree(make_subject({"kind": "anny", "seed": seed, "clothing": True}), framing, yaw,
                                 args.resolution, args.embree_dirs, 7)
            np.savez_compressed(path, **{k: v.astype(np.float32) for k, v in sample.items()})
            print(f"{kind} {name} {framing} yaw {yaw:+.0f}: {time.monotonic() - t0:.0f} s", flush=True)
        with np.load(path) as z:
            sets.setdefault(kind, []).append({k: z[k] for k in z.files} | {"name": name, "framing": framing})
    if args.heldout is not None:
        sets.update(heldout_sets(Path(args.heldout)))
    return sets


def heldout_sets(root: Path) -> dict[str, list[dict]]:
    """The people of benchmarks/heldout_change.py (``make``'s folder): ``heldout/embree``, their embree samples
    (test_FRAMING); ``heldout/photo``, the same with the photos of render-photos (photos_FRAMING: non-diffuse,
    under the lamps) as the input in place of the diffuse image, each photo with its own true light."""
    from benchmarks.heldout_change import _read
    from export import dataset

    sets: dict[str, list[dict]] = {"heldout/embree": [], "heldout/photo": []}
    for test in sorted(root.glob("test_*")):
        framing = test.name.split("_", 1)[1]
        photos = root / f"photos_{framing}"
        for name in dataset.list_samples(test):
            s = dataset.read_sample(test, name)
            sample = {"albedo": s["albedo"], "mask": s["mask"][..., None], "skin": s["skin"][..., None],
                      "transport": s["transport"], "name": name, "framing": framing}
            sets["heldout/embree"].append(sample)
            shots = []
            for f in sorted(photos.glob(f"{name}__L*_photo.png")):
                photo, _, light = _read(photos, f.name[: -len("_photo.png")])  # (heldout_change's reader)
                shots.append((photo, light))
            if shots:
                sets["heldout/photo"].append(sample | {"photos": shots})
    return {k: v for k, v in sets.items() if v}


def _band_ratio(t, m) -> float:
    """Mean over the mask of |T₂| / |T₀| (T: (N, 9, H, W) tensor, m: (N, 1, H, W) bool)."""
    deg2 = t[:, 4:9].square().sum(1, keepdim=True).sqrt()
    ratio = deg2 / t[:, :1].abs().clamp_min(1e-3)
    return float(ratio[m].mean())


def score(sets: dict[str, list[dict]], graphs: dict[str, Path], lights: np.ndarray) -> dict:
    """{graph: {set: {figure: mean}}} (module doc)."""
    import torch

    from export.frozen import OnnxStage
    from export.losses import Stage1Loss, band_magnitude_loss, direction_loss
    from export.shading import render_diffuse, shading

    loss_fn = Stage1Loss(sf_scale=0.2)
    light_t = torch.as_tensor(lights)
    out: dict = {}
    for gname, gpath in graphs.items():
        stage = OnnxStage(gpath, "stage1")
        for sname, samples in sets.items():
            rows = []
            for s in samples:
                b = {k: torch.as_tensor(s[k].transpose(2, 0, 1))[None].float() for k in
                     ("albedo", "mask", "skin", "transport")}
                own = light_t
                if "photos" in s:  # the photos are the input, each under its own light
                    own = torch.as_tensor(np.stack([light for _, light in s["photos"]]))
                n = len(own)
                batch = {k: v.expand(n, -1, -1, -1) for k, v in b.items()} | {"light": own}
                image = render_diffuse(batch["albedo"], batch["transport"], batch["light"], batch["mask"])
                if "photos" in s:
                    image = torch.as_tensor(np.stack([p.transpose(2, 0, 1) for p, _ in s["photos"]])) * batch["mask"]
                pred = stage.run({"image": image, "mask": batch["mask"]})
                m = batch["mask"] > 0.5
                for i in range(n):
                    one = {k: v[i : i + 1] for k, v in batch.items()}
                    p = {k: pred[k][i : i + 1] for k in ("transport", "albedo", "skin", "light")}
                    terms = loss_fn(p, one)
                    other = own[(i + 1) % n][None]
                    relit = (p["albedo"] * shading(p["transport"], other)).clamp(0, 1)
                    truth = (one["albedo"] * shading(one["transport"], other)).clamp(0, 1)
                    mi = m[i : i + 1].expand_as(relit)
                    rows.append({
                        "loss": float(terms["total"]), "transport_l1": float(terms["transport"]),
                        "albedo_l1": float(terms["albedo"]), "light_l1": float(terms["light"]),
                        "band_loss": float(band_magnitude_loss(p["transport"], one["transport"], one["mask"])),
                        "direction_loss": float(direction_loss(p["transport"], one["transport"], one["mask"])),
                        "relit_rmse": float(((relit - truth)[mi] ** 2).mean().sqrt()),
                        "band2": _band_ratio(p["transport"], m[i : i + 1]),
                        "band2_true": _band_ratio(one["transport"], m[i : i + 1]),
                    })
            out.setdefault(gname, {})[sname] = {k: float(np.mean([r[k] for r in rows])) for k in rows[0]} | {
                "samples": len(samples), "rows": len(rows)}
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--bank", type=Path, required=True, help="the training bank")
    p.add_argument("--new", type=Path, required=True, help="a bank of people never trained on")
    p.add_argument("--new256", type=Path, help="the --new people in a bank of smaller textures (optional)")
    p.add_argument("--heldout", type=Path, help="benchmarks/heldout_change.py make's folder (optional)")
    p.add_argument("--cache", type=Path, required=True, help="rendered samples are kept here")
    p.add_argument("--graphs", nargs="+", required=True, help="NAME=PATH stage-1 graphs")
    p.add_argument("--n-bank", type=int, default=6)
    p.add_argument("--held-out", type=int, default=4,
                   help="the bank's last people gpu-train held out (its --val-people): never picked as trained on; "
                        "0 for a bank trained whole (the first lend's)")
    p.add_argument("--n-new", type=int, default=6)
    p.add_argument("--resolution", type=int, default=256)
    p.add_argument("--dirs", type=int, default=128)
    p.add_argument("--shadow-size", type=int, default=256)
    p.add_argument("--embree-dirs", type=int, default=128)
    p.add_argument("--bank-lights", type=int, default=4)
    p.add_argument("--sets", nargs="+", help="score only these sets (default: all)")
    p.add_argument("--json", type=Path)
    args = p.parse_args(argv)
    from export.gpu import bank

    graphs = {g.split("=", 1)[0]: Path(g.split("=", 1)[1]) for g in args.graphs}
    sets = render_sets(args)
    sets = {k: v for k, v in sets.items() if not args.sets or k in args.sets}
    bank_lights = bank.read_lights(args.bank, bank.read_index(args.bank))
    picked = bank_lights[np.random.default_rng(3).choice(len(bank_lights), args.bank_lights, replace=False)]
    result = {"albedo_mae_vs_full_textures": {}}
    if "new/embree" in sets:  # the renders' albedo against the full-size textures', per set, in both masks
        for sname, samples in sets.items():
            if sname.startswith("new") and len(samples) == len(sets["new/embree"]):
                errs = [np.abs(a["albedo"] - b["albedo"])[((a["mask"] > 0.5) & (b["mask"] > 0.5))[..., 0]].mean()
                        for a, b in zip(samples, sets["new/embree"], strict=True)]
                result["albedo_mae_vs_full_textures"][sname] = float(np.mean(errs))
        print("albedo MAE against the full-size textures:", result["albedo_mae_vs_full_textures"])
    for lname, lights in (("bank lights", picked), ("lamps", lamp_lights())):
        chosen = {k: v for k, v in sets.items() if lname == "lamps" or k != "heldout/photo"}  # photos: own lamps
        result[lname] = score(chosen, graphs, lights)
        print(f"\n{lname}: loss / transport L1 / relit RMSE / degree-2/0 (truth)")
        for sname in result[lname][next(iter(graphs))]:
            cells = [f"{g} {r[sname]['loss']:.3f} / {r[sname]['transport_l1']:.4f} / {r[sname]['relit_rmse']:.4f} / "
                     f"{r[sname]['band2']:.2f} ({r[sname]['band2_true']:.2f})" for g, r in result[lname].items()]
            print(f"  {sname:16s} " + " | ".join(cells))
        print(f"{lname}: albedo L1 / light L1 / band loss / direction loss")
        for sname in result[lname][next(iter(graphs))]:
            cells = [f"{g} {r[sname]['albedo_l1']:.4f} / {r[sname]['light_l1']:.4f} / {r[sname]['band_loss']:.4f} / "
                     f"{r[sname]['direction_loss']:.4f}" for g, r in result[lname].items()]
            print(f"  {sname:16s} " + " | ".join(cells))
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
