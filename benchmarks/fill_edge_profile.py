"""How far the deep shadow's fill reaches toward the photo's own shadow edge (issue 48, faces17): its weight against
each near-black pixel's distance to the shadow's edge, in input pixels; and where the penumbra's ratio cap reaches.

    python benchmarks/fill_edge_profile.py [--yale ../shared/realdata/yale] [--no-yale] [--per-photo]
        [--reference ../shared/reference]

A pixel counts when its own weight (its luminance over stage 1's albedo, unblurred, by ``fill_edge.fill_share``) is
>= 0.95 (near black) and the network's weight says a shadow's core is within 4 px; its distance is to the nearest
pixel whose own weight is <= 0.5 (the lit side or the penumbra). Printed: the mean fill weight at distances 1, 2, 3,
4, 5-6, 7-8 px (and how many pixels). A fill that stops short leaves a band just inside the shadow multiplied, not
filled: darker than the fill, a new edge.

- synthetic: the test scenes (tests/_graphs.py's analytic stage 1 at 64 px, the photo 150 x 100: 2.3 input px a
  network px): A, a textured person with a hard black shadow (tests/runtime/relight/test_shadow_fill.py), and B, a
  smooth skin-coloured one whose shadow's edge is blurred over 1 px (test_fill_edges.py); the weight the relight uses
  (``Factor.gain_and_fill``) under twice the photo's own light; and A's lit side: the largest change 0-6 px beside
  the edge against the relight without the fill (the "leak").
- stripes: the penumbra's ratio cap beside a hard shadow (``CAP_SHADOW_REACH``, gated by stage 1's skin probability,
  ``shadow_rim.skin_gate``) on a striped shirt (2-px stripes, red / blue, dark / light grey, beige / brown), stage
  1's skin probability 0 and 0.5 (clothes read up to about 0.5): the stripes' contrast 2 and 10 px from the edge under
  4x the light, over their contrast 100 px away (1: kept). (faces17's colour gate on the cap kept them at 0.90-0.93
  but drew a bright line on the lit side of non-skin clothing; dropped after its review: docs/RESULTS.md.)
- photos: the reference photo (../shared/reference) and the bundled example: the share of the person off a face mesh
  that the penumbra cap reaches (> 0.1).
- Yale: Extended Yale B's photos lit from |azimuth| 50 and 70 (the ellipse mask of benchmarks/yale_eval.py), de-lit
  to its frontal lamp: the weight the relight uses (the ratio cap's handover included). Evaluation data only.
"""

from __future__ import annotations

import argparse
import csv
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))

from _shared import missing, shared_path  # noqa: E402

from relight_rt.relight import fill_edge, shadow_fill  # noqa: E402

BINS = (1, 2, 3, 4, 6, 8)


def weights(relighter, dec, light) -> tuple[tuple, np.ndarray, dict]:
    """(box, weight, inputs): the fill's weight the relight of ``dec`` under ``light`` uses, over ``box`` of the crop
    box, and what ``edge_weight`` was given there (network weight mapped, luminance, albedo, level)."""
    seen: dict = {}
    edge, gain_and_fill = fill_edge.edge_weight, relighter._factor.gain_and_fill

    def spy_edge(w, least, most, luma, albedo, level, low, high):
        seen.update(w=w, luma=luma, albedo=albedo, level=level)
        return edge(w, least, most, luma, albedo, level, low, high)

    def spy_fill(*args, **kwargs):
        out = gain_and_fill(*args, **kwargs)
        seen["fill"] = out[1]
        return out

    shadow_fill.edge_weight, relighter._factor.gain_and_fill = spy_edge, spy_fill
    try:
        relighter.relight(dec, light, exposure="physical")
    finally:
        shadow_fill.edge_weight = edge
        del relighter._factor.gain_and_fill
    if seen.get("fill") is None or "luma" not in seen:
        return None, None, seen
    box, _, weight = seen["fill"]
    return box, weight, seen


def profile(weight: np.ndarray, seen: dict, inside: np.ndarray | None = None) -> dict:
    """{distance bin: (mean weight, pixels)} over the near-black pixels near a shadow's core (module docstring)."""
    own = fill_edge.fill_share(seen["luma"] / seen["albedo"], seen["level"], shadow_fill.FILL_LOW,
                               shadow_fill.FILL_HIGH)
    black = own >= 0.95
    if inside is not None:
        black &= inside
    black &= cv2.dilate((seen["w"] > 0.5).astype(np.uint8), np.ones((9, 9), np.uint8)) > 0
    dist = cv2.distanceTransform((own > 0.5).astype(np.uint8), cv2.DIST_L2, 3)
    out, lo = {}, 0.0
    for b in BINS:
        sel = black & (dist > lo) & (dist <= b + 0.01)
        out[b] = (float(weight[sel].mean()) if sel.any() else float("nan"), int(sel.sum()))
        lo = b + 0.01
    return out


def pooled(rows: list[dict]) -> dict:
    out = {}
    for b in BINS:
        n = sum(r[b][1] for r in rows)
        out[b] = (sum(r[b][0] * r[b][1] for r in rows if r[b][1]) / max(n, 1), n)
    return out


def show(name: str, prof: dict) -> None:
    labels = {1: "1", 2: "2", 3: "3", 4: "4", 6: "5-6", 8: "7-8"}
    print(f"{name:34s} " + "  ".join(f"{labels[b]} px {v:.3f} ({n})" for b, (v, n) in prof.items()), flush=True)


def synthetic() -> None:
    from _graphs import OWN_LIGHT, make_models_dir, person

    import relight_rt
    from relight_rt.engine.config import RuntimeConfig

    with tempfile.TemporaryDirectory() as tmp:
        relighter = relight_rt.open(RuntimeConfig(models=make_models_dir(Path(tmp), 64, stage2=True, dvp=True),
                                                  device="cpu"))
        img, mask = person()
        shadowed = img.copy()
        shadowed[20:140, 30:55] *= 0.01  # the photo's own edge between x = 54 and 55
        dec = replace(relighter.decompose(shadowed, mask), albedo_chw=relighter.decompose(img, mask).albedo_chw)
        box, weight, seen = weights(relighter, dec, 2 * OWN_LIGHT)
        show("synthetic A (hard edge, textured)", profile(weight, seen))
        filled = relighter.relight(dec, 2 * OWN_LIGHT, exposure="physical")
        relighter._factor.fill.shadow_weight = lambda *args: None
        try:
            plain = relighter.relight(replace(dec), 2 * OWN_LIGHT, exposure="physical")
        finally:
            del relighter._factor.fill.shadow_weight
        print(f"{'':34s} lit side 0-6 px from the edge: largest change "
              f"{np.abs(filled[40:120, 55:62] - plain[40:120, 55:62]).max():.4f}")
        h, w = 150, 100
        yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
        true = np.array([0.62, 0.47, 0.40], np.float32) * (1 + 0.05 * np.sin(yy / 9.0))[..., None]
        mask = np.zeros((h, w), np.float32)
        mask[20:140, 20:85] = 1
        shade = cv2.GaussianBlur(np.where(xx < 45, 0.01, 1.0).astype(np.float32), (0, 0), 1.0)
        dec = replace(relighter.decompose(true * shade[..., None], mask),
                      albedo_chw=relighter.decompose(true, mask).albedo_chw)
        box, weight, seen = weights(relighter, dec, 2 * OWN_LIGHT)
        show("synthetic B (edge blurred 1 px)", profile(weight, seen))


def stripes() -> None:
    from _graphs import OWN_LIGHT, make_models_dir

    import relight_rt
    from relight_rt.engine.config import RuntimeConfig

    h, w, edge = 300, 400, 150
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    mask = np.zeros((h, w), np.float32)
    mask[30:270, 40:360] = 1
    shade = cv2.GaussianBlur(np.where(xx < edge, 0.01, 1.0).astype(np.float32), (0, 0), 1.0)
    cloths = {"red / blue": ((0.25, 0.06, 0.06), (0.05, 0.12, 0.25)), "grey": ((0.08,) * 3, (0.25,) * 3),
              "beige / brown": ((0.55, 0.42, 0.33), (0.30, 0.20, 0.14))}

    def contrast(out: np.ndarray, d: int) -> float:
        cols = out[60:240, edge + d - 1 : edge + d + 2].mean(axis=1)
        stripe = (np.arange(60, 240) % 4) < 2
        return float(np.abs(cols[stripe].mean(0) - cols[~stripe].mean(0)).sum() / cols.mean(0).sum())

    with tempfile.TemporaryDirectory() as tmp:
        relighter = relight_rt.open(RuntimeConfig(models=make_models_dir(Path(tmp), 64, stage2=True, dvp=True),
                                                  device="cpu"))
        for name, (a, b) in cloths.items():
            true = np.where((yy % 4 < 2)[..., None], np.float32(a), np.float32(b)).astype(np.float32)
            line = []
            for skin in (0.0, 0.5):
                dec = relighter.decompose(true * shade[..., None], mask)
                dec = replace(dec, albedo_chw=relighter.decompose(true, mask).albedo_chw,
                              skin=dec.skin * np.float32(skin / 0.5))  # the analytic graph's skin: 0.5
                out = relighter.relight(dec, 4 * OWN_LIGHT, exposure="physical")
                kept = [contrast(out, d) / contrast(out, 100) for d in (2, 10)]
                line.append(f"skin {skin:.1f} {kept[0]:.2f} / {kept[1]:.2f}")
            print(f"stripes {name:14s} kept at 2 / 10 px: " + ",  ".join(line), flush=True)


def photos(reference: Path) -> None:
    import relight_rt
    from relight_rt import RuntimeConfig
    from relight_rt.image.io import read_image, read_mask

    items = [(reference / "photo" / "sample.jpg", reference / "photo" / "sample_mask.png"),
             (HERE.parent / "relight_rt" / "data" / "example.png", None)]
    for path, mask_path in items:
        if not path.is_file():
            print(f"WARNING: {missing(path)}; skipped", file=sys.stderr)
            continue
        raw = read_image(path, path.name)  # (the project's intake: the bundled example's alpha is its mask)
        rgb = np.ascontiguousarray(raw[..., :3])
        mask = read_mask(mask_path, rgb.shape[:2]) if mask_path is not None else raw[..., 3]
        relighter = relight_rt.open(RuntimeConfig(device="cpu"))
        dec = relighter.decompose(rgb, mask)
        own = relighter._factor.own(dec, with_residual=False)
        share = 0.0
        if relighter._factor.fill.shadow_weight(dec) is not None:
            base = relighter._factor.fill.fill_base(dec, relighter._composer.foreground(dec)[0])
            off = own["inner"] & ~(own["cap_face"] > 0 if own["cap_face"] is not None else False)
            reach = base["reach"]
            share = 0.0 if reach is None else float((reach[off] > 0.1).mean())
        print(f"{path.name:24s} the penumbra cap reaches {share:.4f} of the person off a face mesh", flush=True)


def yale(folder: Path, per_photo: bool) -> None:
    from yale_eval import ellipse, find_file, lamp, read_grey

    from relight_rt import Relighter, RuntimeConfig

    relighter = Relighter(RuntimeConfig(device="cpu"))
    with open(folder / "lights.csv") as f:
        subjects = sorted({row["subject"] for row in csv.DictReader(f)})
    rows: dict[int, list] = {50: [], 70: []}
    for subject in subjects:
        for a in rows:
            for az in (-a, a):
                path = find_file(folder, subject, az)
                if not path.is_file():
                    continue
                photo = read_grey(path)
                mask = ellipse(photo.shape[:2])
                dec = relighter.decompose(photo, mask)
                box, weight, seen = weights(relighter, dec, lamp(0))
                if weight is None:
                    continue
                y0, _, x0, _ = dec.geometry.box
                crop = mask[y0 + box[0].start : y0 + box[0].stop, x0 + box[1].start : x0 + box[1].stop]
                inside = cv2.erode((crop > 0.99).astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
                prof = profile(weight, seen, inside)
                rows[a].append(prof)
                if per_photo:
                    show(f"{subject} {az:+d} (mesh: {bool(dec.face_meshes)})", prof)
    for a, found in rows.items():
        if found:
            show(f"Yale, lit from |azimuth| {a} ({len(found)})", pooled(found))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--yale", type=Path, default=shared_path("realdata", "yale"))
    p.add_argument("--no-yale", action="store_true")
    p.add_argument("--per-photo", action="store_true")
    p.add_argument("--reference", type=Path, default=shared_path("reference"))
    args = p.parse_args(argv)
    synthetic()
    stripes()
    photos(args.reference)
    if not args.no_yale:
        if args.yale.is_dir():
            yale(args.yale, args.per_photo)
        else:
            print(f"WARNING: {missing(args.yale)}; the Yale faces left out", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
