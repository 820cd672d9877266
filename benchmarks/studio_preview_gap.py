"""How far the studio's live preview is from the full result it stands for, and what makes the gap.

    PYTHONPATH=$PWD python benchmarks/studio_preview_gap.py [--without head-blend,head,fill]
    PYTHONPATH=$PWD python benchmarks/studio_preview_gap.py --band [--photos reference,p104,p286]

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

``--band``: the kept background's rim (relight_rt.relight.kept_rim) on the person's outline, preview against result
with the rim and without it, on the reference photo and people_masks photos (``band``; issue 48, studio43).
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
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


BAND_LIGHTS = ("LEFT", "RIGHT", "campfire")
BAND_EDGE, BAND_REACH = 8, 12  # benchmarks/dark_edge.py's band: this near the outline, background this near


def band_photo(name: str, folder: Path) -> Path:
    """``name`` ("reference": the reference photo, else a people_masks photo such as p104) copied alone into
    ``folder`` (outside the repository), so that the studio finds no mask beside it and mattes it itself."""
    from _shared import shared_path

    src = (shared_path("reference", "photo", "sample.jpg") if name == "reference"
           else shared_path("realdata", "people_masks", "photos", f"{name}.jpg"))
    dst = folder / f"{name}.jpg"
    shutil.copyfile(src, dst)
    return dst


def band(names: list[str]) -> None:
    """The kept background's rim (relight_rt.relight.kept_rim) in the preview: the preview (settled) against the full
    result, mean |difference| in 8-bit levels on the outline's band (the person's preview pixels within
    ``BAND_EDGE`` px inside the shown matte's 0.5 outline with background, the matte <= 0.02, within ``BAND_REACH``
    px) with the rim and without it, and the largest difference the rim makes off its own pixels (0: elsewhere
    unchanged); the automatic matte, the photo's own background, "auto" exposure."""
    from real_photos import LEFT, RIGHT

    rl = relighter(set())
    print("outline band, |preview - result| (8-bit levels, mean): without the rim -> with it; off the rim's pixels")
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            t0 = time.perf_counter()
            studio = Studio(band_photo(name, Path(tmp)), None, "original", rl)
            meta = studio.info()["preview"]
            layers = unpack_layers(studio.layers_bytes(), meta)
            bare = {k: v for k, v in layers.items() if k != "rim"}
            m = layers["mask"]
            inside = (m >= 0.5).astype(np.uint8)
            depth = cv2.distanceTransform(np.pad(inside, 1, constant_values=1), cv2.DIST_L2, 3)[1:-1, 1:-1]
            to_bg = cv2.distanceTransform((m > 0.02).astype(np.uint8), cv2.DIST_L2, 3)
            where = (inside > 0) & (depth <= BAND_EDGE) & (to_bg <= BAND_REACH)
            off = np.ones(m.shape, bool)
            off.reshape(-1)[layers["rim"]["index"]] = False
            back = layers["background"].transpose(1, 2, 0) * (1 - m[..., None])
            print(f"  {name}: {meta['width']}x{meta['height']}, rim {meta['rim_samples']} pixels "
                  f"({16 * meta['rim_samples']} bytes of {len(studio.layers_bytes())}), band {int(where.sum())} px")
            for light_name in BAND_LIGHTS:
                light = np.asarray({"LEFT": LEFT, "RIGHT": RIGHT}.get(light_name) if light_name in ("LEFT", "RIGHT")
                                   else lights.preset(light_name), np.float32)
                answer = studio.shadow(light.ravel().tolist())
                plane = shadow_plane(answer, meta["height"], meta["width"])
                shown = studio.preview_light(light, meter=answer["meter"])
                with_rim = back + preview_picture(layers, meta, shown, plane)
                without = back + preview_picture(bare, meta, shown, plane)
                _, rec = studio.render(light.ravel().tolist())
                final = cv2.resize(decoded(rec.png), (meta["width"], meta["height"]), interpolation=cv2.INTER_AREA)
                gap = [float(np.abs(np.clip(p, 0, 1) - final)[where].mean()) * 255 for p in (without, with_rim)]
                moved = float(np.abs(with_rim - without)[off].max()) * 255
                print(f"    {light_name:9s} {gap[0]:.3f} -> {gap[1]:.3f} ({gap[1] / gap[0] - 1:+.1%}); off {moved:.3f}")
            print(f"    ({time.perf_counter() - t0:.0f} s)", flush=True)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--without", default="", help="comma-separated: head-blend, head, fill")
    p.add_argument("--band", action="store_true", help="the kept rim on the outline's band (band's docstring)")
    p.add_argument("--photos", default="reference,p104,p286", help="--band's photos: reference and people_masks names")
    args = p.parse_args()
    if args.band:
        band(args.photos.split(","))
        return
    without = {w for w in args.without.split(",") if w}
    if not without <= {"head-blend", "head", "fill"}:
        p.error(f"--without: unknown {sorted(without - {'head-blend', 'head', 'fill'})}")
    brightness(without)
    grade(without)


if __name__ == "__main__":
    main()
