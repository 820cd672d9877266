"""Which path colours a near-neutral dark under a white lamp (issue 48's first look, cast42): the ratio multiplying
the photo, the deep shadow's fill, or ``look.keep_neutral`` holding it (or not).

    python benchmarks/cast_paths.py p041:RIGHT p287:RIGHT p264:LEFT [--out /tmp/cast42/paths]

Each PHOTO:LIGHT (a people_masks photo's stem; LEFT / RIGHT of benchmarks/real_photos.py or a preset) is relit as the
first look relights it (``first_look.py``: the automatic matte, the background kept, CPU). The pixels looked at are
``neutral_darks.py``'s near-neutral darks (on the person, alpha > 0.5, photo L* < 35 and C* < 10) that come out
"seen" (C* up by more than 8, or the hue turned by more than 20 degrees at a relit C* of 6 or more), on the relit
person's own colour (``Composer.person_colour``, before the composite). For them, the means of: the photo's Lab; the
Lab of the photo times the factor (``plain``: the ratio path alone), after the deep shadow's fill (``filled``) and
after ``keep_neutral`` (``relit``); the fill's weight; ``neutral_darks``' weight; the factor's luminance and its
colour; on the network's grid the luminance ratio, the own and new luminance it divides (``Factor._change``), stage
1's albedo (RGB) and the fill's colour at luminance 1 (``ShadowFill.shadow_weight``). Then the largest connected
groups of them with their own means. With ``--out``, a sheet per PHOTO:LIGHT around the largest group, 3x: photo |
plain | filled | relit / the pixels (magenta) | fill weight | neutral weight.

Figures only for looking: it spies on the runtime's stages (the same code, recorded), it changes nothing.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np
from real_photos import LEFT, RIGHT

# isort: split
from _shared import shared_path

import relight_rt
from relight_rt import RuntimeConfig
from relight_rt.image.color import REC709
from relight_rt.relight import compose, factor
from relight_rt.relight.detail import unpremultiply


def lab(rgb: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(np.clip(rgb, 0, 1).astype(np.float32), cv2.COLOR_RGB2Lab)


def seen(photo: np.ndarray, relit: np.ndarray) -> np.ndarray:
    """``neutral_darks.py``'s "seen" per pixel of two Lab images."""
    c0, c1 = np.hypot(photo[..., 1], photo[..., 2]), np.hypot(relit[..., 1], relit[..., 2])
    turn = np.degrees(np.abs(np.angle(np.exp(1j * (np.arctan2(relit[..., 2], relit[..., 1])
                                                   - np.arctan2(photo[..., 2], photo[..., 1]))))))
    return (c1 - c0 > 8) | ((turn > 20) & (c1 >= 6))


def record(relighter, dec, light) -> dict:
    """The stages of ``dec`` relit under ``light`` (crop box), spied on."""
    got: dict = {}
    keep, change, gain_and_fill = compose.keep_neutral, factor.Factor._change, factor.Factor.gain_and_fill

    def spy_keep(colour, gain, neutral):
        out = keep(colour, gain, neutral)
        got.update(filled=colour.copy(), gain=gain.copy(), relit=out.copy(), neutral=neutral)
        return out

    def spy_fill(self, d, light_, image, residual=None, fill=True):
        out = gain_and_fill(self, d, light_, image, residual, fill)
        if d is dec and "fill" not in got:
            got.update(fill=out[1], image=image.copy())
        return out

    def spy_change(self, own, light_, residual, cast=None):
        out = change(self, own, light_, residual, cast)
        if "net" not in got:
            got["net"] = (own, out)
        return out

    compose.keep_neutral, factor.Factor._change, factor.Factor.gain_and_fill = spy_keep, spy_change, spy_fill
    try:
        relighter.relight(dec, light)
    finally:
        compose.keep_neutral, factor.Factor._change, factor.Factor.gain_and_fill = keep, change, gain_and_fill
    return got


def report(relighter, dec, name: str, light: str, out: Path | None) -> None:
    """Print (and with ``out`` draw) the paths of ``dec``'s seen casts under ``light`` (module docstring)."""
    got = record(relighter, dec, {"LEFT": LEFT, "RIGHT": RIGHT}.get(light, light))
    geom = dec.geometry
    y0, y1, x0, x1 = geom.box
    image = got["image"]
    photo = np.asarray(dec.image, np.float32)[y0:y1, x0:x1]
    alpha = np.asarray(dec.mask, np.float32)[y0:y1, x0:x1]
    p = lab(photo)
    near = (alpha > 0.5) & (p[..., 0] < 35) & (np.hypot(p[..., 1], p[..., 2]) < 10)
    gain = got["gain"]
    stages = {"plain": image * gain, "filled": got["filled"], "relit": got["relit"]}
    faults = seen(p, lab(stages["relit"])) & near
    fill_w = np.zeros(alpha.shape, np.float32)
    if got.get("fill") is not None:
        fill_w[got["fill"][0]] = got["fill"][2]
    neutral_w = np.zeros(alpha.shape, np.float32)
    if got["neutral"] is not None:
        neutral_w.reshape(-1)[got["neutral"].index[0] // 3] = got["neutral"].weight
    own, (ratio, _tint, new) = got["net"]
    wy0, wy1, wx0, wx1 = own["window"]

    def crop(a: np.ndarray) -> np.ndarray:
        return geom.to_crop(np.ascontiguousarray(a, np.float32), (wy0, wx0))

    albedo = crop(unpremultiply(np.ascontiguousarray(dec.albedo[wy0:wy1, wx0:wx1]), own["alpha"]))
    shadow = relighter._factor.fill.shadow_weight(dec)
    net = {"ratio": crop(ratio), "own": crop(own["own"]), "new": crop(new), "albedo": albedo}
    if shadow is not None:
        net["fill colour"] = crop(shadow[1])
    y = gain @ REC709

    def describe(where: np.ndarray) -> str:
        parts = [f"photo Lab {np.round(p[where].mean(0), 1)}"]
        parts += [f"{k} {np.round(lab(v)[where].mean(0), 1)}" for k, v in stages.items()]
        parts += [f"fill w {fill_w[where].mean():.2f}", f"neutral w {neutral_w[where].mean():.2f}",
                  f"factor {np.median(y[where]):.2f} x {np.round((gain[where] / y[where, None]).mean(0), 3)}"]
        parts += [f"{k} {np.round(np.median(v[where], axis=0), 3)}" for k, v in net.items()]
        return "; ".join(parts)

    share = faults.sum() / max(near.sum(), 1)
    print(f"{name} {light}: near-neutral darks {near.sum()}, seen {faults.sum()} ({share:.3f}), of them with fill "
          f"weight > 0.5 {(faults & (fill_w > 0.5)).sum()}, neutral weight < 0.5 {(faults & (neutral_w < 0.5)).sum()}")
    if not faults.any():
        return
    print("   all: " + describe(faults))
    count, label, stats, _ = cv2.connectedComponentsWithStats(cv2.dilate(faults.astype(np.uint8), np.ones((5, 5))))
    order = np.argsort(-stats[1:, 4])[:3] + 1
    for k in order:
        bx, by, bw, bh, _ = stats[k]
        group = (label == k) & faults
        print(f"   group rows {by}-{by + bh} cols {bx}-{bx + bw} ({group.sum()} px): " + describe(group))
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        bx, by, bw, bh, _ = stats[order[0]]
        cy, cx, r = by + bh // 2, bx + bw // 2, max(bh, bw) // 2 + 30
        sl = (slice(max(cy - r, 0), cy + r), slice(max(cx - r, 0), cx + r))
        over = photo.copy()
        over[faults] = (1, 0, 1)
        grey = lambda a: np.repeat(np.clip(a, 0, 1)[..., None], 3, axis=2)  # noqa: E731
        tiles = [photo, stages["plain"], stages["filled"], stages["relit"], over, grey(fill_w), grey(neutral_w)]
        tiles = [cv2.resize(np.clip(t[sl], 0, 1), None, fx=3, fy=3, interpolation=cv2.INTER_NEAREST) for t in tiles]
        tiles.append(np.zeros_like(tiles[0]))
        sheet = np.vstack([np.hstack(tiles[:4]), np.hstack(tiles[4:])])
        cv2.imwrite(str(out / f"{name}_{light}.png"),
                    cv2.cvtColor((sheet * 255).round().astype(np.uint8), cv2.COLOR_RGB2BGR))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("pairs", nargs="+", help="PHOTO:LIGHT")
    ap.add_argument("--people", type=Path, default=shared_path("realdata", "people_masks"))
    ap.add_argument("--models", type=Path, default=None)
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args(argv)
    relighter = relight_rt.open(RuntimeConfig(models=args.models, device="cpu"))
    decs: dict = {}
    for pair in args.pairs:
        name, light = pair.split(":")
        if name not in decs:
            bgr = cv2.imread(str(args.people / "photos" / f"{name}.jpg"), cv2.IMREAD_COLOR)
            if bgr is None:
                raise SystemExit(f"no photo {name}")
            decs[name] = relighter.decompose(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB).astype(np.float32) / 255)
        report(relighter, decs[name], name, light, args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
