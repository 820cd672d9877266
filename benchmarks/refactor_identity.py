"""Outputs to compare bit for bit across a refactor (split37): save them on the old tree, save them on the new one,
compare.

    (in a checkout of the old tree)  PYTHONPATH=$PWD python benchmarks/refactor_identity.py save /tmp/before
    (in the new tree)                PYTHONPATH=$PWD python benchmarks/refactor_identity.py save /tmp/after
    PYTHONPATH=$PWD python benchmarks/refactor_identity.py compare /tmp/before /tmp/after

``save`` writes DIR/outputs.npz: on the bundled example person (CPU, default models), ``relight`` under presets,
backgrounds and exposures, ``layers``, ``relight_many`` of a list and of an array, ``iter_relight`` of a photo,
``resolve_light`` (float32, float64, a Decomposition, a photo), ``cast_shadows``; a group (the example beside its
mirror image, ``matting="all"``) through the same verbs; the studio's packed layers, its preview of two lights
with the server's shadow plane, and a render's PNG. ``compare`` says which arrays differ in dtype, shape or any
byte (exit status 1 if one does).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

import relight_rt
from relight_rt import RuntimeConfig, lights
from relight_rt.cli.demo import example_path
from relight_rt.image.compositing import Background
from relight_rt.image.io import read_image


def _one_person(out: dict) -> relight_rt.Relighter:
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


def _studio(out: dict, r: relight_rt.Relighter) -> None:
    from relight_rt.apps.studio import core

    try:  # where the preview maths lives since split37, and before
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


def save(folder: Path) -> None:
    out: dict[str, np.ndarray] = {}
    r = _one_person(out)
    _group(out)
    _studio(out, r)
    folder.mkdir(parents=True, exist_ok=True)
    np.savez(folder / "outputs.npz", **out)
    print(f"{len(out)} arrays in {folder / 'outputs.npz'}")


def compare(a: Path, b: Path) -> int:
    old, new = np.load(a / "outputs.npz"), np.load(b / "outputs.npz")
    names = sorted(set(old.files) | set(new.files))
    differ = [n for n in names if n not in old.files or n not in new.files or old[n].dtype != new[n].dtype
              or old[n].shape != new[n].shape or old[n].tobytes() != new[n].tobytes()]
    print(f"{len(names)} arrays, {len(differ)} differ" + (f": {', '.join(differ)}" if differ else " (bit for bit)"))
    return 1 if differ else 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="verb", required=True)
    sub.add_parser("save").add_argument("folder", type=Path)
    cmp = sub.add_parser("compare")
    cmp.add_argument("before", type=Path)
    cmp.add_argument("after", type=Path)
    args = parser.parse_args()
    if args.verb == "save":
        save(args.folder)
        return 0
    return compare(args.before, args.after)


if __name__ == "__main__":
    sys.exit(main())
