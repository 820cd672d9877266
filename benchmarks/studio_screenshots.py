"""Screenshots of ``relight-rt studio`` with the bundled example person in a street (no mask), for the README
(docs/studio_*.png), in a 1366x768 window.

Drives the page as a user would (drags the lamp, moves sliders, picks a preset, zooms on the face with the
mouse wheel, holds B for the original photo) in headless Debian chromium and saves the window once the full
result is shown: studio_lamp.png, studio_preset.png, studio_zoom.png (the result, zoomed) and
studio_before.png (the same view with B held).

    python benchmarks/studio_screenshots.py --out docs
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

from headless_studio import launch_chromium, start_server  # noqa: E402

import relight_rt  # noqa: E402
from relight_rt import RuntimeConfig  # noqa: E402
from relight_rt.apps.studio.core import Studio  # noqa: E402
from relight_rt.cli.demo import example_path  # noqa: E402


def sphere_point(page, u: float, v: float) -> tuple[float, float]:
    """Client coordinates of the lamp sphere at (u, v) sphere radii (u right, v up)."""
    return page.evaluate(
        """([u, v]) => { const c = document.getElementById('sphere'), r = c.getBoundingClientRect();
        const half = c.width / 2, radius = half / 1.3 - 6, k = r.width / c.width;
        return [r.left + (half + u * radius) * k, r.top + (half - v * radius) * k]; }""",
        [u, v],
    )


def settle(page) -> None:
    page.wait_for_function("() => studio.state.result && studio.state.result.seq === studio.state.seq", timeout=60_000)
    page.wait_for_timeout(300)


def set_input(page, selector: str, value) -> None:
    """Set an input (a slider, a colour "#rrggbb") as a person would: its value, then input and change."""
    page.fill(selector, str(value))
    page.dispatch_event(selector, "input")
    page.dispatch_event(selector, "change")


def drag_lamp(page, u: float, v: float) -> None:
    """Drag the lamp's handle on the light sphere from where it is to the widget point (u, v)."""
    start = page.evaluate("studio.sh.directionToWidget(studio.state.lamp.direction, 1.3)")
    page.mouse.move(*sphere_point(page, *start))
    page.mouse.down()
    page.mouse.move(*sphere_point(page, u, v), steps=8)
    page.mouse.up()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="docs")
    ap.add_argument("--chromium", default="/usr/bin/chromium")
    args = ap.parse_args(argv)
    from playwright.sync_api import sync_playwright

    out = Path(args.out).resolve()
    os.chdir(REPO)  # the command line on the page names the photo relative to here
    # the example person in a street, no mask: the page shows the automatic matte at work too
    photo = (example_path().parent / "example_scene.jpg").relative_to(REPO)
    studio = Studio(photo, None, "original", relight_rt.open(RuntimeConfig(device="cpu")))
    srv, thread, url = start_server(studio)
    with sync_playwright() as p:
        context = launch_chromium(p, args.chromium, tempfile.mkdtemp(prefix="chromium-"), (1366, 768))
        page = context.new_page()
        page.goto(url)
        page.wait_for_selector("body[data-ready='1']", timeout=60_000)
        settle(page)
        # 1. a warm key light dragged to the upper left, low ambient
        drag_lamp(page, -0.72, 0.45)
        set_input(page, "#lamp-colour", "#ffd7a8")
        set_input(page, "#lamp-intensity", 2.4)
        set_input(page, "#lamp-size", 12)
        set_input(page, "#ambient", 0.08)
        settle(page)
        page.evaluate("document.activeElement.blur()")
        page.screenshot(path=str(out / "studio_lamp.png"))
        # 2. the neon preset as the base light, turned, with a soft cool lamp from behind on the right
        page.select_option("#base", "preset:neon")
        set_input(page, "#base-rotate", 30)
        set_input(page, "#base-level", 1.5)
        drag_lamp(page, 1.15, 0.35)
        set_input(page, "#lamp-colour", "#a8c8ff")
        set_input(page, "#lamp-size", 35)
        set_input(page, "#ambient", 0.02)
        settle(page)
        page.evaluate("document.activeElement.blur()")
        page.screenshot(path=str(out / "studio_preset.png"))
        # 3. zoomed on the face (the mouse wheel over it), the result; then B held: the original photo
        face = page.evaluate(
            """() => { const v = studio.state.view, r = document.getElementById('frame').getBoundingClientRect();
            return [r.left + v.x + v.face[0] * v.scale, r.top + v.y + v.face[1] * v.scale]; }"""
        )
        page.mouse.move(*face)
        for _ in range(4):
            page.mouse.wheel(0, -150)
        page.wait_for_timeout(300)
        page.screenshot(path=str(out / "studio_zoom.png"))
        page.keyboard.down("b")
        page.wait_for_function("() => document.getElementById('original').complete")
        page.wait_for_timeout(200)
        page.screenshot(path=str(out / "studio_before.png"))
        page.keyboard.up("b")
        context.close()
    srv.should_exit = True
    thread.join(10)
    names = ("studio_lamp.png", "studio_preset.png", "studio_zoom.png", "studio_before.png")
    print("wrote " + ", ".join(str(out / n) for n in names))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
