"""Where the teal that ``photo_faults.py --teal-only`` counts comes from: for each teal pixel, which gate of
``look.neutral_darks`` / ``look.keep_neutral`` let it through (issue 48, teal42).

    python benchmarks/teal_sources.py p104:rim p224:window-left [--out /tmp/teal42/sources] [--max-side 1000]

Each PHOTO:LIGHT (a people_masks photo's stem, or ``reference_photo``; a preset or LEFT / RIGHT) is relit as
``photo_faults.py`` relights it (the service-made mask, reduced to ``--max-side``, CPU). Its teal pixels are those
``photo_faults`` counts: the person's near-black input pixels (L* < 30, C* < 8) that come out with a* < -8. Each is
put in the first class it fits:

- ``light``: a grey surface gets a* < -8 from the light alone there: the gain's own colour (the new light's, at
  luminance 1: what ``keep_neutral`` keeps) at the pixel's relit luminance (not a fault: the light's share);
- ``edge``: the matte is not solid there (``compose.solid_crop``: a soft edge's mix, where the relit colour is the
  estimated foreground's, which ``neutral_darks`` does not read);
- ``gate:<name>``: ``neutral_darks`` gives it no weight; <name> the first gate that is 0 there: ``L`` (the reduced
  pixel's L* past ``_GREY_L``), ``C`` (its C*, or its pixels' mean C* less ``_GREY_NOISE``, past ``_GREY_C``),
  ``vivid``, ``warm`` (the reduced pixel's hue), ``material`` (its hue reaches ``_GREY_MATERIAL`` nearby),
  ``own_warm`` (the pixel's own colour warm and past ``_GREY_C``);
- ``weight``: in ``neutral_darks`` at a weight below 0.9 (a partial gate: reduced C* 8-12, L* 35-45, ...);
- ``lift``: brightened less than ``NEUTRAL_LIFT[1]`` x (blended in part or not at all);
- ``kept``: fully held to the photo's chroma at its new lightness and the light's colour, and teal still: the
  photo's own cast (input a* < -4: a tinted dark keeps its C*, and its a* passes -8 once the light's tint adds).

Also counts the teal pixels on the matte's outline (within ``look._GREY_EDGE`` px of a pixel that is not solid). Prints
the classes' shares per PHOTO:LIGHT with the input a* split (tinted: a* < -4) and the light's own a* (a grey
surface at L* 30 under the pixel's tint) and writes, with ``--out``, a sheet per PHOTO:LIGHT at 100 % around the
teal pixels: photo | relit | classes (light cyan, edge yellow, gate red, weight magenta, lift blue, kept green).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import cv2
import numpy as np
from photo_faults import DARK_L, NEUTRAL_C, TEAL_A, UNTINTED_A, lab, read_mask, read_rgb
from real_photos import LEFT, RIGHT

# isort: split
from _shared import shared_path

import relight_rt
from relight_rt import RuntimeConfig
from relight_rt.image.color import REC709
from relight_rt.relight import compose, look
from relight_rt.relight.look import NEUTRAL_LIFT

CLASSES = ("light", "edge", "gate:L", "gate:C", "gate:vivid", "gate:warm", "gate:material", "gate:own_warm",
           "weight", "lift", "kept")
COLOURS = {"light": (0, 255, 255), "edge": (255, 255, 0), "weight": (255, 0, 255), "lift": (0, 80, 255),
           "kept": (0, 200, 0)}  # RGB; every gate: red


def gates(image: np.ndarray, origin: tuple[int, int], solid: np.ndarray) -> dict[str, np.ndarray]:
    """``neutral_darks``' gates on ``image`` (the crop box's photo), each (h, w) at the photo's pixels (the reduced
    grid's values, nearest): look.block_gates' own, under this script's names."""
    names = {"L": "L", "C": "C", "vivid": "vivid", "warm": "warm", "material": "material", "hue": "hue",
             "reduced_C": "C*", "reduced_L": "L*"}
    g = look.block_gates(image, origin, solid)
    return {k: look.at_pixels(g[v], image.shape[:2], origin) for k, v in names.items()}


def diagnose(relighter, rgb: np.ndarray, mask: np.ndarray, light) -> dict:
    """The teal pixels of ``rgb`` relit under ``light`` and each one's class (module docstring)."""
    seen: dict = {}
    keep = compose.keep_neutral

    def spy(colour, gain, neutral):
        out = keep(colour, gain, neutral)
        seen.update(colour=colour.copy(), gain=gain.copy(), neutral=neutral, out=out.copy())
        return out

    compose.keep_neutral = spy
    try:
        dec = relighter.decompose(rgb, mask)
        relit = relighter.relight(dec, light)
    finally:
        compose.keep_neutral = keep
    person = mask > 0.5
    lab_in, lab_out = lab(rgb), lab(relit)
    black = person & (lab_in[..., 0] < DARK_L) & (np.hypot(lab_in[..., 1], lab_in[..., 2]) < NEUTRAL_C)
    teal = black & (lab_out[..., 1] < TEAL_A)
    y0, y1, x0, x1 = dec.geometry.box
    h, w = y1 - y0, x1 - x0
    photo = compose.photo_crop(dec)
    solid = compose.solid_crop(dec)
    g = gates(photo, compose.crop_origin(dec), solid)
    weight = np.zeros(h * w, np.float32)
    n = seen["neutral"]
    if n is not None:
        weight[n.index[0] // 3] = n.weight
    weight = weight.reshape(h, w)
    gain = seen["gain"]
    tint = gain / np.maximum(gain @ REC709, 1e-6)[..., None]
    y_in = photo @ REC709
    white = seen["colour"] / np.where(gain > 1e-4, tint, 1)
    lift = (white @ REC709) / np.maximum(y_in, 1e-6)
    # the light's own share: a grey surface at the pixel's relit luminance, coloured by the gain's tint
    y_out = np.maximum(seen["out"] @ REC709, 1e-6)
    grey_lab = look.to_lab(np.clip(tint * y_out[..., None], 0, 1).astype(np.float32))
    light_a = grey_lab[..., 1]
    ys, xs = np.nonzero(teal)
    cls = []
    for y, x in zip(ys, xs, strict=True):
        cy, cx = y - y0, x - x0
        if not (0 <= cy < h and 0 <= cx < w):
            cls.append("edge")
            continue
        if light_a[cy, cx] < TEAL_A:
            cls.append("light")
        elif not solid[cy, cx]:
            cls.append("edge")
        elif weight[cy, cx] <= 1e-3:
            for name in ("L", "C", "vivid", "warm", "material"):
                if g[name][cy, cx] <= 1e-3:
                    cls.append(f"gate:{name}")
                    break
            else:
                cls.append("gate:own_warm")
        elif weight[cy, cx] < 0.9:
            cls.append("weight")
        elif lift[cy, cx] < NEUTRAL_LIFT[1]:
            cls.append("lift")
        else:
            cls.append("kept")
    cls = np.array(cls, dtype=object)
    tinted = lab_in[..., 1][ys, xs] < UNTINTED_A
    rows = {}
    for c in CLASSES:
        sel = cls == c
        if sel.any():
            cy, cx = ys[sel] - y0, xs[sel] - x0
            inside = (cy >= 0) & (cy < h) & (cx >= 0) & (cx < w)
            rows[c] = {"pixels": int(sel.sum()), "tinted": int(tinted[sel].sum()),
                       "input_a_median": float(np.median(lab_in[..., 1][ys[sel], xs[sel]])),
                       "light_a_median": float(np.median(light_a[cy[inside], cx[inside]])) if inside.any() else None,
                       "lift_median": float(np.median(lift[cy[inside], cx[inside]])) if inside.any() else None,
                       "weight_median": float(np.median(weight[cy[inside], cx[inside]])) if inside.any() else None,
                       "reduced_C_median": float(np.median(g["reduced_C"][cy[inside], cx[inside]]))
                       if inside.any() else None,
                       "gates_median": {k: round(float(np.median(g[k][cy[inside], cx[inside]])), 3)
                                        for k in ("L", "C", "vivid", "warm", "material", "hue")} if inside.any()
                       else None}
    # on the matte's outline (within look._GREY_EDGE px of a pixel that is not solid): the block mixes the backdrop
    band = np.zeros(rgb.shape[:2], bool)
    disk = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * look._GREY_EDGE + 1,) * 2)
    band[y0:y1, x0:x1] = solid & (cv2.erode(solid.astype(np.uint8), disk) == 0)
    return {"black": int(black.sum()), "teal": int(teal.sum()), "share": float(teal.sum() / max(black.sum(), 1)),
            "outline": int((teal & band).sum()),
            "untinted": int((teal & (lab_in[..., 1] >= UNTINTED_A)).sum()),
            "untinted_of": int((black & (lab_in[..., 1] >= UNTINTED_A)).sum()), "classes": rows,
            "_sheet": (rgb, relit, ys, xs, cls)}


def sheet(rgb: np.ndarray, relit: np.ndarray, ys: np.ndarray, xs: np.ndarray, cls: np.ndarray, size: int = 360,
          zoom: int = 1) -> np.ndarray:
    """photo | relit | classes at 100 % around the densest teal pixels (a ``size`` square), each pixel drawn
    ``zoom`` x ``zoom`` (nearest: a small photo's pixels seen one by one)."""
    h, w = rgb.shape[:2]
    if ys.size == 0:
        cy, cx = h // 2, w // 2
    else:
        dens = np.zeros((h, w), np.float32)
        dens[ys, xs] = 1
        dens = cv2.boxFilter(dens, -1, (size // 3, size // 3), normalize=False)
        cy, cx = np.unravel_index(int(dens.argmax()), dens.shape)
    t, l = int(np.clip(cy - size // 2, 0, max(h - size, 0))), int(np.clip(cx - size // 2, 0, max(w - size, 0)))
    win = (slice(t, t + size), slice(l, l + size))
    mark = (rgb * 0.35).copy()
    for y, x, c in zip(ys, xs, cls, strict=True):
        mark[y, x] = np.array(COLOURS.get(c, (255, 0, 0))) / 255
    tiles = [np.clip(a[win], 0, 1) for a in (rgb, relit, mark)]
    tiles = [np.repeat(np.repeat(a, zoom, 0), zoom, 1) for a in tiles]
    row = np.concatenate([np.pad(a, ((0, 0), (0, 4), (0, 0)), constant_values=1) for a in tiles], axis=1)
    return cv2.cvtColor((row * 255).round().astype(np.uint8), cv2.COLOR_RGB2BGR)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("cases", nargs="+", help="PHOTO:LIGHT")
    p.add_argument("--people", type=Path, default=shared_path("realdata", "people_masks"))
    p.add_argument("--reference", type=Path, default=shared_path("reference"))
    p.add_argument("--max-side", type=int, default=1000)
    p.add_argument("--out", type=Path, default=None)
    p.add_argument("--size", type=int, default=360, help="the sheet's window, in photo pixels")
    p.add_argument("--zoom", type=int, default=1, help="each photo pixel drawn this many times across")
    args = p.parse_args(argv)
    relighter = relight_rt.open(RuntimeConfig(device="cpu"))
    if args.out:
        args.out.mkdir(parents=True, exist_ok=True)
    report = {}
    for case in args.cases:
        name, light = case.split(":")
        if name == "reference_photo":
            image, maskf = args.reference / "photo" / "sample.jpg", args.reference / "photo" / "sample_mask.png"
        else:
            image = args.people / "photos" / f"{name}.jpg"
            maskf = image.with_name(f"{name}_mask.png")
        rgb = read_rgb(image, args.max_side)
        mask = read_mask(maskf, rgb.shape[:2])
        r = diagnose(relighter, rgb, mask, {"LEFT": LEFT, "RIGHT": RIGHT}.get(light, light))
        if args.out:
            cv2.imwrite(str(args.out / f"{name}_{light}.png"), sheet(*r["_sheet"], size=args.size, zoom=args.zoom))
        del r["_sheet"]
        report[case] = r
        print(f"{case}: teal {r['teal']} of {r['black']} ({100 * r['share']:.2f} %), untinted {r['untinted']} of "
              f"{r['untinted_of']}, on the outline {r['outline']}", flush=True)
        for c, row in r["classes"].items():
            print(f"   {c:14s} {row['pixels']:6d} px (tinted {row['tinted']:5d}) input a* {row['input_a_median']:6.1f}"
                  f"  light a* {row['light_a_median']}  lift {row['lift_median']}  weight {row['weight_median']}"
                  f"  reduced C* {row['reduced_C_median']}\n      gates {row['gates_median']}")
    if args.out:
        (args.out / "sources.json").write_text(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
