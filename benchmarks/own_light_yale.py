"""Where the runtime puts a real photo's own light, against Yale's known lamps (../shared/realdata/yale).

    python benchmarks/own_light_yale.py [--yale ../shared/realdata/yale] [--max-elevation 45] [--out OUT.json]
        [--reading own,raw,refit,mesh,mesh1,mesh-lamp,mesh-lamp-front,mesh-lamp-linear] [--subjects yaleB02 ...]
    python benchmarks/own_light_yale.py --renders ~/.cache/relight_rt_real_photos/heldout   # the same on renders

Every Yale photo whose lamp lies within ``--max-elevation`` of the horizon (and is not flagged bad) is decomposed
as benchmarks/yale_eval.py does (grey, the ellipse mask); the photo's light ``Decomposition.light`` (stage 1's
estimate, refit so that albedo x shading explains the photo) gives a direction from its degree-1 band (luminance
weighted; DESIGN.md §3: k = 3, 1, 2 are x, y, z), compared with the lamp's (yale_eval ``lamp_direction``).
Printed per lamp azimuth band: the median angle between the two, the median elevation of ours against the
lamp's, the share whose left-right side (the sign of y) is right, and how directional the light is read
(``sh.dominant_direction``: 0 uniform, 1 one direction). Two later sessions found the own light read "from above"
on soft-lit real photos (spec28: p080's soft front light, blacks28: p041); this measures that bias
where the truth is known.
``--renders DIR``: the held-out renders instead (DIR/photos_*/NAME_photo.png with NAME_mask.png and the true light
NAME_light.npy, as benchmarks/heldout_change.py writes them): the same reading of both lights, its angle and
elevation. Evaluation only: nothing of the data is written but figures.

``--reading``: which steps' light to measure ("own" by default; all of them come from one stage-1 pass per photo):
"own" ``Decomposition.light``; "raw" stage 1's estimate; "refit" after ``refit_light`` alone (before the face
mesh's ``face_refit``); and, on the face mesh's skin with the albedo taken as one constant (photos without a
mesh have none), "mesh" plain least squares of the luminance on the mesh's 9-term transport, "mesh1" on its
degree 0 and 1 only, "mesh-lamp" one point lamp plus ambient (``lamp_fit``), "mesh-lamp-front" the same with the
lamp within 120 deg of the camera, "mesh-lamp-linear" the lamp fit on the linearised luminance. Results and
what they say: docs/RESULTS.md "Faces", "Still wrong" (light28).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
from pathlib import Path

import cv2
import numpy as np
from _shared import missing, shared_path
from yale_eval import ellipse, lamp_direction, read_grey

from relight_rt import Relighter, RuntimeConfig, lights
from relight_rt.image.color import REC709, srgb_to_linear
from relight_rt.image.io import read_image
from relight_rt.light import sh
from relight_rt.relight.strength import refit_light

BANDS = ((0, 15), (15, 40), (40, 65), (65, 95), (95, 181))
READINGS = ("own", "raw", "refit", "mesh", "mesh1", "mesh-lamp", "mesh-lamp-front", "mesh-lamp-linear")
MESH_TRIM = 2.5  # mesh_fit, lamp_fit: skin pixels beyond this many robust deviations are dropped (as face_refit)


def mesh_fit(transport: np.ndarray, photo: np.ndarray, bands: int = 9) -> np.ndarray | None:
    """(9,) the classical reading of a face's light: its skin taken as one albedo, luminance ~ transport . l by
    plain least squares (no ridge toward any estimate) on the first ``bands`` coefficients (4: degree 0 and 1; the
    rest zero), pixels beyond ``MESH_TRIM`` robust deviations dropped, three rounds (eyes, brows, lips); None with
    fewer than 50 skin pixels."""
    t, y = np.asarray(transport, np.float64)[:, :bands], np.asarray(photo, np.float64)
    keep = np.ones(y.shape[0], bool)
    m = None
    for _ in range(3):
        if keep.sum() < 50:
            break
        m = np.linalg.lstsq(t[keep], y[keep], rcond=None)[0]
        r = y - t @ m
        centre = float(np.median(r[keep]))
        keep = np.abs(r - centre) < MESH_TRIM * (1.4826 * float(np.median(np.abs(r[keep] - centre))) + 1e-6)
    return None if m is None else np.concatenate([m, np.zeros(9 - bands)])


def _lamps(count: int = 3000) -> tuple[np.ndarray, np.ndarray]:
    """(count, 9) the luminance of a unit point lamp from each of ``count`` directions spread over the sphere
    (``sh.sphere_directions``' Fibonacci lattice), and (9,) unit ambient light's."""
    d = sh.sphere_directions(count)
    return np.stack([lights.directional(v)[:, 0] for v in d]), lights.ambient(1.0)[:, 0]


LAMPS = _lamps()


def lamp_fit(transport: np.ndarray, photo: np.ndarray, front: bool = False) -> np.ndarray | None:
    """(9,) a face's light read as one point lamp plus ambient: for each of ``LAMPS``' directions the skin's
    luminance ~ a x (transport . ambient) + b x (transport . lamp), a, b >= 0 by least squares; the direction with
    the least residual wins; pixels beyond ``MESH_TRIM`` robust deviations dropped, three rounds. Degree 2 follows
    from the lamp's direction instead of being free (a frontal face's normals cannot tell degree 1's up from
    degree 2's xz); None with fewer than 50 skin pixels."""
    t, y = np.asarray(transport, np.float64), np.asarray(photo, np.float64)
    lamps, amb = LAMPS
    if front:  # lamps within 120 deg of the camera only (x > -0.5)
        lamps = lamps[lamps[:, 3] / np.linalg.norm(lamps[:, 1:4], axis=1) > -0.5]
    keep = np.ones(y.shape[0], bool)
    best = None
    for _ in range(3):
        if keep.sum() < 50:
            break
        tk, yk = t[keep], y[keep]
        a = tk @ amb  # (n,)
        b = tk @ lamps.T  # (n, K)
        aa, ab, bb = a @ a, a @ b, (b * b).sum(0)
        ay, by = a @ yk, b.T @ yk
        det = aa * bb - ab * ab
        ca = np.where(det > 1e-12, (ay * bb - by * ab) / np.maximum(det, 1e-12), 0)
        cb = np.where(det > 1e-12, (by * aa - ay * ab) / np.maximum(det, 1e-12), 0)
        # a negative coefficient: the best with it at zero instead
        only_b = np.maximum(by / np.maximum(bb, 1e-12), 0)
        ca, cb = np.where(ca < 0, 0, ca), np.where(ca < 0, only_b, cb)
        ca, cb = np.where(cb < 0, max(ay / aa, 0), ca), np.maximum(cb, 0)
        err = (yk @ yk) - 2 * (ca * ay + cb * by) + ca * ca * aa + 2 * ca * cb * ab + cb * cb * bb
        k = int(np.argmin(err))
        best = ca[k] * amb + cb[k] * lamps[k]
        r = y - t @ best
        centre = float(np.median(r[keep]))
        keep = np.abs(r - centre) < MESH_TRIM * (1.4826 * float(np.median(np.abs(r[keep] - centre))) + 1e-6)
    return best


def readings(relighter: Relighter, rgb: np.ndarray, mask: np.ndarray, which: list[str]) -> dict[str, np.ndarray | None]:
    """The photo's light as each step in ``which`` reads it, (9, 3) RGB or (9,) luminance, by ``READINGS`` name (see
    the module's docstring; the mesh readings None where the photo has fewer than 50 pixels of a face mesh's skin).
    "own" is ``decompose``'s light for a photo of one person (``Relighter._photos``: the refit, the face's turn, a
    head pass). Uses the Relighter's private stages: a measurement, not an API."""
    (dec,), _, _ = relighter._stage1([rgb], [mask], False, faces=relighter.detail)
    factor = relighter._factor
    out: dict[str, np.ndarray | None] = {"raw": dec.light}
    if "refit" in which:
        out["refit"] = refit_light(dec.light, *factor.refit_inputs(dec))
    if "own" in which:
        out["own"] = relighter._photos([dec])[0].light
    if not any(name.startswith("mesh") for name in which):
        return out  # the face mesh's restored transport is only the mesh readings'
    base = factor.restored(dec)
    skin = base["face_skin"]
    t, y = base["transport"][skin], base["photo"][skin]
    fits = {"mesh": lambda: mesh_fit(t, y), "mesh1": lambda: mesh_fit(t, y, 4), "mesh-lamp": lambda: lamp_fit(t, y),
            "mesh-lamp-front": lambda: lamp_fit(t, y, True), "mesh-lamp-linear": lambda: lamp_fit(t, srgb_to_linear(y))}
    for name, fit in fits.items():
        if name in which:
            out[name] = fit() if skin.sum() >= 50 else None
    return out


def light_direction(light: np.ndarray) -> tuple[np.ndarray | None, float]:
    """A (9, 3) RGB or (9,) SH light's direction and directionality (``sh.dominant_direction`` of its luminance)."""
    y = np.asarray(light, np.float64)
    return sh.dominant_direction(y @ REC709 if y.ndim == 2 else y)


def compare(light: np.ndarray | None, truth: np.ndarray) -> dict | None:
    """One reading against a true direction: the angle, our elevation, our y and directionality (None: no reading,
    or a light without a direction)."""
    ours, strength = light_direction(light) if light is not None else (None, 0.0)
    if ours is None:
        return None
    return {"angle": math.degrees(math.acos(float(np.clip(ours @ truth, -1, 1)))),
            "our_elevation": math.degrees(math.asin(float(np.clip(ours[2], -1, 1)))), "y": float(ours[1]),
            "strength": strength, "direction": ours.tolist()}


def renders(folder: Path, relighter: Relighter, which: list[str], out: Path | None) -> int:
    """Each reading of every held-out render under ``folder`` against the light it was rendered under."""
    photos = sorted(folder.glob("photos_*/*_photo.png"))
    if not photos:
        print(f"own_light_yale: no photos_*/*_photo.png under {folder}", file=sys.stderr)
        return 2
    rows = []
    for f in photos:
        mask = cv2.imread(str(f.with_name(f.name.replace("_photo.png", "_mask.png"))), cv2.IMREAD_GRAYSCALE)
        truth, _ = light_direction(np.load(f.with_name(f.name.replace("_photo.png", "_light.npy"))))
        got = readings(relighter, read_image(f), mask.astype(np.float32) / 255, which)
        rows.append({"render": f.name, "truth": truth.tolist(),
                     "true_elevation": math.degrees(math.asin(float(np.clip(truth[2], -1, 1)))),
                     **{k: compare(got[k], truth) for k in which}})
    for k in which:
        have = [r for r in rows if r[k] is not None]
        if not have:
            print(f"{k}: no render gives this reading")
            continue
        ours = [r[k]["our_elevation"] for r in have]
        true = [r["true_elevation"] for r in have]
        strength = np.median([r[k]["strength"] for r in have])
        print(f"{k}: {len(have)} renders: angle median {np.median([r[k]['angle'] for r in have]):.1f} deg; "
              f"elevation ours / true (medians) {np.median(ours):+.1f} / {np.median(true):+.1f}, ours minus true "
              f"mean {np.mean(ours) - np.mean(true):+.1f}; directionality {strength:.2f}")
    if out is not None:
        out.write_text(json.dumps(rows, indent=1))
    return 0


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--yale", type=Path, default=shared_path("realdata", "yale"))
    p.add_argument("--models", type=Path, default=None)
    p.add_argument("--max-elevation", type=float, default=45.0)
    p.add_argument("--out", type=Path, default=None)
    p.add_argument("--renders", type=Path, default=None, help="held-out renders' folder (photos_*/*_photo.png)")
    p.add_argument("--reading", default="own",
                   help=f"comma-separated readings to measure, of {', '.join(READINGS)} (default: own)")
    p.add_argument("--subjects", nargs="*", default=None, help="only these Yale subjects (yaleB02 ...)")
    args = p.parse_args(argv)
    which = [w for w in args.reading.split(",") if w]
    if not which or set(which) - set(READINGS):
        p.error(f"--reading: expected names among {', '.join(READINGS)}, got {args.reading!r}")
    if args.renders is not None:
        return renders(args.renders.expanduser(), Relighter(RuntimeConfig(models=args.models, device="cpu")), which,
                       args.out)
    if not args.yale.is_dir():
        print(missing(args.yale), file=sys.stderr)
        return 2
    relighter = Relighter(RuntimeConfig(models=args.models, device="cpu"))
    rows = []
    with open(args.yale / "lights.csv") as f:
        lamps = [r for r in csv.DictReader(f)
                 if abs(float(r["elevation_deg"])) <= args.max_elevation and r["flagged_bad_in_source"] in ("", "0")
                 and (args.subjects is None or r["subject"] in args.subjects)]
    for r in lamps:
        az, el = float(r["azimuth_deg"]), float(r["elevation_deg"])
        rgb = read_grey(args.yale / r["file"])
        truth = np.array(lamp_direction(az, el))
        got = readings(relighter, rgb, ellipse(rgb.shape[:2]), which)
        rows.append({"subject": r["subject"], "azimuth": az, "elevation": el, "truth": truth.tolist(),
                     "truth_y": float(truth[1]),
                     **{k: compare(got[k], truth) for k in which}})
    print(f"{len(rows)} photos, lamps within {args.max_elevation:g} deg of the horizon")
    for k in which:
        print(f"reading {k}: |azimuth| | photos | angle (median) | elevation: ours / lamp (medians) | side right | "
              "directionality")
        for lo, hi in BANDS:
            band = [r for r in rows if lo <= abs(r["azimuth"]) < hi and r[k] is not None]
            if not band:
                continue
            sides = [np.sign(r[k]["y"]) == np.sign(r["truth_y"]) for r in band if abs(r["azimuth"]) >= 10]
            side = f"{np.mean(sides):.0%}" if sides else "-"
            print(f"{lo}-{hi} | {len(band)} | {np.median([r[k]['angle'] for r in band]):.1f} | "
                  f"{np.median([r[k]['our_elevation'] for r in band]):+.1f} / "
                  f"{np.median([r['elevation'] for r in band]):+.1f} | {side} | "
                  f"{np.median([r[k]['strength'] for r in band]):.2f}")
    if args.out is not None:
        args.out.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
