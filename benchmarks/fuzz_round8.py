"""Hostile input, round 8 (fuzz8): the surfaces changed on 2026-11-29, through the public API and the CLI.

Surfaces: the matte's pocket rules (``image.matte_edges`` open_pockets / refine_edges), ``VideoMatter(complete=True)``,
the graphs' answers kept per region (``image.regions``: Pyramid.answer, reductions_shared, from several threads),
``apps.scene_people.find_people``, the face mesh's occlusion and mirror (``person.face_mesh``) and
``relight.shadow_fill.mirror_shadow`` (through the Relighter, with the landmarker's answer bent), the CLI on tiny,
strip and crowded backgrounds and one-frame clips. A case holds when valid odd input gives a finite result in range
and bad input one RelightError (CLI: one line, exit 2, no traceback); thread cases hold when every thread's picture
equals one thread's to the bit.

    PYTHONPATH=$PWD python benchmarks/fuzz_round8.py [--only SURFACE] [--no-cli]

Faces come from Extended Yale B (../shared/realdata/yale, evaluation only; those cases are skipped without it).
Prints one line per broken case and the counts per surface; exit status = broken cases.
"""

from __future__ import annotations

import argparse
import collections
import glob
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import cv2
import numpy as np
from _shared import shared_path, warn_missing

REPO = Path(__file__).resolve().parents[1]
YALE = shared_path("realdata", "yale")
COUNTS: dict[str, list[int]] = collections.defaultdict(lambda: [0, 0])


def case(surface: str, name: str, fn, expect_error: bool = False, unit: bool = True) -> None:
    """Run one case: it holds when ``fn()`` returns finite arrays (in [0, 1] with ``unit``) or no arrays, or, with
    ``expect_error``, raises RelightError."""
    from relight_rt import RelightError

    COUNTS[surface][0] += 1
    try:
        out = fn()
        bad = [
            a
            for a in (out if isinstance(out, (list, tuple)) else [out])
            if isinstance(a, np.ndarray)
            and a.dtype.kind == "f"
            and not (np.isfinite(a).all() and (not unit or a.size == 0 or (a.min() >= 0 and a.max() <= 1)))
        ]
        if expect_error or bad:
            raise AssertionError("no RelightError" if expect_error else "not finite or out of [0, 1]")
        COUNTS[surface][1] += 1
    except RelightError as exc:
        if expect_error:
            COUNTS[surface][1] += 1
        else:
            print(f"BROKE {surface} {name}: RelightError {exc}")
    except Exception as exc:  # noqa: BLE001 - every other exception is a broken case
        print(f"BROKE {surface} {name}: {type(exc).__name__} {str(exc)[:160]}")


def person_photo() -> np.ndarray:
    rgba = cv2.cvtColor(
        cv2.imread(str(REPO / "relight_rt" / "data" / "example.png"), cv2.IMREAD_UNCHANGED), cv2.COLOR_BGRA2RGBA
    )
    a = rgba[..., 3:] / 255.0
    return (rgba[..., :3] * a + np.array([200, 190, 180]) * (1 - a)).astype(np.uint8)


def matte_cases(side: int = 1000) -> None:
    from relight_rt.image.matte_edges import open_pockets, refine_edges

    rng = np.random.default_rng(0)
    for h, w in [(1, 1), (2, 2), (1, 7), (7, 1), (1, 500), (500, 1), (3, 900), (900, 3), (64, 64), (200, 150)]:
        yy, xx = np.indices((h, w))
        ring = np.full((h, w), 0.7, np.float32)
        ring[0], ring[-1], ring[:, 0], ring[:, -1] = 1, 1, 1, 1
        one = np.zeros((h, w), np.float32)
        one[h // 2, w // 2] = 1
        alphas = {
            "zeros": np.zeros((h, w), np.float32),
            "ones": np.ones((h, w), np.float32),
            "half": np.full((h, w), 0.5, np.float32),
            "checker": ((yy + xx) % 2).astype(np.float32),
            "checker.7": np.where((yy + xx) % 2, 1.0, 0.7).astype(np.float32),
            "one pixel": one,
            "all pocket": ring,
            "random": rng.random((h, w)).astype(np.float32),
        }
        for an, a in alphas.items():
            for rn, img in {
                "constant": np.full((h, w, 3), 0.5, np.float32),
                "black": np.zeros((h, w, 3), np.float32),
                "random": rng.random((h, w, 3)).astype(np.float32),
            }.items():
                for f in (open_pockets, refine_edges):
                    case("matte", f"{f.__name__} {h}x{w} {an} {rn}", lambda f=f, img=img, a=a: f(img, a))
    # a matte riddled with pockets (of half the band's width + 2 px, 12 px apart): time, not only correctness
    from relight_rt.image.matte_edges import band_width

    yy, xx = np.indices((side, side))
    a = np.ones((side, side), np.float32)
    a[:20], a[-20:], a[:, :20], a[:, -20:] = 0, 0, 0, 0
    hole = max(3, band_width((side, side)) // 2 + 2)
    inner = (yy > 40) & (yy < side - 40) & (xx > 40) & (xx < side - 40)
    pockets = inner & (yy % (12 + hole) < hole) & (xx % (12 + hole) < hole)
    a[pockets] = 0.7
    img = rng.random((side, side, 3)).astype(np.float32) * 0.2 + 0.4
    for name, alpha in {
        "pockets everywhere": a,
        "diagonal seams": np.where((yy > side // 2) & ((yy + xx) % 7 != 0), 1.0, 0.0).astype(np.float32),
    }.items():
        start = time.perf_counter()
        case("matte", f"riddled {name}", lambda alpha=alpha: open_pockets(img, alpha))
        print(f"  open_pockets, {side} x {side} matte, {name}: {time.perf_counter() - start:.2f} s")


def mesh_cases() -> None:
    from relight_rt.person import face_mesh as fm
    from relight_rt.relight.shadow_fill import mirror_shadow

    tri = np.loadtxt(REPO / "relight_rt" / "models" / "face_mesh_triangles.txt", dtype=np.int64).reshape(-1, 3)

    def face(cx: float, cy: float, s: float) -> np.ndarray:
        p = np.zeros((468, 3))
        ang, rad = np.linspace(0, 2 * np.pi, 468, endpoint=False), np.sqrt(np.linspace(0.01, 1, 468))
        p[:, 0], p[:, 1] = cx + s * rad * np.cos(ang * 37), cy + s * 1.2 * rad * np.sin(ang * 37)
        p[:, 2] = -s * np.sqrt(np.maximum(0, 1 - rad**2))
        partner = fm.read_partners()
        a = np.flatnonzero(partner > np.arange(len(partner)))
        b = partner[a]
        p[b, 0], p[b, 1], p[b, 2] = 2 * cx - p[a, 0], p[a, 1], p[a, 2]
        p[partner == np.arange(len(partner)), 0] = cx
        return p

    meshes = {
        "face": face(50, 50, 30),
        "mirrored": face(50, 50, 30) * [-1, 1, 1] + [100, 0, 0],
        "point": np.full((468, 3), 50.0),
        "flat": face(50, 50, 30) * [1, 1, 0],
        "tiny": face(50, 50, 0.1),
        "line": np.stack([np.linspace(0, 100, 468), np.full(468, 50.0), np.zeros(468)], 1),
        "half out": face(0, 50, 30),
        "far out": face(-500, -500, 30),
    }
    rng = np.random.default_rng(1)
    for shape in [(1, 1), (2, 2), (1, 100), (100, 1), (100, 100)]:
        for name, p in meshes.items():

            def occlusion(p=p, shape=shape):
                depth, seen = fm.rasterise_depth(p, tri, shape)
                normals = np.zeros(shape + (3,), np.float32)
                normals[..., 0] = 1
                return fm.occlusion_loss(depth, seen, normals, float(np.ptp(p[:, :2], 0).max()))

            case("face mesh", f"occlusion {shape} {name}", occlusion, unit=False)
            case("face mesh", f"mirror {shape} {name}", lambda p=p: fm.mirror(p), unit=False)
            case(
                "face mesh",
                f"mirror_shadow {shape} {name}",
                lambda p=p, shape=shape: mirror_shadow(
                    rng.random(shape).astype(np.float32), np.ones(shape, bool), np.ones(shape, bool), (p,)
                ),
            )


def region_cases() -> None:
    from relight_rt.image.regions import Region, crop_region, reductions_shared
    from relight_rt.person.matting._layout import backed_logits

    images = [
        np.zeros((1, 1, 3), np.float32),
        np.zeros((1, 500, 3), np.float32),
        np.ones((500, 1, 3), np.float32),
        np.random.default_rng(2).random((64, 64, 3)).astype(np.float32),
    ]
    for values in [(0, 0, 1e-9), (-1e9, 5, 10), (32, 32, 1e9), (0.5, 0.5, 1), (1e12, 1e12, 3)]:
        for img in images:

            def shared(img=img, values=values):
                with reductions_shared(img):
                    crop_region(img, Region(*values))
                    return crop_region(img, Region(*values))

            case(
                "regions",
                f"crop {values} of {img.shape}",
                lambda img=img, values=values: crop_region(img, Region(*values)),
            )
            case("regions", f"crop {values} of {img.shape}, shared", shared)
    for values in [(0, 0, 0), (32, 32, -10), (float("nan"), 0, 10), (0, float("inf"), 10), (0, 0, float("inf"))]:
        case("regions", f"region {values}", lambda values=values: Region(*values), True)
    rng = np.random.default_rng(3)
    for shape in [(1, 1), (2, 2), (1, 256), (256, 1), (256, 256)]:
        for name, logits in {
            "zeros": np.zeros(shape),
            "random": rng.normal(0, 3, shape),
            "1e30": np.full(shape, 1e30),
            "-1e30": np.full(shape, -1e30),
        }.items():
            for lift_name, lift in {
                "none": np.zeros(shape, bool),
                "all": np.ones(shape, bool),
                "checker": np.indices(shape).sum(0) % 2 == 1,
            }.items():
                case(
                    "regions",
                    f"backed_logits {shape} {name} {lift_name}",
                    lambda logits=logits, lift=lift: (
                        np.tanh(backed_logits(logits.astype(np.float32), lift)) * 0.5 + 0.5
                    ),
                )


def yale_faces() -> list[np.ndarray]:
    from yale_eval import read_grey

    files = sorted(glob.glob(str(YALE / "yaleB0*" / "*A+050E+00.png")))[:3]
    return [cv2.resize(read_grey(Path(f)), None, fx=2, fy=2) for f in files]


def relighter_cases() -> None:
    from yale_eval import ellipse

    import relight_rt
    from relight_rt import RuntimeConfig
    from relight_rt.person.face_mesh import FaceMesh

    r = relight_rt.open(RuntimeConfig(device="cpu"))
    faces = yale_faces()
    f0 = faces[1]  # the first of them gets no mesh
    h, w = f0.shape[:2]
    el = ellipse((h, w))
    photos = {
        "face": (f0, el),
        "mirrored": (f0[:, ::-1], el[:, ::-1]),
        "upside down": (f0[::-1], el[::-1]),
        "two identical": (np.concatenate([f0, f0], 1), np.concatenate([el, el], 1)),
        "one mirrored beside": (np.concatenate([f0, f0[:, ::-1]], 1), np.concatenate([el, el], 1)),
        "four in a row": (np.concatenate(faces + [f0[:, ::-1]], 1), np.concatenate([el] * 4, 1)),
        "one-pixel mask": (f0, (np.indices((h, w)) == [[[h // 2]], [[w // 2]]]).all(0).astype(np.float32)),
        "checkerboard mask": (f0, (np.indices((h, w)).sum(0) % 2).astype(np.float32)),
        "constant": (np.full_like(f0, 0.5), el),
        "black": (np.zeros_like(f0), el),
        "small": (cv2.resize(f0, (48, 40)), cv2.resize(el, (48, 40))),
        "wide": (cv2.resize(f0, (4000, 60)), cv2.resize(el, (4000, 60))),
        "tall": (cv2.resize(f0, (30, 3000)), cv2.resize(el, (30, 3000))),
    }
    for frac in (-0.45, -0.3, -0.15, 0.15, 0.3, 0.45):  # the face at the border, cut
        s = int(frac * w)
        img, m = np.roll(f0, s, axis=1), np.roll(el, s, axis=1)
        cut = slice(s - 5, None) if s > 0 else slice(None, w + s + 5)
        photos[f"cut at {frac:+.2f}"] = (img[:, cut], m[:, cut])
    for name, (img, m) in photos.items():
        for light in ("window-left", "rim"):
            case(
                "relighter",
                f"{name} {light}",
                lambda img=img, m=m, light=light: r.relight(
                    np.ascontiguousarray(img), light, mask=np.ascontiguousarray(m)
                ),
            )
    case("relighter", "mask 0.5 everywhere", lambda: r.relight(f0, "rim", mask=np.full((h, w), 0.5, np.float32)), True)
    # the landmarker's answer bent (collapsed, mirrored, blown up, not finite)
    mesh = r._faces._mesh
    real = mesh.mesh

    class Bent:
        def __init__(self, change):
            self.change = change

        def run(self, names, feeds):
            lm, flag = real.run(names, feeds)
            return self.change(lm.reshape(-1, 3).astype(np.float64)).reshape(lm.shape).astype(lm.dtype), flag

    c = lambda p: p.mean(0)  # noqa: E731
    bends = {
        "collapsed to a point": lambda p: np.repeat(c(p)[None], len(p), 0),
        "collapsed to a line": lambda p: np.stack([p[:, 0], np.full(len(p), c(p)[1]), p[:, 2]], 1),
        "flat": lambda p: p * [1, 1, 0],
        "depth reversed": lambda p: p * [1, 1, -1],
        "mirrored": lambda p: p * [-1, 1, 1] + [2 * c(p)[0], 0, 0],
        "upside down": lambda p: p * [1, -1, 1] + [0, 2 * c(p)[1], 0],
        "shuffled": lambda p: p[np.random.default_rng(0).permutation(len(p))],
        "1000x": lambda p: (p - c(p)) * 1000 + c(p),
        "depth 1000x": lambda p: p * [1, 1, 1000],
        "one Inf": lambda p: np.where(np.arange(len(p))[:, None] == 1, np.inf, p),
        "NaN": lambda p: p * np.nan,
    }
    for name, change in bends.items():
        mesh.mesh = Bent(change)
        for light in ("window-left", "rim"):
            case("relighter", f"landmarker {name} {light}", lambda light=light: r.relight(r.decompose(f0, el), light))
    mesh.mesh = real
    assert isinstance(mesh, FaceMesh)


def video_cases() -> None:
    from relight_rt.person.matting import VideoMatter, shared_matter

    m = shared_matter(device="cpu")
    person = person_photo()
    pad = lambda img, t, b, l, r: np.pad(img, ((t, b), (l, r), (0, 0)), mode="edge")  # noqa: E731

    def frames(seq):
        vm = VideoMatter(m, complete=True)
        return [vm(f) for f in seq]

    ok = {
        "one frame": [person],
        "float frame": [person.astype(np.float32) / 255],
        "16x16": [person[:16, :16]] * 2,
        "squashed 17x3000": [cv2.resize(person, (3000, 17))] * 2,
        "strip wide": [pad(person, 0, 0, 3000, 3000)] * 2,
        "strip tall": [pad(person, 2000, 2000, 0, 0)] * 2,
        "cut left": [person[:, 145:]] * 2,
        "cut bottom": [person[:250]] * 2,
        "head only": [person[:90]] * 2,
        "two side by side": [np.hstack([person] * 2)] * 2,
        "two overlapping": [np.hstack([person[:, :200], person[:, 60:]])] * 2,
        "mirrored": [person[:, ::-1]] * 2,
        "upside down": [person[::-1]] * 2,
        "constant": [np.full((300, 200, 3), 128, np.uint8)] * 2,
        "person then nobody then person": [person, np.full_like(person, 128), person],
        "holes everywhere": [
            np.where((np.indices(person.shape[:2]).sum(0) % 4 == 0)[..., None], 255, person).astype(np.uint8)
        ]
        * 2,
        "RGBA": [np.dstack([person, np.full(person.shape[:2], 255, np.uint8)])],
        "grey": [person[..., 0]],
    }
    for name, seq in ok.items():
        case("video complete", name, lambda seq=seq: frames([np.ascontiguousarray(f) for f in seq]))
    bad = {
        "sizes differ": [person, cv2.resize(person, (200, 300))],
        "1x1": [person[:1, :1]],
        "2x2": [person[:2, :2]],
        "1x50": [person[:1, :50]],
        "3x2000": [cv2.resize(person, (2000, 3))],
        "NaN": [np.full((30, 20, 3), np.nan, np.float32)],
    }
    for name, seq in bad.items():
        case("video complete", name, lambda seq=seq: frames(seq), True)


def people_cases() -> None:
    from relight_rt.apps.scene_people import find_people
    from relight_rt.person.matting import shared_matter

    m = shared_matter(device="cpu")
    person = person_photo()
    fine = {
        f"{h}x{w}": cv2.resize(person, (w, h))
        for h, w in [(1, 1), (2, 2), (1, 50), (50, 1), (2, 5000), (5000, 2), (16, 16), (15, 900), (20000, 16)]
    }
    fine.update(
        {
            "person": person,
            "two": np.hstack([person] * 2),
            "constant": np.full((300, 200, 3), 128, np.uint8),
            "float": person.astype(np.float32) / 255,
            "16-bit": person.astype(np.uint16) * 257,
            "strided": np.hstack([person] * 2)[:, ::2],
            "read-only": person.copy(),
        }
    )
    fine["read-only"].setflags(write=False)
    for name, img in fine.items():
        case("find_people", name, lambda img=img: find_people(img, m))
    for name, img in {
        "empty": person[:0],
        "grey": person[..., 0],
        "RGBA": np.dstack([person, person[..., :1]]),
        "NaN": np.full((30, 20, 3), np.nan, np.float32),
        "int64": person.astype(np.int64),
        "float 0-255": person.astype(np.float32),
    }.items():
        case("find_people", name, lambda img=img: find_people(img, m), True)


def thread_cases() -> None:
    from yale_eval import ellipse

    import relight_rt
    from relight_rt import RuntimeConfig, lights
    from relight_rt.apps.scene_people import find_people
    from relight_rt.person.matting import VideoMatter, shared_matter

    def at_once(f, n: int = 4) -> list:
        out: list = [None] * n
        threads = [threading.Thread(target=lambda i=i: out.__setitem__(i, f(i))) for i in range(n)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        return out

    def equal(a, b) -> bool:
        return np.array_equal(a, b) if isinstance(a, np.ndarray) else a == b

    def same(name: str, want: list, got: list) -> None:
        def check():
            if not all(equal(a, b) for a, b in zip(want, got, strict=True)):
                raise AssertionError("a thread's answer differs from one thread's")

        case("threads", name, check)

    person = person_photo()
    r = relight_rt.open(RuntimeConfig(device="cpu"))
    m = shared_matter(device="cpu")
    two = np.hstack([person, person[:, ::-1]])
    same("relight, automatic matte", [r.relight(person, "studio")] * 4, at_once(lambda i: r.relight(person, "studio")))
    same("find_people", [find_people(two, m)] * 4, at_once(lambda i: find_people(two, m)))
    same("matter", [m(two)] * 4, at_once(lambda i: m(two)))

    def clip(i):
        vm = VideoMatter(m, complete=True)
        return np.stack([vm(person), vm(np.ascontiguousarray(person[:, ::-1])), vm(person)])

    same("VideoMatter(complete=True)", [clip(0)] * 4, at_once(clip))
    if not YALE.is_dir():
        warn_missing(YALE, "the threads' two-face cases")
    else:
        f = yale_faces()
        el = ellipse(f[0].shape[:2])
        img, mask = np.hstack(f[:2]), np.hstack([el, el])
        ls = [
            "window-left",
            "rim",
            "night",
            "campfire",
            lights.directional((0.2, -1, 0.3)) + lights.ambient(0.05),
            "studio",
            "golden-hour",
            lights.directional((0.5, 1, 0.1)),
        ]
        dec = r.decompose(img, mask)
        fresh = relight_rt.open(RuntimeConfig(device="cpu"))
        want = [fresh.relight(fresh.decompose(img, mask), light) for light in ls]
        for rep in range(3):
            same(
                f"two faces, 8 lights at once on one Decomposition, try {rep}",
                want,
                at_once(lambda i: r.relight(dec, ls[i]), len(ls)),
            )
    # a caller writing into the photo between calls: the same answer as a fresh copy
    other = np.ascontiguousarray(person[:, ::-1])
    for name, f in {
        "relight": lambda x: r.relight(x, "studio"),
        "matter": m,
        "find_people": lambda x: find_people(x, m),
    }.items():

        def rewritten(f=f):
            buf = person.copy()
            f(buf)
            buf[...] = other
            got, want = f(buf), f(other.copy())
            if not (np.array_equal(got, want) if isinstance(want, np.ndarray) else got == want):
                raise AssertionError("the answer kept the photo as it was")

        case("threads", f"photo rewritten between calls: {name}", rewritten)


def cli_cases() -> None:
    person = person_photo()
    scene = cv2.imread(str(REPO / "relight_rt" / "data" / "example_scene.jpg"))
    with tempfile.TemporaryDirectory() as tmp:
        t = Path(tmp)
        cv2.imwrite(str(t / "p.png"), person[..., ::-1])
        bgs = {
            "1x1": scene[:1, :1],
            "2x2": scene[:2, :2],
            "1x50": scene[:1, :50],
            "50x1": scene[:50, :1],
            "1x3000": cv2.resize(scene, (3000, 1)),
            "3000x1": cv2.resize(scene, (1, 3000)),
            "constant": np.full((300, 400, 3), 128, np.uint8),
            "black": np.zeros((300, 400, 3), np.uint8),
            "three people": np.hstack([person] * 3),
            "people tiny": cv2.resize(np.hstack([person] * 3), (60, 35)),
            "people cut": np.hstack([person] * 2)[:250],
            "people strip": cv2.resize(np.hstack([person] * 3), (6000, 200)),
            "mirrored people": np.hstack([person, person[:, ::-1]]),
        }
        runs = []
        for name, img in bgs.items():
            path = t / f"bg_{len(runs)}.png"
            cv2.imwrite(str(path), img)
            runs.append(
                (
                    f"composite over {name}",
                    ["composite", str(t / "p.png"), "--background", str(path), "-o", str(t / f"out_{len(runs)}.png")],
                )
            )
        for name, img in {"1x1": person[:1, :1], "2x2": person[:2, :2], "1x50": person[:1, :50]}.items():
            cv2.imwrite(str(t / f"tiny_{name}.png"), img)
            runs.append(
                (
                    f"relight {name}",
                    [
                        "relight",
                        str(t / f"tiny_{name}.png"),
                        "--preset",
                        "studio",
                        "-o",
                        str(t / f"tiny_out_{name}.png"),
                    ],
                )
            )
        cv2.imwrite(str(t / "two.png"), np.hstack([person, person[:, ::-1]])[..., ::-1])
        runs.append(
            (
                "relight two --person all",
                ["relight", str(t / "two.png"), "--person", "all", "--preset", "rim", "-o", str(t / "two_out.png")],
            )
        )
        (t / "v1").mkdir()
        cv2.imwrite(str(t / "v1" / "f1.png"), person[..., ::-1])
        runs.append(("video of one frame", ["video", str(t / "v1"), "--preset", "studio", "-o", str(t / "v1.mp4")]))
        (t / "vd").mkdir()
        cv2.imwrite(str(t / "vd" / "f1.png"), person[..., ::-1])
        cv2.imwrite(str(t / "vd" / "f2.png"), cv2.resize(person, (200, 300))[..., ::-1])
        runs.append(
            ("video of frames of two sizes", ["video", str(t / "vd"), "--preset", "studio", "-o", str(t / "vd.mp4")])
        )
        env = {**os.environ, "PYTHONPATH": str(REPO)}
        for name, args in runs:
            p = subprocess.run(
                [sys.executable, "-m", "relight_rt", *args], capture_output=True, text=True, env=env, timeout=180
            )
            lines = p.stderr.strip().splitlines()
            held = "Traceback" not in p.stderr and (
                p.returncode == 0
                or (p.returncode == 2 and len(lines) == 1 and lines[0].startswith("relight-rt: error:"))
            )
            COUNTS["cli"][0] += 1
            COUNTS["cli"][1] += held
            if not held:
                print(f"BROKE cli {name}: exit {p.returncode}: {p.stderr.strip()[:200]}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", help="one surface: matte, regions, mesh, relighter, video, people, threads, cli")
    parser.add_argument("--no-cli", action="store_true")
    parser.add_argument("--matte-side", type=int, default=1000, help="side of the riddled mattes timed (default 1000)")
    args = parser.parse_args()
    sys.path.insert(0, str(REPO / "benchmarks"))
    surfaces = {
        "matte": matte_cases,
        "regions": region_cases,
        "mesh": mesh_cases,
        "relighter": relighter_cases,
        "video": video_cases,
        "people": people_cases,
        "threads": thread_cases,
        "cli": cli_cases,
    }
    for name, run in surfaces.items():
        if (args.only and args.only != name) or (name == "cli" and args.no_cli):
            continue
        if name == "relighter" and not YALE.is_dir():
            warn_missing(YALE, "the relighter cases")
            continue
        start = time.perf_counter()
        run(args.matte_side) if name == "matte" else run()
        print(f"{name}: {time.perf_counter() - start:.0f} s")
    broken = 0
    for surface, (tried, held) in COUNTS.items():
        print(f"{surface}: {held} / {tried} held")
        broken += tried - held
    return broken


if __name__ == "__main__":
    sys.exit(main())
