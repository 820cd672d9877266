"""Near-neutral darks under white lamps: how often dark, near-grey pixels of a photo come out coloured (issue 48's
first look: dark hair blue-grey, a black sweater teal under a white lamp).

    python benchmarks/neutral_darks.py [--n 30] [--seed 48] [--people ../shared/realdata/people_masks]
                                       [--against ROOT] [--save DIR]

The photos of ``first_look.py`` (the same ``--n`` and ``--seed``: both halves, the automatic matte, the background
kept), relit under the white lamps LEFT and RIGHT (benchmarks/real_photos.py) and window-left. On the person
(alpha > 0.5), the pixels of the photo with Lab L* < 35 and C* < 10 (per pixel) are the near-neutral darks; a white
light should change their brightness, not their colour. Per photo and light, the share of them whose relit
(a*, b*) hue turned more than 20 degrees or whose C* rose more than 8 (``fault``, the brief's figure; the hue of a
pixel of C* ~1 turns with JPEG's noise, so it counts much that no one sees), and the share whose C* rose more than
8 or that turned more than 20 degrees at a relit C* of 6 or more (``seen``), and ``seen`` among the pixels whose
photo hue is not warm (Lab hue outside ``WARM``: the blue-grey, teal, violet and magenta casts; a warm dark made
browner reads as its material). Prints the mean over the photos per half and light; writes nothing unless
``--save``.

``--against ROOT`` (another checkout's root, e.g. ``git archive main`` unpacked): its relit images of the same photos
(this script run with ROOT's ``relight_rt`` and ``--save`` in a subprocess, which prints that checkout's table first)
are compared with this checkout's pixel by pixel, for warm colour lost: on the person, the pixels whose relit C* is
more than ``LOSS`` below ROOT's, as a share of the photo's warm person pixels, (a) warm by the photo's hue alone (Lab
hue within ``WARM``) and (b) warm in fact: also a photo C* of ``WARM_C`` or more (below it a pixel has no hue of its
own) and ROOT's relit hue within ``WARM`` (a pixel ROOT relit cool had no warm colour to lose). Prints the worst
photo and light and the mean over the photo-lights of each.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np
from real_photos import LEFT, RIGHT

# isort: split
from _shared import shared_path
from first_look import picked_photos, read_rgb

import relight_rt
from relight_rt import RuntimeConfig

LIGHTS = ("LEFT", "RIGHT", "window-left")
WARM = (15.0, 95.0)  # Lab hue angles (degrees) of a warm dark: skin, brown hair (``cool``: the others)
LOSS = 3.0  # a relit C* this much below the other checkout's counts as warm colour lost (``--against``)
WARM_C = 4.0  # (b): a photo C* below it has no hue of its own


def lab(rgb: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(np.clip(rgb, 0, 1).astype(np.float32), cv2.COLOR_RGB2Lab)


def shares(photo: np.ndarray, relit: np.ndarray, where: np.ndarray) -> tuple[float, float, float]:
    """(fault, seen, seen among the cool or magenta ones) over the near-neutral dark pixels ``where`` (module
    docstring)."""
    p, r = lab(photo)[where], lab(relit)[where]
    c0, c1 = np.hypot(p[:, 1], p[:, 2]), np.hypot(r[:, 1], r[:, 2])
    h0 = np.arctan2(p[:, 2], p[:, 1])
    turn = np.degrees(np.abs(np.angle(np.exp(1j * (np.arctan2(r[:, 2], r[:, 1]) - h0)))))
    rise = c1 - c0 > 8
    seen = rise | ((turn > 20) & (c1 >= 6))
    cool = ~((np.degrees(h0) % 360 >= WARM[0]) & (np.degrees(h0) % 360 <= WARM[1]))
    return float(np.mean((turn > 20) | rise)), float(np.mean(seen)), float(np.mean(seen[cool])) if cool.any() else 0.0


def warm_lost(photo: np.ndarray, relit: np.ndarray, other: np.ndarray, person: np.ndarray
              ) -> tuple[tuple[float, int], tuple[float, int]]:
    """((share, pixels) by the photo's hue alone, (share, pixels) warm in fact) of the warm person pixels whose relit
    C* is more than ``LOSS`` below ``other``'s (module docstring: ``--against``)."""
    p, r, o = lab(photo)[person], lab(relit)[person], lab(other)[person]
    inside = lambda q: (np.degrees(np.arctan2(q[:, 2], q[:, 1])) % 360 >= WARM[0]) & (  # noqa: E731
        np.degrees(np.arctan2(q[:, 2], q[:, 1])) % 360 <= WARM[1])
    lost = np.hypot(o[:, 1], o[:, 2]) - np.hypot(r[:, 1], r[:, 2]) > LOSS
    warm = inside(p)
    fact = warm & (np.hypot(p[:, 1], p[:, 2]) >= WARM_C) & inside(o)
    return tuple((float(np.mean(lost[m])) if m.any() else 0.0, int(np.sum(lost & m))) for m in (warm, fact))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--people", type=Path, default=shared_path("realdata", "people_masks"))
    ap.add_argument("--n", type=int, default=30)
    ap.add_argument("--seed", type=int, default=48)
    ap.add_argument("--models", type=Path, default=None)
    ap.add_argument("--against", type=Path, default=None, help="another checkout's root: warm colour lost against it")
    ap.add_argument("--save", type=Path, default=None, help="write the relit images here (float16 .npy)")
    args = ap.parse_args(argv)
    saved = None
    if args.against is not None:
        saved = Path(tempfile.mkdtemp(prefix="neutral_darks_"))
        # ROOT's relight_rt imported before this script runs: real_photos puts this checkout first on sys.path
        start = ("import runpy, sys; sys.path[:0] = sys.argv[1:3]; import relight_rt; sys.argv = sys.argv[3:]; "
                 "runpy.run_path(sys.argv[0], run_name='__main__')")
        command = [sys.executable, "-c", start, str(args.against.resolve()), str(Path(__file__).resolve().parent),
                   str(Path(__file__).resolve()), "--people", str(args.people), "--n", str(args.n), "--seed",
                   str(args.seed), "--save", str(saved)]
        command += [] if args.models is None else ["--models", str(args.models)]
        print(f"against {args.against}:", flush=True)
        subprocess.run(command, check=True)
        print("this checkout:", flush=True)
    if args.save is not None:
        args.save.mkdir(parents=True, exist_ok=True)
        print(f"relight_rt: {Path(relight_rt.__file__).parent}", flush=True)
    found = picked_photos(args.people, args.n, args.seed)
    if found is None:
        return 2
    folder, chosen, halves = found
    relighter = relight_rt.open(RuntimeConfig(models=args.models, device="cpu"))
    table: dict = {}
    lost: list = []  # (name, light, (share, pixels) by hue, (share, pixels) in fact)
    for name in chosen:
        rgb = read_rgb(folder / f"{name}.jpg")
        dec = relighter.decompose(rgb)
        L = lab(rgb)
        where = (np.asarray(dec.mask) > 0.5) & (L[..., 0] < 35) & (np.hypot(L[..., 1], L[..., 2]) < 10)
        if not where.any() and saved is None and args.save is None:
            continue
        row = []
        for light in LIGHTS:
            relit = np.asarray(relighter.relight(dec, {"LEFT": LEFT, "RIGHT": RIGHT}.get(light, light)), np.float32)
            row.append(shares(rgb, relit, where))
            if args.save is not None:
                np.save(args.save / f"{name}_{light}.npy", relit.astype(np.float16))
            if saved is not None:
                other = np.load(saved / f"{name}_{light}.npy").astype(np.float32)
                lost.append((name, light, *warm_lost(rgb, relit, other, np.asarray(dec.mask) > 0.5)))
        if not where.any():  # relit for the warm check only
            continue
        table[name] = (halves[name], row)
        figures = ", ".join(f"{n} {f:.3f}/{s:.3f}/{c:.3f}" for n, (f, s, c) in zip(LIGHTS, row, strict=True))
        print(f"{name} ({halves[name]}): {figures}", flush=True)
    for half in ("A", "B", "AB"):
        rows = [r for h, r in table.values() if h in half]
        if rows:
            mean = np.mean(np.array(rows), axis=0)
            print(f"half {half} ({len(rows)} photos) fault / seen / seen cool: "
                  + ", ".join(f"{n} {f:.4f} / {s:.4f} / {c:.4f}" for n, (f, s, c) in zip(LIGHTS, mean, strict=True)))
    fact = f"(b) warm in fact (photo C* >= {WARM_C:g}, the other's relit hue warm)"
    for k, what in ((2, "(a) by the photo's hue"), (3, fact)):
        if lost:
            name, light, *worst = max(lost, key=lambda r: r[k][0])
            print(f"warm person pixels whose relit C* fell by > {LOSS:g} against {args.against}, {what}: worst "
                  f"{name} {light} {worst[k - 2][0]:.2%} ({worst[k - 2][1]} px), next "
                  + ", ".join(f"{r[0]} {r[1]} {r[k][0]:.2%} ({r[k][1]})"
                              for r in sorted(lost, key=lambda r: -r[k][0])[1:4])
                  + f"; mean {np.mean([r[k][0] for r in lost]):.3%}")
    if saved is not None:
        shutil.rmtree(saved)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
