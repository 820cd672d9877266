"""Front- or back-lit from one view: candidate rules for light.from_background's call, on every map (issue 49).

    python benchmarks/scene_frontback.py --envs runs/scene/envs [--out runs/scene/frontback.json]
    python benchmarks/scene_frontback.py --maps runs/scene/frontback.json --sets shared,blender   # the 68 places

ENVS: ``benchmarks/scene_eval.py --prepare-envs`` (25 scenes x 4 turns: ../shared/hdri, blender-data, npm's
@pmndrs/assets). For each map, the background photo is scene_eval's (a 60° view, metered to 0.18, 8-bit sRGB), the
truth its SH light's camera-facing over back irradiance (scene_eval.front_back); scored on the maps whose sides
differ by >= 1 EV. Each rule is scored with its numbers fitted with the map's whole scene left out (loso), and
fitted on the other scene sets only (cross), per set. Rules without a fitted number score the same everywhere
("today" is the shipped BACKLIGHT, fitted on all 100 maps: no figure of it is held out; its rule fitted per fold is
"lstsq top_bottom+contrast clip 1"). ``--sets`` keeps some scene sets only (shared,blender: the 68 places, fitted
among themselves as scene_eval --sets fits them); ``--maps`` reads the features of an earlier ``--out`` (seconds).
scene24's combinations: both statistics in one fit, ``both`` / ``either`` / ``vote`` of the two fitted rules, the
truth clipped to +-1 EV (``clip``) or only the clear maps fitted on (``clear_only``).
``glow``: the mean luminance 5-15 px around the largest compact clipped region (apps.scene_rim's source) over the
median, in EV: a source in frame lights its surround (a sun's aureole, a lamp's flare), a sunlit facade's edge
meets shade.

The colour cues (issue 49: a cue the view's luminance does not carry; none fitted but by the rules):
``colour_share`` (scene5's, shipped until scene24: from_background.colour_share): the chromaticity's spread over
log2 luminance's: lit from behind the camera a view varies by reflectance (colour), toward the light by
illumination (sky or window over shaded sides: none). ``sky_ground_blue``: log2 B/R of the top third minus the
bottom third's: toward the sun the sky whitens and the ground one sees is in blue skylight, away from it the sky
is deep blue over sunlit, warmer ground; unchanged by white balance. ``chroma_spread``: the colour share's
numerator alone. ``sky_over_ground``: the median log2 luminance of the smooth bright region joined to the top
edge (a sky, a ceiling) over the view's median: toward the sun a bright sky over shaded ground. ``sky_slope``:
that region's log2 luminance per 10° of elevation: circumsolar brightening above a sun ahead, darkening toward
90° from a sun behind. ``perez_ahead``: a clear-sky model (Perez, Preetham's coefficients) fitted to that region's
unclipped pixels with the sun free: does a sun ahead of the camera explain it better than one behind?

The view's own objects' shading (issue 49, scene10; ``shading_cues``): the bottom half's spread and dark share, the
ground's gradient below the horizon, the polarity of vertical steps, the vertical faces' shade between sky and
ground. ``opposed_order``: how many of the clear maps' opposite views (the same place turned 180°) the shipped score
orders right, i.e. how many wrong calls are the place's offset rather than the cue's direction.

``--fit`` prints the shipped rule's BACKLIGHT fitted on every map (least squares, as scene_eval.fit).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
for p in (REPO, REPO / "benchmarks"):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

from scene_eval import (  # noqa: E402
    BACKLIGHT_CLIP_EV,
    CLEAR_EV,
    GREY,
    front_back,
    mean_lum,
    photograph,
    scene_of,
    scene_set,
    view_linear,
)

from relight_rt import envmap  # noqa: E402
from relight_rt.image.color import REC709, srgb8_to_linear  # noqa: E402
from relight_rt.light import from_background as bgmod  # noqa: E402


def features(photo: np.ndarray) -> dict[str, float]:
    """The view's statistics a rule may read (log2 where a ratio)."""
    parts = bgmod.scene_light(photo, 60.0)
    lum = srgb8_to_linear(photo) @ REC709
    h = lum.shape[0]
    med = max(float(np.median(lum)), 1e-6)
    clipped = photo.max(axis=2) >= 250
    top = lum[: h // 3]
    return {
        "top_bottom": parts.top_bottom,
        "contrast": parts.contrast,
        "mean_median": math.log2(max(float(lum.mean()), 1e-6) / med),
        "p99_median": math.log2(max(float(np.quantile(lum, 0.99)), 1e-6) / med),
        "clipped": float(clipped.mean()),
        "clipped_top": float(clipped[: h // 2].mean()),
        "top_median": math.log2(max(float(top.mean()), 1e-6) / med),
        "source_share": float(
            (bgmod.FRONT_WEIGHTS @ (parts.source @ REC709))
            / max(bgmod.BACK_WEIGHTS @ ((parts.view + parts.source) @ REC709), 1e-9)
        ),
        "bright_el": parts.bright[1],
        "glow": source_glow(photo, lum, med),
        "score": parts.backlight_score(),
        "colour_share": parts.colour_share,
        "chroma_spread": parts.colour_share * max(parts.contrast, 0.05),
        "log_colour_share": math.log2(max(parts.colour_share, 1e-3)),
        "log_chroma": math.log2(max(parts.colour_share * max(parts.contrast, 0.05), 1e-3)),
        "log_contrast": math.log2(max(parts.contrast, 0.05)),
        "sky_ground_blue": blue_red(srgb8_to_linear(photo[: h // 3])) - blue_red(srgb8_to_linear(photo[-(h // 3) :])),
        **sky_region(photo, lum),
        **shading_cues(lum),
    }


#: shading_cues: a log2-luminance step (per pixel, after a 1-px blur) from which an edge counts
_EDGE = 0.5


def shading_cues(lum: np.ndarray) -> dict[str, float]:
    """The view's own objects' shading (issue 49, scene10; chosen before any was scored), all in log2 luminance of
    the (h, w) linear view, the horizon at mid-height (a level camera):
    ``lower_contrast``: the spread of the bottom half (ground, the near sides of things): toward the light the
    camera sees shaded sides beside lit tops and shadows falling toward it; lit from behind, surfaces lit evenly
    and their shadows hidden behind them. ``lower_over_upper``: that spread minus the top half's.
    ``lower_dark``: the share of the bottom half darker than a quarter of the view's median (shade toward the camera).
    ``ground_gradient``: the band just below the horizon (rows h/2 .. 2h/3) over the bottom third: toward the sun
    the far ground shines (forward scattering, sheen at grazing angles) and near things show their shaded side;
    away from it the near ground nearer the anti-solar point is the brighter (the hot spot).
    ``edge_polarity``: over the strong vertical steps (|Δ| > _EDGE between the rows above and below), the share
    brighter above minus the share brighter below: toward the light, silhouettes against a bright sky and dark
    faces under lit tops; lit from behind, lit faces against the sky and under them.
    ``vertical_dark``: the band around the horizon (rows 0.4 h .. 0.6 h, where a level camera sees the vertical faces
    of things: walls, trunks, hills) below the mean of the view's top and bottom fifths: toward the light those faces
    are in their own shade between a bright sky (or lamp) and lit ground; lit from behind they face the light."""
    import cv2

    h, w = lum.shape
    ll = cv2.GaussianBlur(np.log2(np.maximum(lum, 2.0**-13)).astype(np.float32), (0, 0), 1.0)
    upper, lower = ll[: h // 2], ll[h // 2 :]
    med = float(np.median(ll))
    dy = ll[:-2] - ll[2:]  # above minus below
    strong = np.abs(dy) > _EDGE
    n = max(int(strong.sum()), 1)
    return {
        "lower_contrast": float(lower.std()),
        "lower_over_upper": float(lower.std() - upper.std()),
        "lower_dark": float((lower < med - 2).mean()),
        "ground_gradient": float(ll[h // 2 : 2 * h // 3].mean() - ll[2 * h // 3 :].mean()),
        "vertical_dark": float((ll[: h // 5].mean() + ll[-(h // 5) :].mean()) / 2 - ll[2 * h // 5 : 3 * h // 5].mean()),
        "edge_polarity": float(((dy > _EDGE).sum() - (dy < -_EDGE).sum()) / n) if strong.any() else 0.0,
    }


def blue_red(lin: np.ndarray) -> float:
    """log2 of the mean blue over the mean red of linear pixels."""
    m = lin.reshape(-1, 3).astype(np.float64).mean(0) + 1e-6
    return math.log2(m[2] / m[0])


def sky_region(photo: np.ndarray, lum: np.ndarray) -> dict[str, float]:
    """``sky_over_ground`` and ``sky_slope`` (module docstring) of the region of the top half that is smooth (log2
    luminance gradient < 0.5 per pixel after a 1.5-px blur), at least the median and joined to the top edge; both 0
    where it covers under 2 % of the view."""
    import cv2

    h, w = lum.shape
    ll = np.log2(np.maximum(lum, 2.0**-13)).astype(np.float32)
    g = cv2.GaussianBlur(ll, (0, 0), 1.5)
    smooth = np.hypot(cv2.Sobel(g, cv2.CV_32F, 1, 0), cv2.Sobel(g, cv2.CV_32F, 0, 1)) < 0.5
    sky = smooth & (np.arange(h)[:, None] < h // 2) & (ll >= np.median(ll))
    lab = cv2.connectedComponents(sky.astype(np.uint8), connectivity=4)[1]
    sky &= np.isin(lab, np.unique(lab[0][sky[0]]))
    if sky.sum() < 0.02 * h * w:
        return {"sky_over_ground": 0.0, "sky_slope": 0.0, "perez_ahead": 0.0}
    tan_v = math.tan(math.radians(30)) * h / w
    el = np.broadcast_to(np.degrees(np.arctan((1 - (np.arange(h) + 0.5) / h * 2) * tan_v))[:, None], (h, w))[sky]
    slope = np.linalg.lstsq(np.stack([np.ones_like(el), el], 1), ll[sky], rcond=None)[0][1]
    return {"sky_over_ground": float(np.median(ll[sky]) - np.median(ll)), "sky_slope": float(slope) * 10,
            "perez_ahead": perez_ahead(ll, sky & (photo.max(axis=2) < 250))}  # fmt: skip


#: Preetham et al.'s luminance coefficients (A..E) of the Perez sky model at turbidity 3 (a clear sky)
_PEREZ = tuple(a * 3.0 + b for a, b in ((0.1787, -1.4630), (-0.3554, 0.4275), (-0.0227, 5.3251), (0.1206, -2.5771),
                                        (-0.0670, 0.3703)))  # fmt: skip


def perez_ahead(ll: np.ndarray, sky: np.ndarray) -> float:
    """``perez_ahead``: log of the best fit's mean squared log-luminance error over the sky pixels with the sun
    behind the camera over that with it ahead (a clear-sky Perez model, the sun on a 10° x 6° grid of azimuths and
    elevations 2-74°, the scale free); > 0: a sun ahead explains the sky better. 0 with under 3 % of sky."""
    h, w = ll.shape
    ys, xs = np.nonzero(sky)
    if len(ys) < 0.03 * h * w:
        return 0.0
    tan_h = math.tan(math.radians(30))
    d = np.stack([-np.ones(len(xs)), ((xs + 0.5) / w * 2 - 1) * tan_h, (1 - (ys + 0.5) / h * 2) * tan_h * h / w], 1)
    d /= np.linalg.norm(d, axis=1, keepdims=True)  # the camera looks along -x, the image's right +y, up +z
    a, b, c, dd, e = _PEREZ
    zenith = 1 + a * np.exp(b / np.maximum(d[:, 2], 0.02))
    y = ll[ys, xs] * math.log(2)
    best = {True: math.inf, False: math.inf}
    for az in np.radians(np.arange(0, 360, 10)):
        for el in np.radians(np.arange(2, 75, 6)):
            cos_g = np.clip(d @ [math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)], -1, 1)
            r = y - np.log(np.maximum(zenith * (1 + c * np.exp(dd * np.arccos(cos_g)) + e * cos_g**2), 1e-6))
            ahead = math.cos(az) < 0
            best[ahead] = min(best[ahead], float(r.var()))
    return math.log(best[False] / best[True])


def source_glow(photo: np.ndarray, lum: np.ndarray, med: float) -> float:
    """log2 of the mean luminance around the largest compact clipped region (apps.scene_rim's source: 2 px to 3 %
    of the frame) over the median, 5 to 15 px out; 0 when there is none."""
    import cv2

    clip = (photo.max(axis=2) >= 250).astype(np.uint8)
    n, lab, st, _ = cv2.connectedComponentsWithStats(clip, connectivity=8)
    areas = st[1:, cv2.CC_STAT_AREA]
    ok = (areas >= 2) & (areas <= 0.03 * clip.size)
    if not ok.any():
        return 0.0
    src = (lab == 1 + int(np.argmax(np.where(ok, areas, 0)))).astype(np.uint8)
    ring = cv2.dilate(src, np.ones((15, 15), np.uint8)) > cv2.dilate(src, np.ones((5, 5), np.uint8))
    return math.log2(max(float(lum[ring].mean()), 1e-6) / med)


def either(a, b):
    """Back-lit where either rule says so."""
    return lambda train: (lambda fa, fb: lambda f: fa(f) or fb(f))(a(train), b(train))


def both(a, b):
    """Back-lit only where both rules say so (they disagree: unsure, read as front-lit, the call without a key
    behind)."""
    return lambda train: (lambda fa, fb: lambda f: fa(f) and fb(f))(a(train), b(train))


def vote(a, b, c):
    """Where rules a and b agree, their call; where they disagree (unsure), rule c's."""
    return lambda train: (lambda fa, fb, fc: lambda f: fa(f) if fa(f) == fb(f) else fc(f))(a(train), b(train),
                                                                                            c(train))  # fmt: skip


def lstsq_rule(names, clip=None, clear_only=False):
    """A rule: back-lit where the least-squares fit of the truth's front/back EV on [1, features] is < 0 (``clip``:
    the truth clipped to +-clip EV first, so that a sun's 6 EV does not outweigh the calls near 0; ``clear_only``:
    fitted on the clear maps only)."""

    def fit(train):
        rows = [(f, t) for f, t in train if abs(t) >= CLEAR_EV] if clear_only else train
        x = np.array([[1.0, *(f[n] for n in names)] for f, _ in rows])
        y = np.array([t for _, t in rows])
        if clip is not None:
            y = np.clip(y, -clip, clip)
        w = np.linalg.lstsq(x, y, rcond=None)[0]
        return lambda f: float(w @ np.array([1.0, *(f[n] for n in names)])) < 0

    return fit


def threshold_rule(name, sign=1):
    """A rule on one feature: back-lit where sign · feature > the threshold that is best on the training maps."""

    def fit(train):
        vals = sorted({f[name] for f, _ in train})
        cands = [(a + b) / 2 for a, b in zip(vals, vals[1:], strict=False)] or [0.0]
        clear = [(f, t) for f, t in train if abs(t) >= CLEAR_EV]

        def acc(th):
            return np.mean([(sign * f[name] > sign * th) == (t < 0) for f, t in clear])

        th = max(cands, key=acc)
        return lambda f: sign * f[name] > sign * th

    return fit


#: the feature sets each rule variant (clipped truth, clear maps only) is fitted on
_FEATURE_SETS = (
    ["top_bottom", "contrast"],
    ["top_bottom", "colour_share"],
    ["top_bottom", "contrast", "colour_share"],
    ["top_bottom", "log_colour_share"],
    ["top_bottom", "log_chroma", "log_contrast"],
)

RULES = {
    "today (score < 0)": lambda train: lambda f: f["score"] < 0,
    "lstsq top_bottom+contrast clip 1 (today's, scene24, fitted)": lstsq_rule(["top_bottom", "contrast"], clip=1.0),
    "lstsq top_bottom+colour_share (scene5's, fitted)": lstsq_rule(["top_bottom", "colour_share"]),
    "lstsq top_bottom+contrast (before scene5)": lstsq_rule(["top_bottom", "contrast"]),
    "lstsq top_bottom+contrast+colour_share": lstsq_rule(["top_bottom", "contrast", "colour_share"]),
    "threshold colour_share": threshold_rule("colour_share", -1),
    "lstsq top_bottom+chroma_spread": lstsq_rule(["top_bottom", "chroma_spread"]),
    "lstsq top_bottom+contrast+chroma_spread": lstsq_rule(["top_bottom", "contrast", "chroma_spread"]),
    "threshold sky_ground_blue": threshold_rule("sky_ground_blue", -1),
    "lstsq top_bottom+contrast+sky_ground_blue": lstsq_rule(["top_bottom", "contrast", "sky_ground_blue"]),
    "threshold sky_over_ground": threshold_rule("sky_over_ground"),
    "lstsq top_bottom+contrast+sky_over_ground": lstsq_rule(["top_bottom", "contrast", "sky_over_ground"]),
    "perez_ahead > 0": lambda train: lambda f: f["perez_ahead"] > 0,
    "lstsq top_bottom+colour_share+perez_ahead": lstsq_rule(["top_bottom", "colour_share", "perez_ahead"]),
    "threshold sky_slope": threshold_rule("sky_slope", -1),
    "lstsq top_bottom+contrast+sky_slope": lstsq_rule(["top_bottom", "contrast", "sky_slope"]),
    "lstsq +mean_median": lstsq_rule(["top_bottom", "contrast", "mean_median"]),
    "lstsq +p99_median": lstsq_rule(["top_bottom", "contrast", "p99_median"]),
    "lstsq +clipped_top": lstsq_rule(["top_bottom", "contrast", "clipped_top"]),
    "lstsq top_median+contrast": lstsq_rule(["top_median", "contrast"]),
    "lstsq top_bottom+p99_median": lstsq_rule(["top_bottom", "p99_median"]),
    "lstsq top_bottom+contrast+bright_el": lstsq_rule(["top_bottom", "contrast", "bright_el"]),
    "threshold glow": threshold_rule("glow"),
    "glow >= 2 EV": lambda train: lambda f: f["glow"] >= 2,
    "glow >= 2 EV or lstsq": either(lambda train: lambda f: f["glow"] >= 2, lstsq_rule(["top_bottom", "contrast"])),
    "glow >= 3 EV or lstsq": either(lambda train: lambda f: f["glow"] >= 3, lstsq_rule(["top_bottom", "contrast"])),
    "lstsq top_bottom+contrast+glow": lstsq_rule(["top_bottom", "contrast", "glow"]),
    # the view's own objects' shading (shading_cues; scene10)
    "threshold lower_contrast": threshold_rule("lower_contrast"),
    "threshold lower_over_upper": threshold_rule("lower_over_upper"),
    "threshold lower_dark": threshold_rule("lower_dark"),
    "threshold ground_gradient": threshold_rule("ground_gradient"),
    "threshold edge_polarity": threshold_rule("edge_polarity"),
    "threshold vertical_dark": threshold_rule("vertical_dark"),
    "lstsq top_bottom+colour_share+vertical_dark": lstsq_rule(["top_bottom", "colour_share", "vertical_dark"]),
    "lstsq top_bottom+colour_share+lower_contrast": lstsq_rule(["top_bottom", "colour_share", "lower_contrast"]),
    "lstsq top_bottom+colour_share+lower_over_upper": lstsq_rule(["top_bottom", "colour_share", "lower_over_upper"]),
    "lstsq top_bottom+colour_share+lower_dark": lstsq_rule(["top_bottom", "colour_share", "lower_dark"]),
    "lstsq top_bottom+colour_share+ground_gradient": lstsq_rule(["top_bottom", "colour_share", "ground_gradient"]),
    "lstsq top_bottom+colour_share+edge_polarity": lstsq_rule(["top_bottom", "colour_share", "edge_polarity"]),
    "lstsq colour_share+ground_gradient+edge_polarity": lstsq_rule(
        ["colour_share", "ground_gradient", "edge_polarity"]
    ),
    # scene24: one call that holds on the 68 places and on the 100 maps (both statistics, or a vote)
    "lstsq top_bottom+contrast+log_colour_share": lstsq_rule(["top_bottom", "contrast", "log_colour_share"]),
    "lstsq top_bottom+log_chroma+log_contrast": lstsq_rule(["top_bottom", "log_chroma", "log_contrast"]),
    "lstsq top_bottom+log_colour_share": lstsq_rule(["top_bottom", "log_colour_share"]),
    "back where both (contrast, colour_share) say": both(
        lstsq_rule(["top_bottom", "contrast"]), lstsq_rule(["top_bottom", "colour_share"])
    ),
    "back where either (contrast, colour_share) says": either(
        lstsq_rule(["top_bottom", "contrast"]), lstsq_rule(["top_bottom", "colour_share"])
    ),
    "vote contrast/colour_share, unsure: both together": vote(
        lstsq_rule(["top_bottom", "contrast"]),
        lstsq_rule(["top_bottom", "colour_share"]),
        lstsq_rule(["top_bottom", "contrast", "colour_share"]),
    ),
    **{
        f"lstsq {'+'.join(n)} clip {c}": lstsq_rule(n, clip=c)
        for c in (1.0, 2.0)
        for n in _FEATURE_SETS
    },
    **{
        f"lstsq {'+'.join(n)} clear only": lstsq_rule(n, clear_only=True)
        for n in _FEATURE_SETS
    },
    "threshold mean_median": threshold_rule("mean_median"),
    "threshold contrast": threshold_rule("contrast"),
    "threshold top_bottom": threshold_rule("top_bottom"),
    "threshold top_median": threshold_rule("top_median"),
    "threshold source_share": threshold_rule("source_share"),
}


def score(rule, rows, train_of) -> dict:
    """Accuracy on the clear maps, per scene set and all, each map judged by the rule fitted on train_of(map)."""
    right = {}
    for m, (f, t) in rows.items():
        if abs(t) < CLEAR_EV:
            continue
        train = [rows[n] for n in train_of(m)]
        right[m] = rule(train)(f) == (t < 0)
    out = {"all": (float(np.mean(list(right.values()))), len(right))}
    for s in ("shared", "blender", "npm"):
        v = [r for m, r in right.items() if scene_set(m) == s]
        out[s] = (float(np.mean(v)) if v else float("nan"), len(v))
    out["wrong"] = sorted(m for m, r in right.items() if not r)
    return out


def opposed_order(rows: dict, name: str = "score") -> tuple[int, list[str]]:
    """The clear maps come in opposite views of one place (turned 180°: one back-lit, the other front-lit): over
    those pairs, (how many the feature ``name`` orders right, i.e. lower on the back-lit view, the pairs' back-lit
    maps). A rule's call is ``feature < threshold``: a pair ordered right but called wrong is the place's offset
    (one view cannot see it), not the cue's direction."""
    clear = {m for m, (_, t) in rows.items() if abs(t) >= CLEAR_EV}
    right, backs = 0, []
    for m in sorted(clear):
        place, turn = m.rsplit("_y", 1)
        other = f"{place}_y{(int(turn) + 180) % 360:03d}"
        if rows[m][1] < 0 and other in clear:
            backs.append(m)
            right += rows[m][0][name] < rows[other][0][name]
    return right, backs


def best_line(rows: dict, names=("top_bottom", "colour_share")) -> float:
    """The ceiling of a rule on two features: the best share of the clear maps any line in their plane (720
    directions, every threshold) calls right, chosen on the answers (in-sample: held out it can only do worse)."""
    clear = [(f, t) for f, t in rows.values() if abs(t) >= CLEAR_EV]
    x = np.array([[f[n] for n in names] for f, _ in clear])
    back = np.array([t < 0 for _, t in clear])
    best = 0.0
    for angle in np.linspace(0, 2 * math.pi, 720, endpoint=False):
        z = x @ [math.cos(angle), math.sin(angle)]
        for cut in np.concatenate([z - 1e-9, z + 1e-9]):
            best = max(best, float(np.mean((z < cut) == back)))
    return best


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--envs", type=Path)
    ap.add_argument("--maps", type=Path, help="read the maps' features and truths from an earlier --out (no --envs)")
    ap.add_argument("--out", type=Path)
    ap.add_argument("--fit", action="store_true", help="print BACKLIGHT fitted on every map")
    ap.add_argument("--sets", metavar="A,B", help="only these scene sets (shared, blender, npm; default: every map)")
    ap.add_argument("--rules", metavar="TEXT", help="only the rules whose name contains TEXT")
    args = ap.parse_args(argv)
    rows = {}
    if args.maps:
        rows = {m: ({k: v for k, v in r.items() if k != "truth_ev"}, r["truth_ev"])
                for m, r in json.loads(args.maps.read_text())["maps"].items()}  # fmt: skip
    elif args.envs is None:
        ap.error("give --envs or --maps")
    for path in sorted(args.envs.glob("*.hdr")) if not args.maps else ():
        env = envmap.load_envmap(path)
        lin = view_linear(env)
        photo = photograph(lin, GREY / max(mean_lum(lin), 1e-9))
        rows[path.stem] = (features(photo), front_back(envmap.project_envmap(env)))
    if args.sets:
        rows = {m: r for m, r in rows.items() if scene_set(m) in args.sets.split(",")}
    maps = list(rows)
    loso = lambda m: [n for n in maps if scene_of(n) != scene_of(m)]  # noqa: E731
    cross = lambda m: [n for n in maps if scene_set(n) != scene_set(m)]  # noqa: E731
    report = {}
    for name, rule in RULES.items():
        if args.rules and args.rules not in name:
            continue
        a, c = score(rule, rows, loso), score(rule, rows, cross)
        report[name] = {"loso": a, "cross": c}
        print(f"{name:30s} loso all {100 * a['all'][0]:3.0f}% ({a['all'][1]}) shared {100 * a['shared'][0]:3.0f}% "
              f"blender {100 * a['blender'][0]:3.0f}% npm {100 * a['npm'][0]:3.0f}% | cross shared "
              f"{100 * c['shared'][0]:3.0f}% blender {100 * c['blender'][0]:3.0f}% npm {100 * c['npm'][0]:3.0f}%  "
              f"wrong(loso): {' '.join(a['wrong'])}")  # fmt: skip
    right, backs = opposed_order(rows)
    report["opposed_order"] = {"right": right, "pairs": len(backs)}
    report["best_line_in_sample"] = best_line(rows)
    print(
        f"any line on top_bottom and colour_share, chosen on the answers: {100 * report['best_line_in_sample']:.0f} %"
    )
    print(f"the shipped score orders {right} of {len(backs)} opposite clear pairs right (lower on the back-lit view)")
    report["maps"] = {m: {"truth_ev": t, **f} for m, (f, t) in rows.items()}
    if args.fit:
        x = np.array([[1.0, f["top_bottom"], f["contrast"]] for f, _ in rows.values()])
        y = np.clip([t for _, t in rows.values()], -BACKLIGHT_CLIP_EV, BACKLIGHT_CLIP_EV)
        w = np.linalg.lstsq(x, y, rcond=None)[0]  # as scene_eval.fit_backlight
        print("BACKLIGHT fitted on every map:", tuple(round(float(v), 3) for v in w))
    if args.out:
        args.out.write_text(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
