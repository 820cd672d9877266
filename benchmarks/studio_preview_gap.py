"""How far the studio's live preview is from the full result it stands for, and what makes the gap.

    PYTHONPATH=$PWD python benchmarks/studio_preview_gap.py [--without head-blend,head,fill]

Brightness: the person's mean luminance (Rec. 709 of the values, weighted by the mask) in the preview the page
draws once the light has settled (albedo x shading with the shaded-skin gain over the photo, at the page's size,
the shading times the server's plane for that light: the body's cast shadows and the head pass's change,
``Studio.shadow``; the Python mirror of the shaders, relight_rt.apps.studio.preview ``preview_picture``, as
tests/integration/test_studio_browser.py draws it) over the full result's, on the bundled example person, per preset
given as an array ("auto" exposure, no preset EV); beside it, the same without the server's plane (the preview
while a light is being dragged). ``--without`` switches off, in the full result, the head pass's blend of its
shading (Factor.blend_head), the head pass itself (Relighter.face_pass) or the deep-shadow fill
(ShadowFill.shadow_weight): each ratio that moves to 1 names a part of the gap the preview leaves out (both figures
below take ``--without``).

Background grade: on the bundled street photo (a backdrop to grade, the automatic matte), the grade the preview
draws (Studio.preview_grade, what sh.js backgroundGrade computes on the relighter's grade sample,
relight_rt.relight.compose ``Composer.grade_inputs``) against the full result's (the median ratio of the backdrop's
values with --grade-background and without), per channel in EV of light (x 2.2). The preview's grade carries the
head pass's blend (compose ``HeadBlend``); ``--without head-blend`` takes it out of both (window-left's gap was 0.14
EV with the blend in the result only, 0.03 with it in neither).
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
from relight_rt.light.exposure import DISPLAY_GAMMA
from relight_rt.relight import factor as _factor
from relight_rt.relight import shadow_fill as _shadow_fill

BUNDLED = Path(relight_rt.__file__).resolve().parent / "models"
STREET = Path(relight_rt.__file__).resolve().parent / "data" / "example_scene.jpg"
PRESETS = ("rim", "window-left", "studio", "night", "campfire", "golden-hour")


def decoded(png: bytes) -> np.ndarray:
    return cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)[..., ::-1].astype(np.float32) / 255


def relighter(without: set[str]):
    """The bundled models' Relighter with the parts named in ``without`` switched off (module docstring)."""
    rl = relight_rt.open(RuntimeConfig(models=BUNDLED, device="cpu"))
    if "head" in without:
        rl.face_pass = False
    if "head-blend" in without:  # in the result and in the preview's grade sample
        _factor.Factor.blend_head = lambda self, *args, **kwargs: None
        _factor.Factor.head_grade_inputs = lambda self, dec: None
    if "fill" in without:
        _shadow_fill.ShadowFill.shadow_weight = lambda self, dec: None
    return rl


def brightness(without: set[str]) -> None:
    studio = Studio(example_path(), None, "original", relighter(without))
    meta = studio.info()["preview"]
    layers = unpack_layers(studio.layers_bytes(), meta)
    m = layers["mask"]
    print(f"preview / result, person's mean luminance, bundled example, without: {sorted(without) or 'nothing'};"
          " settled (the server's plane drawn), dragged (not yet)")
    back = layers["background"].transpose(1, 2, 0) * (1 - m[..., None])
    for name in PRESETS:
        light = lights.preset(name).astype(np.float32)
        answer = studio.shadow(light.ravel().tolist())
        plane = shadow_plane(answer, meta["height"], meta["width"])
        settled = back + preview_picture(layers, meta, studio.preview_light(light, meter=answer["meter"]), plane)
        dragged = back + preview_picture(layers, meta, studio.preview_light(light))
        _, rec = studio.render(light.tolist())
        final = cv2.resize(decoded(rec.png), (meta["width"], meta["height"]), interpolation=cv2.INTER_AREA)
        want = float((final @ REC709 * m).sum())
        ratios = [float((p @ REC709 * m).sum()) / want for p in (settled, dragged)]
        print(f"  {name:12s} {ratios[0]:.3f} {ratios[1]:.3f}")


def grade(without: set[str]) -> None:
    studio = Studio(str(STREET), None, "original", relighter(without))
    back = np.asarray(studio.dec.mask) == 0
    print(f"background grade, preview against the full result, {STREET.name}: per channel R, G, B")
    for name in PRESETS:
        light = lights.preset(name).astype(np.float32)
        drawn = studio.preview_grade(studio.preview_light(light))
        _, off = studio.render(light.tolist(), grade_background=False)
        _, on = studio.render(light.tolist(), grade_background=True)
        a, b = decoded(off.png) * 255, decoded(on.png) * 255
        keep = back & (a.min(axis=2) > 20) & (a.max(axis=2) < 235)  # clear of rounding and of the clip at white
        result = np.median(b[keep] / a[keep], axis=0)
        ev = np.log2(drawn / result) * DISPLAY_GAMMA
        r3 = lambda v: np.round(np.asarray(v, np.float64), 3).tolist()  # noqa: E731
        print(f"  {name:12s} preview {r3(drawn)} result {r3(result)} preview - result {r3(ev)} EV")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--without", default="", help="comma-separated: head-blend, head, fill")
    args = p.parse_args()
    without = {w for w in args.without.split(",") if w}
    if not without <= {"head-blend", "head", "fill"}:
        p.error(f"--without: unknown {sorted(without - {'head-blend', 'head', 'fill'})}")
    brightness(without)
    grade(without)


if __name__ == "__main__":
    main()
