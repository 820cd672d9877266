"""Which path relights background the automatic matte holds (glow43, issue 48's first look: p204's bag glowing, the
campfire band beside p091's and p262's arms).

    python benchmarks/held_paths.py p204:456,480,333,360 p262:522,686,280,330 p091:100,170,320,391 [--out /tmp/held]

Each PHOTO:Y0,Y1,X0,X1 (a people_masks photo's stem and a box in its pixels) is relit as the first look relights it
(``first_look.py``: the automatic matte, the background kept, CPU) under its six lights. In the box, three sets of
pixels by the service's mask (people_masks' ``NAME_mask.png``, a second opinion): ``held``, the matte's (alpha >= 0.5)
that the mask calls background; ``soft``, the matte's rim (0.05 < alpha < 0.5) there; ``person``, the matte's that the
mask calls person. For each, the means of the relighting factor's inputs in the person's window of the network frame
(relight_rt.relight.factor ``Factor._change``, spied on): stage 1's albedo luminance, the own shading (the transport
under the photo's light taken as white), stage 2's residual under the own light and the new one (luminance), the new
shading, the luminance ratio and the full-resolution factor's luminance (``gain``); the alpha the photo is composited
with (``compose.shown_mask``); then the output's and the photo's CIELAB. Last, over the whole photo, the background
the composite shows changed (off the mask grown 1 px, shown alpha > 0.25): mean |dL*|, mean |d(a*, b*)| and the share
with dE76 > 10, per light. With ``--out``: a sheet per photo (the box at 4x: photo, mask, matte, then each light).

Figures only for looking: it spies on the runtime's stages (the same code, recorded), it changes nothing. The masks
are evaluation data: nothing of them is written but under ``--out`` (keep it out of the repository).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np
from real_photos import LEFT, RIGHT

# isort: split
from _shared import shared_path
from first_look import LIGHTS

import relight_rt
from relight_rt import RuntimeConfig
from relight_rt.image.color import REC709
from relight_rt.light import sh
from relight_rt.relight import factor
from relight_rt.relight.compose import shown_mask

SHEET_SCALE = 4


def lab(rgb: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(np.clip(rgb, 0, 1).astype(np.float32), cv2.COLOR_RGB2Lab)


def relit(relighter, dec, light) -> tuple[np.ndarray, dict]:
    """``relighter.relight(dec, light)`` and its first ``Factor._change`` and ``gain_and_fill`` on ``dec`` (own, light,
    ratio, new; gain in the crop box)."""
    got: dict = {}
    change, gain_and_fill = factor.Factor._change, factor.Factor.gain_and_fill

    def spy_change(self, own, light_, residual, cast=None):
        out = change(self, own, light_, residual, cast)
        if "ratio" not in got:
            got.update(own=own, light=light_, ratio=out[0], new=out[2])
        return out

    def spy_fill(self, d, light_, image, residual=None, fill=True):
        out = gain_and_fill(self, d, light_, image, residual, fill)
        if d is dec and "gain" not in got:
            got["gain"] = out[0].copy()
        return out

    factor.Factor._change, factor.Factor.gain_and_fill = spy_change, spy_fill
    try:
        image = np.asarray(relighter.relight(dec, light), np.float32)
    finally:
        factor.Factor._change, factor.Factor.gain_and_fill = change, gain_and_fill
    return image, got


def input_frame(dec, window_map: np.ndarray, window: tuple[int, int, int, int]) -> np.ndarray:
    """A (r, r') map of the person's window of the network frame, in the photo's pixels (0 outside the crop box)."""
    y0, y1, x0, x1 = window
    r = dec.geometry.resolution
    full = np.zeros((r, r), np.float32)
    full[y0:y1, x0:x1] = window_map
    return dec.to_input(full)


def paths(got: dict, dec) -> dict[str, np.ndarray]:
    """The factor's inputs under one light (module docstring), each (H, W) in the photo's pixels."""
    own, light = got["own"], got["light"]
    albedo, missing = own["albedo"], own["missing"]
    shading_own = sh.shading(own["transport"], dec.white_light)[..., 0]
    shading_new = sh.shading(own["transport"], light) @ REC709
    maps = {"albedo": albedo, "own shading": shading_own,
            "own residual": own["own"] - albedo * shading_own - missing, "new shading": shading_new,
            "new residual": got["new"] - albedo * shading_new - missing, "ratio": got["ratio"]}
    out = {k: input_frame(dec, v.astype(np.float32), own["window"]) for k, v in maps.items()}
    gain = np.zeros(dec.image.shape[:2], np.float32)
    y0, y1, x0, x1 = dec.geometry.box
    gain[y0:y1, x0:x1] = got["gain"] @ REC709
    out["gain"] = gain
    return out


def report(relighter, people: Path, name: str, box: tuple[int, int, int, int], out: Path | None) -> None:
    bgr = cv2.imread(str(people / "photos" / f"{name}.jpg"), cv2.IMREAD_COLOR)
    mask = cv2.imread(str(people / "photos" / f"{name}_mask.png"), cv2.IMREAD_GRAYSCALE)
    if bgr is None or mask is None:
        raise SystemExit(f"no photo or mask {name}")
    rgb = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB).astype(np.float32) / 255
    truth = mask > 127
    dec = relighter.decompose(rgb)
    alpha, shown = np.asarray(dec.mask), shown_mask(dec)
    y0, y1, x0, x1 = box
    inside = np.zeros(alpha.shape, bool)
    inside[y0:y1, x0:x1] = True
    sets = {"held": inside & (alpha >= 0.5) & ~truth, "soft": inside & (alpha > 0.05) & (alpha < 0.5) & ~truth,
            "person": inside & (alpha >= 0.5) & truth}
    shown_bg = (cv2.dilate(truth.astype(np.uint8), np.ones((3, 3), np.uint8)) == 0) & (shown > 0.25)
    photo_lab = lab(rgb)
    print(f"{name} box {box}: " + ", ".join(f"{k} {int(v.sum())} px (alpha {alpha[v].mean():.2f}, shown "
                                             f"{shown[v].mean():.2f})" for k, v in sets.items() if v.any()))
    tiles = [rgb, np.dstack([truth.astype(np.float32)] * 3), np.dstack([alpha] * 3)]
    changed = []
    for light in LIGHTS:
        image, got = relit(relighter, dec, {"LEFT": LEFT, "RIGHT": RIGHT}.get(light, light))
        tiles.append(image)
        maps, image_lab = paths(got, dec), lab(image)
        print(f"  {light} (light's DC norm {np.linalg.norm(got['light'][0]):.3f})")
        for k, where in sets.items():
            if where.any():
                lo, li = photo_lab[where].mean(0), image_lab[where].mean(0)
                print(f"    {k:6s} " + " ".join(f"{m} {v[where].mean():.3f}" for m, v in maps.items())
                      + f" | out L* {li[0]:.1f} a* {li[1]:+.1f} b* {li[2]:+.1f} (photo {lo[0]:.1f} {lo[1]:+.1f} "
                      f"{lo[2]:+.1f})")
        d = image_lab[shown_bg] - photo_lab[shown_bg]
        if d.size:
            changed.append(f"{light} |dL*| {np.abs(d[:, 0]).mean():.1f} |dab| {np.hypot(d[:, 1], d[:, 2]).mean():.1f} "
                           f"dE>10 {(np.linalg.norm(d, axis=1) > 10).mean():.2f}")
    print(f"  background shown changed ({int(shown_bg.sum())} px): " + "; ".join(changed))
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        crops = [cv2.resize(np.clip(t[y0:y1, x0:x1], 0, 1), None, fx=SHEET_SCALE, fy=SHEET_SCALE,
                            interpolation=cv2.INTER_NEAREST) for t in tiles]
        gap = np.full((crops[0].shape[0], 4, 3), 0.5, np.float32)
        sheet = np.concatenate(sum([[c, gap] for c in crops], [])[:-1], axis=1)
        cv2.imwrite(str(out / f"{name}_held.png"),
                    cv2.cvtColor(np.round(sheet * 255).astype(np.uint8), cv2.COLOR_RGB2BGR))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("boxes", nargs="+", help="PHOTO:Y0,Y1,X0,X1")
    ap.add_argument("--people", type=Path, default=shared_path("realdata", "people_masks"))
    ap.add_argument("--models", type=Path, default=None)
    ap.add_argument("--out", type=Path, default=None, help="sheets (keep it out of the repository)")
    args = ap.parse_args(argv)
    relighter = relight_rt.open(RuntimeConfig(models=args.models, device="cpu"))
    for item in args.boxes:
        name, box = item.split(":")
        report(relighter, args.people, name, tuple(int(v) for v in box.split(",")), args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
