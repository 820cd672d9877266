"""A photographer's first look: sheets of relit web photos nobody here chose, for a person to judge (issue 48).

    python benchmarks/first_look.py --out /tmp/look [--n 30] [--seed 48] [--people ../shared/realdata/people_masks]

Picks ``--n`` photos of ``people_masks/photos`` by a fixed seed over both halves (``people_masks_eval.half_of``: A is
the half thresholds are tuned on, B the checked one; the listing says which each photo is in) and relights each as
``relight-rt relight`` does by default: the public API, the automatic matte (no mask given), the background kept.
Lights: the white side lamps LEFT and RIGHT (benchmarks/real_photos.py), then the presets night, rim, campfire and
window-left (by name, so their own exposure applies). Writes to ``--out`` (keep it out of the repository: the
photos are evaluation only):

- ``NAME_sheet.png``: input | LEFT | RIGHT | night over rim | campfire | window-left | the matte's outline (alpha
  0.5, magenta) on the input, each tile at most ``--tile`` px tall;
- ``NAME_face.png``: the largest face's head box at 100 % (input | LEFT | RIGHT | window-left), where a face mesh
  was found (the Decomposition's meshes, a group's people included); else the head pass's box;
- ``look.json``: the photos, their halves, the sizes, whether a face crop was written, and per light the mean
  change in EV of the person (alpha > 0.5), the share of the person's pixels clipped (any channel >= 254/255), and
  ``halo``: on the matte's soft pixels outside its outline whose colour is the plain background beside them (the
  photo shows no person there), the share the light changed by more than 10 levels and the mean change: the
  person's new light spread past the edge the photo shows; ``inner``: the same on the matte's pixels inside its
  outline (alpha >= 0.5, within ``INNER`` px of it) whose colour is the plain background's (``inner_plain``): the
  background the matte holds, changed as the person is (inner26). The summary prints their median and mean over the
  photos per light, then the mean and median over the photos and lights per half (A, B, both).

It measures nothing a photographer would judge; it puts the pictures where one can look at them.
"""

from __future__ import annotations

import argparse
import json
import random
import sys
import time
from pathlib import Path

import cv2
import numpy as np

# real_photos puts this checkout (and benchmarks/) first on sys.path: the relight_rt imported below is this one
from real_photos import LEFT, RIGHT, luminance

# isort: split
from _shared import missing, shared_path
from people_masks_eval import half_of

import relight_rt
from relight_rt import RuntimeConfig

LIGHTS = ("LEFT", "RIGHT", "night", "rim", "campfire", "window-left")
FACE_LIGHTS = ("LEFT", "RIGHT", "window-left")
REACH = 6  # halo: how far (px) the solid person and background are looked for beside a soft pixel
CLOSE, APART = 0.1, 0.02  # ... plain background: within sqrt(CLOSE) |F - B| of B, where |F - B|^2 >= APART
STEP = 10 / 255  # ... changed: by more than this
INNER = 6  # inner halo: the matte's pixels at alpha >= 0.5 within this many px of its 0.5 outline ...
INNER_REACH = 12  # ... their plain background's colour and the person's, looked for this far (px)


def pick(names: list[str], n: int, seed: int) -> list[str]:
    """``n`` names drawn by ``seed`` from all of them (both halves), in sorted order."""
    return sorted(random.Random(seed).sample(sorted(names), min(n, len(names))))


def picked_photos(people: Path, n: int, seed: int) -> tuple[Path, list[str], dict[str, str]] | None:
    """The photos folder of ``people``, ``n`` of its photo names drawn by ``seed`` (``pick``) and every name's half
    (``people_masks_eval.half_of``); None, said on stderr, when the folder is absent."""
    folder = people / "photos"
    if not folder.is_dir():
        print(missing(folder), file=sys.stderr)
        return None
    names = [f.stem for f in folder.glob("*.jpg")]
    return folder, pick(names, n, seed), half_of(names)


def read_rgb(path: Path) -> np.ndarray:
    bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if bgr is None:
        raise FileNotFoundError(path)
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB).astype(np.float32) / 255


def to_bgr8(rgb: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(np.round(np.clip(rgb, 0, 1) * 255).astype(np.uint8), cv2.COLOR_RGB2BGR)


def meshes(dec) -> list[np.ndarray]:
    """Every face mesh of a Decomposition and its people, (468, 3) in the photo's pixels (x, y, z)."""
    out = [np.asarray(m) for m in (dec.face_meshes or ())]
    for person in dec.people:
        oy, ox = person.origin
        out += [np.asarray(m) + np.array([ox, oy, 0.0]) for m in (person.face_meshes or ())]
    return out


def head_box(dec, shape: tuple[int, int]) -> tuple[int, int, int, int] | None:
    """(y0, y1, x0, x1): the largest face mesh's box grown to take in hair and chin; else the head pass's box."""
    found = meshes(dec)
    h, w = shape
    if found:
        pts = max(found, key=lambda m: np.ptp(m[:, 0]) * np.ptp(m[:, 1]))
        x0, x1 = pts[:, 0].min(), pts[:, 0].max()
        y0, y1 = pts[:, 1].min(), pts[:, 1].max()
        cx, cy, side = (x0 + x1) / 2, (y0 + y1) / 2 - 0.1 * (y1 - y0), 1.6 * max(x1 - x0, y1 - y0)
        box = (cy - side / 2, cy + side / 2, cx - side / 2, cx + side / 2)
    elif dec.head_box is not None:
        box = dec.head_box
    else:
        return None
    y0, y1, x0, x1 = (int(round(v)) for v in box)
    y0, y1, x0, x1 = max(0, y0), min(h, y1), max(0, x0), min(w, x1)
    return (y0, y1, x0, x1) if y1 - y0 >= 16 and x1 - x0 >= 16 else None


def label(tile: np.ndarray, text: str) -> np.ndarray:
    out = tile.copy()
    cv2.putText(out, text, (4, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 3, cv2.LINE_AA)
    cv2.putText(out, text, (4, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (255, 255, 255), 1, cv2.LINE_AA)
    return out


def row(tiles: list[tuple[str, np.ndarray]], height: int | None) -> np.ndarray:
    """Tiles side by side, each scaled to ``height`` (None: as they are), labelled, with a 4-px gap."""
    out = []
    for text, t in tiles:
        if height is not None and t.shape[0] != height:
            k = height / t.shape[0]
            t = cv2.resize(t, (max(1, round(t.shape[1] * k)), height), interpolation=cv2.INTER_AREA)
        out += [label(t, text), np.full((t.shape[0], 4, 3), 128, np.uint8)]
    return np.concatenate(out[:-1], axis=1)


def grid(tiles: list[tuple[str, np.ndarray]], height: int, columns: int = 4) -> np.ndarray:
    """Rows of ``columns`` tiles (see ``row``), stacked with a 4-px gap."""
    rows = [row(tiles[i:i + columns], height) for i in range(0, len(tiles), columns)]
    width = max(r.shape[1] for r in rows)
    rows = [np.pad(r, ((0, 4), (0, width - r.shape[1]), (0, 0)), constant_values=128) for r in rows]
    return np.concatenate(rows, axis=0)[:-4]


def outline(rgb: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """The input with the matte's 0.5 contour drawn in magenta (BGR 8-bit)."""
    out = to_bgr8(rgb)
    contours, _ = cv2.findContours((alpha > 0.5).astype(np.uint8), cv2.RETR_LIST, cv2.CHAIN_APPROX_NONE)
    cv2.drawContours(out, contours, -1, (255, 0, 255), max(1, round(max(rgb.shape[:2]) / 500)))
    return out


def side_colour(picture: np.ndarray, where: np.ndarray, reach: int) -> tuple[np.ndarray, np.ndarray]:
    """The mean colour of ``picture`` over ``where`` in a (2 reach + 1)^2 box around each pixel, and whether any
    such pixel lies in the box."""
    w = where.astype(np.float32)
    k = (2 * reach + 1, 2 * reach + 1)
    n = cv2.boxFilter(w, -1, k, normalize=False)
    mean = cv2.boxFilter(picture * w[..., None], -1, k, normalize=False) / np.maximum(n, 1e-6)[..., None]
    return mean, n > 0.5


def plain_background(photo: np.ndarray, alpha: np.ndarray, reach: int = REACH) -> np.ndarray:
    """The matte's soft pixels outside its outline (0 < alpha < 0.5) whose colour is the plain background's: within
    ``CLOSE`` of the mean solid background (alpha 0) within ``reach`` px, measured against how far the solid person
    (alpha 1) lies from it, where the two differ (|F - B|^2 >= ``APART``)."""
    b, has_b = side_colour(photo, alpha <= 0, reach)
    f, has_f = side_colour(photo, alpha >= 1, reach)
    apart = ((f - b) ** 2).sum(axis=2)
    near = ((photo - b) ** 2).sum(axis=2)
    return (alpha > 0) & (alpha < 0.5) & has_b & has_f & (apart >= APART) & (near <= CLOSE * apart)


def inner_plain(photo: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """The matte's pixels inside its outline (alpha >= 0.5) within ``INNER`` px of it whose colour is the plain
    background's: within ``CLOSE`` of the mean solid background (alpha 0) within ``INNER_REACH`` px, measured against
    how far the person lies from it (``APART``). The person's colour is the mean over the solid matte deeper than
    ``INNER`` px inside the outline (nearer it is what this looks for: background the matte holds); a thin limb
    without such a core is not measured. Colour alone: a person's own edge as pale as a pale backdrop counts too
    (benchmarks/shown_edge_landing.py checks against the service masks)."""
    inside = (alpha >= 0.5).astype(np.uint8)
    depth = cv2.distanceTransform(np.pad(inside, 1, constant_values=1), cv2.DIST_L2, 3)[1:-1, 1:-1]
    b, has_b = side_colour(photo, alpha <= 0, INNER_REACH)
    f, has_f = side_colour(photo, (alpha >= 1) & (depth > INNER), INNER_REACH)
    apart = ((f - b) ** 2).sum(axis=2)
    near = ((photo - b) ** 2).sum(axis=2)
    return (inside > 0) & (depth <= INNER) & has_b & has_f & (apart >= APART) & (near <= CLOSE * apart)


def halo(photo: np.ndarray, alpha: np.ndarray, relit: np.ndarray, plain: np.ndarray) -> dict:
    """The relit picture's change on ``plain`` (``plain_background``'s pixels): a change there is the person's light
    spread past the edge the photo shows (a halo). Share changed by more than ``STEP``, and the mean change, in
    8-bit levels (largest channel)."""
    n = int(plain.sum())
    if n == 0:
        return {"pixels": 0, "share": 0.0, "mean": 0.0}
    d = np.abs(relit - photo).max(axis=2)[plain]
    return {"pixels": n, "share": float((d > STEP).mean()), "mean": float(255 * d.mean())}


def look_at(relighter, path: Path, out: Path, tile: int) -> dict:
    rgb = read_rgb(path)
    dec = relighter.decompose(rgb)  # no mask: the automatic matte, as relight-rt relight
    alpha = np.asarray(dec.mask)
    person = alpha > 0.5
    y_in = float(luminance(rgb)[person].mean()) if person.any() else 0.0
    relit: dict[str, np.ndarray] = {}
    plain, inner = plain_background(rgb, alpha), inner_plain(rgb, alpha)
    figures: dict = {}
    for name in LIGHTS:
        light = {"LEFT": LEFT, "RIGHT": RIGHT}.get(name, name)
        img = np.asarray(relighter.relight(dec, light), dtype=np.float32)
        relit[name] = img
        if person.any():
            y = float(luminance(img)[person].mean())
            figures[name] = {"ev": float(np.log2(max(y, 1e-8) / max(y_in, 1e-8))),
                             "clipped": float((img[person].max(axis=1) >= 254 / 255).mean()),
                             "halo": halo(rgb, alpha, img, plain), "inner": halo(rgb, alpha, img, inner)}
    tiles = [("input", to_bgr8(rgb)), *[(n, to_bgr8(relit[n])) for n in LIGHTS], ("matte", outline(rgb, alpha))]
    cv2.imwrite(str(out / f"{path.stem}_sheet.png"), grid(tiles, min(tile, rgb.shape[0])))
    box = head_box(dec, rgb.shape[:2])
    if box is not None:
        y0, y1, x0, x1 = box
        crops = [("input", to_bgr8(rgb[y0:y1, x0:x1]))] + [(n, to_bgr8(relit[n][y0:y1, x0:x1])) for n in FACE_LIGHTS]
        cv2.imwrite(str(out / f"{path.stem}_face.png"), row(crops, None))
    return {"size": list(rgb.shape[:2]), "person_share": float(person.mean()), "face_box": box,
            "people": len(dec.people), "lights": figures}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, required=True, help="where the sheets go (not the repository)")
    p.add_argument("--people", type=Path, default=shared_path("realdata", "people_masks"))
    p.add_argument("--n", type=int, default=30)
    p.add_argument("--seed", type=int, default=48)
    p.add_argument("--tile", type=int, default=420, help="a sheet tile's largest height in pixels")
    p.add_argument("--models", type=Path, default=None)
    p.add_argument("--only", default=None, help="comma-separated photo names (of the pick): these only")
    args = p.parse_args(argv)
    found = picked_photos(args.people, args.n, args.seed)
    if found is None:
        return 2
    folder, chosen, halves = found
    if args.only:
        chosen = [n for n in chosen if n in set(args.only.split(","))]
    args.out.mkdir(parents=True, exist_ok=True)
    relighter = relight_rt.open(RuntimeConfig(models=args.models, device="cpu"))
    t0 = time.time()
    photos: dict = {}
    for name in chosen:
        photos[name] = {"half": halves[name], **look_at(relighter, folder / f"{name}.jpg", args.out, args.tile)}
        print(f"{name} ({halves[name]}): {time.time() - t0:.0f} s", flush=True)
    (args.out / "look.json").write_text(json.dumps({"seed": args.seed, "n": args.n, "photos": photos}, indent=1))
    count = {h: sum(v["half"] == h for v in photos.values()) for h in "AB"}
    for kind in ("halo", "inner"):
        for name in LIGHTS:
            rows = [v["lights"][name][kind] for v in photos.values() if name in v["lights"]]
            rows = [r for r in rows if r["pixels"]]
            if rows:
                share, mean = [r["share"] for r in rows], [r["mean"] for r in rows]
                print(f"{name:12s} {kind}: share changed median {np.median(share):.3f} mean {np.mean(share):.3f}, "
                      f"change median {np.median(mean):.2f} mean {np.mean(mean):.2f} levels ({len(rows)} photos)")
        for half in ("A", "B", "AB"):
            rows = [r for v in photos.values() if v["half"] in half for n in LIGHTS if n in v["lights"]
                    for r in [v["lights"][n][kind]] if r["pixels"]]
            if rows:
                mean, share = [r["mean"] for r in rows], [r["share"] for r in rows]
                print(f"{kind} half {half}: change mean {np.mean(mean):.2f} median {np.median(mean):.2f} levels, "
                      f"share changed mean {np.mean(share):.3f} ({len(rows)} photo-lights)")
    print(f"{len(photos)} photos (A {count['A']}, B {count['B']}), "
          f"{sum(v['face_box'] is not None for v in photos.values())} face crops -> {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
