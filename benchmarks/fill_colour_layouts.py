"""Whether the deep shadow's fill colour (relight_rt.relight.fill_colour, fill31) depends on where the network grid
falls: tests/runtime/relight/test_fill_colour.py's scene (a person lit green on its left, a deep shadow, lit skin on
its right) with the person's top row and the green's edge moved a pixel at a time.

    python benchmarks/fill_colour_layouts.py [--rows 17-24] [--edges 36-44] [--plain] [--where ROW,EDGE]

The photo is 150 x 100, the person rows TOP..139 and columns 20..79 (the crop, and so the network grid's scale and
phase, follow its height), green left of EDGE, the shadow EDGE..EDGE+19 (photo 0.01 of its albedo: grey for "black",
half the skin for "skin"), lit skin beyond; tests/_graphs.py's analytic stage 1 at 64 px (its albedo the photo's,
replaced by the unshadowed scene's), relit under twice the photo's own light. Printed per material and edge column:
the chroma error (max over R, G, B of the shadow's mean colour at luminance 1, rows 40..119, columns EDGE+3..EDGE+8,
against grey's or the skin's) for each top row, and the worst. ``--plain`` gives the rule before fill31 (the lit
pixels' plain mean). ``--where ROW,EDGE`` prints, for that layout's black shadow, the lit pixels that vote into the
shadow's own material cell (network frame: column, weight, photo chroma, albedo) as main's rule sees them.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))

import relight_rt  # noqa: E402
from relight_rt.engine.config import RuntimeConfig  # noqa: E402
from relight_rt.image.color import REC709  # noqa: E402
from relight_rt.relight import fill_colour, shadow_fill  # noqa: E402

GREEN = np.array([0.25, 0.60, 0.30], np.float32)
SKIN = np.array([0.62, 0.47, 0.40], np.float32)
GREY = np.array([0.30, 0.30, 0.30], np.float32)


def relit_strips(relighter, shadowed: tuple[np.ndarray, np.ndarray], own_light: np.ndarray, top: int = 20,
                 edge: int = 40) -> np.ndarray:
    """The scene (module docstring; tests/runtime/relight/test_fill_colour.py relights the same): a person (rows
    ``top``-139, x 20-79) lit green on its left (x < ``edge``), a deep shadow of albedo ``shadowed[1]`` 20 px wide
    (photo ``shadowed[0]``), lit skin on its right; relit under twice ``own_light`` (white)."""
    h, w = 150, 100
    mask = np.zeros((h, w), np.float32)
    mask[top:140, 20:80] = 1
    photo = np.broadcast_to(SKIN, (h, w, 3)).copy()
    albedo = photo.copy()
    photo[:, :edge] = albedo[:, :edge] = GREEN
    photo[:, edge : edge + 20], albedo[:, edge : edge + 20] = shadowed
    dec = relighter.decompose(photo, mask)
    dec = replace(dec, albedo_chw=relighter.decompose(albedo, mask).albedo_chw)
    return relighter.relight(dec, 2 * own_light, exposure="physical")


def chroma_error(relighter, own_light, top: int, edge: int, material: str) -> float:
    """The shadow's chroma error beside the green in the layout (``top``, ``edge``) (module docstring)."""
    shade = GREY if material == "black" else 0.5 * SKIN
    out = relit_strips(relighter, (0.01 * shade, shade), own_light, top, edge)
    mean = out[40:120, edge + 3 : edge + 9].reshape(-1, 3).mean(axis=0)
    want = np.ones(3) if material == "black" else SKIN / float(SKIN @ REC709)
    return float(np.abs(mean / float(mean @ REC709) - want).max())


def span(text: str) -> range:
    lo, hi = (int(v) for v in text.split("-"))
    return range(lo, hi + 1)


def voters(relighter, own_light, top: int, edge: int) -> None:
    """The lit pixels whose vote lands in the black shadow's own (grey) cell, in the network frame."""
    seen = {}
    inner = fill_colour.material_colour

    def spy(rgb, luma, trust, albedo, sigma):
        seen.update(rgb=rgb, luma=luma, trust=trust, albedo=albedo, sigma=sigma)
        return inner(rgb, luma, trust, albedo, sigma)

    fill_colour.material_colour = spy
    try:
        err = chroma_error(relighter, own_light, top, edge, "black")
    finally:
        fill_colour.material_colour = inner
    a = np.maximum(seen["albedo"], fill_colour.MATERIAL_FLOOR)
    uv = np.log(a[..., [0, 2]] / a[..., 1:2]) / fill_colour.MATERIAL_STEP
    grey = np.prod(np.clip(1 - np.abs(uv), 0, 1), axis=-1)  # the share in cell (0, 0): grey's
    vote = grey * seen["trust"] * seen["luma"]
    row = vote.shape[0] // 2
    print(f"top {top} edge {edge}: chroma error {err:.3f}; window {vote.shape[:2]}, sigma {seen['sigma']}; "
          f"the grey cell's lit votes {vote.sum():.3f}")
    for col in np.nonzero(vote.sum(axis=0) > 1e-3)[0]:
        rgb, luma = seen["rgb"][row, col], seen["luma"][row, col]
        print(f"  column {col}: votes {vote[:, col].sum():.3f}, trust {seen['trust'][row, col]:.2f}, grey share "
              f"{grey[row, col]:.2f}, photo chroma {np.round(rgb / max(luma, 1e-6), 2)}, albedo "
              f"{np.round(seen['albedo'][row, col], 3)}")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rows", type=span, default=span("17-24"))
    p.add_argument("--edges", type=span, default=span("36-44"))
    p.add_argument("--plain", action="store_true", help="the rule before fill31 (FILL_BY_MATERIAL off)")
    p.add_argument("--where", help="ROW,EDGE: the lit votes in the black shadow's cell for that layout")
    args = p.parse_args(argv)
    from _graphs import OWN_LIGHT, make_models_dir

    shadow_fill.FILL_BY_MATERIAL = not args.plain
    with tempfile.TemporaryDirectory() as tmp:
        models = make_models_dir(Path(tmp), 64, stage2=True, dvp=True)
        relighter = relight_rt.open(RuntimeConfig(models=models, device="cpu"))
        if args.where:
            top, edge = (int(v) for v in args.where.split(","))
            voters(relighter, OWN_LIGHT, top, edge)
            return 0
        print("material edge  " + " ".join(f"{r:>6}" for r in args.rows))
        for material in ("black", "skin"):
            worst = 0.0
            for edge in args.edges:
                errs = [chroma_error(relighter, OWN_LIGHT, top, edge, material) for top in args.rows]
                worst = max(worst, *errs)
                print(f"{material:>8} {edge:>4}  " + " ".join(f"{e:6.3f}" for e in errs))
            print(f"{material}: worst {worst:.3f} over {len(args.rows)} rows x {len(args.edges)} edges")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
