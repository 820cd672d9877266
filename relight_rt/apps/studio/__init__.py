"""The studio (``relight-rt studio PHOTO``): a light editor in the browser.

A local web server decomposes the photo once (stage 1) and serves one page. On the page you drag a lamp
on a sphere, set its colour, size and intensity, the ambient level, a preset, an uploaded environment
map (with rotation) or the light of another photo; while you drag, the page relights by itself from the
albedo and transport at display resolution (WebGL 2, or Canvas 2D where WebGL is missing): the diffuse
image max(0, T·L) ⊙ albedo. When you let go it asks the server for the full result (stage 2 and
full-resolution detail). Export: the relit PNG, the light (.npy, .json) and the ``relight-rt relight``
command that makes the same picture.

Needs the ``studio`` extra (``pip install "relight-rt[studio]"``: FastAPI and uvicorn), imported only
when the server starts. Binds 127.0.0.1 unless told otherwise.
"""

from __future__ import annotations

import importlib
import logging
import signal
import threading
import webbrowser

from ...engine.errors import RelightError
from ...engine.process import Terminated

log = logging.getLogger(__name__)

EXTRA_HINT = 'the studio needs FastAPI and uvicorn: pip install "relight-rt[studio]"'


def _require(module: str):
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise RelightError(f"{EXTRA_HINT} ({exc.name or module} is missing)") from None


def check_extra() -> None:
    """Raise RelightError, saying what to install, when FastAPI or uvicorn is missing."""
    _require("fastapi")
    _require("uvicorn")


def create_app(studio, allowed_hosts: list[str] | None = None):
    """The web app (a FastAPI instance) serving a ``relight_rt.apps.studio.core.Studio``; needs the extra."""
    _require("fastapi")
    from .app import create_app as _create

    return _create(studio, allowed_hosts)


def _allowed_hosts(host: str) -> list[str]:
    from .app import LOCAL_HOSTS

    if host in ("0.0.0.0", "::", ""):
        log.warning("studio: listening on every interface (%s): anyone who can reach this machine can use it", host)
        return ["*"]
    return sorted({host, *LOCAL_HOSTS})


def serve(studio, host: str = "127.0.0.1", port: int = 8000, open_browser: bool = False) -> None:
    """Run the studio's server until interrupted; prints its URL once it listens. Ctrl-C or SIGTERM stop the
    server, which then raises the signal again under the handlers that were in place (KeyboardInterrupt for
    Ctrl-C; the CLI's SIGTERM handler). uvicorn raises it again itself, from inside its event loop, where
    asyncio's own Ctrl-C handling can swallow it (a loaded machine once ended a Ctrl-C'd studio with status 0):
    the signal that stopped the server is raised once more here, after the loop has ended, if nothing was."""
    uvicorn = _require("uvicorn")
    app = create_app(studio, _allowed_hosts(host))

    class Server(uvicorn.Server):
        stopped_by: int | None = None

        def handle_exit(self, sig: int, frame) -> None:
            if self.stopped_by is None:
                self.stopped_by = sig
            super().handle_exit(sig, frame)

    server = Server(uvicorn.Config(app, host=host, port=port, log_level="warning", access_log=False))

    def announce() -> None:
        while not server.started and not server.should_exit:
            threading.Event().wait(0.05)
        if not server.started:
            return
        sock = server.servers[0].sockets[0].getsockname() if server.servers else (host, port)
        shown = f"[{sock[0]}]" if ":" in str(sock[0]) else sock[0]
        url = f"http://{shown}:{sock[1]}/"
        # the name's control characters escaped (a CR/LF in a file name would split the line a caller reads)
        name = "".join(c if c.isprintable() else repr(c)[1:-1] for c in studio.photo.name)
        print(f"relight-rt studio: {name} at {url}  (Ctrl+C stops)", flush=True)
        if open_browser:
            webbrowser.open(url)

    threading.Thread(target=announce, daemon=True).start()
    try:
        server.run()
    except SystemExit:  # uvicorn exits when it cannot listen (it has logged why)
        raise RelightError(f"cannot listen on {host}:{port} (in use, or not an address of this machine)") from None
    if server.stopped_by == signal.SIGINT:  # the run ended quietly although a signal stopped it
        raise KeyboardInterrupt
    if server.stopped_by is not None:
        signal.raise_signal(server.stopped_by)  # SIGTERM: the CLI's handler raises, unless it already ran ...
        raise Terminated()  # ... and was swallowed with the loop (it ignores a second SIGTERM)


__all__ = ["check_extra", "create_app", "serve"]
