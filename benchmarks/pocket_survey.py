"""Background the automatic matte holds, region by region, against people_masks' masks (pocket27; evaluation only).

    python benchmarks/pocket_survey.py [--set photos|clip|both] [--half A|B] [--list 20] [--only p077,p281]
    python benchmarks/pocket_survey.py --candidate      # + the colour rule for pockets tried and dropped, landed

For each image of ``people_masks`` (``photos/``: the service's masks, a second opinion; ``clip/``: hand masks) the
default matte (``PersonMatter()``, as ``relight`` uses it) and, for the same people, the coarse matte it refines (the
graphs' answer after the guided filter, before ``matte_edges.refine_edges``). A *held region* is a connected part
(8-connected) of the matte at alpha >= 0.5 that the mask calls background, at least max(16, r^2) px (r the edge band's
half-width, ``matte_edges.band_width``). Its *rim* (the pixels just around it) says what bounds it: the share of the
rim the mask calls person. Kinds: ``pocket`` (rim >= 0.8 person: background seen through a gap the body encloses,
between arm and body, between legs), ``bay`` (0.5-0.8: a notch of background the outline runs across, p077's grass
between his shirt and the ground), ``outline`` (< 0.5: the matte lying past the person's edge).

Per region: what the graphs say there, as means over it: the coarse matte, the matter's own probability (its people's
logits, every rule applied), the selfie graph and the pose graph each on the person's region; whether
``open_pockets``' search (the coarse matte under ``_GAP`` more than r inside the outline, holes filled, rim mostly the
interior) reaches it at all; the share of its pixels whose colour is the backdrop's (within ``_GAP_MATCH`` of the mean
sure background within ``_GAP_REACH`` x r: the colour test ``_open_gap`` uses); and how many of first_look's ``inner``
pixels (background-coloured, alpha >= 0.5 within 6 px inside the outline) it holds, against all of the image's.

``--candidate``: the rule tried for pockets, written before its figures: a part of the matte's interior more than r
inside the outline (holes filled), which the coarse matte holds under ``DOUBT`` (no graph sure), whose rim lies at
least ``ENCLOSED`` in that interior, and of whose pixels at least ``BACKDROP_SHARE`` lie nearer (CIELAB) the
backdrop's colours (k-means centres of the sure background within 4 r + half the part's size of it) than ``RATIO`` x
their distance to the person's colours round it (centres of the sure interior within 2 r of it), is opened; the alpha
it would take is landed on the masks: background (outside the mask grown 1 px), person (inside it shrunk 2 px).

``--doubted`` (glow43, written before its figures): the matte's pixels (alpha >= 0.5) the pose graph alone holds (the
selfie graph on the person's region under ``DOUBTED``, the pose graph at least ``POSE_HELD``: p204's bag's handle loop,
selfie 0.19, pose 0.95), in a part of at least r^2 px whose rim lies at least ``ENCLOSED_BY`` (``--enclosed-by``) in
the matte, opened where their colour is the backdrop's (``backdrop_coloured``'s test), the whole part only where at
least ``--doubted-share`` of it is (0: pixel by pixel); landed as ``--candidate``, with the images it acts on.

Nothing of the data is written except where ``--json`` points (keep it under /tmp). About 4.5 min for both sets.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import cv2
import numpy as np

# first_look and people_masks_eval put this checkout first on sys.path: the relight_rt imported below is this one
from first_look import inner_plain
from people_masks_eval import data_root, half_of, items, read_mask, read_rgb

from relight_rt import RelightError
from relight_rt.image import matte_edges as E
from relight_rt.image.regions import grid_of_region, reductions_shared
from relight_rt.person import matting as M
from relight_rt.person.matting._colours import centres, nearest
from relight_rt.person.matting._detect import roi_prob
from relight_rt.person.matting._segmentation import sigmoid

KINDS = (("pocket", 0.8), ("bay", 0.5), ("outline", 0.0))  # by the rim's share of the mask's person, at least
GRAPHS = ("coarse", "matter", "selfie", "pose")
DOUBT = 0.97  # --candidate: the coarse matte under this ...
ENCLOSED = 0.7  # ... a part whose rim lies at least this share in the interior ...
RATIO = 0.5  # ... a pixel nearer the backdrop's colours than this x its distance to the person's ...
BACKDROP_SHARE = 0.5  # ... over at least this share of the part
DOUBTED = 0.3  # --doubted: the matte's pixels the selfie graph on the person's region holds under this ...
POSE_HELD = 0.5  # ... and the pose graph at least this (the pose graph alone holds them) ...
ENCLOSED_BY = 0.5  # ... in a part whose rim lies at least this share in the matte (alpha >= 0.5: a bay or pocket) ...
DOUBTED_SHARE = 0.0  # ... opened where at least this share of the part is backdrop-coloured (0: pixel by pixel)
_RING = np.ones((3, 3), np.uint8)


def to_photo(canvas: np.ndarray, region, shape: tuple[int, int]) -> np.ndarray:
    """A (256, 256) map over ``region`` on the photo's pixels (bilinear; 0 beyond the region)."""
    k, bx, by = grid_of_region(region)
    m = np.array([[k, 0.0, bx + 0.5 * k], [0.0, k, by + 0.5 * k]], np.float64)
    flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    return cv2.warpAffine(np.asarray(canvas, np.float32), m, (shape[1], shape[0]), flags=flags,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)


def mattes(matter, plain, rgb: np.ndarray, name: str) -> dict[str, np.ndarray] | None:
    """The default matte, the coarse one and the graphs' maps (``GRAPHS``) for one image; None where it is refused."""
    with reductions_shared(rgb):
        try:
            people = matter.people(rgb, name)
        except RelightError:
            return None
        if not people:
            return None
        alpha = matter.alpha(rgb, people)
        coarse = plain.alpha(rgb, people)
        maps = {g: np.zeros(alpha.shape, np.float32) for g in GRAPHS[1:]}
        for p in people:
            for g, canvas in (("matter", sigmoid(p.logits)), ("selfie", roi_prob(matter.roi, rgb, p.region)),
                              ("pose", sigmoid(matter._pose(rgb, p.region).logits))):
                np.maximum(maps[g], to_photo(canvas, p.region, alpha.shape), out=maps[g])
    return {"alpha": alpha, "coarse": coarse, **maps}


def searched(coarse: np.ndarray, r: int) -> np.ndarray:
    """The pixels of the pockets ``open_pockets`` and ``refine_edges`` decide on a coarse matte (``_pockets``)."""
    out = np.zeros(coarse.shape, bool)
    deep = E._deep_inside((coarse >= 0.5).astype(np.uint8), r)
    for (py, px), pocket in E._pockets(coarse < E._GAP, deep, min_area=r):
        out[py : py + pocket.shape[0], px : px + pocket.shape[1]] |= pocket
    return out


def backdrop_coloured(rgb: np.ndarray, alpha: np.ndarray, comp: np.ndarray, r: int) -> float:
    """The share of ``comp``'s pixels within _GAP_MATCH of the mean sure background (alpha <= 1 - _SURE, more than r
    outside the outline) within _GAP_REACH x r of it (2x that where none, as ``_open_gap``'s windows); NaN where none
    lies that near."""
    out = cv2.distanceTransform((alpha < 0.5).astype(np.uint8), cv2.DIST_L2, 3)
    sure_bg = (alpha <= 1 - E._SURE) & (out > r)
    for reach in (E._GAP_REACH * r, 2 * E._GAP_REACH * r):
        zone = cv2.dilate(comp.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * reach + 1,) * 2))
        sure = zone.astype(bool) & sure_bg
        if sure.any():
            return float(E._backdrop_coloured(rgb[comp], rgb[sure].mean(0)).mean())
    return float("nan")


def regions(rgb: np.ndarray, mask: np.ndarray, m: dict[str, np.ndarray]) -> list[dict]:
    """The held regions of one image (module docstring), largest first."""
    alpha = m["alpha"]
    r = E.band_width(alpha.shape)
    inner = inner_plain(rgb, alpha)
    seen = searched(m["coarse"], r)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(((alpha >= 0.5) & ~mask).astype(np.uint8), connectivity=8)
    rows = []
    for i in 1 + np.argsort(-stats[1:, cv2.CC_STAT_AREA]):
        x, y, w, h, area = (int(v) for v in stats[i])
        if area < max(16, r * r):
            break
        y0, y1, x0, x1 = max(y - 1, 0), y + h + 1, max(x - 1, 0), x + w + 1
        comp = labels[y0:y1, x0:x1] == i
        rim = cv2.dilate(comp.astype(np.uint8), _RING).astype(bool) & ~comp
        person = float(mask[y0:y1, x0:x1][rim].mean())
        kind = next(k for k, least in KINDS if person >= least)
        full = labels == i
        row = {"kind": kind, "area": area, "box": [x, y, w, h], "rim_person": person,
               "held": float(alpha[full].sum()), "seen": float(seen[full].mean()),
               "backdrop": backdrop_coloured(rgb, alpha, full, r), "inner": int(inner[full].sum()),
               "inner_all": int(inner.sum())}
        row.update({g: float(m[g][full].mean()) for g in GRAPHS})
        rows.append(row)
    return rows


def _parts(n: int, labels: np.ndarray, stats: np.ndarray, r: int):
    """The connected parts 1..n-1 (``cv2.connectedComponentsWithStats``' ``labels``, ``stats``) of at least r^2 px:
    each as (its pixels (bool), the ring just round it (bool), its box's (width, height))."""
    for i in range(1, n):
        _, _, w, h, area = (int(v) for v in stats[i])
        if area < r * r:
            continue
        comp = labels == i
        yield comp, cv2.dilate(comp.astype(np.uint8), _RING).astype(bool) & ~comp, (w, h)


class _Landing:
    """Where a candidate's opened alpha lands on the service's ``mask`` (bool (h, w)): on background (beyond a ring
    round the mask) or on the person (two rings inside it); ``out`` sums it and counts the parts."""

    def __init__(self, mask: np.ndarray) -> None:
        self.background = cv2.dilate(mask.astype(np.uint8), _RING) == 0
        self.person = cv2.erode(mask.astype(np.uint8), _RING, iterations=2) > 0
        self.out = {"background": 0.0, "person": 0.0, "parts": 0}

    def add(self, alpha: np.ndarray, opened: np.ndarray) -> None:
        """One part opened where ``opened`` (bool) is, taking its ``alpha``."""
        self.out["parts"] += 1
        self.out["background"] += float(alpha[opened & self.background].sum())
        self.out["person"] += float(alpha[opened & self.person].sum())


def candidate(rgb: np.ndarray, mask: np.ndarray, m: dict[str, np.ndarray]) -> dict[str, float]:
    """The dropped colour rule for pockets (module docstring): the alpha it would take, landed on the mask."""
    alpha, coarse = m["alpha"], m["coarse"]
    r = E.band_width(alpha.shape)
    inside = (alpha >= 0.5).astype(np.uint8)
    deep = E._deep_inside(inside, r)
    n, labels, stats, _ = cv2.connectedComponentsWithStats((deep & (coarse < DOUBT)).astype(np.uint8), connectivity=8)
    land = _Landing(mask)
    if n <= 1:
        return land.out
    lab = cv2.cvtColor(rgb, cv2.COLOR_RGB2Lab)
    outside = cv2.distanceTransform(1 - inside, cv2.DIST_L2, 3)
    for comp, rim, (w, h) in _parts(n, labels, stats, r):
        if deep[rim].mean() < ENCLOSED:
            continue
        far = int(4 * r + max(w, h) / 2)
        zone = cv2.dilate(comp.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * far + 1,) * 2))
        near = cv2.dilate(comp.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (4 * r + 1,) * 2))
        back = zone.astype(bool) & (alpha <= 1 - E._SURE) & (outside > r)
        own = near.astype(bool) & ~comp & deep & (coarse >= DOUBT)
        if back.sum() < 20 or own.sum() < 20:
            continue
        px = lab[comp]
        nearer = nearest(px, centres(lab[back]))[0] < RATIO * nearest(px, centres(lab[own]))[0]
        if nearer.mean() >= BACKDROP_SHARE:
            land.add(alpha, comp)
    return land.out


def doubted(rgb: np.ndarray, mask: np.ndarray, m: dict[str, np.ndarray], enclosed_by: float = ENCLOSED_BY,
            share: float = DOUBTED_SHARE) -> dict[str, float]:
    """glow43's candidate (module docstring, ``--doubted``): the matte's pixels (alpha >= 0.5) the pose graph alone
    holds (``selfie`` < ``DOUBTED``, ``pose`` >= ``POSE_HELD``), in a part of at least r^2 px whose rim lies at least
    ``enclosed_by`` in the matte, opened where their colour is the backdrop's (``backdrop_coloured``'s test: within
    _GAP_MATCH of the mean sure background within _GAP_REACH x r, 2x that where none), and only where at least
    ``share`` of the part is; the alpha it would take, landed on the mask."""
    alpha = m["alpha"]
    r = E.band_width(alpha.shape)
    held = (alpha >= 0.5) & (m["selfie"] < DOUBTED) & (m["pose"] >= POSE_HELD)
    land = _Landing(mask)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(held.astype(np.uint8), connectivity=8)
    outside = cv2.distanceTransform((alpha < 0.5).astype(np.uint8), cv2.DIST_L2, 3)
    sure_bg = (alpha <= 1 - E._SURE) & (outside > r)
    for comp, rim, _ in _parts(n, labels, stats, r):
        if (alpha[rim] >= 0.5).mean() < enclosed_by:
            continue
        for reach in (E._GAP_REACH * r, 2 * E._GAP_REACH * r):
            zone = cv2.dilate(comp.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * reach + 1,) * 2))
            sure = zone.astype(bool) & sure_bg
            if sure.any():
                break
        if not sure.any():
            continue
        opened = np.zeros(comp.shape, bool)
        opened[comp] = E._backdrop_coloured(rgb[comp], rgb[sure].mean(0))
        if opened[comp].mean() < share:
            continue
        if opened.any():
            land.add(alpha, opened)
    return land.out


def summary(rows: list[dict], label: str) -> None:
    """Per kind: how many regions, their pixels and held alpha, the share they hold of first_look's inner pixels (of
    the images with a held region), the graphs' median means over them, how many open_pockets' search reaches, the
    median backdrop-coloured share."""
    images = {r["image"]: r["inner_all"] for r in rows}
    inner_all = sum(images.values())
    for kind, _ in KINDS:
        part = [r for r in rows if r["kind"] == kind]
        if not part:
            print(f"{label:10s} {kind:8s} 0 regions")
            continue
        med = {g: float(np.median([r[g] for r in part])) for g in GRAPHS}
        backdrop = [r["backdrop"] for r in part if np.isfinite(r["backdrop"])]
        print(f"{label:10s} {kind:8s} {len(part):4d} regions in {len({r['image'] for r in part}):3d} images, "
              f"{sum(r['area'] for r in part):7d} px (alpha {sum(r['held'] for r in part):8.0f}); inner "
              f"{sum(r['inner'] for r in part) / max(inner_all, 1):5.1%} of {inner_all}; median coarse "
              f"{med['coarse']:.2f} matter {med['matter']:.2f} selfie {med['selfie']:.2f} pose {med['pose']:.2f}; "
              f"reached by open_pockets {sum(r['seen'] > 0 for r in part)}; backdrop-coloured median "
              f"{np.median(backdrop) if backdrop else float('nan'):.2f}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--set", choices=("clip", "photos", "both"), default="both")
    ap.add_argument("--half", choices=("A", "B"), help="only this half of the photos")
    ap.add_argument("--only", default=None, help="comma-separated image names: these only, every region listed")
    ap.add_argument("--list", type=int, default=15, help="list this many of the largest pockets and bays")
    ap.add_argument("--candidate", action="store_true", help="land the dropped colour rule for pockets on the masks")
    ap.add_argument("--doubted", action="store_true", help="land glow43's candidate (the pose graph alone holding "
                    "backdrop-coloured pixels in a bay) on the masks")
    ap.add_argument("--enclosed-by", type=float, default=ENCLOSED_BY, help="--doubted: ENCLOSED_BY")
    ap.add_argument("--doubted-share", type=float, default=DOUBTED_SHARE, help="--doubted: DOUBTED_SHARE")
    ap.add_argument("--json", type=Path, help="write every region's row here (keep it under /tmp)")
    args = ap.parse_args(argv)
    root = data_root()
    matter, plain = M.PersonMatter(person="largest"), M.PersonMatter(person="largest", edges=False)
    halves = half_of([n for n, _, _ in items(root, "photos")])
    only = set(args.only.split(",")) if args.only else None
    rows: list[dict] = []
    landed: dict[str, dict[str, float]] = {}
    acted: dict[str, list] = {}
    t0 = time.time()
    for which in ("clip", "photos") if args.set == "both" else (args.set,):
        for name, img, mask_path in items(root, which):
            group = halves[name] if which == "photos" else "clip"
            if (args.half and which == "photos" and group != args.half) or (only and name not in only):
                continue
            rgb = read_rgb(img)
            mask = read_mask(mask_path, rgb.shape[:2])
            m = mattes(matter, plain, rgb, name)
            if m is None:
                continue
            rows += [{"image": name, "group": group, **r} for r in regions(rgb, mask, m)]
            if args.candidate:
                c = candidate(rgb, mask, m)
                total = landed.setdefault(group, {"background": 0.0, "person": 0.0, "parts": 0, "images": 0})
                total.update({k: total[k] + c[k] for k in c}, images=total["images"] + (c["parts"] > 0))
            if args.doubted:
                c = doubted(rgb, mask, m, args.enclosed_by, args.doubted_share)
                total = landed.setdefault("doubted " + group, {"background": 0.0, "person": 0.0, "parts": 0,
                                                               "images": 0})
                total.update({k: total[k] + c[k] for k in c}, images=total["images"] + (c["parts"] > 0))
                if c["parts"]:
                    acted.setdefault(group, []).append(f"{name} ({c['background']:.0f} / {c['person']:.0f})")
    print(f"{len({r['image'] for r in rows})} images with held regions, {time.time() - t0:.0f} s", file=sys.stderr)
    for group in ("A", "B", "clip"):
        part = [r for r in rows if r["group"] == group]
        if part:
            summary(part, "photos " + group if group != "clip" else "clip")
    listed = sorted((r for r in rows if r["kind"] != "outline" or only), key=lambda r: -r["held"])
    for r in listed if only else listed[: args.list]:
        print(f"  {r['image']} ({r['group']}) {r['kind']:7s} {r['area']:6d} px at {r['box']}: rim person "
              f"{r['rim_person']:.2f}; coarse {r['coarse']:.2f} matter {r['matter']:.2f} selfie {r['selfie']:.2f} "
              f"pose {r['pose']:.2f}; open_pockets reaches {r['seen']:.0%}; backdrop-coloured {r['backdrop']:.2f}; "
              f"inner {r['inner']} of {r['inner_all']}")
    for group, c in landed.items():
        share = c["background"] / max(c["background"] + c["person"], 1e-9)
        print(f"candidate rule, {group}: {c['parts']} parts in {c['images']} images would open {c['background']:.0f} "
              f"px of alpha on background, {c['person']:.0f} on the person ({share:.0%} background)")
    for group, names in acted.items():
        print(f"doubted, {group}: acts on {len(names)} images (alpha on background / person): {', '.join(names)}")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
