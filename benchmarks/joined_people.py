"""People the default matte takes together, relit as one body (today) or person by person on the same matte (task
joined27): which lights each face on the light's side, with which seams, giving the photo back, at what cost?

    PYTHONPATH=$PWD python benchmarks/joined_people.py --out /tmp/joined [--photos p091,p272] \
        [--extra /tmp/relight_rt_people/group_t1.jpg] [--limit N]

Photos: every people_masks photo (../shared/realdata: evaluation only, both halves) whose default matte
(RuntimeConfig(matting="auto")) holds two or more sure faces (the face graph's score >= 0.75, the matter's
``_JOINED_FACE``; two faces whose centres lie within the larger's width of each other count once: the matter's
``faces_side_by_side``; a face counts where the matte is >= 0.5 at its centre) and relights them as one body (the
matte's ``part_crops`` gives one share), and ``--extra`` photos found the same way.

"per person": the same Relighter with a matter that returns the default's matte unchanged and splits it by the
shares ``matting="all"`` finds (split26's cut along the photo's edges): share_i = part_i / matte_all where the
"all" matte is, the nearest person's elsewhere (blurred shares, normalised); part_i = default matte x share_i.
Same pixels, same matte; only the decomposition is per person (``Relighter._group``, as for ``--person all``).

Per photo and light (LEFT, RIGHT, window-left: side lights; campfire: from below in front), per variant:
(a) per sure face, its lit side: skin-coloured pixels (real_photos.skin_pixels) in the face's box, the mean change
    log(relit luminance) - log(photo luminance) of its left half minus its right half (split at the face box's
    middle); right when its sign is the light's side (LEFT and window-left: +, RIGHT: -). ``faces_right``: how
    many of the photo's sure faces are right; ``side``: the mean signed figure (positive: the light's side).
(b) the seam of benchmarks/group_seams.py (``seam``: the relit step beyond the photo's own across the line where
    the per-person shares meet, on pixels where the photo is one surface; mean over the line, 8-bit levels), the
    same line for both variants.
(c) the own light: ``relight(dec, dec)``'s largest change inside the matte (alpha >= 0.5), 8-bit levels.
(d) seconds: decompose, and the four lights.
Also (not in the criterion; what the first look saw on p091: one person dark all over, each face's halves right):
``spread``, the largest minus the smallest of the sure faces' mean change (skin pixels, log2: EV) under each side
light: a lamp far off lights people side by side alike; one body decomposed for two lights the far one dim.
Writes OUT/NAME.png (photo | LEFT | RIGHT | window-left | campfire; rows default, per person) and OUT/joined.json.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import cv2
import numpy as np

# real_photos puts this checkout (and benchmarks/) first on sys.path: the relight_rt imported below is this one
from real_photos import LEFT, RIGHT, luminance, skin_pixels

# isort: split
from _shared import shared_path
from group_seams import figure, line_pairs, seam_figures, tile

import relight_rt
from relight_rt import RelightError, RuntimeConfig
from relight_rt.image.io import read_image
from relight_rt.person.matting._parts import faces_side_by_side
from relight_rt.relight.people import cropped
from relight_rt.relight.relighter import Relighter

LIGHTS = {"LEFT": LEFT, "RIGHT": RIGHT, "window-left": "window-left", "campfire": "campfire"}
SIDE = {"LEFT": 1.0, "RIGHT": -1.0, "window-left": 1.0}  # the sign of (left - right) change a side light gives
SURE = 0.75  # the matter's _JOINED_FACE
EPS = 1e-3


class SplitMatter:
    """The default matte, each person's share taken from matting="all" (see the module's docstring)."""

    def __init__(self, default, everyone):
        self.default, self.everyone = default, everyone

    def __call__(self, rgb, name="image"):
        return self.default(rgb, name)

    def parts(self, rgb, name="image"):
        alpha, crops = self.part_crops(rgb, name)
        h, w = alpha.shape
        out = []
        for (y0, y1, x0, x1), s in crops:
            full = np.zeros((h, w), np.float32)
            full[y0:y1, x0:x1] = s
            out.append(full)
        return alpha, out

    def part_crops(self, rgb, name="image"):
        alpha, crops = self.default.part_crops(rgb, name)
        if len(crops) > 1:
            return alpha, crops
        all_alpha, all_crops = self.everyone.part_crops(rgb, name)
        if len(all_crops) < 2:
            return alpha, crops
        h, w = alpha.shape
        parts = np.zeros((len(all_crops), h, w), np.float32)
        for i, ((y0, y1, x0, x1), s) in enumerate(all_crops):
            parts[i, y0:y1, x0:x1] = s
        there = all_alpha > 1e-3
        share = np.where(there[None], parts / np.maximum(all_alpha, 1e-3)[None], 0)
        sigma = 0.05 * max(h, w)
        blurred = np.stack([cv2.GaussianBlur(s, (0, 0), sigma) for s in share]) + 1e-12
        blurred /= blurred.sum(axis=0, keepdims=True)
        share = np.where(there[None], share, blurred)
        share /= np.maximum(share.sum(axis=0, keepdims=True), 1e-12)
        return alpha, [cropped(alpha * s) for s in share]


def sure_faces(matter, rgb, alpha) -> list:
    faces = [f for f in matter.find_faces(rgb) if f.score >= SURE]
    h, w = alpha.shape
    inside = []
    for f in faces_side_by_side(faces):
        cx, cy = int((f.box[0] + f.box[2]) / 2), int((f.box[1] + f.box[3]) / 2)
        if 0 <= cx < w and 0 <= cy < h and alpha[cy, cx] >= 0.5:
            inside.append(f)
    return inside


def face_skin(rgb, face) -> np.ndarray:
    """A face's skin-coloured pixels in its box (the whole box where fewer than 50 are)."""
    h, w = rgb.shape[:2]
    x0, y0, x1, y1 = (int(round(v)) for v in face.box)
    region = np.zeros((h, w), bool)
    region[max(y0, 0) : min(y1, h), max(x0, 0) : min(x1, w)] = True
    skin = skin_pixels(rgb, region)
    return skin if skin.sum() >= 50 else region


def face_side(rgb, relit, face) -> float | None:
    h, w = rgb.shape[:2]
    x0, y0, x1, y1 = (int(round(v)) for v in face.box)
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
    region = np.zeros((h, w), bool)
    region[y0:y1, x0:x1] = True
    skin = skin_pixels(rgb, region)
    if skin.sum() < 50:
        skin = region
    d = np.log(luminance(relit) + EPS) - np.log(luminance(rgb) + EPS)
    mid = (x0 + x1) // 2
    left, right = skin.copy(), skin.copy()
    left[:, mid:] = False
    right[:, :mid] = False
    if not left.any() or not right.any():
        return None
    return float(d[left].mean() - d[right].mean())


def measure(rl: Relighter, rgb, faces, pairs, reach) -> dict:
    t0 = time.perf_counter()
    dec = rl.decompose(rgb)
    t1 = time.perf_counter()
    relit = {k: np.asarray(rl.relight(dec, light), np.float32) for k, light in LIGHTS.items()}
    t2 = time.perf_counter()
    back = np.asarray(rl.relight(dec, dec), np.float32)
    inside = np.asarray(dec.mask) >= 0.5
    out = {"people": len(dec.people) or 1, "decompose_s": round(t1 - t0, 2), "lights_s": round(t2 - t1, 2),
           "own_light_max": round(float(255 * np.abs(back[..., :3] - rgb[..., :3]).max(axis=2)[inside].max()), 2)}
    for k in LIGHTS:
        e = {"seam": seam_figures(rgb, relit[k], pairs, reach, np.asarray(dec.mask, np.float32))["seam"]}
        if k in SIDE:
            sides = [face_side(rgb, relit[k], f) for f in faces]
            sides = [SIDE[k] * s for s in sides if s is not None]
            d = np.log2(luminance(relit[k]) + EPS) - np.log2(luminance(rgb) + EPS)
            levels = [float(d[face_skin(rgb, f)].mean()) for f in faces]
            e.update(faces_right=int(sum(s > 0 for s in sides)), faces=len(sides),
                     side=round(float(np.mean(sides)), 3) if sides else None,
                     spread=round(max(levels) - min(levels), 2))
        out[k] = e
    return out, relit


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, type=Path)
    ap.add_argument("--people", type=Path, default=None, help="people_masks folder (default: ../shared/realdata)")
    ap.add_argument("--photos", default="", help="comma-separated people_masks names (default: every photo)")
    ap.add_argument("--extra", default=str(Path("/tmp/relight_rt_people/group_t1.jpg")))
    ap.add_argument("--limit", type=int, default=0)
    ap.add_argument("--height", type=int, default=300)
    args = ap.parse_args(argv)
    people = args.people or shared_path("realdata/people_masks")
    if args.photos:
        paths = [people / "photos" / f"{n}.jpg" for n in args.photos.split(",")]
    else:
        paths = sorted((people / "photos").glob("*.jpg"))
    paths += [Path(p) for p in args.extra.split(",") if p and Path(p).is_file()]
    if args.limit:
        paths = paths[: args.limit]
    args.out.mkdir(parents=True, exist_ok=True)
    default = relight_rt.open(RuntimeConfig(device="cpu"))
    everyone = relight_rt.open(RuntimeConfig(device="cpu", matting="all"))
    split = Relighter(RuntimeConfig(device="cpu"), matter=SplitMatter(default.matter, everyone.matter))
    matter = default.matter._get()
    report, looked, several = {}, 0, 0
    for path in paths:
        rgb = read_image(path)[..., :3]
        try:
            alpha, crops = matter.part_crops(rgb, path.stem)
        except RelightError:
            continue
        looked += 1
        faces = sure_faces(matter, rgb, alpha)
        if len(crops) > 1:
            several += 1
        if len(faces) < 2 or len(crops) > 1:
            continue
        _, parts = split.matter.parts(rgb, path.stem)
        if len(parts) < 2:
            print(f"{path.stem}: {len(faces)} faces, matting='all' finds one person: not split", flush=True)
            report[path.stem] = {"faces": len(faces), "split": False}
            continue
        reach = max(int(round(0.015 * max(rgb.shape[:2]))), 1)
        pairs = line_pairs(np.stack(parts), alpha)
        one, relit_one = measure(default, rgb, faces, pairs, reach)
        each, relit_each = measure(split, rgb, faces, pairs, reach)
        report[path.stem] = {"faces": len(faces), "split": True, "default": one, "per_person": each}
        rows = [np.hstack([tile(rgb, args.height)] + [tile(r[k], args.height) for k in LIGHTS])
                for r in (relit_one, relit_each)]
        cv2.imwrite(str(args.out / f"{path.stem}.png"), cv2.cvtColor(np.vstack(rows), cv2.COLOR_RGB2BGR))
        for k in LIGHTS:
            cv2.imwrite(str(args.out / f"{path.stem}_{k}_each.png"),
                        cv2.cvtColor((np.clip(relit_each[k], 0, 1) * 255).astype(np.uint8), cv2.COLOR_RGB2BGR))
        print(path.stem, json.dumps(report[path.stem]), flush=True)
    print(f"\n{looked} photos matted; {several} already relit person by person by default; "
          f"{len(report)} held >= 2 sure faces as one body ({sum(r['split'] for r in report.values())} split)")
    print(f"{'photo':10s} {'faces':>5s} " + " ".join(f"{k + ' right one/each':>22s}" for k in SIDE)
          + " " + " ".join(f"{k + ' seam':>16s}" for k in LIGHTS) + f" {'own max':>12s} {'s one/each':>12s}")
    for name, r in report.items():
        if not r["split"]:
            continue
        a, b = r["default"], r["per_person"]
        cells = [(f"{a[k]['faces_right']}/{b[k]['faces_right']} of {a[k]['faces']} "
                  f"({figure(a[k]['side'], 2)}/{figure(b[k]['side'], 2)})").rjust(22) for k in SIDE]
        seams = [f"{figure(a[k]['seam'], 2)}/{figure(b[k]['seam'], 2)}".rjust(16) for k in LIGHTS]
        own = f"{a['own_light_max']:.1f}/{b['own_light_max']:.1f}".rjust(12)
        secs = f"{a['decompose_s'] + a['lights_s']:.1f}/{b['decompose_s'] + b['lights_s']:.1f}".rjust(12)
        print(f"{name:10s} {r['faces']:5d} " + " ".join(cells) + " " + " ".join(seams) + f" {own} {secs}")
    print(f"\n{'photo':10s} " + " ".join(f"{k + ' spread one/each (EV)':>28s}" for k in SIDE))
    for name, r in report.items():
        if r["split"]:
            one, each = r["default"], r["per_person"]
            print(f"{name:10s} " + " ".join(f"{one[k]['spread']:.2f}/{each[k]['spread']:.2f}".rjust(28) for k in SIDE))
    (args.out / "joined.json").write_text(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
