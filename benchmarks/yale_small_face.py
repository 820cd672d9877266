"""A side-lit Yale face framed small: does ``shadow_fill.mirror_shadow`` still act on its dark eye socket?

    python benchmarks/yale_small_face.py --out runs/yale_small [--framings 1 2 3 4 6] [--subjects yaleB02 ...]

benchmarks/yale_eval.py's de-light pairs from |azimuth| 70 (the dark-side socket), each photo pasted into a canvas
``framing`` times its height and width (the face at the top centre, a person's grey shoulders below it: the mask is
the face's ellipse joined to a trapezoid that widens to the canvas's sides at its bottom, the shoulders' grey the
photo's own median inside the ellipse), so the face fills 1 / framing of the person's window; framing 1 is
yale_eval's own photo. Relit to the frontal lamp and cut back to the photo's box, it is measured as yale_eval
measures (the dark and lit sockets' ``socket_ratio`` against the real frontal photo, their mean |log|; the change's
correlation and contrast), with the mirror rule on and off (``MIRROR_DARK`` None): the rule acts where the dark
socket's error moves. Also "share" and "peak": the mean and the largest over the dark socket of the fill weight the
rule adds (``ShadowFill.shadow_weight`` with the rule less without it, mapped to the input pixels), inside the ellipse.

Writes OUT/yale_small.json (every pair) and prints a table per framing. The data is for evaluation only: keep OUT out
of the repository.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import cv2
import numpy as np

# real_photos puts this checkout (and benchmarks/) first on sys.path: the relight_rt imported below is this one
import real_photos  # noqa: F401

# isort: split
import yale_eval as ye  # imports relight_rt: after real_photos
from _shared import missing, shared_path

from relight_rt import Relighter, RuntimeConfig
from relight_rt.person.face_mesh import FaceMesh
from relight_rt.relight import shadow_fill

AZ = 70  # the de-light pairs from this |azimuth| (yale_eval's SOCKET_AZ)


def framed(photo: np.ndarray, framing: float) -> tuple[np.ndarray, np.ndarray, tuple[int, int]]:
    """(canvas, mask, (y0, x0)): ``photo`` at the top centre of a canvas ``framing`` times its size, the mask its
    face ellipse joined to grey shoulders that widen to the canvas's sides at its bottom; (y0, x0) where the photo
    lies."""
    h, w = photo.shape[:2]
    face = ye.ellipse((h, w))
    if framing <= 1:
        return photo, face, (0, 0)
    ch, cw = int(round(h * framing)), int(round(w * framing))
    y0, x0 = 0, (cw - w) // 2
    grey = float(np.median(photo[face > 0]))
    canvas = np.full((ch, cw, 3), grey, np.float32)
    mask = np.zeros((ch, cw), np.float32)
    neck = int(0.85 * h)  # the shoulders start under the chin, as wide as the face there
    poly = np.array([[x0 + 0.25 * w, neck], [x0 + 0.75 * w, neck], [cw - 1, ch - 1], [0, ch - 1]], np.int32)
    cv2.fillConvexPoly(mask, poly, 1.0)
    canvas[y0 : y0 + h, x0 : x0 + w] = np.where(face[..., None] > 0, photo, canvas[y0 : y0 + h, x0 : x0 + w])
    mask[y0 : y0 + h, x0 : x0 + w] = np.maximum(mask[y0 : y0 + h, x0 : x0 + w], face)
    return canvas, mask, (y0, x0)


def fill_weight(relighter: Relighter, dec, shape: tuple[int, int], at: tuple[int, int]) -> np.ndarray:
    """(h, w) the fill's weight (``ShadowFill.shadow_weight``) over the photo's pixels at ``at`` in the canvas (0 where
    there is no fill)."""
    found = relighter._factor.fill.shadow_weight(dec)
    full = np.zeros(dec.image.shape[:2], np.float32)
    if found is not None:
        y0, _, x0, _ = relighter._factor.restored(dec)["window"]
        crop = dec.geometry.to_crop(np.ascontiguousarray(found[0]), (y0, x0))
        by0, _, bx0, _ = dec.geometry.box
        full[by0 : by0 + crop.shape[0], bx0 : bx0 + crop.shape[1]] = crop
    return full[at[0] : at[0] + shape[0], at[1] : at[1] + shape[1]]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--yale", type=Path, default=shared_path("realdata", "yale"))
    p.add_argument("--framings", type=float, nargs="*", default=[1, 2, 3, 4, 6])
    p.add_argument("--subjects", nargs="*", default=None)
    args = p.parse_args(argv)
    if not args.yale.is_dir():
        print(missing(args.yale), file=sys.stderr)
        return 2
    subjects = args.subjects or sorted(d.name for d in args.yale.iterdir() if d.is_dir())
    relighter = Relighter(RuntimeConfig(device="cpu"))
    mesh = FaceMesh(relighter.models_dir)
    args.out.mkdir(parents=True, exist_ok=True)
    rows, t0 = [], time.time()
    rule = shadow_fill.MIRROR_DARK
    for subject in subjects:
        frontal_path = ye.find_file(args.yale, subject, 0)
        if not frontal_path.is_file():
            continue
        frontal = ye.read_grey(frontal_path)
        h, w = frontal.shape[:2]
        face = ye.ellipse((h, w)) > 0
        found = mesh.faces(frontal, (0, h, 0, w)) if mesh.available else []
        if not found:
            continue
        region = cv2.resize(face.astype(np.float32), (ye.GRID, ye.GRID), interpolation=cv2.INTER_AREA) > 0.99
        for az in (-AZ, AZ):
            path = ye.find_file(args.yale, subject, az)
            if not path.is_file():
                continue
            side = ye.read_grey(path)
            dark_eye, lit_eye = (ye.RIGHT_EYE, ye.LEFT_EYE) if az < 0 else (ye.LEFT_EYE, ye.RIGHT_EYE)
            eyes = {name: ye.eye_region(found[0], e, (h, w)) for name, e in (("dark", dark_eye), ("lit", lit_eye))}
            for framing in args.framings:
                canvas, mask, (y0, x0) = framed(side, framing)
                row, weights = {"id": f"{subject}:{az:+d}", "framing": framing}, {}
                for on in (True, False):  # each its own Decomposition: what a relight caches depends on the rule
                    shadow_fill.MIRROR_DARK = rule if on else None
                    try:
                        dec = relighter.decompose(canvas, mask)
                        weights[on] = fill_weight(relighter, dec, (h, w), (y0, x0))
                        relit = relighter.relight(dec, ye.lamp(0))[y0 : y0 + h, x0 : x0 + w]
                    finally:
                        shadow_fill.MIRROR_DARK = rule
                    row["on" if on else "off"] = {
                        **ye.compare(side, relit, frontal, region),
                        **{name: ye.socket_ratio(relit, frontal, face, eye) for name, eye in eyes.items()}}
                added = (weights[True] - weights[False])[eyes["dark"] & face]
                row.update(meshes=len(dec.face_meshes or ()), head_pass=dec.head_box is not None,
                           share=float(added.mean()), peak=float(added.max()))
                rows.append(row)
        print(f"{subject}: {len(rows)} rows, {time.time() - t0:.0f} s", flush=True)
    (args.out / "yale_small.json").write_text(json.dumps(rows, indent=1))
    print(f"{'framing':>8s} {'pairs':>5s} {'mesh':>4s} {'head':>4s} {'share':>6s} {'peak':>6s}   dark |log| on / off"
          "   lit |log| on / off   corr on / off   contrast on / off")
    for framing in args.framings:
        sel = [r for r in rows if r["framing"] == framing]
        if not sel:
            continue

        def err(key: str, side: str, sel: list = sel) -> float:
            return float(np.mean([abs(np.log(r[key][side])) for r in sel]))

        def med(key: str, fig: str, sel: list = sel) -> float:
            return float(np.median([r[key][fig] for r in sel]))

        print(f"{framing:8.1f} {len(sel):5d} {sum(r['meshes'] > 0 for r in sel):4d} "
              f"{sum(r['head_pass'] for r in sel):4d} {np.mean([r['share'] for r in sel]):6.3f} "
              f"{np.mean([r['peak'] for r in sel]):6.3f}   {err('on', 'dark'):.3f} / {err('off', 'dark'):.3f}      "
              f"{err('on', 'lit'):.3f} / {err('off', 'lit'):.3f}     {med('on', 'corr'):.3f} / {med('off', 'corr'):.3f}"
              f"   {med('on', 'contrast'):.3f} / {med('off', 'contrast'):.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
