"""Real faces under known lamps (Extended Yale B, ../shared/realdata/yale): relighting and de-lighting against truth.

    python benchmarks/yale_eval.py --out runs/yale [--yale ../shared/realdata/yale] [--dpr DPR_REPO | --no-dpr]
        [--cache runs/dpr_cache] [--subjects yaleB02 yaleB05 ...] [--no-mesh-occlusion] [--no-mirror-dark]
        [--no-rim-fill] [--no-penumbra-cap] [--no-rim-shown] [--own-light {today,true,true-direction,...}]
        [--own-level {meter,refit,dc}] [--own-scale K] [--mirror]

Issue 48's protocol. Every photo is grey (the PNG's one channel as R = G = B), relit with an ellipse mask (the
face: centre at 0.50, 0.52 of the image, semi-axes 0.44 W and 0.46 H) under a white point lamp in the photo's
lamp direction plus 0.05 ambient (``lamp``), exposure "auto". Compared: the change of log luminance (Rec. 709 of
linearised sRGB, + 1e-3) from the source photo, ours against the real photo's under the target lamp, both
reduced to a 48 x 48 grid (area average of the luminance) and taken inside the ellipse; per pair the Pearson
correlation, the contrast (least-squares slope of ours on the truth's, both centred) and the relative error
("relerr": |ours - truth's| / |truth's|, both centred, = sqrt(s^2 - 2 contrast + 1), s = contrast / corr: what the
contrast counts as strength when it points the wrong way, it counts as error); medians over pairs. The
blotches of the sheets, as shares of the face (``detail_shares``, means over pairs): "speckle" where the relit
photo has more than twice the real photo's fine detail, "flat" where it has less than half. The eye sockets
(``socket_ratio``, de-light pairs from |azimuth| 70): each eye's luminance (MediaPipe's eye contour on the real
frontal photo's face mesh, dilated 7 px) over the face's mean in ours, over the same in the real photo; the mean
|log| of that over the pairs, for the eye on the photo's dark side and on its lit side. "edge" (means over pairs):
the share of the face where the change draws an edge that neither the source photo nor the real one under the
target lamp has (benchmarks/new_edges.py ``new_edges``: a fill's border inside a black shadow, a blend's box).

- relight: the frontal photo (A+000E+00) relit to each lamp at elevation 0 and |azimuth| 25, 50, 70;
- de-light: the photos lit from |azimuth| 50 and 70 (elevation 0) relit to the frontal lamp, against the
  frontal photo (does the photo's own hard light go away?).

Lamp directions: Yale's negative azimuth lights the image's right (README of the data; checked there on every
subject), and DESIGN.md's frame has +y toward the image's right, so azimuth a and elevation e give the
direction (cos e cos a, -cos e sin a, sin e).

``--mirror``: Yale mirrored, in memory: every photo flipped left-right and its lamp's azimuth negated (the photo
read for azimuth a is the one at -a, flipped), pair ids prefixed "mirror:"; its pair to (from) azimuth a is the plain
pair to (from) -a mirrored. A chain that does not depend on which way a photo faces gives the same figures on both;
benchmarks/yale_halves.py pools a plain run with a mirrored one ("PLAIN/yale.json+MIRROR/yale.json"), a set whose
own left-right asymmetry cancels (mirror31).

``--own-light`` (a measurement, no product change; ``own_light``): each photo's own light replaced by an oracle
built from Yale's lamp for it (the frontal lamp for the relight pairs, the side lamp for the de-light pairs): "true"
``lamp`` itself, "true-direction" the true direction at stage 1's directionality, "true-hardness" stage 1's direction
at the true directionality, "today-lamp" stage 1's direction and directionality as a lamp plus ambient (the control
for the lamp's shape); each at today's level as "auto" meters it (``--own-level``: or two other readings of it).
yale.json records the mode and, per pair, the own light's angle off the photo's lamp and its directionality;
benchmarks/yale_compare.py sets runs side by side. Results: docs/RESULTS.md (oracle29).

DPR (zhhoper/DPR, benchmarks/dpr_protocol.py: its 512-px grey network on the CPU, the whole photo squashed to
512 as its demo does, our light converted exactly into its frame, its DC set to the demo lights') is measured
the same way beside ours, unless --no-dpr or no copy of its repository is found.

Writes OUT/yale.json (every pair and the medians) and OUT/yale_worst.jpg (the worst pairs by correlation:
source | ours | DPR | truth, and the two changes, ours | truth, grey = no change; OUT/yale_worst_delight.jpg the
same for the de-light pairs alone). The data is for evaluation only: keep OUT out of the repository.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
import time
from pathlib import Path

import cv2
import numpy as np

# real_photos puts this checkout (and benchmarks/) first on sys.path: the relight_rt imported below is this one
from real_photos import luminance

# isort: split
import dpr_protocol as dprp  # imports relight_rt: after real_photos
from _shared import missing, shared_path
from new_edges import new_edges

from relight_rt import Relighter, RuntimeConfig, lights
from relight_rt.image.color import REC709
from relight_rt.light import exposure as exposure_module
from relight_rt.light import sh
from relight_rt.person import face_mesh as face_mesh_module
from relight_rt.person.face_mesh import FaceMesh
from relight_rt.relight import shadow_fill, shadow_rim

EPS = 1e-3
GRID = 48
AMBIENT = 0.05
OWN_LIGHTS = ("today", "true", "true-direction", "true-hardness", "today-lamp")  # own_light's modes
OWN_LEVELS = ("meter", "refit", "dc")  # ... and the levels it keeps today's of
RELIGHT_AZ = (25, 50, 70)
DELIGHT_AZ = (50, 70)
DETAIL_SIGMA = 2.0  # detail_shares: the fine detail is the log luminance less its blur over this many pixels,
DETAIL_BLOCK = 12  # ... its RMS over blocks this many pixels wide,
DETAIL_ERODE = 9  # ... inside the ellipse eroded this many pixels (its own edge is no detail)
DPR_DC = dprp.DEMO_SCALE * 1.0841254962824531  # the DC of DPR's demo lights as its demo uses them
# socket_ratio: MediaPipe's face mesh eye contours (FACEMESH_RIGHT_EYE: the subject's right, the image's left)
RIGHT_EYE = (33, 7, 163, 144, 145, 153, 154, 155, 133, 173, 157, 158, 159, 160, 161, 246)
LEFT_EYE = (362, 382, 381, 380, 374, 373, 390, 249, 263, 466, 388, 387, 386, 385, 384, 398)
SOCKET_DILATE = 7  # ... the eye's contour dilated this many pixels (its lids and lashes)
SOCKET_AZ = 70  # ... measured on the de-light pairs from this |azimuth|


def lamp_direction(azimuth_deg: float, elevation_deg: float) -> tuple[float, float, float]:
    """Yale's lamp angles → DESIGN.md's frame (x toward the camera, y image right, z up)."""
    a, e = math.radians(azimuth_deg), math.radians(elevation_deg)
    return (math.cos(e) * math.cos(a), -math.cos(e) * math.sin(a), math.sin(e))


def lamp(azimuth_deg: float, elevation_deg: float = 0.0) -> np.ndarray:
    """(9, 3) a white point lamp from Yale's angles plus 0.05 ambient."""
    return lights.directional(lamp_direction(azimuth_deg, elevation_deg), (1, 1, 1), 1.0) + lights.ambient(AMBIENT)


def lamp_mix(direction, directionality: float) -> np.ndarray:
    """(9,) the luminance of a white point lamp from ``direction`` plus ambient, mixed so that its directionality
    (``sh.dominant_direction``: |degree 1| / (sqrt 3 x degree 0)) is ``directionality`` (the lamp alone, 1, at most);
    the lamp's intensity 1. ``lamp``'s 0.05 ambient is the mix of directionality 0.825."""
    point = lights.directional(direction, (1, 1, 1), 1.0)[:, 0]
    alone = sh.dominant_direction(point)[1]  # the lamp's own: degree 1 over degree 0, which ambient raises
    d = min(max(float(directionality), 1e-3), 1.0)
    out = point.copy()
    out[0] *= max(alone / d, 1.0)  # the ambient's degree 0 that brings the mix to ``d``
    return out


def own_light(relighter: Relighter, dec, mode: str, azimuth_deg: float, elevation_deg: float = 0.0,
              level: str = "meter", scale: float = 1.0):
    """``dec`` with its own light replaced for a measurement (``--own-light``; ``OWN_LIGHTS``): "today" ``dec``
    itself; else a white lamp plus ambient (``lamp_mix``) whose direction is the photo's true lamp (Yale's
    ``azimuth_deg`` / ``elevation_deg``, "true", "true-direction") or stage 1's (the degree-1 band of ``dec.light``'s
    luminance: "true-hardness", "today-lamp"), and whose directionality is ``lamp``'s, the truth ("true",
    "true-hardness"), or stage 1's own light's ("true-direction", "today-lamp"). "true" is ``lamp(azimuth_deg,
    elevation_deg)`` itself, rescaled. The level (``OWN_LEVELS``), today's kept: "meter" the person's mean luminance
    as "auto" meters it under the own light (relight_rt.light.exposure ``mean_luminance``, ``METER_POWER``), so
    every new light is exposed to the same scale; "refit" the person's mean albedo x shading through the transport
    the factor divides with (the rule ``face_refit`` sets its light's level by: ``Factor.refit_inputs``); "dc" the
    degree-0 luminance. The colour is today's (a grey photo: nearly white; the factor reads ``white_light``). Then the
    light is multiplied by ``scale`` (``--own-scale``; "today" too: how much the level alone moves the figures). The
    head pass (none at Yale's size) gets the same light. Uses the Relighter's private ``_factor`` (``with_light``, which
    recomputes all that depends on the light): a measurement, not an API."""
    factor = relighter._factor
    if mode == "today":
        return dec if scale == 1 else _with_own_light(factor, dec, dec.light * np.float32(scale))
    today, today_d = sh.dominant_direction(dec.white_light[:, 0])
    true_d = sh.dominant_direction(lamp(azimuth_deg, elevation_deg)[:, 0])[1]
    direction = lamp_direction(azimuth_deg, elevation_deg) if mode in ("true", "true-direction") else today
    if direction is None:  # a uniform own light has no direction to keep
        direction = lamp_direction(azimuth_deg, elevation_deg)
    lum = lamp_mix(direction, true_d if mode in ("true", "true-hardness") else today_d)
    colour = dec.light[0].astype(np.float64) / float(dec.light[0] @ REC709)
    light = (lum[:, None] * colour[None, :]).astype(np.float32)
    if level == "meter":
        meter = lambda white: exposure_module.mean_luminance(  # noqa: E731  (white: (9,) luminance, as "auto" reads)
            dec.albedo, dec.transport, dec.network_mask, np.repeat(white[:, None], 3, axis=1),
            exposure_module.METER_POWER)
    elif level == "refit":
        albedo, transport, _ = factor.refit_inputs(dec)
        meter = lambda white: float((albedo * np.maximum(transport @ white, 0)).sum())  # noqa: E731
    else:  # "dc"
        meter = lambda white: float(white[0])  # noqa: E731
    light *= np.float32(scale * meter(dec.white_light[:, 0]) / meter(light @ REC709))
    return _with_own_light(factor, dec, light)


def _with_own_light(factor, dec, light: np.ndarray):
    """``dec`` and its head pass (if any) with ``light`` as their own (``Factor.with_light``)."""
    new = factor.with_light(dec, light)
    if dec.head is not None:
        new = factor.derive(new, head=factor.with_light(dec.head, light))
    return new


def ellipse(shape: tuple[int, int]) -> np.ndarray:
    """(H, W) float32 {0, 1}: the face ellipse of a CroppedYale image."""
    h, w = shape
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32) + 0.5
    return ((((xx - 0.50 * w) / (0.44 * w)) ** 2 + ((yy - 0.52 * h) / (0.46 * h)) ** 2) <= 1).astype(np.float32)


MIRROR = False  # --mirror: the set mirrored (``find_file`` takes the photo at the negated azimuth, ``read_grey`` flips)


def read_grey(path: Path) -> np.ndarray:
    g = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if g is None:
        raise FileNotFoundError(path)
    if MIRROR:
        g = np.ascontiguousarray(g[:, ::-1])
    return np.repeat((g.astype(np.float32) / 255)[..., None], 3, axis=2)


def read_frontal(yale: Path, subject: str, mesh: FaceMesh) -> tuple[np.ndarray, np.ndarray, np.ndarray | None] | None:
    """A subject's frontal photo (lit from azimuth 0), its face ellipse and its face mesh's points (None where no
    mesh is found); None where the photo is absent."""
    path = find_file(yale, subject, 0)
    if not path.is_file():
        return None
    frontal = read_grey(path)
    h, w = frontal.shape[:2]
    meshes = mesh.faces(frontal, (0, h, 0, w)) if mesh.available else []
    return frontal, ellipse((h, w)), (meshes[0] if meshes else None)


def grid_log_lum(rgb: np.ndarray) -> np.ndarray:
    lum = luminance(rgb)
    return np.log(cv2.resize(lum, (GRID, GRID), interpolation=cv2.INTER_AREA) + EPS)


def compare(source: np.ndarray, relit: np.ndarray, truth: np.ndarray, region: np.ndarray) -> dict:
    """Correlation and slope of the relit change on the truth's change, on the grid inside ``region``."""
    base = grid_log_lum(source)
    ours = (grid_log_lum(relit) - base)[region]
    real = (grid_log_lum(truth) - base)[region]
    da, db = ours - ours.mean(), real - real.mean()
    # relerr: |ours - truth's| / |truth's|, both centred, = sqrt(s^2 - 2 contrast + 1), s = contrast / corr: the
    # contrast counts any part of ours along the truth's change as strength; this counts what misses it too
    return {"corr": float((da * db).sum() / math.sqrt((da * da).sum() * (db * db).sum() + 1e-30)),
            "contrast": float((da * db).sum() / max((db * db).sum(), 1e-30)),
            "relerr": float(math.sqrt(((da - db) ** 2).sum() / max((db * db).sum(), 1e-30)))}


def fine_detail(rgb: np.ndarray) -> np.ndarray:
    """(H, W) the local RMS of the log luminance's fine detail (less its blur over ``DETAIL_SIGMA`` pixels)."""
    y = np.log(luminance(rgb) + EPS)
    d = y - cv2.GaussianBlur(y, (0, 0), DETAIL_SIGMA)
    return np.sqrt(cv2.blur(d * d, (DETAIL_BLOCK, DETAIL_BLOCK)))


def detail_shares(relit: np.ndarray, truth: np.ndarray, mask: np.ndarray) -> dict:
    """The blotches the sheets show, as shares of the face: "speckle", where the relit photo has more than twice the
    real photo's fine detail (``fine_detail``: noise multiplied, a seam), and "flat", less than half of it (texture
    lost), inside ``mask`` (the ellipse, eroded ``DETAIL_ERODE`` pixels)."""
    inner = cv2.erode((mask > 0.5).astype(np.uint8), np.ones((DETAIL_ERODE, DETAIL_ERODE), np.uint8)) > 0
    if not inner.any():
        return {"speckle": 0.0, "flat": 0.0}
    ours, real = fine_detail(relit)[inner], fine_detail(truth)[inner]
    return {"speckle": float(np.mean(ours > 2 * real)), "flat": float(np.mean(ours < 0.5 * real))}


def eye_region(points: np.ndarray, eye: tuple[int, ...], shape: tuple[int, int]) -> np.ndarray:
    """(H, W) bool: an eye's contour on the face mesh ``points`` (468, >= 2), filled and dilated."""
    reg = np.zeros(shape, np.uint8)
    cv2.fillConvexPoly(reg, cv2.convexHull(np.asarray(points)[list(eye), :2].astype(np.int32)), 1)
    return cv2.dilate(reg, np.ones((SOCKET_DILATE, SOCKET_DILATE), np.uint8)) > 0


def socket_ratio(relit: np.ndarray, truth: np.ndarray, face: np.ndarray, eye: np.ndarray) -> float:
    """The eye's socket over the face's mean luminance (linear) in ``relit``, over the same in ``truth``: 1 when the
    relit socket is as much darker than the face as the real one (a de-lit face's dark-side eye: faces9 / faces10)."""
    lr, lt = luminance(relit), luminance(truth)
    return float((lr[eye].mean() / lr[face].mean()) / (lt[eye].mean() / lt[face].mean()))


def sockets(rows: list[dict]) -> dict | None:
    """The de-light pairs' socket figures: mean |log| of ``socket_ratio`` for the eye on the photo's dark side and on
    its lit side, and how many dark-side sockets came out more than 1.5x too bright."""
    dark = [r["sockets"]["dark"] for r in rows if "sockets" in r]
    if not dark:
        return None
    lit = [r["sockets"]["lit"] for r in rows if "sockets" in r]
    return {"pairs": len(dark), "dark_mean_abs_log": float(np.mean(np.abs(np.log(dark)))),
            "dark_over_1.5x": int(sum(d > 1.5 for d in dark)), "lit_mean_abs_log": float(np.mean(np.abs(np.log(lit)))),
            "lit_median": float(np.median(lit))}


def find_file(yale: Path, subject: str, az: int, el: int = 0) -> Path:
    """The photo of ``subject`` lit from azimuth ``az`` (``MIRROR``: the one from -az, which ``read_grey`` flips)."""
    az = -az if MIRROR and az else az
    return yale / subject / f"{subject}_P00A{az:+04d}E{el:+03d}.png"


def median(rows: list[dict], method: str, key: str) -> float | None:
    vals = [r[method][key] for r in rows if r.get(method)]
    return float(np.median(vals)) if vals else None


def mean(rows: list[dict], method: str, key: str) -> float | None:
    vals = [r[method][key] for r in rows if r.get(method) and key in r[method]]
    return float(np.mean(vals)) if vals else None


def figures(rows: list[dict], method: str) -> dict:
    """The medians of the correlation and contrast, the means of the detail shares (``detail_shares``) and of the
    new edges' share (``new_edges``)."""
    return {**{k: median(rows, method, k) for k in ("corr", "contrast", "relerr")},
            **{k: mean(rows, method, k) for k in ("speckle", "flat", "edge")}}


def change_image(source: np.ndarray, out: np.ndarray) -> np.ndarray:
    """The change of log luminance as a grey picture: 0.5 = none, +-1.5 in log at the ends."""
    d = grid_log_lum(out) - grid_log_lum(source)
    g = np.clip(0.5 + d / 3.0, 0, 1)
    return np.repeat(cv2.resize(g, (source.shape[1], source.shape[0]), interpolation=cv2.INTER_NEAREST)[..., None],
                     3, axis=2)


def sheet(rows: list[dict], pictures: dict, path: Path, n: int = 8) -> None:
    worst = sorted(rows, key=lambda r: r["ours"]["corr"])[:n]
    lines = []
    for r in worst:
        src, ours, dpr, truth = pictures[r["id"]]
        tiles = [src, ours, dpr if dpr is not None else np.zeros_like(src), truth,
                 change_image(src, ours), change_image(src, truth)]
        line = (np.clip(np.hstack(tiles), 0, 1) * 255 + 0.5).astype(np.uint8)
        cv2.putText(line, f"{r['id']} r={r['ours']['corr']:.2f}", (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.4,
                    (255, 255, 0), 1)
        lines.append(line)
    img = np.vstack(lines)
    cv2.imwrite(str(path), cv2.cvtColor(img, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, 88])


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--yale", type=Path, default=shared_path("realdata", "yale"))
    p.add_argument("--models", type=Path, default=None)
    p.add_argument("--dpr", default=None, help="DPR repository (checkout or bare git dir); default: dpr_protocol's")
    p.add_argument("--no-dpr", action="store_true")
    p.add_argument("--cache", type=Path, default=Path("runs/dpr_cache"))
    p.add_argument("--subjects", nargs="*", default=None)
    p.add_argument("--no-mesh-occlusion", action="store_true",
                   help="the face mesh's own occlusion off (face_mesh.MESH_OCCLUSION; on by default since faces12)")
    p.add_argument("--no-mirror-dark", action="store_true",
                   help="a face's opening far darker than its mirror image not taken as shadow "
                        "(relight.shadow_fill.MIRROR_DARK; on by default since faces13)")
    p.add_argument("--no-rim-fill", action="store_true",
                   help="the deep shadow's fill off a face mesh keeps stage 1's albedo, not its rim's "
                        "(relight.shadow_rim.RIM_RANGE; on by default since faces15)")
    p.add_argument("--no-penumbra-cap", action="store_true",
                   help="the ratio cap only on a face mesh's skin, not in the penumbra around any deep shadow "
                        "(relight.shadow_fill.CAP_SHADOW_REACH; on by default since faces16)")
    p.add_argument("--own-light", choices=OWN_LIGHTS, default="today",
                   help="a measurement: the photo's own light replaced by an oracle built from Yale's lamp (own_light)")
    p.add_argument("--own-level", choices=OWN_LEVELS, default="meter",
                   help="which of today's own light's levels the oracle keeps (own_light; default: meter)")
    p.add_argument("--own-scale", type=float, default=1.0,
                   help="the own light (today's or the oracle's) multiplied by this (own_light; default: 1)")
    p.add_argument("--no-rim-shown", action="store_true",
                   help="the fill's rim albedo read in the penumbra too (shadow_rim.RIM_SHOWN; on since faces16)")
    p.add_argument("--mirror", action="store_true",
                   help="every photo flipped left-right and its azimuth negated (ids prefixed 'mirror:')")
    args = p.parse_args(argv)
    global MIRROR
    MIRROR = args.mirror
    if not (math.isfinite(args.own_scale) and args.own_scale > 0):
        p.error(f"--own-scale: expected a positive number, got {args.own_scale}")
    if args.no_rim_fill:
        shadow_rim.RIM_RANGE = None
    if args.no_penumbra_cap:
        shadow_fill.CAP_SHADOW_REACH = None
    if args.no_rim_shown:
        shadow_rim.RIM_SHOWN = None
    if args.no_mesh_occlusion:
        face_mesh_module.MESH_OCCLUSION = False
    if args.no_mirror_dark:
        shadow_fill.MIRROR_DARK = None
    if not args.yale.is_dir():
        print(missing(args.yale), file=sys.stderr)
        return 2
    with open(args.yale / "lights.csv") as f:
        subjects = sorted({row["subject"] for row in csv.DictReader(f)})
    subjects = args.subjects or subjects
    repo = None if args.no_dpr else dprp.DPRRepo.find(args.dpr)
    dpr = dprp.DPRNet(repo, args.cache) if repo is not None else None
    relighter = Relighter(RuntimeConfig(models=args.models, device="cpu"))
    mesh = FaceMesh(relighter.models_dir)
    args.out.mkdir(parents=True, exist_ok=True)

    rows, pictures = [], {}
    t0 = time.time()

    def run(task: str, subject: str, src_az: int, dst_az: int, source: np.ndarray, dec, truth: np.ndarray,
            points: np.ndarray | None = None) -> None:
        face = ellipse(source.shape[:2])
        region = cv2.resize(face, (GRID, GRID), interpolation=cv2.INTER_AREA) > 0.99
        light = lamp(dst_az)
        ours = relighter.relight(dec, light)
        row = {"id": f"{'mirror:' if MIRROR else ''}{task}:{subject}:{src_az:+d}->{dst_az:+d}", "task": task,
               "subject": subject,
               "source_az": src_az, "target_az": dst_az,
               "ours": {**compare(source, ours, truth, region), **detail_shares(ours, truth, face),
                        "edge": new_edges(source, ours, face, truth)}}
        theirs = None
        if dpr is not None:
            theirs = dpr.relight(source, dprp.ours_to_dpr(light, dc=DPR_DC))
            row["dpr"] = {**compare(source, theirs, truth, region), **detail_shares(theirs, truth, face),
                          "edge": new_edges(source, theirs, face, truth)}
        if points is not None and task == "delight" and abs(src_az) == SOCKET_AZ:  # negative: the image's right lit
            dark_eye, lit_eye = (RIGHT_EYE, LEFT_EYE) if src_az < 0 else (LEFT_EYE, RIGHT_EYE)
            row["sockets"] = {name: socket_ratio(ours, truth, face > 0, eye_region(points, eye, face.shape))
                              for name, eye in (("dark", dark_eye), ("lit", lit_eye))}
        seen, strength = sh.dominant_direction(dec.white_light[:, 0])  # the own light the change is taken from
        true = np.array(lamp_direction(src_az, 0.0))
        angle = None if seen is None else math.degrees(math.acos(float(np.clip(seen @ true, -1, 1))))
        row["own_light"] = {"angle": angle, "directionality": strength}
        rows.append(row)
        pictures[row["id"]] = (source, ours, theirs, truth)

    for subject in subjects:
        found = read_frontal(args.yale, subject, mesh)
        if found is None:
            continue
        frontal, mask, points = found  # points: the real frontal photo's eyes (socket_ratio)
        dec = own_light(relighter, relighter.decompose(frontal, mask), args.own_light, 0, level=args.own_level,
                        scale=args.own_scale)
        for a in RELIGHT_AZ:
            for az in (-a, a):
                path = find_file(args.yale, subject, az)
                if path.is_file():
                    run("relight", subject, 0, az, frontal, dec, read_grey(path))
        for a in DELIGHT_AZ:
            for az in (-a, a):
                path = find_file(args.yale, subject, az)
                if path.is_file():
                    side = read_grey(path)
                    side_dec = own_light(relighter, relighter.decompose(side, mask), args.own_light, az,
                                         level=args.own_level, scale=args.own_scale)
                    run("delight", subject, az, 0, side, side_dec, frontal, points)
        print(f"{subject}: {len(rows)} pairs, {time.time() - t0:.0f} s", flush=True)

    summary = {}
    for task in ("relight", "delight"):
        sel = [r for r in rows if r["task"] == task]
        summary[task] = {"pairs": len(sel)}
        for method in ("ours", "dpr"):
            summary[task][method] = figures(sel, method)
        for a in (RELIGHT_AZ if task == "relight" else DELIGHT_AZ):
            key = "target_az" if task == "relight" else "source_az"
            sub = [r for r in sel if abs(r[key]) == a]
            summary[task][f"|az| {a}"] = {m: figures(sub, m) for m in ("ours", "dpr")}
    summary["delight"]["sockets"] = sockets([r for r in rows if r["task"] == "delight"])
    run_of = {"mirror": args.mirror, "own_light": args.own_light, "own_level": args.own_level,
              "own_scale": args.own_scale}
    (args.out / "yale.json").write_text(json.dumps({**run_of, "summary": summary, "pairs": rows}, indent=1))
    sheet(rows, pictures, args.out / "yale_worst.jpg")
    sheet([r for r in rows if r["task"] == "delight"], pictures, args.out / "yale_worst_delight.jpg")
    fmt = lambda v: "  -  " if v is None else f"{v:5.3f}"  # noqa: E731
    cols = ("corr", "contrast", "relerr", "speckle", "flat", "edge")
    print(f"{'':22s} ours {' '.join(f'{c:>8s}' for c in cols)}   DPR {' '.join(f'{c:>8s}' for c in cols)}")
    for task, s in summary.items():
        for label, v in [("all", s), *[(k, s[k]) for k in s if k.startswith("|az|")]]:
            ours, dpr = (" ".join(f"{fmt(v[m][c]):>8s}" for c in cols) for m in ("ours", "dpr"))
            print(f"{task + ' ' + label:22s}      {ours}       {dpr}")
    sock = summary["delight"]["sockets"]
    if sock is not None:
        print(f"de-light from {SOCKET_AZ} deg, eye socket / face against the real photo's ({sock['pairs']} "
              f"pairs): dark side mean |log| {sock['dark_mean_abs_log']:.3f}, {sock['dark_over_1.5x']} over 1.5x; "
              f"lit side mean |log| {sock['lit_mean_abs_log']:.3f}, median {sock['lit_median']:.2f}")
    worst = sorted(rows, key=lambda r: r["ours"]["corr"])[:5]
    print("worst:", ", ".join(f"{r['id']} {r['ours']['corr']:.2f}" for r in worst))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
