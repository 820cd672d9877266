"""The automatic matte on a broad real set (issue 48): ../shared/realdata/people_masks, evaluation only.

    python benchmarks/people_masks_eval.py                       # clip + photos, every method, summary table
    python benchmarks/people_masks_eval.py --set photos --methods ours --table   # + per-photo table
    python benchmarks/people_masks_eval.py --sheet /tmp/worst.png              # the 12 worst photos (ours)
    python benchmarks/people_masks_eval.py --set photos --methods ours,selfie --below-sheet /tmp/below.png
                                                       # the 12 furthest below the selfie graph, its matte beside
    python benchmarks/people_masks_eval.py --speed [PHOTO]     # the default matte's time on a photo (2.5 MP)
    python benchmarks/people_masks_eval.py --methods ours --outline    # where each outline cuts the photo's edges
    python benchmarks/people_masks_eval.py --methods ours,selfie --grow 1   # ours' outline moved 1 px out: both sets
    python benchmarks/people_masks_eval.py --methods ours,selfie --mirrored  # every image and its mask mirrored

Sets: ``clip/`` (100 frames of a runner vaulting a railing, DAVIS 2016 "parkour", masks drawn by hand) and
``photos/`` (208 web photos, masks made by a commercial matting service: a second opinion, not truth). The
photos are split in two halves by a fixed rule, sorted name, even index = half "A" (the one tuned on), odd
index = half "B" (only checked); a held-out part of the set exists elsewhere.

Methods (alpha >= 0.5 against mask >= 0.5, IoU per image):
- ``ours``: what ``relight`` uses by default, PersonMatter(person="largest") (shared_matter);
- ``all``: PersonMatter(person="all") (``relight --person all``);
- ``selfie``: MediaPipe's selfie graph alone (matte_roi.onnx) on the whole image letterboxed to 256x256, its
  probability resized bilinearly to the image (the usual way to run it);
- ``pose``: the pose graph's segmentation alone (matte_pose.onnx) on the whole image letterboxed, likewise;
- ``video`` (clip only): VideoMatter over the frames in order;
- ``ours-unrefined`` / ``ours-no-edges``: ``ours`` with ``refine=False`` (the segmentation upsampled) / with
  ``edges=False`` (guided filter, no colour band): where along the way an outline moves.

Figures: mean IoU, share of images with IoU < 0.8 ("gross"), per half, and the photos where ``ours`` is
below ``selfie`` (per half: how many, and those below by more than BELOW_BY, :func:`below_by_half`). Targets (issue
48): clip mean >= 0.93; photos mean >= 0.92 and never below the selfie graph; gross errors <= 8 % over clip and photos
together.

``--outline`` (:func:`outline_offset`): how far inside each mask's outline the photo's own edge reaches its half
mix (colour halfway from the backdrop's to the person's), for the given masks and for each method's: 0 when an
outline runs through the middle of the blurred edge, +1 when it takes one pixel more of the edge's backdrop side.
``--mirrored``: every image and its mask mirrored left-right first. The graphs alone score alike either way; a matte
whose rules were chosen on the photos as they come can score lower on their mirrors (matte37: photos A 0.92575 ->
0.89689, B 0.90222 -> 0.87693), a measure of how far its figures are fitted to these very photos.
``--graphs-mirrored`` (:func:`graphs_mirrored`): every graph run on the mirror image of its crop, its answer mirrored
back: with ``--mirrored`` the graphs see the photos as they come while the code around them sees the mirrors, so the
figures measure the code's own left-right asymmetry (equal to the photos' as they come where the code is mirror-blind);
alone, the graphs see the mirrors and the code the photos (matte38).
Nothing of the data is written except where --sheet and
--save point (keep them under /tmp: the data may not enter the repository).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from _shared import missing, shared_dir, shared_path  # noqa: E402

from relight_rt import RelightError  # noqa: E402
from relight_rt.engine.session import Model  # noqa: E402
from relight_rt.image.regions import Region, crop_region, grid_of_region  # noqa: E402
from relight_rt.person import matting as M  # noqa: E402
from relight_rt.person.matting import _detect as D  # noqa: E402
from relight_rt.person.matting._segmentation import sigmoid  # noqa: E402

METHODS = ("ours", "all", "selfie", "pose", "video", "video-complete", "ours-unrefined", "ours-no-edges")
GROSS = 0.8
BELOW_BY = 0.01  # the photos below the selfie graph by more than this are listed per half


_SIDE = (3.5, 6.5)  # outline_offset: the person's and the backdrop's colours from this far (px) either side
_MIN_CONTRAST = 0.04  # ... where they differ at least this much (squared RGB distance)


def outline_offset(rgb: np.ndarray, mask: np.ndarray, reach: int = 6) -> float:
    """How many pixels inside ``mask``'s outline the photo's edge reaches its half mix (NaN where no edge shows
    colour enough). Each pixel within 4 px of the outline gets colour's alpha from the mean colours of the mask's
    pixels _SIDE px inside (F) and outside (B) the outline within ``reach`` px: ((I - B) . (F - B)) / |F - B|^2;
    its median over the pixels at each whole distance from the outline (-3.5 .. 3.5 px, + inside) is the
    edge's profile, and the place where that profile crosses 0.5 (linear between distances, the profile made
    non-decreasing first) is returned. An outline drawn through the middle of a blurred edge gives ~0; one that
    takes in the edge's whole mixed rim, about half the blur's width."""
    inside = mask.astype(np.uint8)
    dist = np.where(mask, cv2.distanceTransform(inside, cv2.DIST_L2, 5) - 0.5,
                    0.5 - cv2.distanceTransform(1 - inside, cv2.DIST_L2, 5))  # fmt: skip
    size = (2 * reach + 1, 2 * reach + 1)

    def side_mean(where: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        w = where.astype(np.float32)
        n = cv2.boxFilter(w, -1, size, normalize=False, borderType=cv2.BORDER_CONSTANT)
        total = cv2.boxFilter(rgb * w[..., None], -1, size, normalize=False, borderType=cv2.BORDER_CONSTANT)
        return total / np.maximum(n, 1e-6)[..., None], n

    f, nf = side_mean((dist > _SIDE[0]) & (dist < _SIDE[1]))
    b, nb = side_mean((dist < -_SIDE[0]) & (dist > -_SIDE[1]))
    d = f - b
    dd = (d * d).sum(-1)
    a = ((rgb - b) * d).sum(-1) / np.maximum(dd, 1e-6)
    ok = (nf > 3) & (nb > 3) & (dd > _MIN_CONTRAST)
    at, prof = [], []
    for x in np.arange(-3.5, 3.6, 1.0):
        sel = ok & (np.abs(dist - x) < 0.5)
        if sel.sum() > 20:
            at.append(x)
            prof.append(float(np.median(a[sel])))
    prof = np.maximum.accumulate(np.array(prof)) if prof else np.array([])
    for i in range(len(prof) - 1):
        if prof[i] < 0.5 <= prof[i + 1]:
            return float(at[i] + (0.5 - prof[i]) / (prof[i + 1] - prof[i]) * (at[i + 1] - at[i]))
    return float("nan")


def data_root() -> Path:
    if shared_dir("realdata", "people_masks") is None:
        raise SystemExit(missing(shared_path("realdata", "people_masks")))
    return shared_path("realdata", "people_masks")


def read_rgb(path: Path) -> np.ndarray:
    return cv2.cvtColor(cv2.imread(str(path), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB).astype(np.float32) / 255.0


def read_mask(path: Path, shape: tuple[int, int]) -> np.ndarray:
    m = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if m.shape != shape:
        m = cv2.resize(m, (shape[1], shape[0]), interpolation=cv2.INTER_LINEAR)
    return m >= 128


def matted(matter, listed: list[tuple[str, Path, Path]]):
    """(name, the matte ``matter(rgb, name)``, the reference mask) for each (name, photo, mask) of ``listed``; a
    photo the matter refuses (``RelightError``) gets an empty matte."""
    for name, img, mask in listed:
        rgb = read_rgb(img)
        gt = read_mask(mask, rgb.shape[:2])
        try:
            alpha = matter(rgb, name)
        except RelightError:
            alpha = np.zeros(gt.shape, np.float32)
        yield name, alpha, gt


def iou(pred: np.ndarray, gt: np.ndarray) -> float:
    union = (pred | gt).sum()
    return float((pred & gt).sum() / union) if union else 1.0


def items(root: Path, which: str) -> list[tuple[str, Path, Path]]:
    folder = root / which
    return [(f.stem, f, f.with_name(f"{f.stem}_mask.png")) for f in sorted(folder.glob("*.jpg"))]


def half_of(names: list[str]) -> dict[str, str]:
    """The fixed split: sorted names, even index -> "A" (tuned on), odd -> "B" (checked only)."""
    return {n: "AB"[i % 2] for i, n in enumerate(sorted(names))}


def whole_image(model, rgb: np.ndarray, output: str, logits: bool) -> np.ndarray:
    """One graph on the whole image letterboxed to 256x256 (zero padding), its map resized to the image."""
    h, w = rgb.shape[:2]
    region = Region(w / 2, h / 2, float(max(h, w)))
    canvas = crop_region(rgb, region)
    out = model.run({"image": canvas.transpose(2, 0, 1)[None]})[output][0, 0]
    prob = sigmoid(out) if logits else out
    k, bx, by = grid_of_region(region)
    m = np.array([[k, 0.0, bx], [0.0, k, by]], np.float64)
    return cv2.warpAffine(prob.astype(np.float32), m, (w, h), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)  # fmt: skip


@contextlib.contextmanager
def images_mirrored() -> Iterator[None]:
    """Inside the block every image and mask this module reads (:func:`read_rgb`, :func:`read_mask`; so
    :func:`run_methods`, :func:`matted` and benchmarks/matte_ablation.py's sets) comes mirrored left-right."""
    global read_rgb, read_mask
    rgb_of, mask_of = read_rgb, read_mask

    def rgb_mirrored(path: Path) -> np.ndarray:
        return np.ascontiguousarray(rgb_of(path)[:, ::-1])

    def mask_mirrored(path: Path, shape: tuple[int, int]) -> np.ndarray:
        return np.ascontiguousarray(mask_of(path, shape)[:, ::-1])

    read_rgb, read_mask = rgb_mirrored, mask_mirrored
    try:
        yield
    finally:
        read_rgb, read_mask = rgb_of, mask_of


@contextlib.contextmanager
def graphs_mirrored() -> Iterator[None]:
    """Inside the block, the matte's three graphs (``Model.run`` of matte_pose, matte_roi, matte_face) see the mirror
    image of each crop they are given: the pose and selfie graphs' maps come back mirrored, the face graph's boxes
    (decoded in canvas fractions) mirrored back (x -> 1 - x). The code around the graphs is untouched."""
    run, decode = Model.run, D.decode
    names = ("matte_pose", "matte_roi", "matte_face")

    def mirrored_run(self: Model, feeds):
        name = Path(self.name).stem  # (a graph's name is its file's path)
        if name not in names:
            return run(self, feeds)
        out = run(self, {k: np.ascontiguousarray(v[..., ::-1]) for k, v in feeds.items()})
        if name == "matte_face":
            return out
        return {k: np.ascontiguousarray(v[..., ::-1]) if v.ndim == 4 else v for k, v in out.items()}

    def mirrored_decode(*args, **kwargs):
        return [(np.array([1.0 - b[2], b[1], 1.0 - b[0], b[3]]), score) for b, score in decode(*args, **kwargs)]

    Model.run, D.decode = mirrored_run, mirrored_decode
    try:
        yield
    finally:
        Model.run, D.decode = run, decode


def run_methods(
    root: Path, which: str, methods: list[str], keep: dict | None, half: str | None = None, inset: int = 0,
    grow: int = 0,
) -> dict[str, dict[str, float]]:  # fmt: skip
    """IoU per method per image; ``keep`` (optional) collects the predicted masks by (method, name); ``inset``: the
    photos' service masks are eroded by this many pixels first (their outline runs ~1 px past the edge's half mix,
    ``--outline``; the clip's hand masks sit on it and are never eroded); ``grow``: the hard mattes of the ``ours``
    methods are dilated by this many pixels (3x3 square steps) on both sets: what moving the outline past the half
    mix, to the service's convention, would give and cost (a measurement, not a setting of the matte). Under
    :func:`images_mirrored` every image and its mask come mirrored left-right."""
    largest = M.PersonMatter(person="largest")
    everyone = M.PersonMatter(person="all") if "all" in methods else None
    variants = {m: M.PersonMatter(refine=m != "ours-unrefined", edges=False) for m in methods if m.startswith("ours-")}
    out: dict[str, dict[str, float]] = {m: {} for m in methods}
    secs: dict[str, float] = {m: 0.0 for m in methods}
    vms = {m: M.VideoMatter(largest, complete=m == "video-complete") for m in methods if m.startswith("video")}
    vms = vms if which == "clip" else {}
    listed = items(root, which)
    if half is not None and which == "photos":
        halves = half_of([n for n, _, _ in listed])
        listed = [t for t in listed if halves[t[0]] == half]
    for name, img, mask in listed:
        rgb = read_rgb(img)
        gt = read_mask(mask, rgb.shape[:2])
        if inset and which == "photos":
            gt = cv2.erode(gt.astype(np.uint8), np.ones((2 * inset + 1, 2 * inset + 1), np.uint8)) > 0
        for m in methods:
            if m.startswith("video") and m not in vms:
                continue
            t = time.perf_counter()
            if m == "ours":
                try:
                    a = largest(rgb, name)
                except RelightError:
                    a = np.zeros(gt.shape, np.float32)
            elif m in ("all", *variants):
                try:
                    a = (everyone if m == "all" else variants[m])(rgb, name)
                except RelightError:
                    a = np.zeros(gt.shape, np.float32)
            elif m == "selfie":
                a = whole_image(largest.roi, rgb, "segmentation", logits=False)
            elif m == "pose":
                a = whole_image(largest.pose, rgb, "segmentation", logits=True)
            else:
                a = vms[m](rgb, name)
            secs[m] += time.perf_counter() - t
            pred = a >= 0.5
            if grow and m.startswith("ours"):
                pred = cv2.dilate(pred.astype(np.uint8), np.ones((3, 3), np.uint8), iterations=grow) > 0
            out[m][name] = iou(pred, gt)
            if keep is not None:
                keep[(m, name)] = pred
    for m in methods:
        if out[m]:
            print(f"  [{which}] {m}: {secs[m] / len(out[m]) * 1000:.0f} ms/image", file=sys.stderr)
    return {m: v for m, v in out.items() if v}


def summary(scores: dict[str, float]) -> tuple[float, float, int]:
    v = np.array(list(scores.values()))
    return float(v.mean()), float((v < GROSS).mean()), len(v)


def below_by_half(
    ours: dict[str, float], selfie: dict[str, float], halves: dict[str, str], by: float = BELOW_BY
) -> dict[str, tuple[list[str], list[str]]]:
    """Per half present in ``ours``: (the photos where ``ours`` is below ``selfie``, those of them below by more than
    ``by``), each list furthest below first (issue 48's photo bar: never below the selfie graph)."""
    out = {}
    for hv in sorted({halves[n] for n in ours}):
        mine = [n for n in ours if halves[n] == hv and ours[n] < selfie[n] - 1e-9]
        mine.sort(key=lambda n: ours[n] - selfie[n])
        out[hv] = (mine, [n for n in mine if ours[n] < selfie[n] - by])
    return out


def sheet(
    root: Path, names: list[str], keep: dict, path: Path, method: str = "ours", height: int = 240,
    beside: str | None = None,
) -> None:  # fmt: skip
    """photo | reference | ours [| ``beside``'s] (each method: green where it agrees, red where it adds, blue where
    it misses), one row each, written to ``path`` (keep it under /tmp)."""

    def over(img: np.ndarray, pred: np.ndarray, gt: np.ndarray) -> np.ndarray:
        out = (img * 0.5).astype(np.uint8)
        out[pred & gt] = (0.4 * img[pred & gt] + [0, 150, 0]).clip(0, 255)
        out[pred & ~gt] = (0.4 * img[pred & ~gt] + [0, 0, 200]).clip(0, 255)
        out[~pred & gt] = (0.4 * img[~pred & gt] + [200, 0, 0]).clip(0, 255)
        return out

    rows = []
    for name in names:
        img = cv2.imread(str(root / "photos" / f"{name}.jpg"), cv2.IMREAD_COLOR)
        gt = read_mask(root / "photos" / f"{name}_mask.png", img.shape[:2])
        ref = np.repeat((gt * 255).astype(np.uint8)[..., None], 3, axis=2)
        panels = [img, ref, over(img, keep[(method, name)], gt)]
        panels += [over(img, keep[(beside, name)], gt)] if beside is not None else []
        row = np.concatenate(panels, axis=1)
        s = height / row.shape[0]
        row = cv2.resize(row, (int(row.shape[1] * s), height), interpolation=cv2.INTER_AREA)
        cv2.putText(row, name, (4, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (0, 255, 255), 2)
        rows.append(row)
    width = max(r.shape[1] for r in rows)
    rows = [cv2.copyMakeBorder(r, 0, 4, 0, width - r.shape[1], cv2.BORDER_CONSTANT, value=0) for r in rows]
    cv2.imwrite(str(path), np.concatenate(rows, axis=0))


def outline_offsets(root: Path, which: str, keep: dict, methods: list[str]) -> dict[str, np.ndarray]:
    """:func:`outline_offset` of every image's mask ("masks") and of each method's matte (kept by run_methods)."""
    out: dict[str, list[float]] = {"masks": []} | {m: [] for m in methods}
    for name, img, mask in items(root, which):
        if (methods[0], name) not in keep:
            continue
        rgb = read_rgb(img)
        out["masks"].append(outline_offset(rgb, read_mask(mask, rgb.shape[:2])))
        for m in methods:
            if (m, name) in keep:
                out[m].append(outline_offset(rgb, keep[(m, name)]))
    return {k: np.array(v) for k, v in out.items() if v}


def speed(photo: Path, repeats: int = 7) -> None:
    """The default matte (PersonMatter(), person="largest") on one photo: best and median of ``repeats`` calls
    after a warm-up, milliseconds (default photo: the reference photo of ../shared/reference, 2.5 MP); with the CPU
    time of the process over each call (every thread's, summed: the work done, less moved by other jobs on a loaded
    machine than the wall time)."""
    rgb = read_rgb(photo)
    matter = M.PersonMatter()
    matter(rgb)
    times, cpu = [], []
    for _ in range(repeats):
        t, c = time.perf_counter(), time.process_time()
        matter(rgb)
        times.append(1000 * (time.perf_counter() - t))
        cpu.append(1000 * (time.process_time() - c))
    print(
        f"matte {photo.name} {rgb.shape[1]}x{rgb.shape[0]}: best {min(times):.0f} ms, median "
        f"{float(np.median(times)):.0f} ms ({repeats} runs); CPU best {min(cpu):.0f} ms, median "
        f"{float(np.median(cpu)):.0f} ms"
    )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--set", choices=("clip", "photos", "both"), default="both")
    ap.add_argument("--methods", default="ours,all,selfie,pose,video", help=f"comma list of {METHODS}")
    ap.add_argument("--half", choices=("A", "B"), help="only this half of the photos")
    ap.add_argument("--table", action="store_true", help="print the per-photo table")
    ap.add_argument("--sheet", type=Path, help="write the 12 worst photos (ours) as a sheet here (under /tmp)")
    ap.add_argument(
        "--below-sheet",
        type=Path,
        help="with ours and selfie: the 12 photos furthest below the selfie graph, photo | reference | ours | selfie",
    )
    ap.add_argument("--save", type=Path, help="write every IoU as JSON here")
    ap.add_argument(
        "--inset",
        type=int,
        default=0,
        metavar="PX",
        help="erode the photos' service masks by PX pixels first (their outline's ~1-px rim past the half mix)",
    )
    ap.add_argument(
        "--grow",
        type=int,
        default=0,
        metavar="PX",
        help="dilate the ours methods' hard mattes by PX pixels before IoU (the service's outline convention)",
    )
    ap.add_argument("--mirrored", action="store_true", help="every image and its mask mirrored left-right first")
    ap.add_argument(
        "--graphs-mirrored", action="store_true",
        help="every graph run on its crop's mirror image, its answer mirrored back (with --mirrored: the graphs see "
        "the photos as they come, the code the mirrors)",
    )  # fmt: skip
    ap.add_argument(
        "--outline",
        action="store_true",
        help="where the masks' and the methods' outlines cut the photo's edges (outline_offset)",
    )
    ap.add_argument(
        "--speed",
        nargs="?",
        const=shared_path("reference", "photo", "sample.jpg"),
        type=Path,
        help="only time the default matte on this photo (default: the reference photo)",
    )
    args = ap.parse_args(argv)
    if args.speed and (args.mirrored or args.graphs_mirrored):
        ap.error("--speed: not with --mirrored or --graphs-mirrored (it times the matte as it ships)")
    if args.speed:
        if not args.speed.is_file():
            raise SystemExit(missing(args.speed))
        speed(args.speed)
        return 0
    methods = [m for m in args.methods.split(",") if m]
    if any(m not in METHODS for m in methods):
        ap.error(f"--methods: expected some of {METHODS}")
    if not 0 <= args.inset <= 8:
        ap.error("--inset: expected 0-8 pixels")
    if not 0 <= args.grow <= 8:
        ap.error("--grow: expected 0-8 pixels")
    if args.mirrored and (args.sheet or args.below_sheet or args.outline):
        ap.error("--mirrored: not with --sheet, --below-sheet or --outline (they read the photos as they come)")
    if args.below_sheet and not {"ours", "selfie"} <= set(methods):
        ap.error("--below-sheet: needs --methods with ours and selfie")
    root = data_root()
    sets = ("clip", "photos") if args.set == "both" else (args.set,)
    keep: dict | None = {} if args.sheet or args.below_sheet or args.outline else None
    with (
        images_mirrored() if args.mirrored else contextlib.nullcontext(),
        graphs_mirrored() if args.graphs_mirrored else contextlib.nullcontext(),
    ):
        results = {s: run_methods(root, s, methods, keep, args.half, args.inset, args.grow) for s in sets}

    print("set      half  method   n    mean IoU  IoU<0.8")
    for s in sets:
        halves = half_of([n for n, _, _ in items(root, s)]) if s == "photos" else None
        for m, scores in results[s].items():
            mean, gross, n = summary(scores)
            print(f"{s:8s} all   {m:7s} {n:4d}  {mean:.3f}     {gross:5.1%}")
            if halves:
                for hv in "AB":
                    part = {k: v for k, v in scores.items() if halves[k] == hv}
                    if not part:
                        continue
                    mean, gross, n = summary(part)
                    print(f"{s:8s} {hv}     {m:7s} {n:4d}  {mean:.3f}     {gross:5.1%}")
    if "clip" in results and "photos" in results and "ours" in methods:
        both = list(results["clip"]["ours"].values()) + list(results["photos"]["ours"].values())
        print(f"gross errors (ours, clip + photos): {np.mean(np.array(both) < GROSS):.1%} of {len(both)}")
    if "photos" in results and {"ours", "selfie"} <= set(methods):
        ours, selfie = results["photos"]["ours"], results["photos"]["selfie"]
        below = sorted((n for n in ours if ours[n] < selfie[n] - 1e-9), key=lambda n: ours[n] - selfie[n])
        loss = sum(selfie[n] - ours[n] for n in below) / len(ours)
        print(
            f"photos where ours < selfie: {len(below)} (mean loss over the set {loss:.4f}); worst: "
            + ", ".join(f"{n} {ours[n]:.2f}<{selfie[n]:.2f}" for n in below[:15])
        )
        for hv, (mine, far) in below_by_half(ours, selfie, half_of([n for n, _, _ in items(root, "photos")])).items():
            print(f"  half {hv}: {len(mine)} below, {len(far)} by > {BELOW_BY}: "
                  + ", ".join(f"{n} {ours[n]:.3f}<{selfie[n]:.3f}" for n in far))  # fmt: skip
    if args.table and "photos" in results:
        halves = half_of([n for n, _, _ in items(root, "photos")])
        cols = list(results["photos"])
        print("name  half " + " ".join(f"{c:>7s}" for c in cols))
        for n in sorted(results["photos"][cols[0]]):
            print(f"{n}  {halves[n]}    " + " ".join(f"{results['photos'][c][n]:7.3f}" for c in cols))
    if args.sheet and "photos" in results:
        ours = results["photos"][methods[0]]
        worst = sorted(ours, key=ours.get)[:12]
        sheet(root, worst, keep, args.sheet, methods[0])
        print(f"sheet: {args.sheet} ({', '.join(f'{n} {ours[n]:.2f}' for n in worst)})")
    if args.below_sheet and "photos" in results:
        ours, selfie = results["photos"]["ours"], results["photos"]["selfie"]
        worst = sorted((n for n in ours if ours[n] < selfie[n] - 1e-9), key=lambda n: ours[n] - selfie[n])[:12]
        if worst:
            sheet(root, worst, keep, args.below_sheet, "ours", beside="selfie")
        print(f"below-sheet: {args.below_sheet} ({len(worst)} photos)")
    if args.outline:
        for s in sets:
            offsets = outline_offsets(root, s, keep, methods)
            for who, v in offsets.items():
                v = v[np.isfinite(v)]
                q1, med, q3 = np.percentile(v, [25, 50, 75])
                print(
                    f"{s:8s} {who:7s} half mix inside the outline: median {med:+.2f} px (quartiles {q1:+.2f}, "
                    f"{q3:+.2f}); over 0.5 px: {np.mean(v > 0.5):.0%} of {len(v)}"
                )
    if args.save:
        args.save.write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
