"""A group's own light and its people's: does the group's own light give a group photo back, and do people who stand
in one light keep their relative brightness and colour under a new one (task groups26)?

    python benchmarks/group_own_light.py [--people ../shared/realdata/people_masks] [--only p273,p240 | --every]
        [--extra /tmp/relight_rt_people/group_t1.jpg] [--variant product] [--json /tmp/g.json]

Per group photo (five people_masks photos the default matte finds several people in, ``GROUPS``; with ``--every``
all such photos, found by the matte first, ~1 s a photo; and any ``--extra`` photo), decomposed as ``relight-rt
relight`` does (the automatic matte, no mask given), per person (their pixels: their share of the matte > 0.5 and the
largest there; their skin: those where their stage 1 sees skin > 0.5): how far their light is from the group's (the
largest coefficient of the two lights taken as white, over the group's degree-0 one: ``dev``), and what
``relight(dec, dec)`` (the group's own light) changes there (max / mean levels, plain backdrop and the graded one).
Under each new light (the white side lamps LEFT and RIGHT, then every preset), per pair of people: how much their
relative brightness moved (``|log2 (Yi'/Yj') - log2 (Yi/Yj)|``, Y their mean luminance, in EV), how much their
relative colour moved (the largest of ``|log (gi_c / gi_G) - log (gj_c / gj_G)|`` over c = R, B, g = mean relit over
mean photo per channel), both over their pixels and over their skin (people with 50 skin pixels or more), and per
person the side swing ``log2 (YL'/YR') - log2 (YL/YR)`` (their left half over their right half): under one lamp
people in one light swing the same way, so the spread (max - min over the people) is printed too. The last line:
the means over the photos and lights.

``--variant``: ``product`` (this checkout: each person keeps the light fitted to them, a light L reaches person i
as L + s (own_i - group), s per colour L's degree-0 coefficient over the group's, ``people.reaching``), or a
candidate rule put in place for the measurement only: ``own`` (a light asked for reaches everyone as it is: main
before groups26), ``white`` (the deviation scaled by L's degree-0 luminance, white), ``group`` (one light: each
person's replaced by the group's after their refit and face pass, candidate (b)), ``joint`` (one light: the group's
refit over every person's own pixels, then set on each).
Evaluation photos only: nothing is written but ``--json``.
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
import time
from pathlib import Path

import numpy as np

# real_photos puts this checkout (and benchmarks/) first on sys.path: the relight_rt imported below is this one
from real_photos import LEFT, RIGHT, luminance

# isort: split
from _shared import shared_path
from first_look import read_rgb

import relight_rt
from relight_rt import RelightError, RuntimeConfig, lights
from relight_rt.image.color import REC709
from relight_rt.image.compositing import Background
from relight_rt.relight import people as per_person
from relight_rt.relight import relighter as relighter_module

GROUPS = ("p273", "p240", "p194", "p209", "p238")
LIGHTS = ("LEFT", "RIGHT", *lights.list_presets())


def shares(dec) -> list[np.ndarray]:
    """Each person's share of the group's matte over the whole frame (H, W) float32."""
    h, w = dec.geometry.frame
    out = []
    for part in dec.people:
        oy, ox = part.origin
        m = np.asarray(part.mask, np.float32)
        full = np.zeros((h, w), np.float32)
        full[oy : oy + m.shape[0], ox : ox + m.shape[1]] = m
        out.append(full)
    return out


def skins(dec, where: list[np.ndarray]) -> list[np.ndarray]:
    """Person i's skin: their pixels (``person_pixels``) where stage 1's skin probability for them is > 0.5."""
    h, w = dec.geometry.frame
    out = []
    for part, mine in zip(dec.people, where, strict=True):
        oy, ox = part.origin
        alpha = np.maximum(np.asarray(part.network_mask, np.float32), 1e-6)
        prob = part.to_input(np.asarray(part.skin, np.float32) / alpha)
        full = np.zeros((h, w), np.float32)
        full[oy : oy + prob.shape[0], ox : ox + prob.shape[1]] = prob
        out.append(mine & (full > 0.5))
    return out


def white_lum(light: np.ndarray) -> np.ndarray:
    return np.asarray(light, np.float64) @ REC709.astype(np.float64)


def person_pixels(sh: list[np.ndarray]) -> list[np.ndarray]:
    """Person i's pixels: their share > 0.5 and the largest there."""
    stack = np.stack(sh)
    top = stack.argmax(axis=0)
    return [(s > 0.5) & (top == i) for i, s in enumerate(sh)]


def stats(photo: np.ndarray, relit: np.ndarray, where: np.ndarray) -> dict:
    d = 255 * np.abs(relit[..., :3] - photo).max(axis=2)[where]
    return {"max": float(d.max()), "mean": float(d.mean()), "over_half": int((d > 0.5).sum())}


def side_swing(photo_y: np.ndarray, relit_y: np.ndarray, where: np.ndarray) -> float:
    cols = np.flatnonzero(where.any(axis=0))
    mid = (cols[0] + cols[-1] + 1) // 2
    left, right = where.copy(), where.copy()
    left[:, mid:] = False
    right[:, :mid] = False
    if not left.any() or not right.any():
        return 0.0

    def lr(y):
        return np.log2(max(y[left].mean(), 1e-6) / max(y[right].mean(), 1e-6))

    return float(lr(relit_y) - lr(photo_y))


def measure(rl, path: Path) -> dict:
    rgb = read_rgb(path)
    t0 = time.time()
    dec = rl.decompose(rgb)
    took = time.time() - t0
    if not dec.people:
        return {"people": 0}
    sh = shares(dec)
    where = person_pixels(sh)
    group = white_lum(dec.light)
    dc = abs(group[0])
    people = []
    for part, w in zip(dec.people, where, strict=True):
        own = white_lum(part.light)
        people.append({"pixels": int(w.sum()), "dev": float(np.abs(own - group).max() / dc),
                       "dev_abs": float(np.abs(np.asarray(part.light) - np.asarray(dec.light)).max())})
    for key, bg in (("plain", "original"), ("graded", Background.original(grade=True))):
        back = np.asarray(rl.relight(dec, dec, background=bg), np.float32)
        for p, w in zip(people, where, strict=True):
            p[key] = stats(rgb, back, w)
        if key == "plain":
            outside = dec.mask <= 0
            off = 255 * np.abs(back - rgb).max(axis=2)
            whole = {"max": float(off.max()), "outside_max": float(off[outside].max()) if outside.any() else 0.0}
    photo_y = luminance(rgb)
    skin = skins(dec, where)
    for p, k in zip(people, skin, strict=True):
        p["skin_pixels"] = int(k.sum())
    pairs, swings = {}, {}
    for name in LIGHTS:
        light = {"LEFT": LEFT, "RIGHT": RIGHT}.get(name, name)
        img = np.asarray(rl.relight(dec, light), np.float32)
        y = luminance(img)
        pairs[name] = {}
        for key, regions in (("", where), ("skin_", skin)):
            gains = []
            for w in regions:
                if w.sum() < 50:
                    gains.append(None)
                    continue
                g = img[w].mean(axis=0) / np.maximum(rgb[w].mean(axis=0), 1e-6)
                gains.append((float(y[w].mean() / max(photo_y[w].mean(), 1e-6)), np.log(np.maximum(g, 1e-6))))
            lum, col = [], []
            for i, j in itertools.combinations(range(len(regions)), 2):
                if gains[i] is None or gains[j] is None:
                    continue
                lum.append(abs(np.log2(gains[i][0] / gains[j][0])))
                ci, cj = gains[i][1] - gains[i][1][1], gains[j][1] - gains[j][1][1]
                col.append(float(np.abs(ci - cj)[[0, 2]].max()))
            if lum:
                pairs[name].update({key + "lum_ev_max": float(max(lum)), key + "lum_ev_mean": float(np.mean(lum)),
                                    key + "colour_max": float(max(col)), key + "colour_mean": float(np.mean(col))})
        swings[name] = [side_swing(photo_y, y, w) for w in where]
    return {"people": len(dec.people), "decompose_s": took, "persons": people, "own_light_whole": whole,
            "pairs": pairs, "swings": swings}


# ------------------------------------------------------------------------------------------ candidate rules

def use_variant(name: str) -> None:
    """Put a candidate rule in place for this process (``product``: the checkout as it is)."""
    if name == "product":
        return
    if name in ("own", "group", "joint"):  # a light asked for reaches everyone as it is
        per_person.reaching = lambda lights_, part, dec: np.asarray(lights_, np.float32)
    if name == "white":  # the deviation scaled by the light's degree-0 luminance, white
        def white(lights_, part, dec):
            arr, group = np.asarray(lights_, np.float32), dec.white_light
            scale = np.maximum(arr[..., :1, :] @ REC709, 0)[..., None] / group[0, 0]
            return (arr + scale * (part.white_light - group)).astype(np.float32)

        per_person.reaching = white
    if name == "group":
        relighter_module.Relighter._group = _shared_group
    if name == "joint":
        relighter_module.Relighter._group = _joint_group


def _shared_group(self, dec, crops):
    """Candidate (b): each person's light replaced by the group's after their refit and face pass."""
    parts = []
    for image, mask, origin in per_person.windows(dec.image, crops):
        (part,) = self._photos(self._stage1([image], [mask], False, faces=self.detail)[0])
        part = self._factor.with_light(part, dec.light)
        if part.head is not None:
            part = self._factor.derive(part, head=self._factor.with_light(part.head, dec.light))
        part = self._factor.derive(part, origin=origin)
        parts.append(self._factor.derive(part, foreground=per_person.colours_in_group(part, dec.mask)))
    return per_person.with_shown_edge(self._factor, dec, parts)


def _rows(factor, raw):
    """The rows ``Factor.refit`` fits ``raw`` (a person's stage-1 Decomposition) with: albedo x transport (N, 9) and
    the luminance it is fitted to (N,), weighted by the photo pixels a network pixel holds."""
    albedo, transport, y = factor.refit_inputs(raw)
    w = np.sqrt(raw.geometry.side / raw.geometry.resolution)
    return (transport * albedo[:, None]) * w, y * w


def _joint_group(self, dec, crops):
    """Candidate (c): one light for the scene, refit over every person's own pixels from the group's."""
    from relight_rt.relight.strength import REFIT_PRIOR, _luminance_changed

    raws, xs, ys = [], [], []
    for image, mask, origin in per_person.windows(dec.image, crops):
        (raw,) = self._stage1([image], [mask], False, faces=self.detail)[0]
        x, y = _rows(self._factor, raw)
        raws.append((raw, origin))
        xs.append(x)
        ys.append(y)
    x, y = np.concatenate(xs).astype(np.float64), np.concatenate(ys).astype(np.float64)
    l0 = dec.light.astype(np.float64) @ REC709
    normal = x.T @ x
    ridge = REFIT_PRIOR * max(float(np.trace(normal)) / 9, 1e-12)
    light = _luminance_changed(dec.light, np.linalg.solve(normal + ridge * np.eye(9), x.T @ (y - x @ l0)))
    parts = []
    for raw, origin in raws:
        one = [self._factor.with_light(raw, light)]
        if self.detail and self.face_pass:
            self._look_at_faces(one)  # the head pass; its light is set to the scene's below
        part = self._factor.with_light(one[0], light)
        if part.head is not None:
            part = self._factor.derive(part, head=self._factor.with_light(part.head, light))
        part = self._factor.derive(part, origin=origin)
        parts.append(self._factor.derive(part, foreground=per_person.colours_in_group(part, dec.mask)))
    return per_person.with_shown_edge(self._factor, self._factor.with_light(dec, light), parts)


def summary(out: dict) -> None:
    """The means over the group photos and the lights: pair EV and colour (whole person, skin), swing spread."""
    rows = [r for r in out.values() if r["people"]]
    if not rows:
        return

    def mean(key):
        if key == "swing":
            return np.mean([max(v) - min(v) for r in rows for v in r["swings"].values()])
        return np.mean([v[key] for r in rows for v in r["pairs"].values() if key in v])

    back = max(q["plain"]["max"] for r in rows for q in r["persons"])
    graded = max(q["graded"]["max"] for r in rows for q in r["persons"])
    print(f"{len(rows)} group photos: own light at most {back:.2f} levels inside a person (graded {graded:.2f}); "
          f"new lights, mean over photos and lights: pair EV {mean('lum_ev_mean'):.3f}, colour "
          f"{mean('colour_mean'):.3f}, skin EV {mean('skin_lum_ev_mean'):.3f}, skin colour "
          f"{mean('skin_colour_mean'):.3f}, swing spread {mean('swing'):.3f}")


def found_people(rl, path: Path) -> int:
    """How many people the default matte finds in the photo at ``path`` (relight_rt.relight.people ``PartsMatter``)."""
    matter = per_person.PartsMatter(rl.matter)
    matter(read_rgb(path))
    return len(matter.found or [])


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--people", type=Path, default=shared_path("realdata", "people_masks"))
    p.add_argument("--only", default=None, help="comma-separated people_masks photo names (default: GROUPS)")
    p.add_argument("--every", action="store_true",
                   help="every people_masks photo the default matte finds several people in (not only GROUPS)")
    p.add_argument("--extra", action="append", default=[], type=Path, help="another group photo (repeatable)")
    p.add_argument("--variant", default="product", choices=("product", "own", "white", "group", "joint"))
    p.add_argument("--json", type=Path, default=None)
    args = p.parse_args(argv)
    use_variant(args.variant)
    rl = relight_rt.open(RuntimeConfig(device="cpu"))
    if args.every:
        names = [q.stem for q in sorted((args.people / "photos").glob("*.jpg")) if found_people(rl, q) > 1]
    else:
        names = args.only.split(",") if args.only else list(GROUPS)
    paths = [args.people / "photos" / f"{n}.jpg" for n in names] + list(args.extra)
    paths = [q for q in paths if q.is_file()]
    if not paths:
        print("no group photos found", file=sys.stderr)
        return 2
    out = {}
    for path in paths:
        try:
            r = measure(rl, path)
        except RelightError as exc:  # the product refuses the photo: said, and the others go on
            out[path.stem] = {"people": 0, "error": str(exc)}
            print(f"{path.stem}: refused: {exc}", flush=True)
            continue
        out[path.stem] = r
        if not r["people"]:
            print(f"{path.stem}: one person")
            continue
        devs = " ".join(f"{q['dev']:.2f}" for q in r["persons"])
        plain = max(q["plain"]["max"] for q in r["persons"])
        graded = max(q["graded"]["max"] for q in r["persons"])
        mean = max(q["plain"]["mean"] for q in r["persons"])
        lum = max(v["lum_ev_max"] for v in r["pairs"].values())
        col = max(v["colour_max"] for v in r["pairs"].values())
        spread = {k: max(v) - min(v) for k, v in r["swings"].items()}
        print(f"{path.stem}: {r['people']} people, dev {devs}; own light: max {plain:.2f} (graded {graded:.2f}), "
              f"worst person's mean {mean:.2f} levels, whole photo {r['own_light_whole']['max']:.2f}; "
              f"new lights: pair EV max {lum:.3f}, colour max {col:.3f}; swing spread LEFT {spread['LEFT']:.2f} "
              f"RIGHT {spread['RIGHT']:.2f} max {max(spread.values()):.2f}", flush=True)
    summary(out)
    if args.json:
        args.json.write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
