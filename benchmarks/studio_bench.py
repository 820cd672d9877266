"""Benchmark of ``relight-rt studio``: repaint time of the live preview in headless chromium and the
server's time for the full result.

The bundled example person is enlarged (Lanczos) to about ``--pixels`` pixels, so the preview runs at
that size (1 megapixel by default), and served by the studio's own server (bundled models, CPU) on a free
port of 127.0.0.1. In Debian's chromium (headless, software WebGL: SwiftShader), for each renderer (WebGL 2
and Canvas 2D):

* ``repaint``: the light changes (the lamp moves one step along a circle) and the preview is drawn and
  finished (``gl.readPixels`` of one pixel waits for the GPU, or the Canvas 2D loop ends), ``--frames``
  times; median / p95 milliseconds and the frames per second that median allows.
* ``pointer``: real pointer drags on the lamp sphere sent by Playwright (``mouse.move``); the page records,
  for each painted frame, the time from the first unpainted pointer event (its ``timeStamp``) to the end
  of that frame's paint (finished as above); median / p95.

Server: ``Studio.render`` (stage 2, full-resolution detail, PNG encoding) at the photo's full size, and
the time the page waits from its request to the decoded full result, median over ``--renders``.

    python benchmarks/studio_bench.py [--pixels 1000000] [--frames 120] [--json out.json]

Needs the ``studio`` extra, playwright (pip) and /usr/bin/chromium (.ci/install-browser).
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

from headless_studio import launch_chromium, start_server  # noqa: E402

import relight_rt  # noqa: E402
from relight_rt import RuntimeConfig, lights  # noqa: E402
from relight_rt.apps.studio.core import Studio  # noqa: E402
from relight_rt.cli.demo import example_path  # noqa: E402


def enlarged_example(folder: Path, pixels: int) -> Path:
    """The example person (RGBA) resized to about ``pixels`` pixels."""
    rgba = cv2.imread(str(example_path()), cv2.IMREAD_UNCHANGED)
    h, w = rgba.shape[:2]
    s = math.sqrt(pixels / (h * w))
    size = (round(w * s), round(h * s))
    big = cv2.resize(rgba, size, interpolation=cv2.INTER_LANCZOS4 if s > 1 else cv2.INTER_AREA)
    path = folder / f"example_{size[0]}x{size[1]}.png"
    cv2.imwrite(str(path), big)
    return path


def stats(values) -> dict:
    v = sorted(values)
    return {
        "n": len(v),
        "median_ms": round(statistics.median(v), 2),
        "p95_ms": round(v[min(len(v) - 1, int(0.95 * len(v)))], 2),
        "min_ms": round(v[0], 2),
        "max_ms": round(v[-1], 2),
    }


REPAINT_JS = """n => {
    const s = studio.state;
    const times = [];
    for (let i = 0; i < n; i++) {
        const a = 2 * Math.PI * i / n;
        s.lamp.direction = [0.6, 0.8 * Math.cos(a), 0.8 * Math.sin(a)];
        const t0 = performance.now();
        s.dirty = true; studio.paint();
        times.push([performance.now() - t0, s.stats.last.preview, s.stats.last.sphere]);
    }
    return times;
}"""


def measure_page(context, url: str, frames: int) -> dict:
    page = context.new_page()
    page.goto(url)
    page.wait_for_selector("body[data-ready='1']", timeout=120_000)
    kind = page.evaluate("studio.state.preview.kind")
    size = page.evaluate("[studio.state.layers.width, studio.state.layers.height]")
    page.evaluate(REPAINT_JS, 5)  # warm-up
    times = page.evaluate(REPAINT_JS, frames)
    repaint = stats([t[0] for t in times])
    repaint["preview_only"] = stats([t[1] for t in times])
    repaint["light_panel_sphere"] = stats([t[2] for t in times])
    # real pointer drags on the sphere
    page.evaluate("studio.state.stats.latencies = []")
    box = page.locator("#sphere").bounding_box()
    cx, cy, r = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2, box["width"] * 0.3
    page.mouse.move(cx + r, cy)
    page.mouse.down()
    t0 = time.perf_counter()
    for i in range(frames):
        a = 2 * math.pi * i / frames
        page.mouse.move(cx + r * math.cos(a), cy - r * math.sin(a))
    page.wait_for_function("() => studio.state.dirty === false")
    drag_seconds = time.perf_counter() - t0
    latencies = page.evaluate("studio.state.stats.latencies.slice()")
    # release: the page asks for the full result; time it as the page sees it
    page.evaluate("studio.state.result = null")
    t1 = time.perf_counter()
    page.mouse.up()
    page.wait_for_function("() => studio.state.result && studio.state.result.seq === studio.state.seq", timeout=120_000)
    full_in_page = time.perf_counter() - t1
    page.close()
    pointer = stats(latencies)
    pointer["painted_frames"] = len(latencies)
    pointer["pointer_events"] = frames
    pointer["drag_seconds"] = drag_seconds
    return {
        "renderer": kind,
        "preview_size": size,
        "repaint": {**repaint, "fps_at_median": round(1000 / repaint["median_ms"], 1)},
        "pointer": pointer,
        "release_to_full_result_s": full_in_page,
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pixels", type=int, default=1_000_000, help="photo and preview size in pixels")
    ap.add_argument("--frames", type=int, default=120)
    ap.add_argument("--renders", type=int, default=5)
    ap.add_argument("--chromium", default="/usr/bin/chromium")
    ap.add_argument("--json", metavar="OUT")
    args = ap.parse_args(argv)
    from playwright.sync_api import sync_playwright

    with tempfile.TemporaryDirectory() as folder:
        photo = enlarged_example(Path(folder), args.pixels)
        t0 = time.perf_counter()
        studio = Studio(photo, None, "original", relight_rt.open(RuntimeConfig(device="cpu")),
                        preview_pixels=args.pixels)
        startup = time.perf_counter() - t0
        light = lights.preset("studio").astype(np.float32)
        studio.render(light)  # warm-up
        server_times = [studio.render(light)[1].seconds * 1000 for _ in range(args.renders)]
        srv, thread, url = start_server(studio)
        report = {
            "photo": f"{photo.name} ({studio.dec.image.shape[1]}x{studio.dec.image.shape[0]})",
            "machine": f"{platform.machine()}, {platform.processor() or 'cpu'}, python {platform.python_version()}",
            "server_startup_s (load models + decompose + pack layers)": startup,
            "server_full_result": stats(server_times),
            "layers_bytes": len(studio.layers_bytes()),
            "browser": {},
        }
        with sync_playwright() as p:
            context = launch_chromium(p, args.chromium, tempfile.mkdtemp(prefix="chromium-"), (1280, 800))
            report["browser"]["version"] = context.browser.version if context.browser else "chromium"
            report["browser"]["webgl"] = measure_page(context, url + "/?renderer=webgl", args.frames)
            report["browser"]["canvas"] = measure_page(context, url + "/?renderer=canvas", args.frames)
            page = context.new_page()  # what the page picks by itself ("auto": the faster of the two)
            page.goto(url)
            page.wait_for_selector("body[data-ready='1']", timeout=120_000)
            report["browser"]["auto_choice"] = page.evaluate(
                "[studio.state.preview.kind, studio.state.preview.timings]"
            )
            page.close()
            context.close()
        srv.should_exit = True
        thread.join(10)
    text = json.dumps(report, indent=1)
    print(text)
    if args.json:
        Path(args.json).write_text(text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
