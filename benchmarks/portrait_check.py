"""Head-and-shoulders crops of real photos relit: does the skin keep its hue, is the lit side the brighter one?

    python benchmarks/portrait_check.py --reference ../shared/reference --out runs/portrait [--models DIR]

The crops: the top 30 % of the person (its mask's rows) of the reference photo and of three reference video
frames, 4:5 portrait boxes centred on the head, cut by the bottom border (the body continues below, as in a
portrait). Each is relit with ``Relighter.relight`` (default "auto" exposure) under
- white lights: ``front`` (the preset), a white soft light from the image's left and one from its right;
- three coloured presets for the contact sheet: window-left, golden-hour, studio.

Measured on the face's skin (skin-coloured input pixels inside the mask, in the top half of the crop):
- hue under the white lights: the angle between the mean linear skin colour's chromaticity before and after
  (degrees in the HSV hue circle) — a white light should not change it;
- the same hue shift for the whole (uncropped) photo under ``front``, on the skin of the person's top 15 %;
- side ratio: mean luminance of the face's image-left half over its right half (split at the face's centroid),
  before and under the white side lights: under the left light > 1, under the right < 1.

Writes OUT/sheet.png (rows: crops; columns: input, then each light; the reference photos are CC BY-NC-SA:
keep the sheet out of the repository) and OUT/portrait_check.json.
"""

from __future__ import annotations

import argparse
import colorsys
import json
import sys
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

import relight_rt  # noqa: E402
from relight_rt import RuntimeConfig, lights  # noqa: E402
from relight_rt.image.color import REC709  # noqa: E402
from relight_rt.image.io import read_image, read_mask  # noqa: E402

WHITE = {
    "front": lights.preset("front"),
    "white-left": lights.directional((0.35, -1.0, 0.25), (1, 1, 1), 1.0, angular_radius=0.6) + lights.ambient(0.06),
    "white-right": lights.directional((0.35, 1.0, 0.25), (1, 1, 1), 1.0, angular_radius=0.6) + lights.ambient(0.06),
}
COLOURED = ("window-left", "golden-hour", "studio")


def portrait_crop(image: np.ndarray, mask: np.ndarray, top: float = 0.30, aspect: float = 0.8):
    """The head-and-shoulders box of a full-body photo: top ``top`` of the person, ``aspect`` = width / height."""
    rows = np.flatnonzero(mask.max(1) > 0.5)
    y0, y1 = int(rows[0]), int(rows[0] + top * (rows[-1] - rows[0]))
    head = mask[y0 : y0 + max((y1 - y0) // 3, 1)] > 0.5
    cx = int(np.mean(np.nonzero(head)[1]))
    y0 = max(y0 - (y1 - y0) // 12, 0)  # a little room above the head
    w = int(round(aspect * (y1 - y0)))
    x0 = int(np.clip(cx - w // 2, 0, image.shape[1] - w))
    return image[y0:y1, x0 : x0 + w].copy(), mask[y0:y1, x0 : x0 + w].copy()


def face_region(image: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Skin-coloured pixels of the input (the classic YCrCb box: Cr 135-180, Cb 85-135) inside the mask, in the
    crop's top half: the face and neck, chosen without the model under test."""
    ycc = cv2.cvtColor((np.clip(image, 0, 1) * 255).astype(np.uint8), cv2.COLOR_RGB2YCrCb)
    cr, cb = ycc[..., 1].astype(int), ycc[..., 2].astype(int)
    region = (cr >= 135) & (cr <= 180) & (cb >= 85) & (cb <= 135) & (mask > 0.5)
    region[region.shape[0] // 2 :] = False
    return region


def hue_degrees(rgb: np.ndarray) -> float:
    return 360.0 * colorsys.rgb_to_hsv(*(rgb / max(float(rgb.max()), 1e-8)))[0]


def hue_shift(a: np.ndarray, b: np.ndarray, region: np.ndarray) -> float:
    d = hue_degrees(b[region].mean(0)) - hue_degrees(a[region].mean(0))
    return float((d + 180.0) % 360.0 - 180.0)


def side_ratio(img: np.ndarray, region: np.ndarray) -> float:
    lum = img @ REC709
    cx = np.nonzero(region)[1].mean()
    cols = np.arange(img.shape[1])[None, :]
    left, right = region & (cols < cx), region & (cols >= cx)
    return float(lum[left].mean() / max(lum[right].mean(), 1e-8))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--reference", type=Path, required=True, help="../shared/reference")
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--models", type=Path, default=None, help="folder with stage1.onnx / stage2.onnx (default: bundled)")
    args = p.parse_args(argv)
    ref = args.reference
    inputs = [("photo", ref / "photo" / "sample.jpg", ref / "photo" / "sample_mask.png")]
    inputs += [(f"frame_{i:03d}", ref / "video" / f"frame_{i:03d}.png", ref / "video" / f"frame_{i:03d}_mask.png")
               for i in (1, 3, 5)]
    relighter = relight_rt.open(RuntimeConfig(models=args.models, device="cpu"))
    args.out.mkdir(parents=True, exist_ok=True)
    rows, report = [], {}
    for name, img_path, mask_path in inputs:
        image = read_image(img_path)
        mask = read_mask(mask_path, image.shape[:2])
        full_region = face_region(image, mask)
        rows_in = np.flatnonzero(mask.max(1) > 0.5)
        full_region[rows_in[0] + int(0.15 * (rows_in[-1] - rows_in[0])) :] = False  # the head of the whole body
        full_shift = hue_shift(image, relighter.relight(image, WHITE["front"], mask=mask), full_region)
        crop, crop_mask = portrait_crop(image, mask)
        dec = relighter.decompose(crop, crop_mask)
        region = face_region(crop, crop_mask)
        entry = {"size": list(crop.shape[:2]), "face_pixels": int(region.sum()),
                 "side_ratio_input": side_ratio(crop, region), "hue_shift_front_whole_photo": full_shift}
        tiles = [crop]
        for lname, light in WHITE.items():
            out = relighter.relight(dec, light)
            entry[f"hue_shift_{lname}"] = hue_shift(crop, out, region)
            entry[f"side_ratio_{lname}"] = side_ratio(out, region)
            tiles.append(out)
        for preset in COLOURED:
            tiles.append(relighter.relight(dec, lights.preset(preset)))
        report[name] = entry
        h = 320
        rows.append(np.concatenate([cv2.resize(t, (int(round(t.shape[1] * h / t.shape[0])), h),
                                               interpolation=cv2.INTER_AREA) for t in tiles], 1))
        print(name, json.dumps({k: round(v, 3) if isinstance(v, float) else v for k, v in entry.items()}))
    width = max(r.shape[1] for r in rows)
    sheet = np.concatenate([np.pad(r, ((0, 0), (0, width - r.shape[1]), (0, 0))) for r in rows], 0)
    cv2.imwrite(str(args.out / "sheet.png"), cv2.cvtColor((np.clip(sheet, 0, 1) * 255 + 0.5).astype(np.uint8),
                                                        cv2.COLOR_RGB2BGR))
    columns = ["input", *WHITE, *COLOURED]
    summary = {
        "columns": columns,
        "models": str(args.models or "bundled"),
        "mean_abs_hue_shift_white": float(np.mean([abs(e[f"hue_shift_{k}"]) for e in report.values() for k in WHITE])),
        "mean_abs_hue_shift_front_whole_photo": float(np.mean([abs(e["hue_shift_front_whole_photo"])
                                                               for e in report.values()])),
        "left_brighter_under_white_left": int(sum(e["side_ratio_white-left"] > 1 for e in report.values())),
        "right_brighter_under_white_right": int(sum(e["side_ratio_white-right"] < 1 for e in report.values())),
        "crops": report,
    }
    (args.out / "portrait_check.json").write_text(json.dumps(summary, indent=1))
    print(json.dumps({k: v for k, v in summary.items() if k != "crops"}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
