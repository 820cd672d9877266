"""How well relight_rt.apps.scene_place.estimate_horizon finds the horizon: on panorama views, whose horizon is known.

    python benchmarks/scene_horizon.py --hdri ../shared/hdri [--size 640x480] [--out runs/scene/horizon.json] \
        [--places PLACE ...]

Every map of ``--hdri``, seen at azimuths 0/120/240° and elevations −12/0/+12° (60° field of view; the plate of
relight_rt.apps.panorama.panorama_view, 8-bit sRGB, whose ``horizon`` is exact): how often the estimate answers, and
its error (fractions of the picture's height) where it does, against the level camera's 0.5 that stands without it.
``--photos DIR``: also every .jpg/.png there (real photos, no truth): how often it answers and the spread of its
answers (most photos of people are taken nearly level: a wide spread means wild answers).

Also the sky line (``sky_line``: no sky below the horizon) and what ``composite`` uses (``find_horizon``: the
verticals' answer or 0.5; where they see the camera turned up, no higher than the sky line; at most 0.9): on the
views, how often the sky line lies more than 0.02 below the true horizon (a bound should not), and the error of
``find_horizon`` against the verticals' answer-or-0.5 over all views. Every view's readings go to ``--out``, so
other ways to combine them can be scored from the file. ``--places``: photos of places (centre-cropped to
``--size``'s aspect as benchmarks/scene_sheet.py does) with each reading, to look at.

The people in a background (relight_rt.apps.scene_people: the person graphs find them, the full bodies' heads and
feet give a horizon): on every plain view, whether anybody is found and whether composite's horizon moves (it should
not: no people there); with ``--renders DIR --people DIR`` (export's ``render-photos`` output and the ``render``
samples it lit, whose meta gives each body's height in metres), the same views with 1, 2 or 3 rendered people
pasted standing on the ground at random rows below the horizon, scaled by perspective for a level camera
``--camera`` metres up (a range "LO:HI" draws one per view; the estimate assumes 1.5 m), and the errors of the
people's horizon, the verticals' and composite's against the exact one. ``--photos``: also how many photos get a
people's horizon and how far it lies from the verticals' where both answer. ``--speed``: the people search's time on
each ``--places`` photo enlarged to 2 MP.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from relight_rt import envmap  # noqa: E402
from relight_rt.apps.panorama import panorama_view, parse_size  # noqa: E402
from relight_rt.apps.scene_people import find_people, people_horizon, scene_horizon  # noqa: E402
from relight_rt.apps.scene_place import HORIZON_ESTIMATE_MAX, estimate_horizon, find_horizon, sky_line  # noqa: E402


def load_renders(renders: Path, people: Path) -> list[tuple[np.ndarray, np.ndarray, float]]:
    """Each rendered person of ``people`` (export render samples) as (RGB, alpha, height in metres): the photo of
    ``renders`` (export render-photos) whose mean over the person is nearest 0.35 (lit, not clipped), cut to its
    mask's box."""
    import cv2

    out = []
    for meta in sorted(people.glob("*_meta.json")):
        name, cam = meta.name[: -len("_meta.json")], json.loads(meta.read_text())["camera"]
        best = None
        for photo in sorted(renders.glob(f"{name}__L*_photo.png")):
            rgb = cv2.imread(str(photo))[..., ::-1].astype(np.float32) / 255
            a = cv2.imread(str(photo).replace("_photo.png", "_mask.png"), cv2.IMREAD_GRAYSCALE).astype(np.float32) / 255
            lum = float((rgb.mean(axis=2) * a).sum() / max(a.sum(), 1.0))
            if best is None or abs(lum - 0.35) < abs(best[0] - 0.35):
                best = (lum, rgb, a)
        if best is None:
            continue
        _, rgb, a = best
        rows, cols = np.flatnonzero(a.max(axis=1) > 0.5), np.flatnonzero(a.max(axis=0) > 0.5)
        y0, y1, x0, x1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
        out.append((rgb[y0:y1, x0:x1], a[y0:y1, x0:x1], (y1 - y0) * 2 * cam["half_extent"] / cam["resolution"]))
    return out


def paste_people(plate: np.ndarray, horizon: float, renders: list, n: int, camera_m: float, rng) -> int:
    """Up to ``n`` of ``renders`` standing on the ground of ``plate`` (uint8, changed in place) whose horizon is the
    row fraction ``horizon``: feet at random rows below it, each as tall as a level camera ``camera_m`` up sees
    them, in separate slots across; returns how many went in (head and feet in frame, >= 8 % of the height)."""
    import cv2

    h, w = plate.shape[:2]
    put = 0
    slots = rng.permutation(n)
    for i in range(n):
        rgb, a, metres = renders[int(rng.integers(len(renders)))]
        for _ in range(20):
            feet = rng.uniform(max(horizon + 0.08, 0.3), 0.97)
            tall = (feet - horizon) * metres / camera_m * h
            if 0.08 * h <= tall <= feet * h - 0.02 * h:
                break
        else:
            continue
        scale = tall / rgb.shape[0]
        pw, ph = max(1, round(rgb.shape[1] * scale)), max(1, round(tall))
        interp = cv2.INTER_AREA if scale < 1 else cv2.INTER_LINEAR
        pr, pa = cv2.resize(rgb, (pw, ph), interpolation=interp), cv2.resize(a, (pw, ph), interpolation=interp)
        cx = (slots[i] + rng.uniform(0.3, 0.7)) / n * w
        top, left = round(feet * h) - ph, round(cx - pw / 2)
        y0, x0, y1, x1 = max(top, 0), max(left, 0), min(top + ph, h), min(left + pw, w)
        if y1 <= y0 or x1 <= x0:
            continue
        sub_a = pa[y0 - top : y1 - top, x0 - left : x1 - left, None]
        sub = pr[y0 - top : y1 - top, x0 - left : x1 - left]
        region = plate[y0:y1, x0:x1].astype(np.float32) / 255
        plate[y0:y1, x0:x1] = np.clip((region * (1 - sub_a) + sub * sub_a) * 255 + 0.5, 0, 255).astype(np.uint8)
        put += 1
    return put


def error_summary(err) -> dict:
    err = np.asarray(err, np.float64)
    if err.size == 0:
        return {"n": 0}
    return {"n": int(err.size), "median": round(float(np.median(err)), 4), "mean": round(float(err.mean()), 4),
            "p90": round(float(np.quantile(err, 0.9)), 4), "max": round(float(err.max()), 4),
            "within_0.05": round(float(np.mean(err <= 0.05)), 3)}  # fmt: skip


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hdri", type=Path, required=True)
    ap.add_argument("--size", default="640x480")
    ap.add_argument("--out", type=Path)
    ap.add_argument("--photos", type=Path, help="a folder of real photos (no truth): the spread of the answers")
    ap.add_argument("--places", type=Path, nargs="*", default=[], help="photos of places: each reading, printed")
    ap.add_argument("--renders", type=Path, help="export render-photos output: people pasted into the views")
    ap.add_argument("--people", type=Path, help="the export render samples those photos lit (their meta)")
    ap.add_argument("--camera", default="1.5", help="the pasted people's camera height, metres, or LO:HI")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--speed", action="store_true",
                    help="time the people search on each --places photo at 1920 x 1080 (median of 7)")  # fmt: skip
    args = ap.parse_args(argv)
    size = parse_size(args.size)
    from relight_rt.person.matting import shared_matter

    matter = shared_matter()
    renders = load_renders(args.renders, args.people) if args.renders else []
    cam_lo, cam_hi = (float(v) for v in (args.camera.split(":") * 2)[:2])
    rng = np.random.default_rng(args.seed)
    rows, pasted = [], []
    for path in sorted(args.hdri.glob("*.hdr")):
        env = envmap.load_envmap(path)
        for az in (0, 120, 240):
            for el in (-12, 0, 12):
                pv = panorama_view(env, size, (az, el, 60))
                est = estimate_horizon(pv.plate, 60.0)
                used = find_horizon(pv.plate, 60.0)
                people = find_people(pv.plate, matter)
                rows.append({"map": path.stem, "az": az, "el": el, "truth": pv.horizon, "estimate": est,
                             "sky_line": sky_line(pv.plate), "used": used, "people_found": len(people),
                             "full_bodies": sum(p.full_body for p in people),
                             "used_with_people": scene_horizon(pv.plate, 60.0, people)})  # fmt: skip
                for n in (1, 2, 3) if renders else ():
                    plate = pv.plate.copy()
                    cam = float(rng.uniform(cam_lo, cam_hi))
                    put = paste_people(plate, pv.horizon, renders, n, cam, rng)
                    found = find_people(plate, matter)
                    ph = people_horizon(found)
                    pasted.append({"map": path.stem, "az": az, "el": el, "truth": pv.horizon, "camera": cam,
                                   "pasted": put, "found": len(found), "full_bodies": sum(p.full_body for p in found),
                                   "people": None if ph is None else ph[0], "people_se": None if ph is None else ph[1],
                                   "verticals": estimate_horizon(plate, 60.0), "old": find_horizon(plate, 60.0),
                                   "new": scene_horizon(plate, 60.0, found)})  # fmt: skip
    found = [r for r in rows if r["estimate"] is not None]
    err = np.array([abs(r["estimate"] - r["truth"]) for r in found])
    level = np.array([abs(0.5 - r["truth"]) for r in found])
    summary = {
        "views": len(rows), "answered": len(found),
        "median_error": float(np.median(err)), "p90_error": float(np.quantile(err, 0.9)), "max_error": float(err.max()),
        "level_camera_median_error_same_views": float(np.median(level)),
        "within_0.05": float(np.mean(err <= 0.05)),
    }  # fmt: skip
    # what composite used before the sky line (the verticals' answer or 0.5, clipped) and uses now, on every view
    before = np.array([abs(min(max(0.5 if r["estimate"] is None else r["estimate"], 0.0), HORIZON_ESTIMATE_MAX)
                           - r["truth"]) for r in rows])  # fmt: skip
    after = np.array([abs(r["used"] - r["truth"]) for r in rows])
    sky = [r for r in rows if r["sky_line"] is not None]
    summary["sky_line"] = {
        "answered": len(sky), "below_truth_by_over_0.02": sum(r["sky_line"] > r["truth"] + 0.02 for r in sky),
        "composite_horizon_error_before": {"median": float(np.median(before)), "mean": float(before.mean()),
                                           "p90": float(np.quantile(before, 0.9)), "max": float(before.max())},
        "composite_horizon_error_after": {"median": float(np.median(after)), "mean": float(after.mean()),
                                          "p90": float(np.quantile(after, 0.9)), "max": float(after.max())},
        "views_changed": int(np.sum(np.abs(after - before) > 1e-9)),
        "views_better_by_0.02": int(np.sum(after < before - 0.02)),
        "views_worse_by_0.02": int(np.sum(after > before + 0.02)),
    }  # fmt: skip
    summary["people_on_plain_views"] = {
        "views_with_anybody": sum(r["people_found"] > 0 for r in rows),
        "views_with_a_full_body": sum(r["full_bodies"] > 0 for r in rows),
        "views_whose_horizon_moved": sum(abs(r["used_with_people"] - r["used"]) > 1e-9 for r in rows),
    }
    if pasted:
        by_n = {}
        for n in sorted({r["pasted"] for r in pasted}):
            sel = [r for r in pasted if r["pasted"] == n]
            got = [r for r in sel if r["people"] is not None]
            vert = [r for r in sel if r["verticals"] is not None]
            z = [abs(r["people"] - r["truth"]) / r["people_se"] for r in got if r["people_se"]]
            bodies = round(float(np.mean([r["full_bodies"] for r in sel])), 2)
            by_n[str(n)] = {
                "views": len(sel), "full_bodies_found_per_view": bodies, "people_answered": len(got),
                "people_error": error_summary([abs(r["people"] - r["truth"]) for r in got]),
                "people_error_over_se_median": round(float(np.median(z)), 2) if z else None,
                "verticals_error": error_summary([abs(r["verticals"] - r["truth"]) for r in vert]),
                "composite_before": error_summary([abs(r["old"] - r["truth"]) for r in sel]),
                "composite_after": error_summary([abs(r["new"] - r["truth"]) for r in sel]),
            }  # fmt: skip
        summary["people_pasted"] = {"camera_m": args.camera, "by_people_pasted": by_n}
    print(json.dumps(summary, indent=1))
    for r in found:
        if abs(r["estimate"] - r["truth"]) > 0.05:
            print(f"off: {r['map']} {r['az']},{r['el']}: {r['estimate']:.2f} for {r['truth']:.2f}")
    photos, skies, moved, photo_people, people_moved = {}, {}, {}, {}, {}
    if args.photos:
        import cv2

        for path in sorted(p for p in args.photos.iterdir() if p.suffix.lower() in (".jpg", ".png")):
            img = cv2.imread(str(path), cv2.IMREAD_COLOR)
            if img is not None and not path.stem.endswith("_mask"):
                rgb = np.ascontiguousarray(img[..., ::-1])
                photos[path.name], skies[path.name] = estimate_horizon(rgb, 60.0), sky_line(rgb)
                found_people = find_people(rgb, matter)
                ph = people_horizon(found_people)
                photo_people[path.name] = None if ph is None else ph[0]
                shift = scene_horizon(rgb, 60.0, found_people) - find_horizon(rgb, 60.0)
                if abs(shift) > 1e-9:
                    people_moved[path.name] = shift
                old = min(max(0.5 if photos[path.name] is None else photos[path.name], 0.0), HORIZON_ESTIMATE_MAX)
                if abs(find_horizon(rgb, 60.0) - old) > 1e-9:
                    moved[path.name] = (old, find_horizon(rgb, 60.0))
        for name, found in (("verticals", photos), ("sky_line", skies)):
            got = np.array([v for v in found.values() if v is not None])
            print(json.dumps({"photos": len(found), name: int(got.size),
                              "percentiles_5_25_50_75_95": np.percentile(got, [5, 25, 50, 75, 95]).round(3).tolist()
                              if got.size else []}))  # fmt: skip
        both = [(photos[k], v) for k, v in photo_people.items() if v is not None and photos[k] is not None]
        diff = np.array([abs(a - b) for a, b in both])
        print(json.dumps({"photos": len(photo_people), "people_answered": sum(v is not None for v in
                          photo_people.values()), "both_answered": len(both),
                          "people_minus_verticals_abs": error_summary(diff),
                          "composite_horizon_moved_by_people": len(people_moved),
                          "moved_by_abs": error_summary([abs(v) for v in people_moved.values()])}))  # fmt: skip
        print(
            f"composite's horizon moved by the sky line on {len(moved)} photos: "
            + ", ".join(f"{k} {a:.2f} -> {b:.2f}" for k, (a, b) in sorted(moved.items()))
        )
    if args.places:
        from scene_sheet import photo_background

        for path in args.places:
            bg = photo_background(path, (size[1], size[0]))
            est, line = estimate_horizon(bg, 60.0), sky_line(bg)
            est_s, line_s = "-" if est is None else f"{est:.3f}", "-" if line is None else f"{line:.3f}"
            people = find_people(bg, matter)
            ph = people_horizon(people)
            ph_s = "-" if ph is None else f"{ph[0]:.3f}±{ph[1]:.3f}"
            print(f"{path.name:28s} verticals {est_s:>6s}  sky line {line_s:>6s}  used {find_horizon(bg, 60.0):.3f}  "
                  f"people {ph_s:>12s} ({len(people)} found, {sum(p.full_body for p in people)} whole)  "
                  f"with people {scene_horizon(bg, 60.0, people):.3f}")  # fmt: skip
    if args.speed:
        import statistics
        import time

        import cv2

        for path in args.places:
            img = cv2.resize(cv2.imread(str(path))[..., ::-1], (1920, 1080), interpolation=cv2.INTER_CUBIC)
            find_people(img, matter)  # warm
            wall, cpu = [], []
            for _ in range(7):
                t0, c0 = time.perf_counter(), time.process_time()
                n = len(find_people(img, matter))
                wall.append(time.perf_counter() - t0)
                cpu.append(time.process_time() - c0)
            print(f"people search, {path.name} at 1920x1080: {n} found, wall {statistics.median(wall):.3f} s "
                  f"(min {min(wall):.3f}), CPU {statistics.median(cpu):.3f} s")  # fmt: skip
    if args.out:
        args.out.write_text(
            json.dumps(
                {
                    "summary": summary,
                    "views": rows,
                    "photos": photos,
                    "photo_sky_lines": skies,
                    "photo_people": photo_people,
                    "pasted": pasted,
                },
                indent=1,
            )
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
