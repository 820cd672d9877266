"""Contact sheet of placement and light: people of each framing composited into many places (issue 49).

    python benchmarks/scene_contact_sheet.py --out runs/scene/contact \\
        --person full:PHOTO[:MASK] --person half:PHOTO[:MASK] --person portrait:PHOTO[:MASK] ... \\
        --hdri ../shared/hdri --views sunset:20,0 dawn:30,0 ... --photos PLACE.jpg ... [--size 640x480] \\
        [--rim on|auto|off] [--no-people]

Each person (its kind, "full", "half" or "portrait", is only a label: ``relight_rt.scene_place`` tells from the
matte how the photo framed them) goes into every place: a panorama view (``NAME:AZ,EL[,FOV]`` of ``--hdri``, by
``relight_rt.apps.panorama.composite_panorama``: the plate and the light from the map, as ``composite --view``) and
every
``--photos`` photo of a place (``relight_rt.scene.composite``: the light estimated from the photo, centre-cropped to
``--size``'s aspect and resized to it first). Everything else is the command's default (automatic placement,
shadows, camera matching, light wrap, frame metering), except the rim of a source behind the person: on views as
``composite --view`` (on), on photos as ``composite --rim-auto`` (where a clipped source is in frame and the photo
reads as back-lit; ``composite``'s default is none); ``--rim on`` puts it on every photo (the source, else a back
key's), ``--rim off`` on none, views included.

Writes under ``--out``: every composite at 100 % (``PERSON/PLACE.png``), one sheet per person (``PERSON.png``, the
places in a grid at half size, each labelled) and ``report.json`` (each composite's placement: the person's box,
their feet, the borders that cut them; and its wall time). The people and photos are whatever you pass: real
photos (../shared/realdata) are for looking at, so keep the output under runs/ (never committed).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from _shared import missing, shared_path  # noqa: E402
from scene_sheet import photo_background  # noqa: E402  (a photo of a place at the sheet's size)

from relight_rt import Relighter, RuntimeConfig, envmap  # noqa: E402
from relight_rt import scene as scene_mod  # noqa: E402
from relight_rt.apps.panorama import composite_panorama, parse_size  # noqa: E402
from relight_rt.apps.scene_place import framing  # noqa: E402
from relight_rt.image.io import write_image  # noqa: E402


def label(tile: np.ndarray, text: str) -> np.ndarray:
    out = tile.copy()
    cv2.putText(out, text, (6, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 3, cv2.LINE_AA)
    cv2.putText(out, text, (6, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1, cv2.LINE_AA)
    return out


def grid(tiles: list[np.ndarray], cols: int) -> np.ndarray:
    blank = np.zeros_like(tiles[0])
    tiles = tiles + [blank] * (-len(tiles) % cols)
    return np.vstack([np.hstack(tiles[i : i + cols]) for i in range(0, len(tiles), cols)])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--person", action="append", default=[], metavar="KIND:PHOTO[:MASK]", required=True)
    ap.add_argument("--hdri", type=Path, default=shared_path("hdri"))
    ap.add_argument("--views", nargs="*", default=[], metavar="NAME:AZ,EL[,FOV]")
    ap.add_argument("--photos", type=Path, nargs="*", default=[])
    ap.add_argument("--size", default="640x480", help="the places' size, WxH")
    ap.add_argument("--rim", choices=("on", "auto", "off"), default="auto",
                    help="the rim of a source behind the person on photos (composite's rim=True, 'auto', False; "
                    "views: on unless off)")  # fmt: skip
    ap.add_argument("--models", default=None)
    ap.add_argument("--no-people", action="store_true",
                    help="look for nobody in the places (as with matting off: the horizon from the verticals alone, "
                    "no room made beside people there); the people's masks must be given")  # fmt: skip
    args = ap.parse_args(argv)
    if args.views and not args.hdri.is_dir():
        raise SystemExit(missing(args.hdri))
    size = parse_size(args.size)
    rl = Relighter(RuntimeConfig(models=args.models, device="cpu", matting="off" if args.no_people else "auto"))
    places = []  # (name, kind, thing)
    for spec in args.views:
        name, view = spec.split(":", 1)
        env = envmap.load_envmap(args.hdri / f"{name}.hdr")
        places.append((f"{name}_{view.replace(',', '_')}", "view", (env, view)))
    for path in args.photos:
        places.append((path.stem, "photo", photo_background(path, (size[1], size[0]))))
    report = []
    seen = set()
    for spec in args.person:
        kind, rest = spec.split(":", 1)
        photo, _, mask = rest.partition(":")
        photo = Path(photo)
        mask_arr = mask or None  # a path, or None: the automatic matte
        matte = cv2.imread(mask, cv2.IMREAD_GRAYSCALE) if mask else None
        who = f"{kind}_{photo.stem}"
        while who in seen:  # two people from photos of one name: each keeps its own folder and sheet
            who += "_"
        seen.add(who)
        (args.out / who).mkdir(parents=True, exist_ok=True)
        tiles = []
        for name, how, thing in places:
            t0 = time.perf_counter()
            if how == "view":
                env, view = thing
                out = composite_panorama(rl, photo, env, view, size=size, mask=mask_arr, rim=args.rim != "off")
            else:
                rim = {"on": True, "auto": "auto"}.get(args.rim, False)
                out = scene_mod.composite(rl, photo, thing, mask=mask_arr, rim=rim)
            seconds = time.perf_counter() - t0
            write_image(args.out / who / f"{name}.png", out)
            fr = framing(matte.astype(np.float32) / 255) if matte is not None else None
            report.append({"person": who, "place": name, "seconds": round(seconds, 2),
                           "cut": sorted(fr.cut) if fr is not None else None})  # fmt: skip
            tile = cv2.resize((out * 255 + 0.5).astype(np.uint8), (size[0] // 2, size[1] // 2),
                              interpolation=cv2.INTER_AREA)  # fmt: skip
            tiles.append(label(tile, name))
            print(f"{who:24s} {name:28s} {seconds:5.2f} s", flush=True)
        write_image(args.out / f"{who}.png", grid(tiles, 4))
    (args.out / "report.json").write_text(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
