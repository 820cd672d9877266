"""Where the studio's settled preview departs from the full result around the head, and how hard the server's
factor for the head pass's change pushes it (preview35).

    PYTHONPATH=$PWD python benchmarks/studio_head_change.py [--photo PHOTO --mask MASK] [--crops DIR]

Per preset (given as an array, "auto" exposure), on the bundled example person and, with ``--photo``, on that photo
too: the person's mean luminance preview / result (what tests/integration/test_studio_browser.py bounds by 0.045),
the mean and p99.9 |dL*| between them over the head box (the box of the server's factor for the head pass's change,
``Studio.shadow``, on the person, mask > 0.5), the largest value of the plane the page multiplies the shading by
(``shadow_plane``), and how many head-box pixels the preview draws brighter than the result by more than 0.1 in
luminance. The preview is the page's drawing in Python (``preview_picture``), as the browser test draws it.
``--crops DIR``: under campfire, a 120 x 100 preview-pixel crop around the plane's peak in the head box, preview |
result, written at 100 % and at 300 % (nearest) as DIR/<photo>_campfire[_3x].png, to look at.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np

import relight_rt
from relight_rt import RuntimeConfig, lights
from relight_rt.apps.studio.core import Studio
from relight_rt.apps.studio.preview import preview_picture, shadow_plane, unpack_layers
from relight_rt.cli.demo import example_path
from relight_rt.image.color import REC709

BUNDLED = Path(relight_rt.__file__).resolve().parent / "models"
PRESETS = ("rim", "window-left", "studio", "night", "campfire", "golden-hour")


def lstar(rgb: np.ndarray) -> np.ndarray:
    y = np.clip(rgb @ REC709, 0, None)
    return np.where(y > 0.008856, 116 * np.cbrt(y) - 16, 903.3 * y)


def report(photo: Path, mask: Path | None, models: Path | None, crops: Path | None) -> None:
    rl = relight_rt.open(RuntimeConfig(models=models, device="cpu") if models else RuntimeConfig(device="cpu"))
    studio = Studio(photo, mask, "original", rl)
    meta = studio.info()["preview"]
    layers = unpack_layers(studio.layers_bytes(), meta)
    m = layers["mask"]
    back = layers["background"].transpose(1, 2, 0) * (1 - m[..., None])
    person = m > 0.5
    print(f"{photo.name}: preview / result brightness | head box |dL*| mean, p99.9 | plane max | brighter by > 0.1")
    for name in PRESETS:
        light = lights.preset(name).astype(np.float32)
        answer = studio.shadow(light.ravel().tolist())
        plane = shadow_plane(answer, meta["height"], meta["width"])
        preview = back + preview_picture(layers, meta, studio.preview_light(light, meter=answer["meter"]), plane)
        _, rec = studio.render(light.tolist())
        final = cv2.imdecode(np.frombuffer(rec.png, np.uint8), cv2.IMREAD_COLOR)[..., ::-1].astype(np.float32) / 255
        final = cv2.resize(final, (meta["width"], meta["height"]), interpolation=cv2.INTER_AREA)
        head = np.zeros_like(person)
        if answer["head_box"]:
            y0, y1, x0, x1 = answer["head_box"]
            head[y0:y1, x0:x1] = True
        head &= person
        d = np.abs(lstar(preview) - lstar(final))
        ratio = float((preview @ REC709 * m).sum() / (final @ REC709 * m).sum())
        brighter = int((head & (preview @ REC709 > final @ REC709 + 0.1)).sum())
        mean, p999 = (float(d[head].mean()), float(np.percentile(d[head], 99.9))) if head.any() else (0.0, 0.0)
        print(f"  {name:12s} {ratio:.3f} | {mean:.2f} {p999:.1f} | {plane.max():.2f} | {brighter}")
        if crops is not None and name == "campfire" and head.any():
            cy, cx = np.unravel_index(np.argmax(np.where(head, plane, 0)), plane.shape)
            y0 = int(np.clip(cy - 50, 0, meta["height"] - 100))
            x0 = int(np.clip(cx - 60, 0, meta["width"] - 120))
            pair = np.concatenate([preview[y0 : y0 + 100, x0 : x0 + 120], final[y0 : y0 + 100, x0 : x0 + 120]], axis=1)
            pair = (np.clip(pair, 0, 1)[..., ::-1] * 255).round().astype(np.uint8)
            crops.mkdir(parents=True, exist_ok=True)
            cv2.imwrite(str(crops / f"{photo.stem}_campfire.png"), pair)
            cv2.imwrite(str(crops / f"{photo.stem}_campfire_3x.png"),
                        cv2.resize(pair, None, fx=3, fy=3, interpolation=cv2.INTER_NEAREST))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--photo", type=Path, help="a further photo (the default models)")
    ap.add_argument("--mask", type=Path, help="its mask (default: PHOTO's NAME_mask.png)")
    ap.add_argument("--crops", type=Path, help="write the campfire crops here")
    args = ap.parse_args()
    report(Path(example_path()), None, BUNDLED, args.crops)
    if args.photo is not None:
        report(args.photo, args.mask, None, args.crops)


if __name__ == "__main__":
    main()
