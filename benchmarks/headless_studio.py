"""The studio served on a free port of 127.0.0.1 and a headless chromium to look at it: what the studio's
benchmarks (studio_bench.py, studio_screenshots.py) and its browser test (tests/integration/test_studio_browser.py)
share.

Needs the ``studio`` extra (uvicorn), playwright (pip) and a chromium binary (.ci/install-browser).
"""

from __future__ import annotations

import contextlib
import threading
import time

# headless, offline, no sandbox (root in CI), software WebGL (SwiftShader through ANGLE)
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-dev-shm-usage",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
]


def start_server(studio, timeout: float = 20.0):
    """Serve ``studio`` (a relight_rt.apps.studio.core.Studio) in a daemon thread on a free port of 127.0.0.1.

    Returns:
        (server, thread, url); stop with ``server.should_exit = True`` and ``thread.join()``.

    Raises:
        RuntimeError: the server did not start within ``timeout`` seconds.
    """
    import uvicorn

    from relight_rt.apps.studio import create_app

    srv = uvicorn.Server(uvicorn.Config(create_app(studio), host="127.0.0.1", port=0, log_level="warning"))
    thread = threading.Thread(target=srv.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + timeout
    while not srv.started:
        if time.monotonic() > deadline or not thread.is_alive():
            raise RuntimeError("the studio server did not start")
        time.sleep(0.02)
    return srv, thread, f"http://127.0.0.1:{srv.servers[0].sockets[0].getsockname()[1]}"


def launch_chromium(playwright, executable: str, profile: str, viewport: tuple[int, int], **options):
    """A headless chromium context with a fresh profile folder (``--user-data-dir``) and ``CHROMIUM_ARGS``.

    Args:
        playwright: the object ``playwright.sync_api.sync_playwright()`` enters as.
        executable: the chromium binary.
        profile: an empty folder for the profile.
        viewport: (width, height) in CSS pixels.
        options: more of Playwright's ``launch_persistent_context`` options (``accept_downloads``, ...).
    """
    return playwright.chromium.launch_persistent_context(
        profile, executable_path=executable, headless=True, args=CHROMIUM_ARGS,
        viewport={"width": viewport[0], "height": viewport[1]}, **options)  # fmt: skip


@contextlib.contextmanager
def serving(studio):
    """``start_server``'s URL for a ``with`` block; the server stops at the block's end."""
    srv, thread, url = start_server(studio)
    try:
        yield url
    finally:
        srv.should_exit = True
        thread.join(10)


@contextlib.contextmanager
def chromium(executable: str, profile: str, viewport: tuple[int, int] = (1280, 800), **options):
    """``launch_chromium``'s context for a ``with`` block, Playwright started and stopped around it."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        context = launch_chromium(p, executable, profile, viewport, **options)
        try:
            yield context
        finally:
            context.close()
