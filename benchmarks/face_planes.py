"""The planes the relighting factor divides and multiplies, along rows of a face: where a blotch comes from (faces25).

    python benchmarks/face_planes.py PHOTO --rows 240,250 [--cols 330,410] [--lights LEFT,RIGHT,night,front]
        [--points 80,105/90,150] [--people ../shared/realdata/people_masks] [--out DIR]

PHOTO: a path, or a name of ``people_masks/photos`` (p080). Decomposes it as ``relight-rt relight`` does (the automatic
matte) and prints, along each input row of ``--rows`` between the input columns ``--cols`` (default: the largest face
mesh's width), one value per network pixel (relight_rt.relight.factor, the person's window of the network frame):

- photo: the luminance stage 1 saw; albedo_s1: stage 1's albedo (luminance, unpremultiplied); albedo: the factor's
  (``unshaded_albedo``, ``mirror_held``); face_skin: the face mesh's skin;
- sh_mesh: the shading under the photo's own light (white) of the transport with the face mesh blended in
  (``Factor.restored``); sh_own: the same after ``explain_photo`` (``Factor.own``: what every ratio divides by);
- for each light (exposed as "auto" does): ratio, the factor's luminance ratio (``Factor._change``, with the
  mesh's cast shadows); mesh, the ratio of the mesh's transport alone (no ``explain_photo``); fill, the deep
  shadow's weight (``ShadowFill.shadow_weight``, the same for every light).

``--points`` (input y,x pairs, / between them): Lab L*, a*, b* and hue angle of the input and of the relit photo
under each light, over 5 x 5 pixels around each.

``--out`` writes DIR/NAME_planes.png: those planes over the face's box at 4x (each scaled to its 1-99 % range, the
ratios to 0-3). Evaluation only: keep the pictures out of the repository.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np
from first_look import read_rgb
from real_photos import LEFT, RIGHT

# isort: split
from _shared import shared_path

import relight_rt
from relight_rt import RuntimeConfig
from relight_rt.image.color import REC709


def photo_path(name: str, people: Path) -> Path:
    path = Path(name)
    return path if path.suffix else people / "photos" / f"{name}.jpg"


def planes(relighter, dec, lights: list[str]) -> dict[str, np.ndarray]:
    """The planes of the module docstring, (r, r') each, in the person's window of the network frame."""
    f = relighter._factor
    base, own = f.restored(dec), f.own(dec, with_residual=False)
    white = dec.white_light[:, 0]
    out = {"photo": base["photo"], "albedo_s1": base["albedo"], "albedo": own["albedo"],
           "face_skin": base["face_skin"].astype(np.float32), "sh_mesh": base["transport"] @ white,
           "sh_own": own["transport"] @ white}
    shadow = f.fill.shadow_weight(dec)
    out["fill"] = shadow[0] if shadow is not None else np.zeros_like(out["photo"])
    for name in lights:
        lit = f.meter.expose(dec, relighter.resolve_light({"LEFT": LEFT, "RIGHT": RIGHT}.get(name, name)), "auto")
        out[f"ratio {name}"] = f._change(own, lit, None, f.cast(dec, own, lit))[0]
        mesh = base["transport"]
        out[f"mesh {name}"] = np.maximum(mesh @ (lit @ REC709), 1e-3) / np.maximum(mesh @ white, 1e-3)
    return out


def to_window(dec, window, y: float, x: float) -> tuple[int, int]:
    """An input pixel (y, x) -> the network window's (row, column)."""
    geom = dec.geometry
    (by0, _, bx0, _), (oy, ox), k = geom.box, geom.offset, geom.scale
    return (int(round((y - by0 + oy) / k - 0.5)) - window[0], int(round((x - bx0 + ox) / k - 0.5)) - window[2])


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("photo")
    p.add_argument("--rows", required=True, help="input rows, comma-separated")
    p.add_argument("--cols", default=None, help="first,last input column (default: the largest face mesh's width)")
    p.add_argument("--lights", default="LEFT,RIGHT,night,front")
    p.add_argument("--points", default=None, help="input y,x pairs whose Lab is printed, separated by /")
    p.add_argument("--people", type=Path, default=shared_path("realdata", "people_masks"))
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args(argv)
    relighter = relight_rt.open(RuntimeConfig(device="cpu"))
    path = photo_path(args.photo, args.people)
    dec = relighter.decompose(read_rgb(path))
    window = relighter._factor.restored(dec)["window"]
    maps = planes(relighter, dec, args.lights.split(","))
    meshes = dec.face_meshes or ()
    face = max(meshes, key=lambda m: np.ptp(m[:, 0]) * np.ptp(m[:, 1])) if meshes else None
    if args.cols:
        c0, c1 = (float(v) for v in args.cols.split(","))
    elif face is not None:
        c0, c1 = float(face[:, 0].min()), float(face[:, 0].max())
    else:
        c0, c1 = 0.0, float(dec.image.shape[1] - 1)
    print(f"{path.name}: {dec}, {len(meshes)} face mesh(es), own light (white) {np.round(dec.white_light[:, 0], 3)}")
    for row in (int(v) for v in args.rows.split(",")):
        r, a = to_window(dec, window, row, c0)
        _, b = to_window(dec, window, row, c1)
        print(f"input row {row}, columns {c0:.0f}-{c1:.0f}: network row {r}, columns {a}-{b}")
        for name, plane in maps.items():
            print(f"  {name:14s}", " ".join(f"{v:5.2f}" for v in plane[r, a : b + 1]))
    if args.points:
        shown = {"input": dec.image}
        for name in args.lights.split(","):
            shown[name] = np.asarray(relighter.relight(dec, {"LEFT": LEFT, "RIGHT": RIGHT}.get(name, name)), np.float32)
        for point in args.points.split("/"):
            y, x = (int(v) for v in point.split(","))
            cells = []
            for name, rgb in shown.items():
                patch = np.clip(rgb[max(y - 2, 0) : y + 3, max(x - 2, 0) : x + 3], 0, 1).reshape(-1, 1, 3)
                lab = cv2.cvtColor(patch.mean(axis=0, keepdims=True).astype(np.float32), cv2.COLOR_RGB2Lab)[0, 0]
                hue = np.degrees(np.arctan2(lab[2], lab[1]))
                cells.append(f"{name} L* {lab[0]:5.1f} a* {lab[1]:5.1f} b* {lab[2]:5.1f} hue {hue:4.0f}")
            print(f"({y}, {x}): " + " | ".join(cells))
    if args.out is not None and face is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        y0, x0 = to_window(dec, window, face[:, 1].min(), face[:, 0].min())
        y1, x1 = to_window(dec, window, face[:, 1].max(), face[:, 0].max())
        y0, x0 = max(y0 - 8, 0), max(x0 - 8, 0)
        tiles = []
        for name, plane in maps.items():
            v = plane[y0 : y1 + 8, x0 : x1 + 8]
            lo, hi = (0.0, 3.0) if name.startswith(("ratio", "mesh")) else np.percentile(v, (1, 99))
            t = (255 * np.clip((v - lo) / max(hi - lo, 1e-6), 0, 1)).astype(np.uint8)
            t = cv2.cvtColor(cv2.resize(t, None, fx=4, fy=4, interpolation=cv2.INTER_NEAREST), cv2.COLOR_GRAY2BGR)
            cv2.putText(t, f"{name} {lo:.2f}-{hi:.2f}", (3, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 255), 1)
            tiles.append(t)
        per_row = 5
        tiles += [np.zeros_like(tiles[0])] * (-len(tiles) % per_row)
        sheet = np.vstack([np.hstack(tiles[i : i + per_row]) for i in range(0, len(tiles), per_row)])
        cv2.imwrite(str(args.out / f"{path.stem}_planes.png"), sheet)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
