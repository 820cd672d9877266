"""Does the face mesh lean one way? A label-free measure: each face's mesh on the photo and on its mirror image.

    python benchmarks/mesh_mirror.py [--variants as-is,box-avg,flip] [--sets yale,side,look,dpr,renders]
                                     [--out FILE.json] [--build-map]

A landmarker without a bias of its own gives, on a photo mirrored left-right, the mirror of the photo's mesh: the
second mesh mapped back (x -> W - x) and re-indexed by the mesh's left-right symmetry (``tests/data/
face_mesh_mirror.txt``: landmark i's partner on the face's other half, the mid-line's landmarks their own) lands on
the first. What it does not flip with the photo is ours, not the face's. Per face:

- ``disagree``: the mean distance (px) between the photo's landmarks and the mirror's mapped back, and ``share``
  that over the mesh's width;
- ``shift``: half the mean horizontal difference (photo minus mirror mapped back), px: the photo's mesh sits this
  far right (< 0: left) of the two's middle;
- ``yaw``: the photo mesh's turn from its left-right landmark pairs (degrees, atan2 of the depth difference over
  the width difference, image right minus image left; > 0: the image's right side further from the camera), and
  ``yaw_bias`` half the photo's yaw minus the mirror's mapped back (the part that does not flip);
- on Yale, ``over_left`` / ``over_right``: how far (px) the mesh reaches past the frame's left and right edges.

Variants (the causes, one at a time; light30's and face31's records, docs/RESULTS.md): ``as-is`` (the product's
FaceMesh.faces as configured); ``box-avg`` (the landmarker run from the detector's box of the photo and of the mirror
mapped back, averaged: a box that is left-right symmetric by construction); ``flip`` (the detector and the
landmarker each shown its crop and the crop's mirror image, the answers averaged: FaceMesh's ``MESH_FLIP``);
``zero`` (no flip: the product before mirror34); and ``+``-joined mixtures. face31 also tried the landmarker's crop
padded with its edge pixels and a second landmarker pass from the first mesh's box (docs/RESULTS.md; both
removed from the product unused, at mirror34's review).

Sets: ``yale`` Extended Yale B's frontal photos (P00A+000E+00, 12 subjects), ``side`` its photos lit from azimuth
+-25 (elevation 0), ``look`` the faces of benchmarks/first_look.py's 30 photos (each face the whole-photo detector
finds, searched in a square three times its box; its mirror in the box mirrored), ``dpr`` DPR's demo portrait
(a DPR repository: $DPR_REPO or the mirror), ``renders`` the held-out renders' faces (photos_face, every light, and
photos_head-shoulders' first light; their heads are frontal: ``yaw`` against 0 is the error).

``--own-light`` prints, per variant, the lean of the Yale frontals' own light (``Relighter.decompose``'s, after
face_refit): its band-1 azimuth toward the image's right on the photo and on its mirror image (a left-right
symmetric chain reads them opposite), and half their sum, the part that does not flip (medians, degrees); variant
``no-mesh``: the chain with no face mesh found (stage 1's light refit on the whole person).

``--build-map`` writes the symmetry map from the meshes of the Yale frontals and their mirrors (``symmetry_map``)
and stops. The data is for evaluation only: keep --out out of the repository.
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
import dpr_protocol as dprp
import yale_eval as ye
from _shared import shared_path
from first_look import picked_photos, read_rgb

from relight_rt.engine.session import bundled_models_dir
from relight_rt.image.regions import Region
from relight_rt.person import face_mesh as fm_module
from relight_rt.person.face_mesh import ROI_SCALE, FaceMesh
from relight_rt.person.matting._detect import find_faces

MAP_FILE = fm_module.MIRROR_FILE
SUBJECTS = ("yaleB02", "yaleB05", "yaleB08", "yaleB11", "yaleB15", "yaleB18", "yaleB21", "yaleB24", "yaleB27",
            "yaleB30", "yaleB33", "yaleB36")
SEARCH = 3.0  # a first-look face is searched in a square this many times its detector box
VARIANTS = {  # name -> (box averaged, flip)
    "zero": (False, False),
    "box-avg": (True, False),
    "flip": (False, True),
}


def read_map(path: Path = MAP_FILE) -> np.ndarray:
    """The mesh's left-right symmetry: (468,) int, landmark i's partner (an involution)."""
    return np.loadtxt(path, dtype=np.int64)


def symmetry_map(meshes: list[np.ndarray], rounds: int = 20) -> np.ndarray:
    """The mesh's left-right symmetry from frontal meshes ((468, 3) each): their mean shape (each centred and scaled
    to unit RMS, then turned onto the first by least squares), and the reflection of it that best lands on it
    (x negated, then a rotation and shift fitted, alternating with nearest neighbours); pairs taken greedily by
    the summed distance both ways, so the map is an involution by construction."""
    shapes = []
    for m in meshes:
        p = m - m.mean(axis=0)
        shapes.append(p / np.sqrt((p**2).sum(axis=1).mean()))
    ref = shapes[0]
    aligned = [s @ _kabsch(s, ref) for s in shapes]
    mean = np.mean(aligned, axis=0)
    flip = mean * np.array([-1.0, 1.0, 1.0])
    partner = np.array([np.argmin(((mean - q) ** 2).sum(axis=1)) for q in flip])
    for _ in range(rounds):
        rot = _kabsch(flip - flip.mean(0), mean[partner] - mean[partner].mean(0))
        moved = (flip - flip.mean(0)) @ rot + mean[partner].mean(0)
        new = np.array([np.argmin(((mean - q) ** 2).sum(axis=1)) for q in moved])
        if (new == partner).all():
            break
        partner = new
    cost = ((moved[:, None, :] - mean[None, :, :]) ** 2).sum(axis=2)
    both = cost + cost.T
    out = -np.ones(len(mean), np.int64)
    for flat in np.argsort(both, axis=None):
        i, j = divmod(int(flat), len(mean))
        if out[i] < 0 and out[j] < 0:
            out[i], out[j] = j, i
    return out


def _kabsch(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """The rotation R (3x3) minimising |src @ R - dst| for centred point sets."""
    u, _, vt = np.linalg.svd(src.T @ dst)
    d = np.sign(np.linalg.det(u @ vt))
    return u @ np.diag([1.0, 1.0, d]) @ vt


def mirrored_box(box, w: int):
    """An (x0, y0, x1, y1) box mirrored in a photo ``w`` wide."""
    x0, y0, x1, y1 = box
    return [w - x1, y0, w - x0, y1]


def nearest(meshes: list[np.ndarray], centre: tuple[float, float]) -> np.ndarray | None:
    if not meshes:
        return None
    return min(meshes, key=lambda m: float(np.hypot(*(m[:, :2].mean(axis=0) - centre))))


def settings(variant: str) -> tuple[bool, bool]:
    """(box averaged, flip) of a variant: a name of ``VARIANTS``, "as-is" (the product's), or several joined by
    "+"."""
    avg, flip = False, False
    for part in variant.split("+"):
        if part == "as-is":
            flip = fm_module.MESH_FLIP
            continue
        a, f = VARIANTS[part]
        avg, flip = avg or a, flip or f
    return avg, flip


def both_meshes(mesh: FaceMesh, rgb: np.ndarray, search: tuple[int, int, int, int], variant: str):
    """(the photo's mesh, the mirror's mesh mapped back (x -> W - x), not re-indexed) for the face searched in
    ``search`` (y0, y1, x0, x1) and in its mirror; either None where not found."""
    h, w = rgb.shape[:2]
    mir = np.ascontiguousarray(rgb[:, ::-1])
    y0, y1, x0, x1 = search
    msearch = (y0, y1, w - x1, w - x0)
    centre = ((x0 + x1) / 2, (y0 + y1) / 2)
    avg, flip = settings(variant)
    saved, fm_module.MESH_FLIP = fm_module.MESH_FLIP, flip
    try:
        if avg:
            ba, bb = mesh.boxes(rgb, search), mesh.boxes(mir, msearch)
            if not ba or not bb:
                return None, None
            box = (np.array(ba[0]) + np.array(mirrored_box(bb[0], w))) / 2
            a = mesh.landmarks(rgb, Region.around(*box, scale=ROI_SCALE))
            b = mesh.landmarks(mir, Region.around(*mirrored_box(box, w), scale=ROI_SCALE))
        else:
            a = nearest(mesh.faces(rgb, search), centre)
            b = nearest(mesh.faces(mir, msearch), (w - centre[0], centre[1]))
    finally:
        fm_module.MESH_FLIP = saved
    if b is not None:
        b = b.copy()
        b[:, 0] = w - b[:, 0]
    return a, b


def yaw(points: np.ndarray, pairs: np.ndarray) -> float:
    """Degrees: atan2 of the summed depth difference over the summed width difference of the (left, right) pairs
    (image left, image right on a frontal face)."""
    d = points[pairs[:, 1]] - points[pairs[:, 0]]
    return float(np.degrees(np.arctan2(d[:, 2].sum(), d[:, 0].sum())))


def measure(a: np.ndarray, b: np.ndarray, partner: np.ndarray, pairs: np.ndarray) -> dict:
    bp = b[partner]
    width = float(np.ptp(a[:, 0]))
    dis = float(np.linalg.norm(a[:, :2] - bp[:, :2], axis=1).mean())
    ya, yb = yaw(a, pairs), yaw(bp, pairs)
    return {"width": width, "disagree": dis, "share": dis / width, "shift": float((a[:, 0] - bp[:, 0]).mean() / 2),
            "yaw": ya, "yaw_mirror": yb, "yaw_bias": (ya - yb) / 2}


def photos(sets: list[str], mesh: FaceMesh, yale: Path, people: Path, heldout: Path):
    """(set, name, rgb, search box (y0, y1, x0, x1)) for every face of the sets."""
    if "yale" in sets or "side" in sets:
        for s in SUBJECTS:
            for az in ([0] if "yale" in sets else []) + ([25, -25] if "side" in sets else []):
                path = ye.find_file(yale, s, az)
                if path.is_file():
                    rgb = ye.read_grey(path)
                    yield ("yale" if az == 0 else "side"), f"{s}{az:+d}", rgb, (0, rgb.shape[0], 0, rgb.shape[1])
    if "look" in sets:
        found = picked_photos(people, 30, 48)
        if found is not None:
            folder, chosen, _ = found
            for name in chosen:
                rgb = read_rgb(folder / f"{name}.jpg")
                h, w = rgb.shape[:2]
                for k, face in enumerate(find_faces(mesh.detector, rgb, every=True)):
                    x0, y0, x1, y1 = face.box
                    cx, cy, side = (x0 + x1) / 2, (y0 + y1) / 2, SEARCH * face.size
                    box = (max(0, int(cy - side / 2)), min(h, int(cy + side / 2)),
                           max(0, int(cx - side / 2)), min(w, int(cx + side / 2)))
                    yield "look", f"{name}#{k}", rgb, box
    if "dpr" in sets:
        repo = dprp.DPRRepo.find(None)
        if repo is not None:
            rgb = repo.image(dprp.DEMO_PHOTO)
            yield "dpr", "dpr_obama", rgb, (0, rgb.shape[0], 0, rgb.shape[1])
        else:
            print("no DPR repository: the dpr set skipped", file=sys.stderr)
    if "renders" in sets:
        files = sorted((heldout / "photos_face").glob("*_photo.png"))
        files += sorted((heldout / "photos_head-shoulders").glob("*__L0_photo.png"))
        for f in files:
            rgb = read_rgb(f)
            yield "renders", f"{f.parent.name[7:]}/{f.name[:-10]}", rgb, (0, rgb.shape[0], 0, rgb.shape[1])


def own_light_lean(yale: Path, variants: list[str], label: str | None = None, relighter=None) -> None:
    """Print the Yale frontals' own-light azimuth toward the image's right, photo / mirror / half their sum;
    variant "no-mesh": with no face mesh found (stage 1's light refit on the whole person)."""
    from relight_rt import Relighter, RuntimeConfig

    relighter = relighter or Relighter(RuntimeConfig(device="cpu"))
    for variant in variants:
        if variant == "no-mesh":  # the chain without face meshes: stage 1's light, refit on the whole person
            faces = fm_module.FaceMesh.faces
            fm_module.FaceMesh.faces = lambda self, rgb, box, lift=1.0: []
            try:
                own_light_lean(yale, ["as-is"], label="no-mesh", relighter=relighter)
            finally:
                fm_module.FaceMesh.faces = faces
            continue
        avg, flip = settings(variant)
        if avg:
            print(f"{variant}: the box averaging is no product setting, the chain cannot run it", file=sys.stderr)
            continue
        saved, fm_module.MESH_FLIP = fm_module.MESH_FLIP, flip
        rows = []
        try:
            for s in SUBJECTS:
                path = ye.find_file(yale, s, 0)
                if not path.is_file():
                    continue
                img = ye.read_grey(path)
                mask = ye.ellipse(img.shape[:2])
                az = []
                for im, m in ((img, mask), (img[:, ::-1], mask[:, ::-1])):
                    light = relighter.decompose(np.ascontiguousarray(im), np.ascontiguousarray(m)).light
                    v = np.asarray(light, np.float64)[[3, 1, 2], 1]  # (toward the camera, image right, up), green
                    az.append(float(np.degrees(np.arcsin(v[1] / np.linalg.norm(v)))))
                rows.append(az)
        finally:
            fm_module.MESH_FLIP = saved
        r = np.array(rows)
        print(f"{label or variant:24s} own light toward the image's right, photo / mirror / not flipping: "
              f"{np.median(r[:, 0]):.2f} / {np.median(r[:, 1]):.2f} / {np.median(r.sum(axis=1) / 2):.2f} deg "
              f"({len(r)} subjects)")


def summary(rows: list[dict]) -> dict:
    out = {"faces": len(rows), "found": sum(r.get("found", False) for r in rows)}
    got = [r for r in rows if r.get("found")]
    for key in ("disagree", "share", "shift", "yaw", "yaw_bias", "over_left", "over_right"):
        vals = [r[key] for r in got if key in r]
        if vals:
            out[key] = float(np.median(vals))
            out[key + "_mean"] = float(np.mean(vals))
    out["abs_yaw_bias"] = float(np.median([abs(r["yaw_bias"]) for r in got])) if got else None
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--variants", default="as-is", help="comma-separated: as-is, zero, box-avg, flip, or +-joined "
                   "mixtures")
    p.add_argument("--sets", default="yale,side,look,dpr,renders")
    p.add_argument("--yale", type=Path, default=shared_path("realdata", "yale"))
    p.add_argument("--people", type=Path, default=shared_path("realdata", "people_masks"))
    p.add_argument("--heldout", type=Path, default=Path.home() / ".cache" / "relight_rt_real_photos" / "heldout")
    p.add_argument("--out", type=Path, default=None, help="every face's figures (JSON; not the repository)")
    p.add_argument("--build-map", action="store_true", help="write tests/data/face_mesh_mirror.txt and stop")
    p.add_argument("--rows", action="store_true", help="print every face")
    p.add_argument("--own-light", action="store_true", help="the Yale frontals' own light's lean, then stop")
    args = p.parse_args(argv)
    cv2.setNumThreads(1)
    mesh = FaceMesh(bundled_models_dir())
    sets = args.sets.split(",")
    if args.build_map:
        found = []
        for _set, _name, rgb, search in photos(["yale"], mesh, args.yale, args.people, args.heldout):
            a, b = both_meshes(mesh, rgb, search, "zero")
            found += [m for m in (a, b) if m is not None]
            if b is not None:  # mapped back, its landmarks' own sides swap: flip it once more to a face's shape
                found[-1] = found[-1] * np.array([-1.0, 1.0, 1.0])
        partner = symmetry_map(found)
        assert (partner[partner] == np.arange(len(partner))).all()
        np.savetxt(MAP_FILE, partner, fmt="%d")
        print(f"{MAP_FILE}: {len(found)} meshes, {int((partner == np.arange(len(partner))).sum())} on the mid-line")
        return 0
    if args.own_light:
        own_light_lean(args.yale, args.variants.split(","))
        return 0
    partner = read_map()
    assert (partner[partner] == np.arange(len(partner))).all(), "the symmetry map is no involution"
    left = np.nonzero(partner > np.arange(len(partner)))[0]
    pairs = np.stack([left, partner[left]], axis=1)
    results = {}
    for variant in args.variants.split(","):
        rows = []
        t0 = time.perf_counter()
        for kind, name, rgb, search in photos(sets, mesh, args.yale, args.people, args.heldout):
            a, b = both_meshes(mesh, rgb, search, variant)
            row = {"set": kind, "name": name, "found": a is not None and b is not None,
                   "found_photo": a is not None, "found_mirror": b is not None}
            if row["found"]:
                # the pairs oriented image left -> right on this face
                pr = np.where((a[pairs[:, 0], 0] < a[pairs[:, 1], 0])[:, None], pairs, pairs[:, ::-1])
                row.update(measure(a, b, partner, pr))
                if kind in ("yale", "side"):
                    row["over_left"] = float(-a[:, 0].min())
                    row["over_right"] = float(a[:, 0].max() - rgb.shape[1])
            rows.append(row)
            if args.rows:
                print(variant, json.dumps({k: (round(v, 3) if isinstance(v, float) else v) for k, v in row.items()}))
        took = time.perf_counter() - t0
        by_set = {s: summary([r for r in rows if r["set"] == s]) for s in dict.fromkeys(r["set"] for r in rows)}
        results[variant] = {"rows": rows, "sets": by_set, "seconds": took}
        for s, f in by_set.items():
            line = ", ".join(f"{k} {v:.3f}" if isinstance(v, float) else f"{k} {v}" for k, v in f.items()
                             if not k.endswith("_mean") or k in ("shift_mean",))
            print(f"{variant:24s} {s:8s} {line}", flush=True)
    if args.out:
        args.out.write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
