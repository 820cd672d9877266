"""How far the studio's live preview is from the final result where the face's cast shadows fall (issue 48).

    python benchmarks/preview_shadow.py [--photo P --mask M]... [--yale ../shared/realdata/yale] [--out runs/ps]

The final result darkens the face mesh's cast shadows under a new light's lamp (the nose's, the brows';
relight_rt.relight.cast_shadow); the preview the page draws from its layers (albedo x max(0, T.L),
relight_rt.apps.studio) had none. Per photo and light (the white side lamps ``LEFT`` and ``RIGHT`` of
benchmarks/real_photos.py), the preview is drawn as the page draws it (``apps.studio.preview.preview_picture``,
the light ``Studio.preview_light``) without and with the server's shadow layer (``Studio.shadow``), and the final result
(``Studio.render``) is reduced to the preview's size. The server's plane also carries the head pass's change
(since mirror34); the shadow's pixels are the cast shadows' alone. Figures, CIE L* of both: mean |dL*| over the
shadow's pixels (depth >= 0.1), its signed mean (> 0: the preview brighter) and mean |dL*| over the whole person
(mask > 0.5). Photos:
the reference photo with its mask (../shared/reference) and a frontal Extended Yale B face with an ellipse mask
(benchmarks/yale_eval.py; evaluation only, nothing is written but the figures). Writes OUT/preview_shadow.json and
prints the table.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

# real_photos puts this checkout (and benchmarks/) first on sys.path: the relight_rt imported below is this one
from real_photos import LEFT, RIGHT

# isort: split
from _shared import shared_path, warn_missing

from relight_rt import Relighter, RuntimeConfig
from relight_rt.apps.studio.core import Studio
from relight_rt.apps.studio.preview import preview_picture, shadow_plane, unpack_layers

DEEP = 0.1  # a shadow pixel: the final result's shading there at most 0.9 of the light's


def lab_l(rgb: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(np.clip(rgb, 0, 1).astype(np.float32), cv2.COLOR_RGB2Lab)[..., 0]


def figures(studio: Studio, light: np.ndarray) -> dict:
    meta = studio.info()["preview"]
    layers = unpack_layers(studio.layers_bytes(), meta)
    h, w = meta["height"], meta["width"]
    m = layers["mask"]
    back = layers["background"].transpose(1, 2, 0) * (1 - m[..., None])
    t0 = time.perf_counter()
    answer = studio.shadow(light.ravel().tolist())
    seconds = time.perf_counter() - t0
    plane = shadow_plane(answer, h, w)
    before = back + preview_picture(layers, meta, studio.preview_light(light))
    after = back + preview_picture(layers, meta, studio.preview_light(light, meter=answer["meter"]), plane)
    _, rec = studio.render(light.tolist())
    final = cv2.imdecode(np.frombuffer(rec.png, np.uint8), cv2.IMREAD_COLOR)[..., ::-1].astype(np.float32) / 255
    final = cv2.resize(final, (w, h), interpolation=cv2.INTER_AREA)
    cast = shadow_plane({**answer, "head_box": []}, h, w)  # the cast shadows alone (without the head pass's change)
    shade, person = (cast <= 1 - DEEP) & (m > 0.5), m > 0.5
    out = {"shadow_pixels": int(shade.sum()), "meter": answer["meter"], "shadow_seconds": seconds,
           "layer_bytes": len(answer["depth"])}
    for name, pic in (("without", before), ("with", after)):
        d = lab_l(pic) - lab_l(final)
        out[name] = {"shadow_abs_dl": float(np.abs(d[shade]).mean()) if shade.any() else None,
                     "shadow_dl": float(d[shade].mean()) if shade.any() else None,
                     "person_abs_dl": float(np.abs(d[person]).mean())}
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--photo", action="append", type=Path, default=[])
    p.add_argument("--mask", action="append", type=Path, default=[])
    p.add_argument("--reference", type=Path, default=shared_path("reference"))
    p.add_argument("--yale", type=Path, default=shared_path("realdata", "yale"))
    p.add_argument("--subject", default="yaleB05")
    p.add_argument("--models", type=Path, default=None)
    p.add_argument("--out", type=Path, default=Path("runs/preview_shadow"))
    args = p.parse_args(argv)
    relighter = Relighter(RuntimeConfig(models=args.models, device="cpu"))
    photos = list(zip(args.photo, args.mask, strict=True))
    if not photos and (args.reference / "photo" / "sample.jpg").is_file():
        photos.append((args.reference / "photo" / "sample.jpg", args.reference / "photo" / "sample_mask.png"))
    elif not photos:
        warn_missing(args.reference / "photo" / "sample.jpg", "the reference photo")
    rows: dict = {}
    with tempfile.TemporaryDirectory(prefix="preview-shadow-") as tmp:
        frontal = args.yale / args.subject / f"{args.subject}_P00A+000E+00.png"
        if frontal.is_file():
            from yale_eval import ellipse

            h, w = cv2.imread(str(frontal), cv2.IMREAD_GRAYSCALE).shape
            mask = Path(tmp) / "ellipse.png"
            cv2.imwrite(str(mask), (ellipse((h, w)) * 255).astype(np.uint8))
            photos.append((frontal, mask))
        else:
            warn_missing(frontal, "the Yale face")
        for photo, mask in photos:
            studio = Studio(photo, mask, "original", relighter)
            for name, light in (("LEFT", LEFT), ("RIGHT", RIGHT)):
                rows[f"{photo.stem} {name}"] = figures(studio, np.asarray(light, np.float32))
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "preview_shadow.json").write_text(json.dumps(rows, indent=1))
    print(f"{'photo, light':42s} {'shadow px':>9s}  |dL*| shadow without / with   signed without / with"
          "   |dL*| person without / with   meter   layer")
    for key, r in rows.items():
        a, b = r["without"], r["with"]
        fmt = lambda v: "   -" if v is None else f"{v:5.2f}"  # noqa: E731
        print(f"{key:42s} {r['shadow_pixels']:9d}  {fmt(a['shadow_abs_dl'])} / {fmt(b['shadow_abs_dl'])}"
              f"              {fmt(a['shadow_dl'])} / {fmt(b['shadow_dl'])}           {a['person_abs_dl']:5.2f} / "
              f"{b['person_abs_dl']:5.2f}         {r['meter']:.3f}  {r['layer_bytes']} B, "
              f"{1000 * r['shadow_seconds']:.0f} ms")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
