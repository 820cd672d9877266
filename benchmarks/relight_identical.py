"""Whether this checkout relights photos to the same pixels as another one (a refactor's check), bit for bit.

    PYTHONPATH=$PWD python benchmarks/relight_identical.py OTHER_CHECKOUT [PHOTO ...] [--presets studio,rim] [--api]

Each checkout runs in its own process (``PYTHONPATH`` set to it, this script's code): the bundled models, the
automatic matte, one ``decompose`` per photo, then ``relight`` of that Decomposition under each preset; the results
go to a temporary .npz (outside the repository: the photos may be evaluation data) and are compared by dtype, shape
and every byte. Prints, per photo and preset, whether the two are equal and the largest difference; exits 1 when any
differs.

``--api`` adds every public verb on the bundled example person (CPU): ``relight`` under presets, backgrounds and
exposures, ``layers``, ``relight_many`` of a list and of an array, ``iter_relight`` of a photo, ``resolve_light``
(float64, a Decomposition, a photo), ``cast_shadows`` (the example: its meter alone); a group (the example beside
its mirror image, ``matting="all"``) through the same verbs; the studio's packed layers, its preview of two lights
with the server's shadow plane, and a render's PNG (split37's check: 37 arrays, ~10 s a checkout).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

PRESETS = "studio,window-left,campfire,night,rim"


def child(out: str, presets: list[str], photos: list[str], api: bool) -> None:
    import relight_rt
    from relight_rt import lights
    from relight_rt.image.io import read_image

    results = {}
    if photos:
        r = relight_rt.open()
        for i, photo in enumerate(photos):
            dec = r.decompose(read_image(photo))
            for name in presets:
                results[f"{i}:{name}"] = r.relight(dec, lights.preset(name))
    if api:
        sweep: dict = {}
        r = _one_person(sweep)
        _group(sweep)
        _studio(sweep, r)
        results.update({f"api:{k}": v for k, v in sweep.items()})
    np.savez(out, **results)


def _one_person(out: dict):
    import relight_rt
    from relight_rt import RuntimeConfig, lights
    from relight_rt.cli.demo import example_path
    from relight_rt.image.compositing import Background

    r = relight_rt.open(RuntimeConfig(device="cpu"))
    ex = example_path()
    dec = r.decompose(ex)
    for p in ("studio", "night", "golden-hour"):
        out[f"relight_{p}"] = r.relight(dec, p)
    out["relight_black_ev"] = r.relight(dec, "rim", background="black", exposure=0.5)
    out["relight_graded"] = r.relight(dec, lights.preset("window-left"), background=Background.original(grade=True))
    result = r.layers(dec, "studio", background="transparent")
    out["layers_image"] = result.image
    out.update({f"layers_{k}": v for k, v in result.layers.items()})
    out["many"] = r.relight_many(dec, ["studio", "night", lights.preset("rim")], batch_size=2)
    out["many_array"] = r.relight_many(dec, np.stack([lights.preset("campfire"), lights.preset("neon")]), batch_size=1)
    out["iter_photo"] = np.stack(list(r.iter_relight(ex, ["overcast", "front"], batch_size=3)))
    out["resolve64"] = r.resolve_light("studio", dtype=np.float64)
    out["resolve_dec"] = r.resolve_light(dec)
    out["resolve_photo"] = r.resolve_light(ex)
    depth, meter = r.cast_shadows(dec, "rim")
    out["cast_meter"] = np.array(meter)
    if depth is not None:
        out["cast_depth"] = depth
    return r


def _group(out: dict) -> None:
    import relight_rt
    from relight_rt import RuntimeConfig, lights
    from relight_rt.cli.demo import example_path
    from relight_rt.image.compositing import Background
    from relight_rt.image.io import read_image

    rgba = read_image(example_path())
    a = rgba[..., 3:4]
    one = rgba[..., :3] * a + 0.55 * (1 - a)
    image = np.ascontiguousarray(np.hstack([one, one[:, ::-1]]))
    r = relight_rt.open(RuntimeConfig(device="cpu", matting="all"))
    dec = r.decompose(image)
    out["group_people"] = np.array(len(dec.people))
    out["group_rim"] = r.relight(dec, "rim")
    out["group_night"] = r.relight(dec, "night", background="transparent")
    result = r.layers(dec, "studio")
    out["group_layers_image"] = result.image
    out.update({f"group_layers_{k}": v for k, v in result.layers.items()})
    out["group_many"] = r.relight_many(dec, ["studio", "night", lights.preset("golden-hour")], batch_size=2,
                                       background=Background.original(grade=True))
    out["group_iter_photo"] = np.stack(list(r.iter_relight(image, [lights.preset("rim"), lights.preset("front")],
                                                           batch_size=1)))


def _studio(out: dict, r) -> None:
    from relight_rt import lights
    from relight_rt.apps.studio import core
    from relight_rt.cli.demo import example_path

    try:  # where the preview maths lives since split37; before it, in core
        from relight_rt.apps.studio import preview
    except ImportError:
        preview = core
    studio = core.Studio(example_path(), None, "original", r, preview_pixels=200_000)
    data = studio.layers_bytes()
    meta = studio._layers
    out["studio_layers_bytes"] = np.frombuffer(data, np.uint8)
    layers = preview.unpack_layers(data, meta)
    for name in ("studio", "rim"):
        plane = preview.shadow_plane(studio.shadow(lights.preset(name)), meta["height"], meta["width"])
        out[f"studio_plane_{name}"] = plane
        out[f"studio_preview_{name}"] = preview.preview_picture(layers, meta, studio.preview_light(lights.preset(name)),
                                                                plane)
    _, render = studio.render(lights.preset("golden-hour"))
    out["studio_render_png"] = np.frombuffer(render.png, np.uint8)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("other", help="the other checkout (its root: relight_rt/ inside)")
    p.add_argument("photos", nargs="*")
    p.add_argument("--presets", default=PRESETS)
    p.add_argument("--api", action="store_true", help="also every public verb on the bundled example (see above)")
    p.add_argument("--child", default=None, help=argparse.SUPPRESS)
    args = p.parse_intermixed_args()  # options anywhere among the photos
    presets = args.presets.split(",")
    photos = [str(Path(x).resolve()) for x in args.photos]
    if not photos and not args.api:
        p.error("give photos, --api or both")
    if args.child:
        child(args.child, presets, photos, args.api)
        return 0

    here = Path(__file__).resolve().parents[1]
    with tempfile.TemporaryDirectory() as tmp:
        saved = []
        for k, root in enumerate((here, Path(args.other).resolve())):
            out = str(Path(tmp) / f"{k}.npz")
            env = {**os.environ, "PYTHONPATH": str(root)}
            subprocess.run([sys.executable, str(Path(__file__).resolve()), str(root), *photos, "--presets",
                            args.presets, *(["--api"] if args.api else []), "--child", out], check=True, env=env,
                           cwd=root)  # fmt: skip
            saved.append(np.load(out))
        a, b = saved
        same = set(a.files) == set(b.files)
        for key in sorted(set(a.files) & set(b.files), key=a.files.index):
            x, y = a[key], b[key]
            equal = x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes()
            worst = float(np.abs(x.astype(np.float64) - y).max()) if x.shape == y.shape and x.size else 0.0
            verdict = "identical" if equal else "DIFFERENT"
            what, name = key.split(":", 1)
            print(f"{'api' if what == 'api' else Path(photos[int(what)]).name} {name}: {verdict} "
                  f"(max |diff| {worst:.3g})")
            same &= equal
        for key in sorted(set(a.files) ^ set(b.files)):
            print(f"{key}: in one checkout only")
    print("all identical" if same else "some differ")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
