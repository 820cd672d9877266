"""Black beards under a new light: do they stay black and neutral? (beard40, issue 48's colour casts)

    python benchmarks/beard_casts.py [--only p024,p264] [--out /tmp/beards] [--people ../shared/realdata/people_masks]
    python benchmarks/beard_casts.py --all [--half A|B] [--out DIR] [--json J]

Each photo is relit as the first look relights it (benchmarks/first_look.py: the public API, the automatic matte)
under LEFT, RIGHT and window-left, with relight_rt.relight.dark_beard's rule off and on (``BEARD``; a fresh
decomposition each, so nothing is shared). Measured on the beard's pixels: the solid person (alpha > 0.9) inside
``dark_beard.beard_region`` of each face mesh (> 0.5) and near black and near neutral in the photo (L* < 35, C* < 12);
against the lit skin: the mesh's convex hull outside that region, L* > 45. Per light and mode: the beard's median
C* and mean a*, b* (input -> relit), its share whose C* rose by more than 3, and its median L* minus the lit skin's
median L* (input -> relit; higher than the input's: lifted more than the skin). With ``--out``: per photo and light
the head box (input | off | on) at 100 % and its beard box at 3x, for looking at (keep it out of the repository:
the photos are evaluation only).

With ``--all``: every photo of the folder instead (the broad check: does the rule act where it should not?). Each is
relit off and on as above; the rule acts on a photo where its weight (``dark_material``'s d, read through a wrapper of
``relight_rt.relight.factor.dark_material``) exceeds 0.2 on any pixel. Per light: the largest change on vs off (8-bit
levels, any channel), where it lies (``beard``: near black in the beard's region; ``chin``: the rest of the region,
the skin under the chin and the neck; ``head``: the head box outside the region, hair; ``else``) and per place the
pixels changed by more than 3 levels. ``--out`` keeps the head box (input | off | on) of each photo it acts on.
Each photo is relit a third time with the rule on but ``dark_beard.BEARD_ACROSS`` off (``ungated``: beard40 as
reviewed) where that rule acts at all: per light the largest change on vs ungated, and the head box gains that
column. ``--half A|B``: the photos of even / odd index in sorted order only (beard41 chose its gate on A).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import cv2
import numpy as np

# real_photos puts this checkout (and benchmarks/) first on sys.path: the relight_rt imported below is this one
from real_photos import LEFT, RIGHT, luminance

# isort: split
from _shared import missing, shared_path
from first_look import head_box, meshes, read_rgb, row, to_bgr8

import relight_rt
from relight_rt import RuntimeConfig
from relight_rt.relight import dark_beard
from relight_rt.relight import factor as factor_module

LIGHTS = {"LEFT": LEFT, "RIGHT": RIGHT, "window-left": "window-left"}


def lab(rgb: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(np.clip(rgb, 0, 1).astype(np.float32), cv2.COLOR_RGB2Lab)


def regions(rgb: np.ndarray, alpha: np.ndarray, found: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(beard, lit skin, half, near) (H, W) of the photo (module docstring); near: the skin in the beard's region
    (L* > 35, C* >= 12: the neck, the jaw between patches); half: -1 / +1 the face's side of each pixel
    (across the line through the nose's base and the chin, the largest face's)."""
    h, w = alpha.shape
    region = np.zeros((h, w), np.float32)
    hull = np.zeros((h, w), np.uint8)
    for pts in found:
        region = np.maximum(region, dark_beard.beard_region(pts, (h, w)))
        cv2.fillConvexPoly(hull, cv2.convexHull(np.round(pts[:, :2]).astype(np.int32)), 1)
    q = lab(rgb)
    chroma = np.hypot(q[..., 1], q[..., 2])
    beard = (alpha > 0.9) & (region > 0.5) & (q[..., 0] < 35) & (chroma < 12)
    skin = (alpha > 0.9) & (hull > 0) & (region < 0.01) & (q[..., 0] > 45)
    near = (alpha > 0.9) & (region > 0.5) & (q[..., 0] > 35) & (chroma >= 12)  # the skin among the beard: the neck
    pts = max(found, key=lambda m: np.ptp(m[:, 0]) * np.ptp(m[:, 1]))
    nose, chin = pts[dark_beard.NOSE, :2], pts[dark_beard.CHIN, :2]
    ys, xs = np.mgrid[0:h, 0:w]
    down = chin - nose
    half = np.sign((xs - nose[0]) * down[1] - (ys - nose[1]) * down[0])
    return beard, skin, half, near


def figures(rgb: np.ndarray, relit: np.ndarray, beard: np.ndarray, skin: np.ndarray, half: np.ndarray,
            near: np.ndarray) -> dict:
    a, b = lab(rgb), lab(relit)
    ca, cb = np.hypot(a[..., 1], a[..., 2])[beard], np.hypot(b[..., 1], b[..., 2])[beard]
    out = {"pixels": int(beard.sum()),
           "C_in": float(np.median(ca)), "C_relit": float(np.median(cb)),
           "C_up3_share": float((cb > ca + 3).mean()),
           "ab_in": [float(a[..., 1][beard].mean()), float(a[..., 2][beard].mean())],
           "ab_relit": [float(b[..., 1][beard].mean()), float(b[..., 2][beard].mean())]}
    for side, sign in (("dL_neg", -1), ("dL_pos", 1)):  # the beard's L* less the lit skin's, on one half of the face
        bs, ss = beard & (half == sign), skin & (half == sign)
        if bs.sum() >= 20 and ss.sum() >= 20:
            out[side] = [float(np.median(x[..., 0][bs]) - np.median(x[..., 0][ss])) for x in (a, b)]
            lift = luminance(relit) / np.maximum(luminance(rgb), 1e-4)  # linear luminance's change
            ns = near & (half == sign)
            out["lift" + side[2:]] = [float(np.median(lift[bs])), float(np.median(lift[ss])),
                                      float(np.median(lift[ns])) if ns.sum() >= 20 else float("nan")]
    return out


def _half(f: dict, side: str) -> str:
    lift = f["lift" + side[2:]]
    return (f"{f[side][0]:+.1f} -> {f[side][1]:+.1f} (lift beard / skin / near {lift[0]:.2f} / {lift[1]:.2f} / "
            f"{lift[2]:.2f})")


def crops(rgb: np.ndarray, pictures: list[tuple[str, np.ndarray]], box, beard: np.ndarray) -> tuple:
    y0, y1, x0, x1 = box
    head = row([("input", to_bgr8(rgb[y0:y1, x0:x1]))] + [(n, to_bgr8(p[y0:y1, x0:x1])) for n, p in pictures], None)
    ys, xs = np.nonzero(beard)
    by0, by1, bx0, bx1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
    zoom = [("input", rgb[by0:by1, bx0:bx1])] + [(n, p[by0:by1, bx0:bx1]) for n, p in pictures]
    zoom = [(n, cv2.resize(to_bgr8(p), None, fx=3, fy=3, interpolation=cv2.INTER_NEAREST)) for n, p in zoom]
    return head, row(zoom, None)


PLACES = ("beard", "chin", "head", "else")


def places(rgb: np.ndarray, dec) -> np.ndarray:
    """(H, W) int8 index into PLACES of each pixel of the photo (``--all``, module docstring)."""
    h, w = rgb.shape[:2]
    region = np.zeros((h, w), np.float32)
    for pts in meshes(dec):
        region = np.maximum(region, dark_beard.beard_region(pts, (h, w)))
    out = np.full((h, w), 3, np.int8)
    box = head_box(dec, (h, w))
    if box is not None:
        out[box[0] : box[1], box[2] : box[3]] = 2
    out[region > 0.5] = 1
    out[(region > 0.5) & (lab(rgb)[..., 0] < 35)] = 0
    return out


def broad(relighter, folder: Path, out: Path | None, half: str | None = None) -> dict:
    """``--all`` (module docstring): per photo the rule's largest weight and, per light, where on vs off differ."""
    weights: list[float] = []
    inner = factor_module.dark_material

    def recording(*args, **kwargs):
        found = inner(*args, **kwargs)
        weights.append(0.0 if found[2] is None else float(found[2].max()))
        return found

    factor_module.dark_material = recording
    switch, gate, result = dark_beard.BEARD, dark_beard.BEARD_ACROSS, {}
    paths = sorted(folder.glob("*.jpg"))
    paths = paths if half is None else paths[0::2] if half == "A" else paths[1::2]
    try:
        for path in paths:
            rgb = read_rgb(path)
            relit, decs, weight = {}, {}, {}
            for mode in ("off", "ungated", "on"):
                dark_beard.BEARD, dark_beard.BEARD_ACROSS = mode != "off", None if mode == "ungated" else gate
                if mode == "on" and weight["ungated"] == 0:  # the gate only takes away: nothing to take
                    relit[mode], decs[mode], weight[mode] = relit["ungated"], decs["ungated"], 0.0
                    continue
                weights.clear()
                dec = decs[mode] = relighter.decompose(rgb)
                relit[mode] = {k: np.asarray(relighter.relight(dec, v), np.float32) for k, v in LIGHTS.items()}
                weight[mode] = max(weights, default=0.0)
            where = places(rgb, decs["on"])
            f = {"weight": weight["on"], "weight_ungated": weight["ungated"], "faces": len(meshes(decs["on"]))}
            for k in LIGHTS:
                diff = np.abs(relit["on"][k] - relit["off"][k]).max(axis=2) * 255
                y, x = np.unravel_index(int(np.argmax(diff)), diff.shape)
                f[k] = {"max": float(diff[y, x]), "at": PLACES[where[y, x]],
                        "over3": {p: int(((diff > 3) & (where == i)).sum()) for i, p in enumerate(PLACES)},
                        "max_vs_ungated": float(np.abs(relit["on"][k] - relit["ungated"][k]).max() * 255)}
            result[path.stem] = f
            acts = max(weight["on"], weight["ungated"]) > 0.2
            print(f"{path.stem}: weight {weight['on']:.2f} (ungated {weight['ungated']:.2f}) faces {f['faces']}"
                  + "".join(f", {k} max {f[k]['max']:.1f} ({f[k]['at']}) >3: "
                            + "/".join(str(f[k]["over3"][p]) for p in PLACES)
                            + f" vs ungated {f[k]['max_vs_ungated']:.1f}" for k in LIGHTS), flush=True)
            box = head_box(decs["on"], rgb.shape[:2])
            if out is not None and acts and box is not None:
                y0, y1, x0, x1 = box
                for k in LIGHTS:
                    cv2.imwrite(str(out / f"{path.stem}_{k}_head.png"), row(
                        [("input", to_bgr8(rgb[y0:y1, x0:x1]))]
                        + [(m, to_bgr8(relit[m][k][y0:y1, x0:x1])) for m in ("off", "ungated", "on")], None))
    finally:
        factor_module.dark_material, dark_beard.BEARD, dark_beard.BEARD_ACROSS = inner, switch, gate
    acting = [n for n, f in result.items() if f["weight"] > 0.2]
    ungated = [n for n, f in result.items() if f["weight_ungated"] > 0.2]
    changed = [n for n, f in result.items() if any(f[k]["max"] > 0 for k in LIGHTS)]
    moved = [n for n, f in result.items() if any(f[k]["max_vs_ungated"] > 3 for k in LIGHTS)]
    print(f"{len(result)} photos: the rule acts (weight > 0.2) on {len(acting)}: {','.join(acting)}; "
          f"any change on vs off on {len(changed)}; ungated it acts on {len(ungated)}: {','.join(ungated)}; "
          f"on vs ungated over 3 levels on {len(moved)}: {','.join(moved)}")
    return result


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--people", type=Path, default=shared_path("realdata", "people_masks"))
    ap.add_argument("--only", default="p024,p264")
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--models", type=Path, default=None)
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--all", action="store_true", help="every photo: where the rule acts (module docstring)")
    ap.add_argument("--half", choices=("A", "B"), default=None, help="with --all: even / odd index in sorted order")
    args = ap.parse_args(argv)
    folder = args.people / "photos"
    if not folder.is_dir():
        print(missing(folder), file=sys.stderr)
        return 0
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
    relighter = relight_rt.open(RuntimeConfig(models=args.models, device="cpu"))
    if args.all:
        result = broad(relighter, folder, args.out, args.half)
        if args.json is not None:
            args.json.write_text(json.dumps(result, indent=1))
        return 0
    switch = dark_beard.BEARD
    result = {}
    for name in args.only.split(","):
        rgb = read_rgb(folder / f"{name}.jpg")
        relit, decs = {}, {}
        for mode in ("off", "on"):
            dark_beard.BEARD = mode == "on"
            dec = decs[mode] = relighter.decompose(rgb)
            relit[mode] = {k: np.asarray(relighter.relight(dec, v), np.float32) for k, v in LIGHTS.items()}
        dark_beard.BEARD = switch
        dec = decs["on"]
        beard, skin, half, near = regions(rgb, np.asarray(dec.mask), meshes(dec))
        if not beard.any() or not skin.any():
            print(f"{name}: no beard or no lit skin found (meshes: {len(meshes(dec))})")
            continue
        result[name] = {k: {m: figures(rgb, relit[m][k], beard, skin, half, near) for m in ("off", "on")}
                        for k in LIGHTS}
        for k in LIGHTS:
            for m in ("off", "on"):
                f = result[name][k][m]
                print(f"{name} {k:11s} {m:3s}: {f['pixels']} px, C* {f['C_in']:.1f} -> {f['C_relit']:.1f} "
                      f"(up > 3: {f['C_up3_share']:.3f}), a*b* ({f['ab_in'][0]:+.1f}, {f['ab_in'][1]:+.1f}) -> "
                      f"({f['ab_relit'][0]:+.1f}, {f['ab_relit'][1]:+.1f}), L* - skin per half "
                      + ", ".join(_half(f, s) for s in ("dL_neg", "dL_pos") if s in f))
            box = head_box(dec, rgb.shape[:2])
            if args.out is not None and box is not None:
                head, zoom = crops(rgb, [("off", relit["off"][k]), ("on", relit["on"][k])], box, beard)
                cv2.imwrite(str(args.out / f"{name}_{k}_head.png"), head)
                cv2.imwrite(str(args.out / f"{name}_{k}_beard3x.png"), zoom)
    if args.json is not None:
        args.json.write_text(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
