"""Held-out renders: where the relit change's contrast is lost, step by step (contrast27).

    PYTHONPATH=$PWD python benchmarks/heldout_steps.py ~/.cache/relight_rt_real_photos/heldout/photos_* \
        [--ablate] [--only SECTION ...] [--json OUT.json]
    # model, ladder, swap and bands ~6 min on the shared 2-core CPU; --ablate ~2.5 min more; every section
    # (--only model ladder swap ladder-true ablate bands) 16 min

The same pairs as ``benchmarks/heldout_change.py measure`` (every ordered pair (i, j) of one person's photos: photo i
relit under the true light j, "physical" exposure, compared with photo j in the mask; contrast = slope of our
per-pixel log-luminance change on the truth's, correlation, RMSE), for:

- ``model``: the SH model's own ceiling and stage 1's raw answer, computed here from the layers (no product step):
  the truth's diffuse image under light j (``NAME__Lj_diffuse.png``: its albedo x true transport . light j, 8 bits),
  and photo i times a shading ratio S_j / S_own (luminance; both floored at 1 % of their medians; clipped to [0, 1] as
  a picture is) for each of {true, stage 1's} transport x {true, stage 1's} own light, and for stage 1's transport
  with the truth's shape or occlusion in it (``mixed_transport``); stage 1's transport unpremultiplied in the network
  frame and its ratio taken to the photo's frame as the runtime's layers are (``CropGeometry.to_input``);
- ``ladder``: the runtime's relight path with every later step switched off, then each switched on in turn in the
  order the path applies them, up to the product (``STEPS``); the last row is the product (``measure``'s figures);
- ``swap``: the product without the head pass (which runs stage 1 again on a crop this script cannot give the true
  transport of), then with the true transport (whole, or its shape or occlusion alone: ``mixed_transport``), the true
  own light or both put in place of stage 1's (the true light
  scaled so that stage 1's albedo x transport . light has the photo's mean luminance: the light's level is the
  exposure, not its shape); with a true light the refit of the photo's light is off (it would re-estimate it), so
  the product without refit is given as well;
- ``ladder-true`` (with ``--only``): the ladder again with the true transport and own light (the refit and the head
  pass off throughout): which step loses contrast when stage 1's inputs are right;
- with ``--ablate``: the product with each step switched off alone.

Each table also gives the contrast over the pixels lit in both photos (luminance >= ``LIT``): most of the truth's log
change lies in the deep shadows, where 8 bits leave the photo mostly noise.

It also prints the band ratios (degree-1 magnitude over degree 0, degree 2 over degree 0, luminance) of the photo's
own light: stage 1's, the product's (after refit and face refit), and the truth's.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import sys
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
for p in (REPO, REPO / "benchmarks"):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

import heldout_change as hc  # noqa: E402

from relight_rt.image.color import REC709  # noqa: E402

# the product's relight path in the order it applies its steps; each name is switched by ``switched_off``
STEPS = ("stage 2 residual", "band gains", "face mesh transport", "light refit", "face refit", "explain photo",
         "missing light", "cast shadows", "deep-shadow fill", "head pass", "look")
LIT = 0.04  # figures' "lit" pixels: luminance at least this in both photos of a pair


# ------------------------------------------------------------------------------------------------ figures


def figures(relit: np.ndarray, src: tuple, dst: tuple) -> dict:
    """heldout_change's per-pair figures of a relit picture (H, W, 3) of photo ``src`` against photo ``dst``."""
    (img_i, mask_i, _), (img_j, mask_j, _) = src, dst
    m = (mask_i > 0.5) & (mask_j > 0.5)
    lum = lambda x: x[m] @ REC709  # noqa: E731
    ours = np.log(lum(relit) + hc.EPS) - np.log(lum(img_i) + hc.EPS)
    truth = np.log(lum(img_j) + hc.EPS) - np.log(lum(img_i) + hc.EPS)
    do, dt = ours - ours.mean(), truth - truth.mean()
    out = {"slope": float((do * dt).sum() / max((dt * dt).sum(), 1e-30)),
           "corr": float((do * dt).sum() / math.sqrt((do * do).sum() * (dt * dt).sum() + 1e-30)),
           "rmse": float(np.sqrt(((relit - img_j) ** 2)[m].mean()))}
    # the same slope over the pixels lit in both photos (luminance >= LIT, ~10 levels of 255: off the deep
    # shadows, where 8 bits leave a log change mostly noise), and the truth's log variance those deep shadows hold
    lit = np.minimum(lum(img_i), lum(img_j)) >= LIT
    if lit.sum() > 10:
        a, b = ours[lit] - ours[lit].mean(), truth[lit] - truth[lit].mean()
        out["slope_lit"] = float((a * b).sum() / max((b * b).sum(), 1e-30))
    out["dark_share"] = float((dt[~lit] ** 2).sum() / max((dt * dt).sum(), 1e-30))
    return out


def summary(rows: list[dict]) -> dict:
    keys = ("slope", "corr", "rmse", "slope_lit", "dark_share")
    return {k: float(np.mean([r[k] for r in rows if k in r])) for k in keys} | {"pairs": len(rows)}


def people(folder: Path) -> dict[str, list[str]]:
    """{person: [photo names]} of a render-photos folder."""
    names = sorted(p.name[: -len("_photo.png")] for p in folder.glob("*__L*_photo.png"))
    out: dict[str, list[str]] = {}
    for n in names:
        out.setdefault(n.rpartition("__L")[0], []).append(n)
    return out


def true_transport(folder: Path, person: str) -> np.ndarray:
    framing = folder.name.rsplit("_", 1)[-1]
    with np.load(folder.parent / f"test_{framing}" / f"{person}_transport.npz", allow_pickle=False) as z:
        return np.asarray(z["T"], np.float32)


def read_rgb(path: Path) -> np.ndarray:
    return cv2.cvtColor(cv2.imread(str(path), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB).astype(np.float32) / 255


# ------------------------------------------------------------------------------------------- the SH model


def mixed_transport(true: np.ndarray, est: np.ndarray, keep: str) -> np.ndarray:
    """A transport (..., 9) that takes one part from ``true`` and the rest from ``est`` (same frame): ``keep`` "true"
    or "est" (all of one), "occlusion" (the truth's degree 0, the pixel's visibility x cosine summed, with the
    estimate's bands 1-2 at the estimate's ratio to its own degree 0: the estimate's shape, the truth's occlusion) or
    "shape" (the estimate's degree 0 with the truth's bands 1-2 at their ratio to the truth's degree 0)."""
    if keep in ("true", "est"):
        return (true if keep == "true" else est).astype(np.float32)
    scale_from, bands_from = (true, est) if keep == "occlusion" else (est, true)
    t0 = scale_from[..., :1]
    ratio = np.divide(bands_from[..., 1:], bands_from[..., :1], out=np.zeros_like(bands_from[..., 1:]),
                      where=np.abs(bands_from[..., :1]) > 1e-4)
    return np.concatenate([t0, ratio * t0], axis=-1).astype(np.float32)


def _ratio(t_new: np.ndarray, t_own: np.ndarray, new: np.ndarray, own: np.ndarray, where: np.ndarray) -> np.ndarray:
    """Luminance shading ratio (T_new . new) / (T_own . own), (9,) lights; both floored at 1 % of their medians."""
    a, b = t_new @ new, t_own @ own
    fa, fb = (0.01 * max(float(np.median(x[where])), 1e-6) for x in (a, b))
    return np.maximum(a, fa) / np.maximum(b, fb)


def model_rows(relighter, folder: Path) -> dict[str, list[dict]]:
    """The ``model`` rows of one framing: {row name: per-pair figures}."""
    rows: dict[str, list[dict]] = {}
    for person, group in people(folder).items():
        data = {n: hc._read(folder, n) for n in group}
        t_true = true_transport(folder, person)
        for a in group:
            img, mask, light_i = data[a]
            dec = relighter._stage1([img], [mask], False, faces=False)[0][0]  # stage 1 alone, no refit
            alpha = dec.network_mask
            inner = alpha > 0.5
            t1 = np.divide(dec.transport, alpha[..., None], out=np.zeros_like(dec.transport),
                           where=inner[..., None])
            l1 = dec.light @ REC709
            where_in = mask > 0.5
            for b in group:
                if b == a:
                    continue
                lj = data[b][2] @ REC709
                li = light_i @ REC709
                maps = {
                    "true T, true own light": _ratio(t_true, t_true, lj, li, where_in),
                    "true T, stage-1 own light": _ratio(t_true, t_true, lj, l1, where_in),
                }
                net = {
                    "stage-1 T, stage-1 own light": _ratio(t1, t1, lj, l1, inner),
                    "stage-1 T, true own light": _ratio(t1, t1, lj, li, inner),
                }
                t_net = dec.geometry.to_network(t_true)
                for part in ("occlusion", "shape"):
                    t = mixed_transport(t_net, t1, part)
                    net[f"true {part} in stage-1 T, true own light"] = _ratio(t, t, lj, li, inner)
                for name, r in net.items():
                    maps[name] = dec.to_input(np.where(inner, r, 1).astype(np.float32))
                out = {"truth's albedo x true T . new light": read_rgb(folder / f"{b}_diffuse.png")}
                out |= {f"photo x ratio: {k}": np.clip(img * r[..., None], 0, 1) for k, r in maps.items()}
                for name, relit in out.items():
                    rows.setdefault(name, []).append(figures(relit, data[a], data[b]))
    return rows


def light_bands(relighter, folder: Path) -> dict:
    """Mean band ratios (degree-1 / degree-0, degree-2 / degree-0, luminance) of the photo's own light: stage 1's,
    the product's and the truth's."""
    out = {"stage 1": [], "product": [], "truth": []}
    for group in people(folder).values():
        for n in group:
            img, mask, light = hc._read(folder, n)
            raw = relighter._stage1([img], [mask], False, faces=False)[0][0]
            dec = relighter.decompose(img, mask)
            for k, lt in (("stage 1", raw.light), ("product", dec.light), ("truth", light)):
                out[k].append(hc._band_ratios(np.asarray(lt, np.float64) @ REC709))
    return {k: [float(np.mean([v[0] for v in vals])), float(np.mean([v[1] for v in vals]))]
            for k, vals in out.items()}


# -------------------------------------------------------------------------------------- the product's steps


@contextlib.contextmanager
def switched_off(relighter, steps) -> None:
    """The relighter with ``steps`` (names from ``STEPS``) switched off, restored on exit."""
    from relight_rt.relight import compose, factor, shadow_fill, strength

    undo = []

    def put(obj, name, value):
        undo.append((obj, name, getattr(obj, name)))
        setattr(obj, name, value)

    steps = set(steps)
    if not steps <= set(STEPS):
        raise ValueError(f"unknown steps {sorted(steps - set(STEPS))}")
    if "stage 2 residual" in steps:
        put(relighter._network, "stage2", None)
    if "band gains" in steps:
        put(strength, "BAND_GAIN", (1.0, 1.0, 1.0))
    if "face mesh transport" in steps:
        put(relighter._faces, "find", lambda image, box: None)
    if "light refit" in steps:
        put(factor, "refit_light", lambda light, *a, **k: np.array(light, np.float32))
    if "face refit" in steps:
        put(factor, "face_refit", lambda light, *a, **k: np.array(light, np.float32))
    if "explain photo" in steps:
        put(strength, "EXPLAIN_SHARE", 0.0)
        put(strength, "EXPLAIN_SHADOW_SHARE", 0.0)
    if "missing light" in steps:
        put(factor, "_OWN_FLOOR", np.float32(0.0))
    if "cast shadows" in steps:
        put(factor.Factor, "cast", lambda self, dec, own, light: None)
    if "deep-shadow fill" in steps:
        put(shadow_fill.ShadowFill, "shadow_weight", lambda self, dec: None)
    if "head pass" in steps:
        put(relighter, "face_pass", False)
    if "look" in steps:
        put(factor, "shaded_skin", lambda f, ratio, *a: f)
        put(compose, "steady_chroma", lambda image, gain, dark=None: image * gain)
        put(compose, "keep_neutral", lambda colour, gain, neutral: colour)
        put(compose, "shoulder", lambda colour, knee: colour)
    try:
        yield relighter
    finally:
        for obj, name, value in reversed(undo):
            setattr(obj, name, value)


@contextlib.contextmanager
def swapped(relighter, truth: dict, transport: bool | str, light: bool):
    """Stage 1's transport (``transport``: True, or a ``mixed_transport`` part: "occlusion", "shape") and/or light
    replaced by the truth's (``truth``: {"T": (H, W, 9), "light": (9, 3)} of the
    photo being decomposed, input frame) in every decomposition of a photo of that size (the body pass)."""
    original = relighter._stage1

    def stage1(images, masks, allow_full, faces):
        decs, groups, automatic = original(images, masks, allow_full, faces)
        out = []
        for dec in decs:
            if dec.image.shape[:2] != truth["T"].shape[:2]:
                out.append(dec)
                continue
            alpha = dec.network_mask
            t = dec.transport
            if transport:
                inner = (alpha > 0.5)[..., None]
                est = np.divide(t, alpha[..., None], out=np.zeros_like(t), where=inner)
                part = "true" if transport is True else transport
                t = mixed_transport(dec.geometry.to_network(truth["T"]), est, part) * alpha[..., None]
            lit = dec.light
            if light:
                inner = alpha > 0.5
                albedo = np.divide(dec.albedo @ REC709, alpha, out=np.zeros_like(alpha), where=inner)
                tt = np.divide(t, alpha[..., None], out=np.zeros_like(t), where=inner[..., None])
                level = float((dec.network_image @ REC709)[inner].sum())
                made = float((albedo * np.maximum(tt @ (truth["light"] @ REC709), 0))[inner].sum())
                lit = truth["light"] * (level / made if made > 1e-9 else 1.0)
            out.append(replace(dec, transport_chw=np.ascontiguousarray(t.transpose(2, 0, 1)), light=lit))
        return out, groups, automatic

    relighter._stage1 = stage1
    try:
        yield relighter
    finally:
        del relighter._stage1


def product_rows(relighter, folder: Path, off=(), swap: tuple[bool, bool] | None = None) -> list[dict]:
    """Per-pair figures of the runtime's relight with ``off`` switched off and, with ``swap`` (transport, light),
    the truth put in stage 1's place."""
    rows = []
    with switched_off(relighter, off):
        for person, group in people(folder).items():
            data = {n: hc._read(folder, n) for n in group}
            t_true = true_transport(folder, person) if swap else None
            for a in group:
                img, mask, light_i = data[a]
                ctx = swapped(relighter, {"T": t_true, "light": light_i}, *swap) if swap else contextlib.nullcontext()
                with ctx:
                    dec = relighter.decompose(img, mask)
                for b in group:
                    if b != a:
                        relit = relighter.layers(dec, data[b][2], exposure="physical").image
                        rows.append(figures(np.asarray(relit, np.float32), data[a], data[b]))
    return rows


# ------------------------------------------------------------------------------------------------- main


def table(title: str, figs: dict, framings: list[str]) -> str:
    lines = [f"\n### {title}\n", "| row | " + " | ".join(framings) + " |", "|---|" + "---|" * len(framings)]
    for name, per in figs.items():
        cells = [f"{per[f]['slope']:.2f} / {per[f]['corr']:.2f} / {per[f]['rmse']:.4f} / {per[f]['slope_lit']:.2f}"
                 if f in per else "" for f in framings]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("folders", type=Path, nargs="+")
    p.add_argument("--models", type=Path, default=None)
    p.add_argument("--ablate", action="store_true", help="also the product with each step switched off alone")
    p.add_argument("--only", nargs="+", default=None, help="sections: model ladder swap ladder-true ablate bands")
    p.add_argument("--json", type=Path, default=None)
    args = p.parse_args(argv)
    import relight_rt
    from relight_rt import RuntimeConfig

    relighter = relight_rt.open(RuntimeConfig(models=args.models, device="cpu"))
    folders = [Path(f) for f in args.folders]
    framings = [f.name.rsplit("_", 1)[-1] for f in folders]
    sections = set(args.only or ["model", "ladder", "swap", "bands"] + (["ablate"] if args.ablate else []))
    result: dict = {}

    def run(section: str, name: str, fn) -> None:
        per = result.setdefault(section, {}).setdefault(name, {})
        for folder, framing in zip(folders, framings, strict=True):
            per[framing] = summary(fn(folder))
        print(f"{section}: {name}: " + ", ".join(f"{f} {v['slope']:.2f}/{v['corr']:.2f}" for f, v in per.items()),
              flush=True)

    if "model" in sections:
        per_framing = {f: model_rows(relighter, folder) for folder, f in zip(folders, framings, strict=True)}
        for name in next(iter(per_framing.values())):
            result.setdefault("model", {})[name] = {f: summary(rows[name]) for f, rows in per_framing.items()}
    if "ladder" in sections:
        run("ladder", "stage 1 + 2's own picture (detail off)", lambda folder: _detail_off(args.models, folder))
        for k in range(len(STEPS) + 1):
            name = "bare ratio (every step off)" if k == 0 else f"+ {STEPS[k - 1]}"
            run("ladder", name, lambda folder, k=k: product_rows(relighter, folder, off=STEPS[k:]))
    if "swap" in sections:
        for name, off, swap in (("product, no head pass", ["head pass"], None),
                                ("... true transport", ["head pass"], (True, False)),
                                ("... true occlusion (degree 0), stage 1's shape", ["head pass"], ("occlusion", False)),
                                ("... stage 1's degree 0, true shape", ["head pass"], ("shape", False)),
                                ("... no light refit", ["head pass", "light refit", "face refit"], None),
                                ("... no refit, true own light", ["head pass", "light refit", "face refit"],
                                 (False, True)),
                                ("... no refit, true transport and light", ["head pass", "light refit", "face refit"],
                                 (True, True))):
            run("swap", name, lambda folder, off=off, swap=swap: product_rows(relighter, folder, off, swap))
    if "ladder-true" in sections:  # the ladder again with the true transport and own light (refit off)
        for k in range(len(STEPS) + 1):
            name = "bare ratio (every step off)" if k == 0 else f"+ {STEPS[k - 1]}"
            off = sorted(set(STEPS[k:]) | {"head pass", "light refit", "face refit"})
            run("ladder-true", name, lambda folder, off=off: product_rows(relighter, folder, off, (True, True)))
    if "ablate" in sections:
        for step in STEPS:
            run("ablate", f"product without {step}", lambda folder, step=step: product_rows(relighter, folder, [step]))
    if "bands" in sections:
        result["bands"] = {f: light_bands(relighter, folder) for folder, f in zip(folders, framings, strict=True)}
    print("\ncells: contrast (slope) / correlation / relight RMSE / contrast over the pixels lit in both photos "
          f"(luminance >= {LIT}), means over pairs")
    shares = {f: v["dark_share"] for per in result.get("model", {}).values() for f, v in per.items()}
    if shares:
        print("the truth's log-change variance in the pixels dark in either photo: "
              + ", ".join(f"{f} {v:.0%}" for f, v in shares.items()))
    for section in ("model", "ladder", "swap", "ladder-true", "ablate"):
        if section in result:
            print(table(section, result[section], framings))
    if "bands" in result:
        print("\n### the photo's own light, luminance: degree-1/0, degree-2/0\n")
        print("| framing | stage 1 | product | truth |\n|---|---|---|---|")
        for f, b in result["bands"].items():
            print(f"| {f} | " + " | ".join(f"{b[k][0]:.2f}, {b[k][1]:.2f}" for k in ("stage 1", "product", "truth"))
                  + " |")
    if args.json:
        args.json.write_text(json.dumps(result, indent=1))
    return 0


def _detail_off(models, folder: Path) -> list[dict]:
    import relight_rt
    from relight_rt import RuntimeConfig

    plain = relight_rt.open(RuntimeConfig(models=models, device="cpu", detail=False))
    return product_rows(plain, folder)


if __name__ == "__main__":
    raise SystemExit(main())
