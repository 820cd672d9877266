"""The deep-shadow fill's colour map on real photos (relight_rt.relight.fill_colour): how rough it is, and how much of
the lit pixels' vote the material rule keeps.

    python benchmarks/fill_colour_maps.py [--only p257,p080] [--save DIR] [--against DIR]
        [--people ../shared/realdata/people_masks]

For each photo of people_masks (given mask, at most 1000 px a side), relight_rt.relight.shadow_fill
``ShadowFill.shadow_weight`` once; over the fill's pixels (its weight > 0.5, network frame) the colour map
``lit_colour`` gave: ``roughness``, the 99th percentile of the largest step over R, G, B (colour at luminance 1) to the
right and lower neighbour, both in the fill (mottling); ``kept``, the share of the lit vote (trust x luminance) that
``fill_colour._pure`` keeps (1 before fill32). ``--save`` writes each map (npz) to DIR; ``--against`` compares with maps
saved by another checkout: the mean over the fill of the largest change over R, G, B, weighted by the fill, per photo,
the largest first. Evaluation data only: nothing of it goes into the repository.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from _shared import shared_path  # noqa: E402
from photo_faults import read_mask, read_rgb  # noqa: E402

import relight_rt  # noqa: E402
from relight_rt import RuntimeConfig  # noqa: E402
from relight_rt.relight import fill_colour, shadow_fill  # noqa: E402


def roughness(colour: np.ndarray, fill: np.ndarray) -> float | None:
    """The 99th percentile of the largest step over R, G, B between neighbours both in ``fill``."""
    steps = [np.abs(colour[:, 1:] - colour[:, :-1]).max(axis=-1)[fill[:, 1:] & fill[:, :-1]],
             np.abs(colour[1:] - colour[:-1]).max(axis=-1)[fill[1:] & fill[:-1]]]
    joined = np.concatenate(steps)
    return float(np.percentile(joined, 99)) if joined.size else None


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--people", type=Path, default=shared_path("realdata", "people_masks"))
    p.add_argument("--only", default=None, help="comma-separated photo names")
    p.add_argument("--save", type=Path, default=None, help="write each photo's map here (npz)")
    p.add_argument("--against", type=Path, default=None, help="compare with the maps another checkout saved")
    p.add_argument("--models", type=Path, default=None)
    args = p.parse_args(argv)
    folder = args.people / "photos"
    names = args.only.split(",") if args.only else sorted(f.stem for f in folder.glob("*.jpg"))
    relighter = relight_rt.open(RuntimeConfig(models=args.models, device="cpu"))
    seen: dict = {}
    inner = shadow_fill.lit_colour

    def spy(rgb, luma, trust, albedo, sigma):
        out = inner(rgb, luma, trust, albedo, sigma)
        seen.update(luma=luma, trust=trust, albedo=albedo, out=out)
        return out

    shadow_fill.lit_colour = spy
    if args.save:
        args.save.mkdir(parents=True, exist_ok=True)
    rough: dict = {}
    changed = []
    for name in names:
        rgb = read_rgb(folder / f"{name}.jpg", 1000)
        dec = relighter.decompose(rgb, read_mask(folder / f"{name}_mask.png", rgb.shape[:2]))
        seen.clear()
        found = relighter._factor.fill.shadow_weight(dec)
        if found is None or "out" not in seen:
            continue
        w, colour = found[0], seen["out"]
        fill = w > 0.5
        vote = seen["trust"] * seen["luma"]
        pure = getattr(fill_colour, "_pure", None)  # (absent before fill32: every vote kept)
        kept = float((vote * pure(fill_colour._chroma(seen["albedo"]))).sum() / vote.sum()) if pure else 1.0
        rough[name] = roughness(colour, fill)
        text = "-" if rough[name] is None else f"{rough[name]:.3f}"
        print(f"{name}: roughness p99 {text}, kept {kept:.3f}, fill {int(fill.sum())} px", flush=True)
        if args.save:
            np.savez_compressed(args.save / f"{name}.npz", colour=colour, w=w)
        if args.against and (args.against / f"{name}.npz").is_file() and fill.sum() >= 50:
            other = np.load(args.against / f"{name}.npz")
            step = np.abs(other["colour"] - colour).max(axis=-1)
            changed.append((float((step * w)[fill].mean()), name))
    got = [v for v in rough.values() if v is not None]
    if got:
        print(f"roughness p99: median {np.median(got):.3f} over {len(got)} photos")
    for change, name in sorted(changed, reverse=True)[:10]:
        print(f"changed most: {name} {change:.4f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
