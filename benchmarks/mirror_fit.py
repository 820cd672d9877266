"""How well does the face's mirror map (relight_rt.person.face_mesh ``mirror``) take each landmark to its partner?

    python benchmarks/mirror_fit.py [--sets yale,side,look,renders] [--rows]
    python benchmarks/mirror_fit.py --relight OUT [--stride 4] [--max-side 1000]

``mirror`` is an affine map fitted to the face mesh's left-right pairs; the cheek rule (``mirror_held``) and the
fill's dark sockets (relight_rt.relight.shadow_fill ``mirror_shadow``) read a face's other half through it. Since
mesh37 it is fitted to the whole 468-point symmetry map (``MIRROR_FILE``, the cheeks' ``MIRROR_CHEEK_PAIRS`` left
out); before, to a hand list of 16 eye-contour pairs and 8 mid-line points (``HAND_PAIRS``, ``HAND_MIDLINE`` below,
kept here only to compare). Per face (its mesh as FaceMesh.faces gives it; benchmarks/mesh_mirror.py's sets) and
per fit, in shares of the face's size (the mesh's larger extent):

- ``cheek``: the largest miss of the cheeks' pairs, both ways: what ``mirror_held`` compares with ``MIRROR_MISS``
  (left out of both fits);
- ``all``: the mean miss of every landmark's partner but the cheeks' (the full map's own fit: in its sample);
- ``eyes``: the mean miss of the eye-contour pairs (the hand fit's own: in its sample).

Printed: each set's median and max per fit.

``--relight OUT``: what the fit changes in a relit photo. benchmarks/mirror_rule_photos.py's photos (the reference
photo and every ``--stride``-th people_masks photo with its given mask, reduced to ``--max-side``) relit under
``LEFT`` and ``RIGHT`` with the product's fit and with the hand fit (``face_mesh.mirror`` swapped, which every
reader reaches through ``face_mesh.reflection``; each its own Decomposition): per photo the largest change in 8-bit
levels (max over channels) and the pixels over 2 levels; OUT/NAME_LIGHT.png (hand | full | change x8, around the
largest change, 3x) for the worst three. The data is for evaluation only: keep OUT out of the repository.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np

# real_photos puts this checkout (and benchmarks/) first on sys.path: the relight_rt imported below is this one
import real_photos

# isort: split
import mesh_mirror as mm
from _shared import shared_path
from photo_faults import read_mask, read_rgb

from relight_rt.engine.session import bundled_models_dir
from relight_rt.person import face_mesh as fm

# the fit before mesh37: MediaPipe's two eye contours point for point (the image's left eye first: outer corner,
# lower lid, inner corner, upper lid) and points on the mid-line (nose tip and bridge, forehead, chin, lips)
HAND_PAIRS = ((33, 263), (7, 249), (163, 390), (144, 373), (145, 374), (153, 380), (154, 381), (155, 382),
              (133, 362), (173, 398), (157, 384), (158, 385), (159, 386), (160, 387), (161, 388), (246, 466))
HAND_MIDLINE = (1, 4, 6, 168, 10, 152, 0, 17)


def hand_mirror(points: np.ndarray) -> np.ndarray:
    """The mirror as fitted before mesh37: (2, 3), least squares on ``HAND_PAIRS`` both ways and ``HAND_MIDLINE``."""
    p = np.asarray(points, np.float64)[:, :2]
    a, b = np.array(HAND_PAIRS).T
    mid = np.array(HAND_MIDLINE)
    src = np.concatenate([p[a], p[b], p[mid]])
    dst = np.concatenate([p[b], p[a], p[mid]])
    fit, *_ = np.linalg.lstsq(np.concatenate([src, np.ones((len(src), 1))], axis=1), dst, rcond=None)
    return fit.T


def misses(points: np.ndarray, m: np.ndarray, partner: np.ndarray) -> dict[str, float]:
    """``cheek``, ``all`` and ``eyes`` (module docstring) of mirror ``m`` on one mesh."""
    p = np.asarray(points, np.float64)[:, :2]
    size = float(np.ptp(p, axis=0).max())
    miss = np.linalg.norm(p @ m[:, :2].T + m[:, 2] - p[partner], axis=1) / size
    cheeks = np.array(fm.MIRROR_CHEEK_PAIRS).ravel()
    rest = np.setdiff1d(np.arange(len(p)), cheeks)
    return {"cheek": float(miss[cheeks].max()), "all": float(miss[rest].mean()),
            "eyes": float(miss[np.array(HAND_PAIRS).ravel()].mean())}


def levels(rgb: np.ndarray) -> np.ndarray:
    return (np.clip(rgb, 0, 1) * 255 + 0.5).astype(np.int16)


def relit_change(out: Path, stride: int, max_side: int, people: Path, reference: Path) -> int:
    """``--relight``: the relit photos with the hand fit against the product's (module docstring)."""
    from relight_rt import Relighter, RuntimeConfig

    inputs = []
    sample = reference / "photo" / "sample.jpg"
    if sample.is_file():
        inputs.append(("sample", sample, sample.with_name("sample_mask.png")))
    inputs += [(f.stem, f, f.with_name(f"{f.stem}_mask.png")) for f in sorted((people / "photos").glob("*.jpg"))[
        ::stride]]
    relighter = Relighter(RuntimeConfig(device="cpu"))
    out.mkdir(parents=True, exist_ok=True)
    full, rows, shown = fm.mirror, [], []
    for name, image, mask_file in inputs:
        rgb = read_rgb(image, max_side)
        mask = read_mask(mask_file, rgb.shape[:2])
        if (mask > 0.5).sum() < 2000:
            continue
        relit = {}
        for fit in ("hand", "full"):
            fm.mirror = hand_mirror if fit == "hand" else full  # face_mesh.reflection reads it there
            try:
                dec = relighter.decompose(rgb, mask)
                relit[fit] = [levels(relighter.relight(dec, light)) for light in (real_photos.LEFT, real_photos.RIGHT)]
            finally:
                fm.mirror = full
        for light, a, b in zip(("LEFT", "RIGHT"), relit["hand"], relit["full"], strict=True):
            d = np.abs(a - b).max(axis=2)
            rows.append((int(d.max()), int((d > 2).sum()), name, light))
            shown.append((int(d.max()), name, light, a, b, d))
            shown = sorted(shown, key=lambda r: -r[0])[:3]
        print(name, " ".join(f"{r[3]} max {r[0]} over_2 {r[1]}" for r in rows[-2:]), flush=True)
    for _, name, light, a, b, d in shown:
        y, x = np.unravel_index(int(np.argmax(d)), d.shape)
        y0, x0 = max(0, y - 40), max(0, x - 40)
        crop = [c[y0 : y0 + 80, x0 : x0 + 80] for c in (a, b, np.repeat(np.minimum(d * 8, 255)[..., None], 3, 2))]
        sheet = np.concatenate(crop, axis=1).astype(np.uint8)
        sheet = cv2.resize(sheet, None, fx=3, fy=3, interpolation=cv2.INTER_NEAREST)
        cv2.imwrite(str(out / f"{name}_{light}.png"), sheet[..., ::-1])
    touched = [r for r in rows if r[0] > 0]
    print(f"{len(rows) // 2} photos x LEFT, RIGHT: changed {len(touched)}, over 2 levels "
          f"{sum(r[1] > 0 for r in rows)}; largest {max(rows)[0]} levels ({max(rows)[2]} {max(rows)[3]})")
    return 0


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--sets", default="yale,side,look,renders")
    p.add_argument("--yale", type=Path, default=shared_path("realdata", "yale"))
    p.add_argument("--people", type=Path, default=shared_path("realdata", "people_masks"))
    p.add_argument("--heldout", type=Path, default=Path.home() / ".cache" / "relight_rt_real_photos" / "heldout")
    p.add_argument("--rows", action="store_true", help="print every face")
    p.add_argument("--relight", type=Path, default=None, help="relit photos, hand fit against full (OUT folder)")
    p.add_argument("--stride", type=int, default=4)
    p.add_argument("--max-side", type=int, default=1000)
    p.add_argument("--reference", type=Path, default=shared_path("reference"))
    args = p.parse_args(argv)
    if args.relight is not None:
        return relit_change(args.relight, args.stride, args.max_side, args.people, args.reference)
    partner = fm.read_partners()
    if partner is None:
        p.error(f"no symmetry map at {fm.MIRROR_FILE}")
    mesh = fm.FaceMesh(bundled_models_dir())
    rows: dict[str, list[dict]] = {}
    for set_name, name, rgb, box in mm.photos(args.sets.split(","), mesh, args.yale, args.people, args.heldout):
        y0, y1, x0, x1 = box
        found = mm.nearest(mesh.faces(rgb, box), ((x0 + x1) / 2, (y0 + y1) / 2))
        if found is None:
            continue
        row = {f"{fit} {k}": v for fit, m in (("hand", hand_mirror(found)), ("full", fm.mirror(found)))
               for k, v in misses(found, m, partner).items()}
        rows.setdefault(set_name, []).append(row)
        if args.rows:
            print(set_name, name, " ".join(f"{k} {v:.4f}" for k, v in row.items()))
    keys = [f"{fit} {k}" for fit in ("hand", "full") for k in ("cheek", "all", "eyes")]
    print(f"{'set':8s} {'n':>3s} " + " ".join(f"{k:>22s}" for k in keys))
    print(f"{'':12s} " + " ".join(f"{'median':>11s}{'max':>11s}" for _ in keys))
    for set_name, got in rows.items():
        print(f"{set_name:8s} {len(got):3d} " + " ".join(
            f"{np.median([r[k] for r in got]):11.4f}{max(r[k] for r in got):11.4f}" for k in keys))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
