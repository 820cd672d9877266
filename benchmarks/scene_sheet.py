"""Contact sheet: one person composited into several backgrounds (docs/RESULTS.md, "Into any scene").

    python benchmarks/scene_sheet.py --hdri ../shared/hdri --out docs/scene_sheet.png [--models DIR] [--size 384]

The person is the bundled example (relight_rt/data/example.png, a render of our own; linear, so it is
sRGB-encoded first, as a camera would write it). Each background is a perspective view (60°, the
camera looking along −x) of one of the CC0 maps in ../shared/hdri, auto-exposed (mean linear
luminance 0.18) and sRGB-encoded. Rows: the person pasted without relighting (same place and size),
then ``relight_rt.scene.composite`` with the background's own light and a contact shadow. Last column
of each row pair: the background's estimated light on a sphere.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from relight_rt import Relighter, sh  # noqa: E402
from relight_rt._io import read_image, write_image  # noqa: E402
from relight_rt.background import envmap_view, light_from_background  # noqa: E402
from relight_rt.color import linear_to_srgb  # noqa: E402
from relight_rt.exposure import REC709  # noqa: E402

MAPS = ("apartment", "city", "forest", "lab", "night", "sunset", "studio", "bridge")
TURNS = {"studio": 90, "night": 90}  # degrees: turn the map so the view shows more than a black backdrop


def background(path: Path, size: tuple[int, int]) -> np.ndarray:
    env = sh.load_envmap(path)
    turn = TURNS.get(path.stem, 0)
    if turn:
        env = np.roll(env, -(turn * env.shape[1] // 360), axis=1)
    view = envmap_view(env, size, 60.0)
    k = 0.18 / max(float((view @ REC709).mean()), 1e-6)
    return (linear_to_srgb(np.clip(view * k, 0, 1)) * 255 + 0.5).astype(np.uint8)


def pasted(person_srgb: np.ndarray, bg: np.ndarray, height: float, pos: tuple[float, float]) -> np.ndarray:
    """The person laid over the background as it is (no relighting), same placement rule as composite."""
    alpha = person_srgb[..., 3]
    rows, cols = np.flatnonzero((alpha > 0.005).any(1)), np.flatnonzero((alpha > 0.005).any(0))
    y0, y1, x0, x1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
    hb, wb = bg.shape[:2]
    s = height * hb / (y1 - y0)
    nh, nw = round((y1 - y0) * s), round((x1 - x0) * s)
    crop = person_srgb[y0:y1, x0:x1]
    pre = np.concatenate([crop[..., :3] * crop[..., 3:], crop[..., 3:]], 2)
    pre = cv2.resize(pre, (nw, nh), interpolation=cv2.INTER_AREA if s < 1 else cv2.INTER_LINEAR)
    out = bg.astype(np.float32) / 255
    top, left = round(pos[1] * hb) - nh, round(pos[0] * wb - nw / 2)
    ty0, tx0 = max(top, 0), max(left, 0)
    ty1, tx1 = min(top + nh, hb), min(left + nw, wb)
    p = pre[ty0 - top : ty1 - top, tx0 - left : tx1 - left]
    region = out[ty0:ty1, tx0:tx1]
    region *= 1 - p[..., 3:]
    region += p[..., :3]
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hdri", type=Path, required=True)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--models", default=None)
    ap.add_argument("--size", type=int, default=384, help="background width (height 3/4 of it)")
    args = ap.parse_args(argv)
    relighter = Relighter(args.models, device="cpu")
    rgba = read_image(REPO / "relight_rt" / "data" / "example.png", "example")
    person = np.concatenate([linear_to_srgb(rgba[..., :3]), rgba[..., 3:]], 2)
    person8 = (np.clip(person, 0, 1) * 255 + 0.5).astype(np.uint8)
    size = (args.size * 3 // 4, args.size)
    height, pos = 0.8, (0.5, 0.95)
    top, bottom = [], []
    for name in MAPS:
        path = args.hdri / f"{name}.hdr"
        if not path.is_file():
            continue
        bg = background(path, size)
        out = relighter.composite(person8, bg, position=pos, height=height, shadow=True)
        light, _ = light_from_background(bg)
        sphere = sh.render_sphere(light, size=size[0] // 3)
        sphere = linear_to_srgb(np.clip(sphere * (0.8 / max(float(sphere.max()), 1e-6)), 0, 1))
        paste = pasted(person, bg, height, pos)
        paste[: sphere.shape[0], : sphere.shape[1]] = sphere  # the estimated light, top-left corner
        top.append(paste)
        bottom.append(out)
    sheet = np.concatenate([np.concatenate(top, 1), np.concatenate(bottom, 1)], 0)
    if sheet.shape[1] > 3072:  # two rows of four maps
        half = len(top) // 2
        sheet = np.concatenate([np.concatenate(top[:half], 1), np.concatenate(bottom[:half], 1),
                                np.concatenate(top[half:], 1), np.concatenate(bottom[half:], 1)], 0)  # fmt: skip
    write_image(args.out, sheet)
    print(f"wrote {args.out} ({sheet.shape[1]} x {sheet.shape[0]})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
