"""The face mesh's artefacts on real photos, measured (issue 32): seams, a low light's dark nose, a side lamp's edge.

    python benchmarks/face_mesh_artefacts.py --out OUT --people CACHE [--reference ../shared/reference] [--crops]

Relights real photos (automatic mattes, automatic exposure) under ``overhead-noon``, ``night``, ``campfire`` and
white lamps from the image's left and right (benchmarks/real_photos.py's LEFT, RIGHT), takes the largest face mesh
the runtime found (relight_rt.person.face_mesh), and measures the change c = log(relit luminance + 1e-3) -
log(input luminance + 1e-3) (Rec. 709 of linearised sRGB) around it, in units of the face's size s (the mesh's
larger extent, input pixels). The photos: the reference photo and video frames 1 and 12 (``--reference``), and
dpr_obama, grace_hopper, julia_trotti, blonde_hair, astronaut from benchmarks/people_photos.py's cache
(``--people``). Writes OUT/face_mesh_artefacts.json and, with ``--crops``, OUT/NAME_LIGHT.png (input | relit |
relit with the mesh's outline in magenta; 2x for small faces).

- seam: the mean gradient magnitude of c (smoothed over 0.01 s) in the band from 0.02 s outside the mesh's
  outline (its openings closed) to 0.14 s inside, over the mean of the bands 0.14-0.26 s inside and 0.02-0.14 s
  outside; rows above the chin only. 1: the outline draws no line of its own.
- step_ratio: |c(0.06 s inside) - c(0.06 s outside)| across the outline over |c(0.18 s) - c(0.06 s)| inside.
- socket, bridge, cheek: c averaged in discs of 0.025 s: between the upper eyelids and the brows (MediaPipe
  landmarks 161, 160, 159, 158, 157 halfway to 46, 53, 52, 65, 55, and their mirror), at the bridge of the nose
  (168, 6, 197), on the cheeks (117, 118, 50, 346, 347, 280); "socket-cheek" and "bridge-cheek" their
  differences (under a light from below, sockets and the bridge should not fall dark against the cheeks).
- edge_max: along the row through the nose tip (landmark 1) between the face's sides (234, 454), the largest step
  of c per face size (a hard shadow edge at the nose is large); far_std: the spread of c over the far half from
  the lamp (0: one flat patch).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import cv2
import numpy as np

# real_photos puts this checkout (and benchmarks/) first on sys.path: the relight_rt imported below is this one
from _shared import shared_path, warn_missing
from real_photos import LEFT, RIGHT, change

import relight_rt
from relight_rt import RuntimeConfig
from relight_rt.person.face_mesh import rasterise_normals

LIGHTS = {"overhead-noon": "overhead-noon", "night": "night", "campfire": "campfire", "left": LEFT, "right": RIGHT}
PEOPLE = ("dpr_obama", "grace_hopper", "julia_trotti", "blonde_hair", "astronaut")
UPPER_LIDS = [[246, 161, 160, 159, 158, 157, 173], [466, 388, 387, 386, 385, 384, 398]]
BROWS = [[46, 53, 52, 65, 55], [276, 283, 282, 295, 285]]
BRIDGE = [168, 6, 197]
CHEEKS = [117, 118, 50, 346, 347, 280]


def disc_mean(img: np.ndarray, pts, r: float) -> float:
    m = np.zeros(img.shape, np.uint8)
    for x, y in pts:
        cv2.circle(m, (int(round(x)), int(round(y))), max(int(r), 1), 1, -1)
    return float(img[m > 0].mean())


def closed_cover(pts: np.ndarray, tri: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """The mesh's coverage with its openings (eyes, lips) closed."""
    _, cover = rasterise_normals(pts, tri, shape)
    out = np.pad((cover > 0).astype(np.uint8), 1)
    cv2.floodFill(out, None, (0, 0), 2)
    return out[1:-1, 1:-1] != 2


def measures(change: np.ndarray, pts: np.ndarray, tri: np.ndarray, lamp_left: bool) -> tuple[dict, np.ndarray]:
    h, w = change.shape
    cover = closed_cover(pts, tri, (h, w)).astype(np.uint8)
    size = float(np.ptp(pts[:, :2], axis=0).max())
    d = (cv2.distanceTransform(cover, cv2.DIST_L2, 3) - cv2.distanceTransform(1 - cover, cv2.DIST_L2, 3)) / size
    sm = cv2.GaussianBlur(change, (0, 0), max(0.01 * size, 0.7))
    gy, gx = np.gradient(sm)
    g = np.hypot(gx, gy) * size
    above = np.broadcast_to(np.arange(h)[:, None] < pts[:, 1].max() - 0.05 * size, (h, w))
    zones = {"in": (d > 0.14) & (d < 0.26), "seam": (d > -0.02) & (d <= 0.14), "out": (d > -0.14) & (d <= -0.02)}
    gz = {k: float(g[z & above].mean()) for k, z in zones.items()}
    out = {"seam": gz["seam"] / max(0.5 * (gz["in"] + gz["out"]), 1e-6)}
    ny, nx = np.gradient(cv2.GaussianBlur(d.astype(np.float32), (0, 0), 2.0))
    nn = np.maximum(np.hypot(nx, ny), 1e-9)
    oy, ox = np.nonzero((np.abs(d) * size < 1.0) & above)

    def sample(k):
        xs = (ox + k * size * nx[oy, ox] / nn[oy, ox]).astype(np.float32)
        ys = (oy + k * size * ny[oy, ox] / nn[oy, ox]).astype(np.float32)
        return cv2.remap(sm.astype(np.float32), xs[None], ys[None], cv2.INTER_LINEAR)[0]

    if oy.size:
        out["step_ratio"] = float(np.abs(sample(0.06) - sample(-0.06)).mean()
                                  / max(np.abs(sample(0.18) - sample(0.06)).mean(), 1e-6))
    r = 0.025 * size
    sockets = [(pts[a, :2] + pts[b, :2]) / 2 for lid, brow in zip(UPPER_LIDS, BROWS, strict=True)
               for a, b in zip(lid[1:6], brow, strict=True)]
    out["socket"] = disc_mean(change, sockets, r)
    out["bridge"] = disc_mean(change, pts[BRIDGE, :2], r)
    out["cheek"] = disc_mean(change, pts[CHEEKS, :2], r)
    out["socket-cheek"] = out["socket"] - out["cheek"]
    out["bridge-cheek"] = out["bridge"] - out["cheek"]
    y = int(round(pts[1, 1]))
    xs = np.arange(int(pts[234, 0]), int(pts[454, 0]) + 1)
    xs = xs[(xs >= 0) & (xs < w)]
    if xs.size > 4 and 0 <= y < h:
        prof = sm[y, xs]
        out["edge_max"] = float(np.abs(np.diff(prof)).max() * size)
        far = xs > pts[1, 0] if lamp_left else xs < pts[1, 0]
        out["far_std"] = float(prof[far].std())
    return out, d


def photos(args) -> dict[str, Path]:
    found = {}
    if args.reference is not None and not args.reference.is_dir():
        warn_missing(args.reference, "the reference photo and frames")
    if args.reference is not None:
        for name, rel in (("reference_photo", "photo/sample.jpg"), ("frame_001", "video/frame_001.png"),
                          ("frame_012", "video/frame_012.png")):
            if (args.reference / rel).is_file():
                found[name] = args.reference / rel
    for name in PEOPLE:
        hits = sorted(args.people.glob(f"{name}.*")) if args.people is not None else []
        if hits:
            found[name] = hits[0]
    return found


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--people", type=Path, default=None, help="benchmarks/people_photos.py's cache")
    p.add_argument("--reference", type=Path, default=shared_path("reference"))
    p.add_argument("--crops", action="store_true")
    p.add_argument("--only", nargs="*", default=None, help="photo names")
    args = p.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    relighter = relight_rt.open(RuntimeConfig(device="cpu"))
    tri = relighter._faces.mesh().triangles
    report = {}
    for name, path in photos(args).items():
        if args.only and name not in args.only:
            continue
        dec = relighter.decompose(str(path))
        meshes = dec.face_meshes or []
        if not meshes:
            print(f"{name}: no face mesh", flush=True)
            continue
        pts = max(meshes, key=lambda q: np.ptp(q[:, 0]))
        size = float(np.ptp(pts[:, :2], axis=0).max())
        rgb = dec.image
        cx, cy = pts[:, :2].mean(0)
        half = int(0.9 * size)
        y0, y1 = max(int(cy) - half, 0), min(int(cy) + half, rgb.shape[0])
        x0, x1 = max(int(cx) - half, 0), min(int(cx) + half, rgb.shape[1])
        report[name] = {"face_px": size}
        for lname, light in LIGHTS.items():
            out = relighter.relight(dec, light)
            c = change(rgb, out)
            report[name][lname], d = measures(c, pts, tri, lname == "left")
            if args.crops:
                marked = out[y0:y1, x0:x1, :3].copy()
                marked[(np.abs(d) < 1.5 / size)[y0:y1, x0:x1]] = (1, 0, 1)
                crop = np.concatenate([rgb[y0:y1, x0:x1], out[y0:y1, x0:x1, :3], marked], axis=1)
                s = 2 if crop.shape[0] < 300 else 1
                crop = cv2.resize(crop, None, fx=s, fy=s, interpolation=cv2.INTER_NEAREST)
                cv2.imwrite(str(args.out / f"{name}_{lname}.png"),
                            cv2.cvtColor((np.clip(crop, 0, 1) * 255 + 0.5).astype(np.uint8), cv2.COLOR_RGB2BGR))
        print(f"{name}: " + "; ".join(
            f"{ln} " + " ".join(f"{k} {v:.2f}" for k, v in report[name][ln].items()
                                if k in ("seam", "step_ratio", "socket-cheek", "bridge-cheek", "edge_max", "far_std"))
            for ln in LIGHTS), flush=True)
    (args.out / "face_mesh_artefacts.json").write_text(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
