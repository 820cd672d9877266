"""Contact sheet: two people composited into ten backgrounds (docs/RESULTS.md, "Into any scene").

    python benchmarks/scene_sheet.py --hdri ../shared/hdri --blender BLENDER_WORLD --out docs/scene_sheet.jpg \\
        [--half-body PHOTO --half-body-mask MASK] [--size 320] [--models DIR] [--rim] [--photos PLACE ...]

People: the bundled example (relight_rt/data/example.png, a render of our own; linear, so sRGB-encoded
first, as a camera would write it) standing full length, and a half body: by default the same person cut
at the hips (its matte then reaches the photo's bottom edge), or ``--half-body`` (e.g. a crop of the
reference photo in ../shared, which is CC BY-NC-SA: such a sheet is for looking at, never for the repo).
Backgrounds: perspective views (60°, a level camera looking along −x) of CC0 photographed panoramas,
auto-exposed (mean linear luminance 0.18) and sRGB-encoded: six of ../shared/hdri and, with ``--blender``
(``datafiles/studiolights/world`` of Debian's blender-data; reading .exr needs ``pip install OpenEXR``), four
of those; ``--photos``: real photos of places (centre-cropped to 4:3 and resized, e.g. scikit-image's
rocket.jpg and motorcycle_left.png from its wheel, ultralytics' bus.jpg). Each row: the realistic paste (the
full-body person as photographed, unrelit, at the same place and size; the estimated light on a sphere in the
corner) | ``composite`` full body | ``composite`` half body, 0.6 of the frame high (otherwise all defaults: the
background's own light, perspective placement, shadows, camera matching, light wrap, frame metering; ``--rim``
adds the back key's rim). Prints each background's camera blur (relight_rt.scene, step 5).

``--panoramas NAME:AZ,EL[,FOV] ...`` (maps of --hdri, or --blender with ``bl-``) makes instead the sheet of a panorama
used exactly (relight_rt.apps.panorama.composite_panorama, ``composite --view``): per view, the plate with the
panorama's light on a sphere | full body | half body, and prints the irradiance error of the light each person got
against the panorama's light resampled into the view's frame (pixels, not SH rotation).
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

import relight_rt  # noqa: E402
from relight_rt import RuntimeConfig, envmap, sh  # noqa: E402
from relight_rt import scene as scene_mod  # noqa: E402
from relight_rt.apps.scene_camera import camera_blur, grey  # noqa: E402
from relight_rt.image.color import REC709, linear_to_srgb  # noqa: E402
from relight_rt.image.io import read_image, read_mask, write_image  # noqa: E402
from relight_rt.light.from_background import envmap_view, light_from_background  # noqa: E402

# (file stem, turn in degrees): turned where the unturned view shows little (a black backdrop, a wall)
SHARED = (("sunset", 0), ("forest", 0), ("apartment", 0), ("lab", 0), ("city", 0), ("night", 90))
BLENDER = (("sunrise", 0), ("courtyard", 0), ("interior", 90), ("city", 0))
HALF_HEIGHT = 0.6  # the half body's height, fraction of the background's (it stands on the bottom edge)


def load_map(path: Path) -> np.ndarray:
    if path.suffix.lower() == ".exr":
        sys.path.insert(0, str(REPO / "benchmarks"))
        from scene_eval import read_exr

        return read_exr(path)
    return envmap.load_envmap(path)


def background(path: Path, size: tuple[int, int], turn: int = 0) -> np.ndarray:
    """8-bit sRGB (H, W, 3) view of the map at ``path``, turned by ``turn`` degrees, auto-exposed."""
    env = load_map(path)
    if turn:
        env = np.roll(env, -(turn * env.shape[1] // 360), axis=1)
    view = envmap_view(env, size, 60.0)
    k = 0.18 / max(float((view @ REC709).mean()), 1e-6)
    return (linear_to_srgb(np.clip(view * k, 0, 1)) * 255 + 0.5).astype(np.uint8)


def photo_background(path: Path, size: tuple[int, int]) -> np.ndarray:
    """8-bit sRGB (H, W, 3): a photo of a place, centre-cropped to the size's aspect and resized to it."""
    img = read_image(path, "place")[..., :3]
    h, w = img.shape[:2]
    want = size[1] / size[0]
    if w / h > want:
        cw = round(h * want)
        img = img[:, (w - cw) // 2 : (w - cw) // 2 + cw]
    else:
        ch = round(w / want)
        img = img[(h - ch) // 2 : (h - ch) // 2 + ch]
    img = cv2.resize(img, (size[1], size[0]), interpolation=cv2.INTER_AREA)
    return (np.clip(img, 0, 1) * 255 + 0.5).astype(np.uint8)


def pasted(person_srgb: np.ndarray, bg: np.ndarray) -> np.ndarray:
    """The person laid over the background as photographed (no relighting), placed as ``composite`` places a
    full-body person by default (feet at DEFAULT_FEET, height from perspective, level camera)."""
    alpha = person_srgb[..., 3]
    rows, cols = np.flatnonzero((alpha > 0.005).any(1)), np.flatnonzero((alpha > 0.005).any(0))
    y0, y1, x0, x1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
    hb, wb = bg.shape[:2]
    feet = scene_mod.DEFAULT_FEET
    s = (feet - 0.5) * scene_mod.PERSON_M / scene_mod.CAMERA_M * hb / (y1 - y0)
    nh, nw = round((y1 - y0) * s), round((x1 - x0) * s)
    crop = person_srgb[y0:y1, x0:x1]
    pre = np.concatenate([crop[..., :3] * crop[..., 3:], crop[..., 3:]], 2)
    pre = cv2.resize(pre, (nw, nh), interpolation=cv2.INTER_AREA if s < 1 else cv2.INTER_LINEAR)
    out = bg.astype(np.float32) / 255
    top, left = round(feet * hb) - nh, round(((x0 + x1) / 2 / person_srgb.shape[1]) * wb - nw / 2)
    ty0, tx0 = max(top, 0), max(left, 0)
    ty1, tx1 = min(top + nh, hb), min(left + nw, wb)
    p = pre[ty0 - top : ty1 - top, tx0 - left : tx1 - left]
    region = out[ty0:ty1, tx0:tx1]
    region *= 1 - p[..., 3:]
    region += p[..., :3]
    return out


def panorama_row(relighter, args, spec: str, person8, half8, half_mask, size) -> np.ndarray:
    """One row of the panorama sheet (module docstring): plate + light sphere | full body | half body."""
    import math

    from relight_rt.apps import panorama

    name, view = spec.split(":", 1)
    path = args.blender / f"{name[3:]}.exr" if name.startswith("bl-") else args.hdri / f"{name}.hdr"
    env = np.maximum(load_map(path), 0)
    az, el, fov = panorama.parse_view(view)
    pv = panorama.panorama_view(env, (size[1], size[0]), (az, el, fov))
    # the truth: the map resampled into the camera's frame pixel by pixel, then projected
    h = 128
    small = cv2.resize(env, (4 * h, 2 * h), interpolation=cv2.INTER_AREA)
    d = envmap.directions_envmap(h) @ panorama.view_rotation(az, el).T
    theta, phi = np.arccos(np.clip(d[..., 2], -1, 1)), np.mod(np.arctan2(-d[..., 1], d[..., 0]), 2 * np.pi)
    pad = np.concatenate([small[:, -1:], small, small[:, :1]], 1)
    mapx = (phi / (2 * np.pi) * 4 * h + 0.5).astype(np.float32)
    mapy = np.clip(theta / np.pi * 2 * h - 0.5, 0, 2 * h - 1).astype(np.float32)
    turned = cv2.remap(pad, mapx, mapy, cv2.INTER_LINEAR)
    truth = envmap.project_envmap(turned) * (pv.exposure / math.pi)
    normals = sh.sphere_directions(2000)
    seen = []
    relight = relighter.relight

    def spy(dec, light, *a, **k):
        seen.append(np.array(light, np.float64))
        return relight(dec, light, *a, **k)

    relighter.relight = spy
    try:
        full = panorama.composite_panorama(relighter, person8, env, (az, el, fov), size=(size[1], size[0]),
                                           rim=args.rim)  # fmt: skip
        halfbody = panorama.composite_panorama(relighter, half8, env, (az, el, fov), size=(size[1], size[0]),
                                               mask=half_mask, height=HALF_HEIGHT, rim=args.rim)  # fmt: skip
    finally:
        del relighter.relight
    b = sh.irradiance(truth, normals) @ REC709
    errs = [float(np.sqrt(np.mean((sh.irradiance(x, normals) @ REC709 - b) ** 2)) / np.sqrt(np.mean(b**2)))
            for x in seen]  # fmt: skip
    print(f"{name} view {az:g},{el:g},{fov:g}: irradiance error of the person's light "
          f"{', '.join(f'{100 * e:.2f} %' for e in errs)}", file=sys.stderr)  # fmt: skip
    plate = pv.plate.astype(np.float32) / 255
    sphere = sh.render_sphere(pv.light, size=size[0] // 3)
    sphere = linear_to_srgb(np.clip(sphere * (0.8 / max(float(sphere.max()), 1e-6)), 0, 1))
    plate[: sphere.shape[0], : sphere.shape[1]] = sphere
    label = (plate * 255 + 0.5).astype(np.uint8)
    cv2.putText(label, f"{name} {az:g},{el:g},{fov:g}", (4, size[0] - 6), cv2.FONT_HERSHEY_SIMPLEX, 0.4,
                (255, 0, 255), 1, cv2.LINE_AA)  # fmt: skip
    plate = label.astype(np.float32) / 255
    gap = np.ones((size[0], 4, 3), np.float32)
    return np.concatenate([plate, gap, full, gap, halfbody], 1)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hdri", type=Path, required=True)
    ap.add_argument("--blender", type=Path, help="blender-data's datafiles/studiolights/world (.exr)")
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--half-body", type=Path, help="a half-body photo (default: the example cut at the hips)")
    ap.add_argument("--half-body-mask", type=Path)
    ap.add_argument("--models", default=None)
    ap.add_argument("--size", type=int, default=320, help="background width (height 3/4 of it)")
    ap.add_argument("--rim", action="store_true", help="composite with rim=True (a back key's rim)")
    ap.add_argument("--photos", type=Path, nargs="*", default=[], help="real photos of places as more backgrounds")
    ap.add_argument("--panoramas", nargs="*", default=[], metavar="NAME:AZ,EL[,FOV]",
                    help="the sheet of panoramas used exactly, these views")  # fmt: skip
    args = ap.parse_args(argv)
    relighter = relight_rt.open(RuntimeConfig(models=args.models, device="cpu"))
    rgba = read_image(REPO / "relight_rt" / "data" / "example.png", "example")
    person = np.concatenate([linear_to_srgb(rgba[..., :3]), rgba[..., 3:]], 2)
    person8 = (np.clip(person, 0, 1) * 255 + 0.5).astype(np.uint8)
    if args.half_body:
        half = read_image(args.half_body, "half body")
        half_mask = read_mask(args.half_body_mask, half.shape[:2], "half body mask")
        half8 = (np.clip(half[..., :3], 0, 1) * 255 + 0.5).astype(np.uint8)
    else:
        rows = np.flatnonzero((rgba[..., 3] > 0.005).any(1))
        cut = rows[0] + int(0.5 * (rows[-1] - rows[0]))  # at the hips
        half8, half_mask = person8[:cut], None
    size = (args.size * 3 // 4, args.size)
    if args.panoramas:
        tiles = [panorama_row(relighter, args, spec, person8, half8, half_mask, size) for spec in args.panoramas]
        gap = np.ones((4, tiles[0].shape[1], 3), np.float32)
        sheet = np.concatenate([x for t in tiles for x in (t, gap)][:-1], 0)
        write_image(args.out, sheet)
        print(f"wrote {args.out} ({sheet.shape[1]} x {sheet.shape[0]})")
        return 0
    maps = [(args.hdri / f"{n}.hdr", t) for n, t in SHARED]
    if args.blender:
        maps += [(args.blender / f"{n}.exr", t) for n, t in BLENDER]
    tiles = []
    for path, turn in [*maps, *((p, None) for p in args.photos)]:
        if not path.is_file():
            continue
        bg = background(path, size, turn) if turn is not None else photo_background(path, size)
        light, _ = light_from_background(bg)
        sphere = sh.render_sphere(light, size=size[0] // 3)
        sphere = linear_to_srgb(np.clip(sphere * (0.8 / max(float(sphere.max()), 1e-6)), 0, 1))
        paste = pasted(person, bg)
        paste[: sphere.shape[0], : sphere.shape[1]] = sphere  # the estimated light, top-left corner
        full = scene_mod.composite(relighter, person8, bg, rim=args.rim)
        halfbody = scene_mod.composite(relighter, half8, bg, mask=half_mask, height=HALF_HEIGHT, rim=args.rim)
        gap = np.ones((size[0], 4, 3), np.float32)
        tiles.append(np.concatenate([paste, gap, full, gap, halfbody], 1))
        blur = camera_blur(grey(bg))  # what the person is blurred toward (step 5)
        what = f"turned {turn}°" if turn is not None else "a photo"
        print(f"{path.name} ({what}): the camera's blur {blur:.2f} px", file=sys.stderr)
    rows = len(tiles) // 2 + len(tiles) % 2
    if len(tiles) % 2:
        tiles.append(np.ones_like(tiles[0]))
    gap = np.ones((4, tiles[0].shape[1], 3), np.float32)
    left = np.concatenate([x for t in tiles[:rows] for x in (t, gap)][:-1], 0)
    right = np.concatenate([x for t in tiles[rows:] for x in (t, gap)][:-1], 0)
    sheet = np.concatenate([left, np.ones((left.shape[0], 12, 3), np.float32), right], 1)
    write_image(args.out, sheet)
    print(f"wrote {args.out} ({sheet.shape[1]} x {sheet.shape[0]})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
