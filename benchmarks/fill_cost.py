"""What a large deep shadow's fill costs per light and per Decomposition (relight_rt.relight.factor
``Factor.gain_and_fill``, and relight_rt.relight.shadow_fill ``ShadowFill.fill_base``), on a synthetic photo made to
have one.

    python benchmarks/fill_cost.py [--size 1936 1296] [--repeats 15] [--models DIR]

A skin-coloured textured person fills most of a 2.5-MP frame (default); its left 45 % lies in a hard shadow at 1 %
of the lit side. The bundled stage 1 is given the albedo of the photo without the shadow (as the fill's tests do),
so the fill covers about half the person. Prints, best and 25th percentile over ``--repeats`` after a warm-up:
``gain_and_fill`` alone under three lights in turn (what every relight pays), ``fill_base`` (once per
Decomposition: the fill's weight at the photo's resolution) recomputed alone, and the fill box's size. Run it
alternately with another checkout (``PYTHONPATH=<other> python <other>/benchmarks/fill_cost.py``) on a loaded CPU.
"""

from __future__ import annotations

import argparse
import inspect
import time
from dataclasses import replace
from pathlib import Path

import numpy as np


def scene(w: int, h: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(photo, true, mask): float32 RGB, the shadowed photo and the one without its shadow, and the person's mask."""
    rng = np.random.default_rng(0)
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    texture = 1 + 0.05 * np.sin(yy / 7.0) * np.cos(xx / 11.0) + rng.normal(0, 0.02, (h, w)).astype(np.float32)
    true = (np.float32([0.62, 0.47, 0.40]) * texture[..., None]).astype(np.float32)
    mask = (((xx - w / 2) / (0.42 * w)) ** 2 + ((yy - h / 2) / (0.47 * h)) ** 2 < 1).astype(np.float32)
    edge = w / 2 - 0.05 * w
    shade = np.where(xx < edge, 0.01, 1.0).astype(np.float32)
    return np.clip(true * shade[..., None], 0, 1), np.clip(true, 0, 1), mask


def best(times: list[float]) -> str:
    times = sorted(times)
    return f"min {1000 * times[0]:.1f} ms, p25 {1000 * times[len(times) // 4]:.1f} ms"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--size", type=int, nargs=2, default=(1936, 1296), metavar=("W", "H"))
    p.add_argument("--repeats", type=int, default=15)
    p.add_argument("--models", type=Path, default=None)
    args = p.parse_args()

    import relight_rt
    from relight_rt import RuntimeConfig

    r = relight_rt.open(RuntimeConfig(models=None if args.models is None else str(args.models), device="cpu"))
    photo, true, mask = scene(*args.size)
    dec = r.decompose(photo, mask)
    dec = replace(dec, albedo_chw=r.decompose(true, mask).albedo_chw)
    factor, composer = r._factor, r._composer
    fill_part = getattr(factor, "fill", factor)  # the fill's own object (split32; the Factor's methods before)
    image, _ = composer.foreground(dec)
    lights = [factor.meter.expose(dec, r.resolve_light(name), "auto") for name in ("front", "window-left", "studio")]
    residuals = [next(r._network.relit(dec, light[None], 1))[1] for light in lights]
    shadow = fill_part.shadow_weight(dec)
    print(f"photo {args.size[0]}x{args.size[1]}, deep shadow found: {shadow is not None}")
    per_light, base = [], []
    for i in range(args.repeats + 1):
        light, residual = lights[i % 3], residuals[i % 3]
        t = time.perf_counter()
        _, fill = factor.gain_and_fill(dec, light, image, residual)
        if i:
            per_light.append(time.perf_counter() - t)
    state = factor.memo(dec)
    # fill_base reads the person's colour (faces16: its grey, the full-resolution guide; before faces16 there was none)
    given = None
    if hasattr(fill_part, "fill_base"):
        given = image if "image" in inspect.signature(fill_part.fill_base).parameters else state["gray"]
    for _ in range(args.repeats if given is not None else 0):
        state.pop("fill_base", None)
        t = time.perf_counter()
        fill_part.fill_base(dec, given)
        base.append(time.perf_counter() - t)
    if fill is not None:
        ys, xs = fill[0]
        print(f"fill box {(ys.stop - ys.start) * (xs.stop - xs.start) / 1e6:.2f} MP")
    print(f"gain_and_fill, a light   {best(per_light)}")
    if base:
        print(f"fill_base, once          {best(base)}")


if __name__ == "__main__":
    main()
