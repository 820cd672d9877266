"""Halo of the old background around cut-outs: before (coarse matte, the photo's own colour) and after (edge
refinement + decontaminated colour), per photo; and a contact sheet of hair edges at 100 %.

    python benchmarks/halo_eval.py --cache /tmp/people [--git OWNER/NAME=GITDIR ...] [--sheet docs/matting_sheet.jpg]

For every photo of benchmarks/people_photos.py, the automatic matte of its largest person, composited over
pure green and over pure magenta:
- band: the pixels 1-15 px inside the alpha = 0.5 outline (distance transform), scaled to the photo
  (x long side / 1000, at least 1-15 px);
- backdrop: how far the band's mean colour moves between the two backdrops, as a fraction of
  |green - magenta| (0: the band shows none of the backdrop; the share of backdrop the band's alpha lets through);
- old background: how far the band's own colour (its mean over green, the backdrop's share taken out) lies from
  the person's colour just further in (16-30 px inside) toward the old background just outside (1-15 px outside,
  in the photo), in 8-bit levels along the line between them (0: none of the old background; "-" where those
  two colours differ by less than 12 levels, so that there is no direction to measure along).
"before" is PersonMatter(edges=False) with the photo's own colour (the composite before issue 33), "after"
that matte refined in its edge band (relight_rt.image.matte_edges, what PersonMatter() does by default) with the colour
of relight_rt.image.foreground.estimate_foreground. Also times the refinement and decontamination together.

The sheet (only photos whose licence allows: public-domain and scikit-image samples) shows, for each photo,
a 100 % crop at the top of the head: before | after over green, then before | after over magenta.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

from people_photos import gather, parse_gitdirs  # noqa: E402

from relight_rt.cli.mask import read_photo  # noqa: E402
from relight_rt.image.foreground import estimate_foreground  # noqa: E402
from relight_rt.person import matting as M  # noqa: E402

GREEN = np.array([0.0, 1.0, 0.0], np.float32)
MAGENTA = np.array([1.0, 0.0, 1.0], np.float32)
SHEET_PHOTOS = ("astronaut", "grace_hopper", "dpr_obama", "cameraman")  # public domain / scikit-image's samples


def bands(alpha: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(band 1-15 px inside, 16-30 px inside, 1-15 px outside) the alpha = 0.5 outline, scaled to the photo."""
    s = max(1.0, max(alpha.shape) / 1000)
    inside = (alpha >= 0.5).astype(np.uint8)
    d_in = cv2.distanceTransform(inside, cv2.DIST_L2, 5)
    d_out = cv2.distanceTransform(1 - inside, cv2.DIST_L2, 5)
    return (
        (d_in >= 1 * s) & (d_in <= 15 * s),
        (d_in >= 16 * s) & (d_in <= 30 * s),
        (d_out >= 1 * s) & (d_out <= 15 * s),
    )


def halo(rgb: np.ndarray, alpha: np.ndarray, colour: np.ndarray) -> tuple[float, float]:
    """(backdrop share, old-background share) of the band (module docstring)."""
    band, deeper, outside = bands(alpha)
    a = alpha[..., None]
    over_g = a * colour + (1 - a) * GREEN
    over_m = a * colour + (1 - a) * MAGENTA
    moved = float(np.linalg.norm(over_g[band].mean(0) - over_m[band].mean(0)) / np.linalg.norm(GREEN - MAGENTA))
    a_band = float(alpha[band].mean())
    person_band = (over_g[band].mean(0) - (1 - a_band) * GREEN) / max(a_band, 1e-6)  # the person's own share
    inner = rgb[deeper].mean(0) if deeper.any() else rgb[band].mean(0)
    old = rgb[outside].mean(0)
    d = old - inner
    n = float(np.linalg.norm(d))
    if n < 12 / 255:
        return moved, float("nan")
    return moved, float(np.dot(person_band - inner, d / n) * 255)


def hair_crop(alpha: np.ndarray, size: int) -> tuple[int, int]:
    """Top-left (y, x) of a size x size crop centred on the top of the person's outline."""
    ys, xs = np.nonzero(alpha >= 0.5)
    top = int(ys.min())
    cx = int(np.median(xs[ys < top + max(4, alpha.shape[0] // 50)]))
    y0 = int(np.clip(top - size // 3, 0, max(alpha.shape[0] - size, 0)))
    x0 = int(np.clip(cx - size // 2, 0, max(alpha.shape[1] - size, 0)))
    return y0, x0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cache", type=Path, default=Path("/tmp/relight_rt_people"))
    ap.add_argument("--git", action="append", default=[], metavar="OWNER/NAME=GITDIR")
    ap.add_argument("--sheet", type=Path, help="write the contact sheet (JPEG) here")
    ap.add_argument("--crop", type=int, default=160, help="crop side in pixels (100 %%)")
    args = ap.parse_args()
    before_m = M.PersonMatter(edges=False)
    rows, tiles = [], []
    print("| photo | size | backdrop share before -> after | toward the old background (levels) before -> after | "
          "refine + decontaminate ms |")  # fmt: skip
    print("|---|---|---|---|---|")
    for photo, path in gather(args.cache, parse_gitdirs(args.git)):
        rgb = read_photo(path)
        try:
            a0 = before_m(rgb, photo.name)
        except Exception as exc:  # noqa: BLE001 (a photo where nobody is found is reported and skipped)
            print(f"| {photo.name} | - | {exc} | | |")
            continue
        t = time.perf_counter()
        a1 = M.refine_edges(rgb, a0)
        fg = estimate_foreground(rgb, a1)
        ms = 1000 * (time.perf_counter() - t)
        b = halo(rgb, a0, rgb)
        c = halo(rgb, a1, fg)
        rows.append((b, c))
        h, w = rgb.shape[:2]
        old = "-" if np.isnan(b[1]) else f"{b[1]:.1f} -> {c[1]:.1f}"
        print(f"| {photo.name} | {w}x{h} | {b[0]:.3f} -> {c[0]:.3f} | {old} | {ms:.0f} |", flush=True)
        if args.sheet is not None and photo.name in SHEET_PHOTOS:
            n = min(args.crop, h, w)
            y0, x0 = hair_crop(a1, n)
            cells = []
            for back in (GREEN, MAGENTA):
                for a, col in ((a0, rgb), (a1, fg)):
                    comp = a[..., None] * col + (1 - a[..., None]) * back
                    cells.append(comp[y0 : y0 + n, x0 : x0 + n])
            tile = np.concatenate([np.pad(c, ((2, 2), (2, 2), (0, 0)), constant_values=1.0) for c in cells], axis=1)
            tiles.append((photo.name, tile))
    r = np.array([[*b, *c] for b, c in rows])
    ok = ~np.isnan(r[:, 1]) & ~np.isnan(r[:, 3])  # both mattes have a direction to measure along
    print(f"\nmean over {len(rows)} photos: backdrop share {r[:, 0].mean():.3f} -> {r[:, 2].mean():.3f}; ", end="")
    print(f"toward the old background ({ok.sum()} photos) {r[ok, 1].mean():.1f} -> {r[ok, 3].mean():.1f} levels")
    if args.sheet is not None and tiles:
        width = max(t.shape[1] for _, t in tiles)
        out = []
        for name, t in tiles:
            label = np.full((22, width, 3), 255, np.uint8)
            cv2.putText(label, f"{name}: before | after over green, before | after over magenta (100 %)", (4, 16),
                        cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1)  # fmt: skip
            pad = np.pad(t, ((0, 0), (0, width - t.shape[1]), (0, 0)), constant_values=1.0)
            out += [label.astype(np.float32) / 255, pad]
        sheet = (np.clip(np.concatenate(out, axis=0), 0, 1) * 255).round().astype(np.uint8)
        cv2.imwrite(str(args.sheet), cv2.cvtColor(sheet, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, 92])
        print(f"wrote {args.sheet}")


if __name__ == "__main__":
    main()
