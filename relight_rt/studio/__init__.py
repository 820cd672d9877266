"""``relight-rt studio PHOTO``: a light editor in the browser.

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

import argparse
import importlib
import logging
import threading
import webbrowser

from .._errors import RelightError

log = logging.getLogger(__name__)

EXTRA_HINT = 'the studio needs FastAPI and uvicorn: pip install "relight-rt[studio]"'


def _require(module: str):
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise RelightError(f"{EXTRA_HINT} ({exc.name or module} is missing)") from None


def create_app(studio, allowed_hosts: list[str] | None = None):
    """The web app (a FastAPI instance) serving a ``relight_rt.studio.core.Studio``; needs the extra."""
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
    Ctrl-C; the CLI's SIGTERM handler)."""
    uvicorn = _require("uvicorn")
    app = create_app(studio, _allowed_hosts(host))
    server = uvicorn.Server(uvicorn.Config(app, host=host, port=port, log_level="warning", access_log=False))

    def announce() -> None:
        while not server.started and not server.should_exit:
            threading.Event().wait(0.05)
        if not server.started:
            return
        sock = server.servers[0].sockets[0].getsockname() if server.servers else (host, port)
        shown = f"[{sock[0]}]" if ":" in str(sock[0]) else sock[0]
        url = f"http://{shown}:{sock[1]}/"
        print(f"relight-rt studio: {studio.photo.name} at {url}  (Ctrl+C stops)", flush=True)
        if open_browser:
            webbrowser.open(url)

    threading.Thread(target=announce, daemon=True).start()
    try:
        server.run()
    except SystemExit:  # uvicorn exits when it cannot listen (it has logged why)
        raise RelightError(f"cannot listen on {host}:{port} (in use, or not an address of this machine)") from None


def add_parser(subparsers) -> None:
    from ..cli import _add_model_options

    p = subparsers.add_parser(
        "studio",
        help="light editor in the browser: drag a lamp, see the person relit",
        description="Decompose PHOTO once and serve a page that relights it live while you move a lamp, pick a "
        'preset, an environment map or the light of another photo. Needs: pip install "relight-rt[studio]".',
    )
    p.add_argument("photo", metavar="PHOTO", help="photo of a person (mask: --mask, NAME_mask.png beside it, or alpha)")
    p.add_argument("--mask", metavar="M", help="mask file")
    p.add_argument("--background", default="original", metavar="BG", help="original | transparent | IMAGE")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1: this machine only)")
    p.add_argument("--port", type=int, default=8000, help="port (default 8000; 0: any free port)")
    p.add_argument("--open", action="store_true", help="open the page in the default browser")
    p.add_argument(
        "--preview-pixels",
        type=int,
        default=1_000_000,
        metavar="N",
        help="most pixels of the live preview in the browser (default 1000000)",
    )
    _add_model_options(p)
    p.set_defaults(func=_cmd_studio)


def _cmd_studio(args: argparse.Namespace) -> int:
    from pathlib import Path

    _require("fastapi")
    _require("uvicorn")
    if not 0 <= args.port <= 65535:
        raise RelightError(f"--port is {args.port}, expected 0 to 65535")
    if not Path(args.photo).is_file():
        raise RelightError(f"photo {args.photo} not found")
    from .._options import relighter as configured_relighter
    from .core import Studio

    relighter = configured_relighter(args)  # --models, --device, --precision, --preprocess, --no-detail
    studio = Studio(args.photo, args.mask, args.background, relighter, args.preview_pixels, models=args.models)
    # Ctrl-C and SIGTERM: uvicorn stops serving, then raises the signal again under the CLI's own handlers,
    # so the command ends as every command does (130 / 143, one line; relight_rt.cli._run)
    serve(studio, args.host, args.port, args.open)
    return 0


__all__ = ["add_parser", "create_app", "serve"]
