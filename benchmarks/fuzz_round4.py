"""Hostile input, round 4 (issue 50): the newer surfaces fuzzed under a memory and a time limit.

Each case runs ``python -m relight_rt ...`` in its own process under RLIMIT_AS (``--memory-gb``, default 4) and a
time limit (``--seconds``, default 60), from a fresh folder of fixtures made here from the bundled example. Inputs are
hashed before and after. A case holds when it exits 0, or 2 with one ``relight-rt: error:`` line and no traceback,
within the limits, with its inputs unchanged, and, when it fails, with no output and no temporary file left.

    python benchmarks/fuzz_round4.py [--memory-gb 4] [--seconds 60] [--only WORD] [--json out.jsonl]

Prints one line per case (HELD/BROKE, exit code, peak MB, seconds, first stderr line) and the counts.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]


def fixtures(folder: Path) -> None:
    """Photos, backgrounds and a clip the cases read (all made from the bundled example or from scratch)."""
    rgba = cv2.imread(str(REPO / "relight_rt" / "data" / "example.png"), cv2.IMREAD_UNCHANGED)
    a = rgba[..., 3:] / 255.0
    person = (rgba[..., :3] * a + np.array([180, 190, 200]) * (1 - a)).astype(np.uint8)
    cv2.imwrite(str(folder / "p.png"), person)
    cv2.imwrite(str(folder / "p_rgba.png"), rgba)
    two = np.full((508, 640, 3), (200, 190, 180), np.uint8)
    two[:, 20:310], two[:, 330:620] = person, person
    cv2.imwrite(str(folder / "two.png"), two)
    scene = cv2.imread(str(REPO / "relight_rt" / "data" / "example_scene.jpg"))
    cv2.imwrite(str(folder / "bg.jpg"), scene)
    cv2.imwrite(str(folder / "bg_tiny.png"), scene[:64, :64])
    cv2.imwrite(str(folder / "bg_1px.png"), scene[:1, :1])
    cv2.imwrite(str(folder / "bg_strip.png"), cv2.resize(scene, (4000, 64)))
    cv2.imwrite(str(folder / "bg_tall.png"), cv2.resize(scene, (64, 4000)))
    cv2.imwrite(str(folder / "bg16.png"), (cv2.resize(scene, (320, 240)).astype(np.uint16) * 257))
    cv2.imwrite(str(folder / "bg_rgba.png"), cv2.cvtColor(cv2.resize(scene, (320, 240)), cv2.COLOR_BGR2BGRA))
    cv2.imwrite(str(folder / "bg_black.png"), np.zeros((240, 320, 3), np.uint8))
    cv2.imwrite(str(folder / "bg_white.png"), np.full((240, 320, 3), 255, np.uint8))
    cv2.imwrite(str(folder / "grey.png"), np.full((300, 200, 3), 128, np.uint8))
    (folder / "not_an_image.png").write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(40))
    writer = cv2.VideoWriter(str(folder / "grey.avi"), cv2.VideoWriter_fourcc(*"MJPG"), 10, (64, 96))
    for _ in range(3):
        writer.write(np.full((96, 64, 3), 128, np.uint8))
    writer.release()
    mf = folder / "mf"
    mf.mkdir()
    cv2.imwrite(str(mf / "a.png"), person)
    cv2.imwrite(str(mf / "a_foreground.png"), person)


def cases() -> list[tuple[str, list[str], list[str]]]:
    """(name, argv after ``relight-rt``, outputs it may write)."""
    out = []
    comp = ["composite", "p.png", "--background", "bg.jpg", "-o", "c.png"]
    for v in ("-90,30", "90,-30", "1e308,0", "nan,0", "inf,0", "0,95", "a,b", "90", "1,2,3", ",", "-0,-0"):
        out.append((f"composite --key-light {v}", [*comp, "--key-light", v], ["c.png"]))
    for v in ("0,0", "1,1", "0.5,2", "-0.5,0.5", "nan,nan", "1e308,0", "0.5"):
        out.append((f"composite --position {v}", [*comp, "--position", v], ["c.png"]))
    for v in ("1e-9", "0", "-1", "1e9", "nan", "inf"):
        out.append((f"composite --height {v}", [*comp, "--height", v], ["c.png"]))
    for v in ("-1", "2", "nan", "0", "1"):
        out.append((f"composite --horizon {v}", [*comp, "--horizon", v], ["c.png"]))
    for v in ("0", "10", "170", "180", "nan", "1e308", "-60"):
        out.append((f"composite --fov {v}", [*comp, "--fov", v], ["c.png"]))
    for flags in (["--no-shadow"], ["--rim"], ["--meter", "background"], ["--no-match-camera", "--no-light-wrap"]):
        out.append((f"composite {' '.join(flags)}", [*comp, *flags], ["c.png"]))
    for bg in ("bg_tiny.png", "bg_1px.png", "bg_strip.png", "bg_tall.png", "bg16.png", "bg_rgba.png", "bg_black.png",
               "bg_white.png", "not_an_image.png", "missing.png", "p.png"):
        out.append((f"composite --background {bg}", ["composite", "p.png", "--background", bg, "-o", "c.png"],
                    ["c.png"]))
    out.append(("composite -o over the background", ["composite", "p.png", "--background", "bg.jpg", "-o", "bg.jpg"],
                []))
    out.append(("composite -o over the person", ["composite", "p.png", "--background", "bg.jpg", "-o", "p.png"], []))
    out.append(("composite --person all", ["composite", "two.png", "--background", "bg.jpg", "--person", "all",
                                           "-o", "c.png"], ["c.png"]))
    # --person all
    for photo in ("two.png", "p.png", "grey.png", "p_rgba.png", "not_an_image.png"):
        out.append((f"relight --person all {photo}", ["relight", photo, "--person", "all", "--preset", "neon",
                                                      "-o", "r.png"], ["r.png"]))
    for bg in ("transparent", "black", "bg.jpg", "bg_tiny.png"):
        out.append((f"relight --person all --background {bg}", ["relight", "two.png", "--person", "all", "--preset",
                                                                 "studio", "--background", bg, "-o", "r.png"],
                    ["r.png"]))
    out.append(("relight --person all -o over the input", ["relight", "two.png", "--person", "all", "--preset",
                                                            "studio", "-o", "two.png"], []))
    out.append(("relight --person all --exposure -1e-05", ["relight", "two.png", "--person", "all", "--preset",
                                                            "night", "--exposure", "-1e-05", "-o", "r.png"],
                ["r.png"]))
    out.append(("decompose --person all", ["decompose", "two.png", "--person", "all", "-o", "layers"], ["layers"]))
    # the matte paths
    for photo in ("two.png", "p.png", "grey.png", "not_an_image.png", "bg_1px.png", "bg_strip.png"):
        out.append((f"mask --person all {photo}", ["mask", photo, "--person", "all", "-o", "m.png"], ["m.png"]))
    out.append(("mask --foreground over the input", ["mask", "p.png", "-o", "m.png", "--foreground", "p.png"],
                ["m.png"]))
    out.append(("mask --foreground over the mask", ["mask", "p.png", "-o", "m.png", "--foreground", "m.png"],
                ["m.png"]))
    out.append(("mask folder, foreground name = another input (a batch)", ["mask", "mf", "-o", "mf_out",
                                                                           "--foreground", "mf"], ["mf_out"]))
    out.append(("mask --binary --no-refine", ["mask", "two.png", "--binary", "--no-refine", "-o", "m.png"],
                ["m.png"]))
    out.append(("mask on a clip of nobody", ["mask", "grey.avi", "-o", "m.avi"], ["m.avi"]))
    out.append(("mask on a clip of nobody, frames", ["mask", "grey.avi", "-o", "mframes"], ["mframes"]))
    out.append(("video on a clip of nobody", ["video", "grey.avi", "--preset", "studio", "-o", "v.avi"], ["v.avi"]))
    return out


def digest(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): hashlib.md5(p.read_bytes()).hexdigest() for p in sorted(folder.rglob("*"))
            if p.is_file()}


def run_case(name: str, folder: Path, argv: list[str], outputs: list[str], memory: int, seconds: float,
             command: list[str] | None = None, prefix: str = "relight-rt: ") -> dict:
    """One case: ``command`` (default ``python -m relight_rt``) + argv in ``folder``; a failure must print one line
    starting with ``prefix`` (or argparse's usage and its one error line)."""
    before = digest(folder)
    env = {**os.environ, "PYTHONPATH": str(REPO)}

    def cap() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (memory, memory))

    start = time.perf_counter()
    command = command or [sys.executable, "-m", "relight_rt"]
    proc = subprocess.Popen([*command, *argv], cwd=folder, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, preexec_fn=cap, start_new_session=True)
    try:
        _, err = proc.communicate(timeout=seconds)
        code = proc.returncode
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, 9)
        _, err = proc.communicate()
        code = "TIMEOUT"
    wall = time.perf_counter() - start
    rusage = resource.getrusage(resource.RUSAGE_CHILDREN)  # this interpreter runs one case: its child's peak
    after = digest(folder)
    changed = [k for k, v in before.items() if after.get(k) != v]
    new = [k for k in after if k not in before]
    hidden = [k for k in new if any(part.startswith(".") for part in Path(k).parts)]
    lines = [x for x in err.splitlines() if x.strip()]
    problems = []
    if code not in (0, 2):
        problems.append(f"exit {code}")
    if "Traceback" in err:
        problems.append("traceback")
    batch = "(a batch)" in name  # a batch lists each failure and keeps what it wrote for the other inputs
    usage = len(lines) >= 2 and lines[0].startswith("usage:") and ": error:" in lines[-1]  # argparse's own
    if code == 2 and not batch and not usage and not (len(lines) == 1 and lines[0].startswith(prefix)):
        problems.append(f"{len(lines)} stderr lines")
    if changed:
        problems.append(f"input changed: {changed}")
    if hidden:
        problems.append(f"temporary files left: {hidden}")
    if code == 2 and not batch:
        left = [k for k in new if any(k == o or k.startswith(o + "/") for o in outputs)]
        if left:
            problems.append(f"partial output: {left}")
    for k in new:  # outputs of a case are removed so that the next case starts from the fixtures
        p = folder / k
        p.unlink(missing_ok=True)
    for o in outputs:
        d = folder / o
        if d.is_dir():
            for p in sorted(d.rglob("*"), reverse=True):
                p.rmdir() if p.is_dir() else p.unlink()
            d.rmdir()
    return {"code": code, "seconds": round(wall, 1), "peak_mb": rusage.ru_maxrss // 1024,
            "first_line": (lines[-1] if usage else lines[0])[:140] if lines else "", "problems": problems}


def tally(res: subprocess.CompletedProcess, name: str, case, args) -> bool:
    """One case's answer (its ``--one`` process ``res``): printed as HELD or BROKE, appended to ``args.json`` when
    given; True when it held (no problem, within ``args.memory_gb``, no timeout)."""
    failed = {"code": "harness", "problems": [res.stderr[-300:]], "seconds": 0, "peak_mb": 0, "first_line": ""}
    rec = json.loads(res.stdout) if res.returncode == 0 else failed
    if rec["code"] == "TIMEOUT" or rec["peak_mb"] > args.memory_gb * 1024:
        rec["problems"].append("over the limits")
    ok = not rec["problems"]
    print(f"{'HELD ' if ok else 'BROKE'} {name}: exit {rec['code']}, {rec['peak_mb']} MB, {rec['seconds']} s, "
          f"{rec['first_line'] or '-'}{'' if ok else '  <- ' + '; '.join(rec['problems'])}", flush=True)
    if args.json:
        with open(args.json, "a", encoding="utf-8") as f:
            f.write(json.dumps({"case": name, "argv": case, **rec}) + "\n")
    return ok


def options(argv: list[str] | None, doc: str, seconds: float) -> argparse.Namespace:
    """A fuzz round's command line: the memory and time limits per case, which cases, where records go."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--memory-gb", type=float, default=4.0)
    ap.add_argument("--seconds", type=float, default=seconds)
    ap.add_argument("--only", default="", help="run the cases whose name contains this")
    ap.add_argument("--json", help="append one JSON record per case here")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = options(argv, __doc__, seconds=60.0)
    held = broke = 0
    with tempfile.TemporaryDirectory(prefix="fuzz4-") as tmp:
        folder = Path(tmp)
        fixtures(folder)
        for name, case, outputs in cases():
            if args.only not in name:
                continue
            # RUSAGE_CHILDREN's peak is the largest child so far: each case in a fresh interpreter of its own
            res = subprocess.run([sys.executable, __file__, "--one", json.dumps([name, str(folder), case, outputs,
                                  int(args.memory_gb * 2**30), args.seconds])], capture_output=True, text=True)
            ok = tally(res, name, case, args)
            held, broke = held + ok, broke + (not ok)
    print(f"{held + broke} cases: {held} held, {broke} broke")
    return 1 if broke else 0


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--one":
        name, folder, case, outputs, memory, seconds = json.loads(sys.argv[2])
        print(json.dumps(run_case(name, Path(folder), case, outputs, memory, seconds)))
        sys.exit(0)
    sys.exit(main())
