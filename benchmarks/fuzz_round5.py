"""Hostile input, round 4, part 2 (issue 50): the panorama path and the stage-1 GPU commands, fuzzed as
fuzz_round4.py fuzzes the rest (same harness: RLIMIT_AS, a time limit, inputs hashed before and after, no partial
output or temporary file left by a failure).

Three kinds of case: ``relight-rt composite ... --view`` (CLI), ``relight_rt.apps.panorama`` called with bad arrays
(API: a RelightError is the clear failure, any other exception a traceback), and ``python -m export gpu-bank /
gpu-train / gpu-check`` on a tiny sphere bank (as tests/export/gpu builds) and broken copies of it.

    python benchmarks/fuzz_round5.py [--memory-gb 4] [--seconds 120] [--only WORD] [--json out.jsonl]
"""

from __future__ import annotations

import io
import json
import os
import shutil
import struct
import subprocess
import sys
import tempfile
import zipfile
import zlib
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

from fuzz_round4 import options, run_case, tally  # noqa: E402

PY = sys.executable
RT = [PY, "-m", "relight_rt"]
EXPORT = [PY, "-m", "export"]
API = [PY, "-c"]

_API_DRIVER = """
import sys, numpy as np
from relight_rt import RelightError
try:
{body}
except RelightError as exc:
    print("relight-rt: error:", exc, file=sys.stderr)
    sys.exit(2)
"""


def _png_header(width: int, height: int) -> bytes:
    """A PNG whose IHDR claims width x height RGBA and whose data is a few bytes."""
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0)
    chunk = lambda kind, data: (struct.pack(">I", len(data)) + kind + data  # noqa: E731
                                + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(bytes(64))) + chunk(b"IEND", b"")


def _npy_header(shape: tuple[int, ...], dtype: str = "<f4") -> bytes:
    """A .npy file that declares ``shape`` and holds 16 bytes."""
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": dtype, "fortran_order": False, "shape": shape})
    return buf.getvalue() + bytes(16)


def _rewrite_npz(src: Path, dst: Path, change) -> None:
    """Copy the npz ``src`` to ``dst`` with ``change(name, bytes) -> bytes | None`` applied to each member (None:
    dropped); change may add members by returning them from change('', b'') as a dict."""
    with zipfile.ZipFile(src) as z:
        members = {n: z.read(n) for n in z.namelist()}
    extra = change("", b"") or {}
    with zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as z:
        for n, data in members.items():
            new = change(n, data)
            if new is not None:
                z.writestr(n, new)
        for n, data in extra.items():
            z.writestr(n, data)


def _npy(a) -> bytes:
    buf = io.BytesIO()
    np.save(buf, a)
    return buf.getvalue()


def fixtures(folder: Path) -> None:
    rgba = cv2.imread(str(REPO / "relight_rt" / "data" / "example.png"), cv2.IMREAD_UNCHANGED)
    a = rgba[..., 3:] / 255.0
    person = (rgba[..., :3] * a + np.array([180, 190, 200]) * (1 - a)).astype(np.uint8)
    cv2.imwrite(str(folder / "p.png"), person)
    rng = np.random.default_rng(0)
    pano = (rng.random((32, 64, 3)) * 2 + 0.1).astype(np.float32)
    pano[2:5, 10:14] = 50.0  # a sun
    cv2.imwrite(str(folder / "pano.hdr"), pano)
    cv2.imwrite(str(folder / "pano_square.hdr"), pano[:, :32])
    cv2.imwrite(str(folder / "pano_tall.hdr"), np.ascontiguousarray(pano.transpose(1, 0, 2)))
    cv2.imwrite(str(folder / "pano_1x1.hdr"), pano[:1, :1])
    cv2.imwrite(str(folder / "pano_2x1.hdr"), pano[:1, :2])
    cv2.imwrite(str(folder / "pano_black.hdr"), np.zeros((32, 64, 3), np.float32))
    cv2.imwrite(str(folder / "pano_8bit.png"), (np.clip(pano, 0, 1) * 255).astype(np.uint8))
    cv2.imwrite(str(folder / "pano_16bit.png"), (np.clip(pano, 0, 1) * 65535).astype(np.uint16))
    good = (folder / "pano.hdr").read_bytes()
    (folder / "pano_trunc.hdr").write_bytes(good[: len(good) // 2])
    (folder / "pano_headonly.hdr").write_bytes(good[: good.index(b"+X") + 8])
    (folder / "pano_huge.hdr").write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 50000 +X 100000\n" + bytes(64))
    (folder / "pano_big.hdr").write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 4096 +X 8192\n" + bytes(64))
    (folder / "pano_neg.hdr").write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y -32 +X -64\n" + bytes(64))
    (folder / "pano_garbage.hdr").write_bytes(b"#?RADIANCE\n" + bytes(range(256)) * 8)
    (folder / "pano_empty.hdr").write_bytes(b"")
    from relight_rt.image.exr import encode_exr

    exr = encode_exr({c: pano[..., i] for i, c in zip((2, 1, 0), "RGB", strict=True)})
    (folder / "pano.exr").write_bytes(exr)
    at = exr.index(b"dataWindow\x00box2i\x00") + len(b"dataWindow\x00box2i\x00") + 4
    forged = bytearray(exr)
    forged[at : at + 16] = struct.pack("<iiii", 0, 0, 99_999, 49_999)
    at = exr.index(b"displayWindow\x00box2i\x00") + len(b"displayWindow\x00box2i\x00") + 4
    forged[at : at + 16] = struct.pack("<iiii", 0, 0, 99_999, 49_999)
    (folder / "pano_huge.exr").write_bytes(bytes(forged))
    (folder / "pano_trunc.exr").write_bytes(exr[: len(exr) // 2])

    # the tiny sphere bank of tests/export/gpu, and broken copies of it
    from export.__main__ import main as export_main
    from export.toy_data import make_lights

    make_lights(folder / "lights", 4)
    argv = ["gpu-bank", "--out", str(folder / "bank"), "--lights", str(folder / "lights"), "--n", "2",
            "--subject", "shapes", "--texture-size", "16"]
    with open(os.devnull, "w") as null:
        err, sys.stderr = sys.stderr, null
        try:
            assert export_main(argv) == 0
        finally:
            sys.stderr = err
    bank = folder / "bank"
    index = json.loads((bank / "bank.json").read_text())
    first = bank / f"{index['subjects'][0]}.npz"

    def broken(name: str, edit) -> None:
        dst = folder / name
        shutil.copytree(bank, dst)
        edit(dst)

    def index_with(**kw):
        return lambda d: (d / "bank.json").write_text(json.dumps({**index, **kw}))

    def npz(change):
        return lambda d: _rewrite_npz(first, d / first.name, change)

    broken("b_noindex", lambda d: (d / "bank.json").unlink())
    broken("b_index_garbage", lambda d: (d / "bank.json").write_bytes(b"\x00\xff{[" * 10))
    broken("b_index_list", lambda d: (d / "bank.json").write_text("[1, 2]"))
    broken("b_index_no_subjects", index_with(subjects=[]))
    broken("b_index_subjects_string", index_with(subjects="shapes"))
    broken("b_index_subjects_numbers", index_with(subjects=[1, 2]))
    broken("b_index_outside", index_with(subjects=[f"../bank/{first.stem}"]))
    broken("b_index_absolute", index_with(subjects=[str(bank / first.stem)]))
    broken("b_index_devzero", index_with(subjects=["/dev/zero"], lights="/dev/zero"))
    broken("b_lights_devzero", index_with(lights="/dev/zero"))
    broken("b_lights_outside", index_with(lights="../lights.npy"))
    broken("b_lights_missing", lambda d: (d / "lights.npy").unlink())
    broken("b_lights_huge", lambda d: (d / "lights.npy").write_bytes(_npy_header((100_000_000, 9, 3))))
    broken("b_lights_shape", lambda d: np.save(d / "lights.npy", np.zeros((4, 3, 9), np.float32)))
    broken("b_lights_nan", lambda d: np.save(d / "lights.npy", np.full((4, 9, 3), np.nan, np.float32)))
    broken("b_subject_missing", lambda d: (d / first.name).unlink())
    broken("b_subject_trunc", lambda d: (d / first.name).write_bytes(first.read_bytes()[: first.stat().st_size // 2]))
    broken("b_subject_garbage", lambda d: (d / first.name).write_bytes(bytes(range(256)) * 4))
    broken("b_subject_empty", lambda d: (d / first.name).write_bytes(b""))
    broken("b_meta_missing", npz(lambda n, b: None if n == "meta.npy" else b))
    broken("b_meta_garbage", npz(lambda n, b: _npy(np.array("{not json")) if n == "meta.npy" else b))

    def meta_edit(**kw):
        def change(n, b):
            if n != "meta.npy":
                return b
            meta = json.loads(str(np.load(io.BytesIO(b))))
            return _npy(np.array(json.dumps({**meta, **kw})))
        return change

    broken("b_meta_many_textures", npz(meta_edit(textures=10**9)))
    broken("b_meta_parts_bad", npz(meta_edit(parts=[{"name": "x", "mode": "mesh", "vertices_of": 99, "texture": 0,
                                                     "skin": 0.5}])))
    broken("b_meta_parts_texture", npz(meta_edit(parts=[{"name": "x", "mode": "mesh", "texture": 99, "skin": 0.5}])))
    broken("b_tex_garbage", npz(lambda n, b: _npy(np.frombuffer(bytes(range(200)), np.uint8)) if n == "tex0.npy"
                                else b))
    broken("b_tex_huge", npz(lambda n, b: _npy(np.frombuffer(_png_header(30_000, 30_000), np.uint8))
                             if n == "tex0.npy" else b))
    broken("b_tex_grey", npz(lambda n, b: _npy(cv2.imencode(".png", np.zeros((16, 16), np.uint8))[1])
                             if n == "tex0.npy" else b))
    broken("b_member_huge", npz(lambda n, b: _npy_header((2_000_000_000, 3), "<u2") if n == "p0_vertices.npy"
                                else b))
    broken("b_member_bomb", lambda d: _bomb(first, d / first.name))
    broken("b_faces_outside", npz(lambda n, b: _npy(np.full((4, 3), 10**6, np.int32)) if n == "p0_faces.npy"
                                  else b))


def _bomb(src: Path, dst: Path) -> None:
    """p0_vertices a 3.6 GB array of zeros, deflated to a few MB, streamed into the zip (never held here)."""
    with zipfile.ZipFile(src) as z:
        members = {n: z.read(n) for n in z.namelist()}
    shape = (600_000_000, 3)
    with zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as z:
        for n, data in members.items():
            if n != "p0_vertices.npy":
                z.writestr(n, data)
        with z.open("p0_vertices.npy", "w", force_zip64=True) as f:
            np.lib.format.write_array_header_1_0(f, {"descr": "<u2", "fortran_order": False, "shape": shape})
            block = bytes(1 << 24)
            for _ in range(shape[0] * 3 * 2 // len(block) + 1):
                f.write(block)


CHECK = ["gpu-check", "--bank", "bank", "--n", "1", "--resolution", "32", "--dirs", "8", "--shadow-size", "16",
         "--reference-dirs", "8", "--embree-dirs", "8"]
TINY = ["--resolution", "64", "--width", "4", "--batch-size", "2", "--pool", "4", "--fresh-per-step", "1",
        "--render-share", "1", "--dirs", "8", "--shadow-size", "32", "--log-every", "1", "--device", "cpu",
        "--val-people", "0", "--init", "none", "--max-steps", "1"]  # the 2-person bank: none held out
BANKS = ["b_noindex", "b_index_garbage", "b_index_list", "b_index_no_subjects", "b_index_subjects_string",
         "b_index_subjects_numbers", "b_index_outside", "b_index_absolute", "b_index_devzero", "b_lights_devzero",
         "b_lights_outside", "b_lights_missing", "b_lights_huge", "b_lights_shape", "b_lights_nan",
         "b_subject_missing", "b_subject_trunc", "b_subject_garbage", "b_subject_empty", "b_meta_missing",
         "b_meta_garbage", "b_meta_many_textures", "b_meta_parts_bad", "b_meta_parts_texture", "b_tex_garbage",
         "b_tex_huge", "b_tex_grey", "b_member_huge", "b_member_bomb", "b_faces_outside"]


def cases() -> list[tuple[str, list[str], list[str], list[str], str]]:
    """(name, command, argv, outputs it may write, prefix of its one error line)."""
    out = []
    rt = "relight-rt: "

    def comp(name, *extra, bg="pano.hdr"):
        out.append((f"composite --view {name}", RT, ["composite", "p.png", "--background", bg, *extra, "-o", "c.png"],
                    ["c.png"], rt))

    for v in ("0,0", "nan,0", "inf,0", "0,nan", "1e308,0", "-1e308,0", "-0,-0", "0,80", "0,81", "0,-90", "0,0,0",
              "0,0,180", "0,0,360", "0,0,1e-9", "0,0,179.9", "0,0,-60", "0,0,nan", "1,2,3,4", "1", ",", "", "a,b",
              "0x10,0", "1_0,0", " 5 , 5 "):
        comp(f"{v!r}", f"--view={v}")
    for s in ("64x64", "1x1", "63x64", "0x0", "-64x64", "100000x50000", "20000x20000", "9" * 30 + "x64", "64",
              "64x64x3", "nanxnan", "64.5x64", "１２８x128"):
        comp(f"0,0 --size {s!r}", "--view", "0,0", f"--size={s}")
    for bg in ("pano_square.hdr", "pano_tall.hdr", "pano_1x1.hdr", "pano_2x1.hdr", "pano_black.hdr", "pano_8bit.png",
               "pano_16bit.png", "pano_trunc.hdr", "pano_headonly.hdr", "pano_huge.hdr", "pano_big.hdr",
               "pano_neg.hdr", "pano_garbage.hdr", "pano_empty.hdr", "pano.exr", "pano_huge.exr", "pano_trunc.exr",
               "p.png", "missing.hdr", "lights"):
        comp(f"0,0 --background {bg}", "--view", "0,0", bg=bg)
    for flags in (["--preset", "studio"], ["--key-light", "30,10"], ["--fov", "50"], ["--light", "l.npy"],
                  ["--horizon", "nan"], ["--horizon", "5"], ["--height", "-1"], ["--position", "nan,0"],
                  ["--exposure", "1e308"], ["--exposure", "nan"], ["--rim", "--no-shadow", "--meter", "background"]):
        comp(f"0,0 {' '.join(flags)}", "--view", "0,0", *flags)
    out.append(("composite --size without --view", RT, ["composite", "p.png", "--background", "p.png", "--size",
                                                        "64x64", "-o", "c.png"], ["c.png"], rt))
    out.append(("composite --view -o over the panorama", RT, ["composite", "p.png", "--background", "pano.hdr",
                                                               "--view", "0,0", "-o", "pano.hdr"], [], rt))
    out.append(("composite --view -o .hdr", RT, ["composite", "p.png", "--background", "pano.hdr", "--view", "0,0",
                                                  "-o", "c.hdr"], ["c.hdr"], rt))

    # the API with bad arrays
    def api(name, body):
        code = _API_DRIVER.format(body="\n".join("    " + line for line in body.strip().splitlines()))
        out.append((f"API {name}", API, [code], [], rt))

    ok = "np.random.default_rng(0).random((32, 64, 3)).astype(np.float32) + 0.1"
    for label, arr in (("NaN pixel", f"a = {ok}; a[3, 3] = np.nan"), ("inf pixel", f"a = {ok}; a[3, 3] = np.inf"),
                       ("all inf", "a = np.full((32, 64, 3), np.inf, np.float32)"),
                       ("negative", f"a = -({ok})"), ("one negative", f"a = {ok}; a[3, 3] = -1e30"),
                       ("1e38", "a = np.full((32, 64, 3), 3e38, np.float32)"),
                       ("float16", f"a = ({ok}).astype(np.float16)"), ("uint8", "a = np.zeros((32, 64, 3), np.uint8)"),
                       ("object", "a = np.empty((32, 64, 3), object)"), ("bool", "a = np.ones((32, 64, 3), bool)"),
                       ("1x1", "a = np.ones((1, 1, 3), np.float32)"), ("1x2", "a = np.ones((1, 2, 3), np.float32)"),
                       ("4 channels", "a = np.ones((32, 64, 4), np.float32)"), ("2-D", "a = np.ones((32, 64))"),
                       ("empty", "a = np.ones((0, 0, 3), np.float32)"), ("list", "a = [[[1.0, 1.0, 1.0]] * 2]"),
                       ("broadcast 50k x 100k", "a = np.broadcast_to(np.float32(1), (50_000, 100_000, 3))"),
                       ("non-contiguous", f"a = ({ok})[:, :, ::-1]")):
        api(f"panorama_view {label}", f"""
from relight_rt.apps.panorama import panorama_view
{arr}
v = panorama_view(a, (96, 64), (0, 0))
assert np.isfinite(v.light).all() and v.plate.dtype == np.uint8, (v.light, v.plate.dtype)
""")
    for label, view, size in (("view nan", "(float('nan'), 0)", "(96, 64)"),
                              ("view str list", "['0', '0']", "(96, 64)"),
                              ("view None", "None", "(96, 64)"), ("view 4", "(0, 0, 60, 1)", "(96, 64)"),
                              ("view numpy", "np.array([0.0, 0.0])", "(96, 64)"),
                              ("size float", "(0, 0)", "(96.0, 64.0)"), ("size bool", "(0, 0)", "(True, 64)"),
                              ("size huge", "(0, 0)", "(10**12, 10**12)"),
                              ("size numpy", "(0, 0)", "np.array([96, 64])"),
                              ("size None", "(0, 0)", "None"), ("size str", "(0, 0)", "'96x64'")):
        api(f"panorama_view {label}", f"""
from relight_rt.apps.panorama import panorama_view
v = panorama_view({ok}, {size}, {view})
assert np.isfinite(v.light).all()
""")
    api("composite_panorama inf pixel", f"""
import relight_rt
from relight_rt.apps.panorama import composite_panorama
a = {ok}; a[3, 3] = np.inf
img = composite_panorama(relight_rt.open(), "p.png", a, (0, 0), size=(64, 64))
assert np.isfinite(img).all()
""")
    api("composite_panorama NaN image", f"""
import relight_rt
from relight_rt.apps.panorama import composite_panorama
img = composite_panorama(relight_rt.open(), np.full((64, 64, 3), np.nan, np.float32), {ok}, (0, 0))
assert np.isfinite(img).all()
""")
    api("composite_panorama huge size", f"""
from relight_rt.apps.panorama import composite_panorama
composite_panorama(None, "p.png", {ok}, (0, 0), size=(100_000, 100_000))
""")

    # the stage-1 GPU commands
    ex = "python -m export "
    for bank in ["bank", *BANKS]:
        out.append((f"gpu-train --bank {bank}", EXPORT, ["gpu-train", "--bank", bank, "--out", "run", *TINY], ["run"],
                    ex + "gpu-train: "))
    for bank in ["bank", "b_noindex", "b_index_list", "b_index_outside", "b_subject_trunc", "b_meta_missing",
                 "b_tex_huge", "b_member_huge", "b_lights_huge"]:
        argv = [*CHECK[:2], bank, *CHECK[3:], "--out", "check.json"]
        out.append((f"gpu-check --bank {bank}", EXPORT, argv, ["check.json"], ex + "gpu-check: "))
    tiny = {k: v for k, v in zip(TINY[::2], TINY[1::2], strict=True)}
    for flag, values in (("--deadline", ("0", "-1", "nan", "inf", "1e308")), ("--batch-size", ("0", "-1")),
                         ("--resolution", ("0", "96", "-64", "100000")), ("--dirs", ("0", "-5", "100000000")),
                         ("--shadow-size", ("0", "100000")), ("--pool", ("0", "1")), ("--width", ("0",)),
                         ("--render-share", ("0", "nan", "2")), ("--lr", ("nan", "0", "inf")),
                         ("--lr-min", ("nan",)), ("--max-yaw", ("nan", "1e308")), ("--export-reserve", ("nan", "-1")),
                         ("--checkpoint-every", ("nan", "0", "-1")), ("--framings", ("nope", "full:nan", "")),
                         ("--log-every", ("0",)), ("--max-steps", ("0", "-1")), ("--fresh-per-step", ("0", "1000"))):
        for v in values:
            argv = dict(tiny)
            argv[flag] = v
            out.append((f"gpu-train {flag} {v}", EXPORT,
                         ["gpu-train", "--bank", "bank", "--out", "run", *[x for kv in argv.items() for x in kv]],
                         ["run"], ex + "gpu-train: "))
    out.append(("gpu-train --out = the bank", EXPORT, ["gpu-train", "--bank", "bank", "--out", "bank", *TINY], [],
                ex + "gpu-train: "))
    out.append(("gpu-train --out = a file", EXPORT, ["gpu-train", "--bank", "bank", "--out", "p.png", *TINY], [],
                ex + "gpu-train: "))
    garbage = ["gpu-train", "--bank", "bank", "--out", "run", *TINY[:-4], "--max-steps", "1", "--init", "p.png"]
    out.append(("gpu-train --init garbage", EXPORT, garbage, ["run"], ex + "gpu-train: "))
    for flag, v in (("--n", "0"), ("--start", "99"), ("--start", "-1"), ("--resolution", "0"), ("--dirs", "0"),
                    ("--shadow-size", "0"), ("--reference-dirs", "0"), ("--embree-dirs", "0"),
                    ("--resolution", "99999"), ("--dirs", "100000000")):
        out.append((f"gpu-check {flag} {v}", EXPORT, [*CHECK, flag, v, "--out", "check.json"], ["check.json"],
                    ex + "gpu-check: "))
    for name, argv in (("--n 0", ["--n", "0"]), ("--texture-size 0", ["--texture-size", "0"]),
                       ("--texture-size 100000", ["--texture-size", "100000", "--n", "1", "--seed", "9"]),
                       ("--lights missing", ["--lights", "nowhere"]), ("--lights = a file", ["--lights", "p.png"]),
                       ("--out = the lights folder", ["--out", "lights"]), ("--out = a file", ["--out", "p.png"]),
                       ("--seed -1", ["--seed", "-1", "--n", "1"])):
        base = {"--out": "nb", "--lights": "lights", "--n": "1", "--subject": "shapes", "--texture-size": "16"}
        for k, v in zip(argv[::2], argv[1::2], strict=True):
            base[k] = v
        out.append((f"gpu-bank {name}", EXPORT, ["gpu-bank", *[x for kv in base.items() for x in kv]], ["nb"],
                    ex + "gpu-bank: "))
    # last: when it breaks (it did: the figures replaced bank.json), the cases after it would see a broken bank
    out.append(("gpu-check --out = bank.json", EXPORT, [*CHECK, "--out", "bank/bank.json"], [], ex + "gpu-check: "))
    return out


def main(argv: list[str] | None = None) -> int:
    args = options(argv, __doc__, seconds=120.0)
    held = broke = 0
    with tempfile.TemporaryDirectory(prefix="fuzz5-") as tmp:
        folder = Path(tmp)
        fixtures(folder)
        for name, command, case, outputs, prefix in cases():
            if args.only not in name:
                continue
            res = subprocess.run([PY, __file__, "--one", json.dumps([name, str(folder), command, case, outputs, prefix,
                                  int(args.memory_gb * 2**30), args.seconds])], capture_output=True, text=True)
            ok = tally(res, name, case, args)
            held, broke = held + ok, broke + (not ok)
    print(f"{held + broke} cases: {held} held, {broke} broke")
    return 1 if broke else 0


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--one":
        name, folder, command, case, outputs, prefix, memory, seconds = json.loads(sys.argv[2])
        print(json.dumps(run_case(name, Path(folder), case, outputs, memory, seconds, command=command,
                                  prefix=prefix)))
        sys.exit(0)
    sys.exit(main())
