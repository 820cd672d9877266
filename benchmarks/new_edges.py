"""Edges a relight draws that the photo does not have (issue 48: "no new edge in the change that the photo does not
have"), on photos without a truth: the share of the person where the change's gradient is large and the photo's is
not (``new_edges``; benchmarks/yale_eval.py reports the same share on Extended Yale B, the real photo under the new
lamp standing in as a second witness).

    python benchmarks/new_edges.py [PHOTO[:MASK] ...] [--lights studio,campfire,LEFT,RIGHT] [--sheet OUT.png]

Default photos: the reference photo with its mask (../shared/reference/photo) and the bundled example (its alpha);
a photo given without a mask or alpha gets the automatic matte.
Lights: presets by name and two white side lamps (LEFT, RIGHT: benchmarks/real_photos.py's, written out here so
that this script runs on any checkout: ``PYTHONPATH=/path/to/other/checkout python benchmarks/new_edges.py`` measures
that checkout's relight_rt, the before of a before/after). Prints the share per photo and light (the person: alpha >
0.5 eroded 9 px; and a face box when the face mesh finds one; measured with the person's box at 256 px, ``to_frame``)
and their mean; ``--sheet``: photo | relit | new edges in red, per photo and light, in the person's frame
(``FRAME``), for looking at (keep it out of the repository when a photo is realdata's).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np

from relight_rt.image.color import REC709, srgb_to_linear

FRAME = 256  # every picture is measured with the person's box's longer side at this many pixels (the network's
# window, about): the thresholds below are per pixel, and the same fill border soft over 2 network pixels scored
# 0.0234 at 256 px and 0 at 512-2048 px measured at the input's size
EDGE_FLOOR = 0.02  # linear luminance added before the log (a black shadow's noise is no edge),
EDGE_SIGMA = 1.0  # ... both pictures blurred over this many pixels,
EDGE_STEP = 0.1  # ... a change's gradient past this (log luminance per pixel) is an edge
ERODE = 9  # the person's region: alpha > 0.5 eroded this many pixels of FRAME's (the matte's own edge is no new edge)


def luminance(rgb: np.ndarray) -> np.ndarray:
    """(H, W) linear luminance (Rec. 709 of linearised sRGB) of an sRGB picture in [0, 1]."""
    return srgb_to_linear(np.clip(rgb, 0, 1).astype(np.float32)) @ REC709


def new_edge_map(source: np.ndarray, relit: np.ndarray, truth: np.ndarray | None = None) -> np.ndarray:
    """(H, W) bool: where the gradient of the change of log luminance (``EDGE_FLOOR`` added, so that a black photo's
    noise is no edge; both blurred over ``EDGE_SIGMA`` pixels) passes ``EDGE_STEP`` per pixel and twice the source
    photo's own gradient (and, given ``truth``, twice the real photo's under the new light: an edge the light
    reveals in a shadow is the truth's too). A fill that ends inside a black shadow, a blend's box, a mask's notch
    count; the photo's own shadow edge cancelled does not (the photo has it)."""

    def log_lum(rgb: np.ndarray) -> np.ndarray:
        return cv2.GaussianBlur(np.log(luminance(rgb) + EDGE_FLOOR).astype(np.float32), (0, 0), EDGE_SIGMA)

    def grad(y: np.ndarray) -> np.ndarray:
        return np.hypot(cv2.Sobel(y, cv2.CV_32F, 1, 0, ksize=3), cv2.Sobel(y, cv2.CV_32F, 0, 1, ksize=3)) / 8

    own = log_lum(source)
    change = grad(log_lum(relit) - own)
    new = (change > EDGE_STEP) & (change > 2 * grad(own))
    if truth is not None:
        new &= change > 2 * grad(log_lum(truth))
    return new


def region(mask: np.ndarray) -> np.ndarray:
    """(H, W) bool: ``mask`` > 0.5 eroded ``ERODE`` pixels."""
    return cv2.erode((mask > 0.5).astype(np.uint8), np.ones((ERODE, ERODE), np.uint8)) > 0


def to_frame(mask: np.ndarray, *pictures: np.ndarray | None, frame: int = FRAME) -> list:
    """``mask`` and ``pictures`` (None kept) resized together so that the box of ``mask`` > 0.5 has its longer side
    at ``frame`` pixels (area-averaged down, linear up); unchanged when the mask is empty."""
    ys, xs = np.nonzero(mask > 0.5)
    if ys.size == 0:
        return [mask, *pictures]
    scale = frame / max(int(ys.max() - ys.min()) + 1, int(xs.max() - xs.min()) + 1)
    h, w = mask.shape[:2]
    size = (max(1, round(w * scale)), max(1, round(h * scale)))
    how = cv2.INTER_AREA if scale < 1 else cv2.INTER_LINEAR
    return [None if p is None else cv2.resize(np.asarray(p, np.float32), size, interpolation=how)
            for p in (mask, *pictures)]


def new_edges(source: np.ndarray, relit: np.ndarray, mask: np.ndarray, truth: np.ndarray | None = None,
              frame: int = FRAME) -> float:
    """The share of ``region(mask)`` that ``new_edge_map`` marks (0 when the region is empty), all measured in the
    person's frame (``to_frame``; ``frame``: the network window's side, about, whose pixels the relight's own are)."""
    mask, source, relit, truth = to_frame(mask, source, relit, truth, frame=frame)
    inner = region(mask)
    return float(np.mean(new_edge_map(source, relit, truth)[inner])) if inner.any() else 0.0


def main(argv=None) -> int:
    import relight_rt
    from relight_rt import RuntimeConfig, lights
    from relight_rt.person.face_mesh import FaceMesh

    here = Path(__file__).resolve().parents[1]
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("photos", nargs="*", help="PHOTO[:MASK] (default: the reference photo and the bundled example)")
    p.add_argument("--lights", default="studio,campfire,rim,night,LEFT,RIGHT")
    p.add_argument("--sheet", type=Path, default=None)
    args = p.parse_args(argv)
    photos = args.photos
    if not photos:
        from _shared import shared_path, warn_missing  # (here: tests load this file without benchmarks/ on the path)

        ref = shared_path("reference", "photo")
        photos = [str(here / "relight_rt/data/example.png")]
        if ref.is_dir():
            photos.insert(0, f"{ref / 'sample.jpg'}:{ref / 'sample_mask.png'}")
        else:
            warn_missing(ref, "the reference photo")
    side = {"LEFT": lights.directional((0.35, -1.0, 0.25), (1, 1, 1), 1.0, angular_radius=0.6) + lights.ambient(0.06),
            "RIGHT": lights.directional((0.35, 1.0, 0.25), (1, 1, 1), 1.0, angular_radius=0.6) + lights.ambient(0.06)}
    relighter = relight_rt.open(RuntimeConfig(device="cpu"))
    mesh = FaceMesh(relighter.models_dir)
    rows, tiles = [], []
    for item in photos:
        path, _, mask_path = item.partition(":")
        raw = cv2.imread(path, cv2.IMREAD_UNCHANGED)
        if raw is None:
            print(f"{path}: not readable, skipped", file=sys.stderr)
            continue
        rgb = cv2.cvtColor(raw[..., :3], cv2.COLOR_BGR2RGB).astype(np.float32) / 255
        mask = None  # none given: the automatic matte's (the bundled one, as the CLI's)
        if mask_path:
            mask = cv2.imread(mask_path, cv2.IMREAD_GRAYSCALE).astype(np.float32) / 255
        elif raw.ndim == 3 and raw.shape[2] == 4:
            mask = raw[..., 3].astype(np.float32) / 255
        dec = relighter.decompose(rgb, mask)
        mask = dec.mask
        h, w = mask.shape
        faces = mesh.faces(rgb, (0, h, 0, w)) if mesh.available else []
        face = np.zeros((h, w), np.float32)
        for pts in faces:  # the face's box, its mesh's extent
            x0, y0 = np.floor(pts[:, :2].min(axis=0)).astype(int)
            x1, y1 = np.ceil(pts[:, :2].max(axis=0)).astype(int)
            face[max(y0, 0):y1, max(x0, 0):x1] = 1
        face *= mask
        for name in args.lights.split(","):
            out = relighter.relight(dec, side.get(name, name))
            frame_mask, frame_face, src, out = to_frame(mask, face, rgb, out)  # (the face's box in the same frame)
            edges = new_edge_map(src, out)
            inner, on_face = region(frame_mask), region(frame_face)
            row = {"photo": Path(path).name, "light": name, "person": float(np.mean(edges[inner])),
                   "face": float(np.mean(edges[on_face])) if on_face.any() else None}
            rows.append(row)
            face_txt = "  -   " if row["face"] is None else f"{row['face']:.4f}"
            print(f"{row['photo']:24s} {name:10s} person {row['person']:.4f}  face {face_txt}", flush=True)
            if args.sheet is not None:
                marked = np.clip(out, 0, 1).copy()
                marked[edges & inner] = (1, 0, 0)
                tiles.append(np.hstack([np.clip(src, 0, 1), np.clip(out, 0, 1), marked]))
    if rows:
        faces_ = [r["face"] for r in rows if r["face"] is not None]
        print(f"mean over {len(rows)}: person {np.mean([r['person'] for r in rows]):.4f}"
              + (f", face {np.mean(faces_):.4f} ({len(faces_)})" if faces_ else ""))
    if args.sheet is not None and tiles:
        width = max(t.shape[1] for t in tiles)
        tiles = [np.pad(t, ((0, 0), (0, width - t.shape[1]), (0, 0))) for t in tiles]
        sheet = (np.vstack(tiles) * 255 + 0.5).astype(np.uint8)
        cv2.imwrite(str(args.sheet), cv2.cvtColor(sheet, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, 88])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
