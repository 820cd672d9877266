"""How real skin's colour changes with its shading (issue 32: why relit shaded skin looked grey).

    python benchmarks/skin_chroma.py PHOTO [PHOTO ...]

In each photo the largest face the bundled face detector finds is taken, and in its box the skin-coloured pixels
(YCrCb, as benchmarks/real_photos.py picks them: chosen without any model). They are split into fifths by Lab
lightness L*; printed per fifth: mean L*, mean chroma C* and mean C*/L*. Then the exponent gamma of C* ~ L*^gamma
from the darkest fifth to the middle one (the shaded side of the face to its middle: the range a new light's
shade moves skin through), per photo and its median. For comparison, the same exponent of one skin colour
dimmed at one chromaticity (what a relighting factor applied to the photo does) and of the runtime's shaded-skin
rule (relight_rt.relight.look ``shaded_skin``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np


def skin_of_face(rgb: np.ndarray, faces) -> np.ndarray | None:
    """Skin-coloured pixels (real_photos.skin_pixels, the YCrCb rule) in the largest face box, or None without
    a face."""
    from real_photos import skin_pixels

    if not faces:
        return None
    box = max(faces, key=lambda f: (f.box[2] - f.box[0]) * (f.box[3] - f.box[1])).box
    x0, y0, x1, y1 = (int(round(v)) for v in box)
    region = np.zeros(rgb.shape[:2], bool)
    region[max(y0, 0) : max(y1, 0), max(x0, 0) : max(x1, 0)] = True
    return skin_pixels(rgb, region)


def fifths(rgb: np.ndarray, skin: np.ndarray) -> list[tuple[float, float, float]]:
    """(mean L*, mean C*, mean C*/L*) of the skin pixels in each fifth of their lightness, darkest first."""
    lab = cv2.cvtColor(np.clip(rgb, 0, 1).astype(np.float32), cv2.COLOR_RGB2Lab)[skin]
    light, chroma = lab[:, 0], np.hypot(lab[:, 1], lab[:, 2])
    edges = np.percentile(light, [0, 20, 40, 60, 80, 100])
    out = []
    for k in range(5):
        m = (light >= edges[k]) & ((light < edges[k + 1]) if k < 4 else (light <= edges[k + 1]))
        saturation = chroma[m] / np.maximum(light[m], 1)
        out.append((float(light[m].mean()), float(chroma[m].mean()), float(saturation.mean())))
    return out


def exponent(dark: tuple[float, float, float], middle: tuple[float, float, float]) -> float:
    """gamma of C* ~ L*^gamma between two (L*, C*, ...) rows."""
    return float(np.log(middle[1] / dark[1]) / np.log(middle[0] / dark[0]))


def model_exponent(relit) -> float:
    """gamma for a skin colour (0.8, 0.6, 0.5) dimmed to half its luminance by ``relit(colour, ratio)``."""
    colour = np.array([0.8, 0.6, 0.5], np.float32)
    lab = lambda c: cv2.cvtColor(np.clip(c, 0, 1).astype(np.float32)[None, None], cv2.COLOR_RGB2Lab)[0, 0]  # noqa: E731
    a, b = lab(colour), lab(relit(colour, 0.5))
    return float(np.log(np.hypot(b[1], b[2]) / np.hypot(a[1], a[2])) / np.log(b[0] / a[0]))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("photos", nargs="+", type=Path)
    args = parser.parse_args(argv)
    from relight_rt import RelightError
    from relight_rt.image.io import read_image
    from relight_rt.person.matting import PersonMatter
    from relight_rt.relight.look import shaded_skin, skin_chroma

    matter = PersonMatter(device="cpu")
    gammas = []
    for path in args.photos:
        try:
            rgb = read_image(path, "photo")[..., :3]
        except RelightError as exc:
            print(f"{path.name}: {exc}", file=sys.stderr)
            continue
        skin = skin_of_face(rgb, matter.find_faces(rgb))
        if skin is None or skin.sum() < 200:
            print(f"{path.name}: no face with skin-coloured pixels", file=sys.stderr)
            continue
        rows = fifths(rgb, skin)
        gammas.append(exponent(rows[0], rows[2]))
        cells = " | ".join(f"L* {L:4.1f} C* {C:4.1f} C*/L* {s:.2f}" for L, C, s in rows)
        print(f"{path.name[:18]:18s} {cells} | gamma {gammas[-1]:+.2f}")
    if gammas:
        print(f"median gamma over {len(gammas)} faces: {np.median(gammas):+.2f} (range {min(gammas):+.2f} .. "
              f"{max(gammas):+.2f})")

    def grey(colour, ratio):
        return colour * ratio

    def rule(colour, ratio):
        factor = np.full((1, 1, 3), ratio, np.float32)
        inputs = skin_chroma(colour[None, None], np.ones((1, 1), np.float32))
        gain = shaded_skin(factor, np.full((1, 1), ratio, np.float32), *inputs)
        return (colour * gain)[0, 0]

    print(f"one skin colour dimmed to half its luminance: at one chromaticity gamma {model_exponent(grey):+.2f}, "
          f"with the shaded-skin rule {model_exponent(rule):+.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
