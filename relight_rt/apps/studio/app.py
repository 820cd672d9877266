"""The studio's web application (Starlette/FastAPI) and its server (uvicorn): routes over a ``Studio``.

Needs the ``studio`` extra (``pip install "relight-rt[studio]"``); this module imports FastAPI at import
time, so import it only through ``relight_rt.apps.studio.create_app`` / ``serve``, which say what to install.

Routes (no route takes a filesystem path; ids are random tokens of the server's own store):
    GET  /                         the page; /static/... its script and style (files of this package)
    GET  /api/info                 sizes, layer format, own light, presets, features (JSON)
    GET  /api/layers               display-resolution layers (binary, see Studio.layers_bytes)
    GET  /api/photo.png            the photo as the pipeline reads it, full resolution (the page's "before")
    POST /api/render               {"light": 27 numbers, "exposure": ..., "grade_background": bool}
                                   -> {"id", "seconds", "command", ...}
    POST /api/shadow               {"light": 27 numbers} -> the faces' cast shadows the render puts under it, for the
                                   preview: {"box": [y0, y1, x0, x1], "meter", "depth": base64 uint8, "head_box",
                                   "head": base64 float32, the head pass's change} (Studio.shadow)
    GET  /api/result/ID.png        a render's PNG at full resolution (?download=1 or true: as an attachment)
    GET  /api/result/ID/light.npy  its light (9, 3) float32 RGB; light.json likewise
    POST /api/envmap               raw body: an .hdr / PNG / JPEG equirectangular map -> {"light"}
    POST /api/photo-light          raw body: a PNG/WebP photo of a person with alpha -> {"light"}
    POST /api/background-light     raw body: a photo of the scene behind the person -> {"light"}
    POST /api/panorama-view        {"panorama": index, "view": [az, el, fov]} (one of the panoramas the server was
                                   started with) -> {"id", "light", "view", "horizon", "name"}
    GET  /api/panorama/ID.png      that view's plate (the background), at the preview's size

Guards (issue 35): the Host header must be a local name (DNS rebinding); a request whose Origin header is
present must come from the server's own origin (403), so no page of another site can drive the studio;
POST bodies must be application/json (render) or application/octet-stream (uploads), which a cross-site
page cannot send without a CORS preflight that this server never answers (415); every body is refused
past its own limit (400) or when it has not arrived within BODY_SECONDS or pauses longer than
BODY_IDLE_SECONDS (408), and all requests together
hold at most MAX_BUFFERED_BYTES of bodies and MAX_UPLOADS uploads at once (503, try again). Bad input is 400
with {"error": one line}.
"""

from __future__ import annotations

import asyncio
import base64
import contextlib
import json
import logging
import unicodedata
import urllib.parse
from pathlib import Path

import numpy as np
from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import FileResponse, JSONResponse, Response
from fastapi.staticfiles import StaticFiles
from starlette.middleware.trustedhost import TrustedHostMiddleware
from starlette.requests import ClientDisconnect

from ...engine.errors import RelightError
from .core import Studio, light_json, light_npy
from .uploads import MAX_UPLOAD_BYTES, one_large_at_a_time

log = logging.getLogger(__name__)

LOCAL_HOSTS = ("127.0.0.1", "localhost", "::1")
STATIC = Path(__file__).resolve().parent / "static"
_HEADERS = {
    "X-Content-Type-Options": "nosniff",
    "Content-Security-Policy": "default-src 'self'; img-src 'self' blob: data:; style-src 'self'; "
    "script-src 'self'; connect-src 'self'; frame-ancestors 'none'",
    "Referrer-Policy": "no-referrer",
}


MAX_BUFFERED_BYTES = 2 * MAX_UPLOAD_BYTES  # request bodies the server holds at once, all requests together
MAX_UPLOADS = 4  # uploads (env maps, photos) read or worked on at once; more are refused (503), never queued
BODY_SECONDS = 10.0  # a request body must have arrived this long after its first read (408): 32 MiB from the
# same machine take well under a second, and a client that trickles its bytes would hold an upload slot for ever
BODY_IDLE_SECONDS = 2.0  # ... and its bytes must keep arriving: no wait for the next ones longer than this (408)
JSON_LIMIT = 1 << 16  # a render request: 27 numbers and an exposure
JSON = "application/json"
UPLOAD = "application/octet-stream"  # what the page sends (studio.js, uploadLight); the kind is read from the bytes


class HTTPRefusal(Exception):
    """A request refused with ``status`` (403 foreign origin, 415 content type, 503 busy) and a message."""

    def __init__(self, status: int, message: str) -> None:
        super().__init__(message)
        self.status = status


def _origin(url: str) -> tuple[str, str, int] | None:
    """(scheme, host, port) of an origin or of "http://" + a Host header; None when it is not one."""
    try:
        parts = urllib.parse.urlsplit(url)
        port = parts.port or {"http": 80, "https": 443}.get(parts.scheme)
    except ValueError:
        return None
    if not parts.hostname or port is None or parts.path or parts.query or parts.fragment or parts.username:
        return None
    return parts.scheme, parts.hostname.lower(), port


def foreign_origin(headers) -> str | None:
    """Why a request is cross-site: its Origin header is present and is not the server's own origin (http://
    and the Host it was sent to, which TrustedHostMiddleware has checked); None for a same-origin request or
    one without Origin (a navigation, a same-origin GET, a tool such as curl)."""
    origin = headers.get("origin")
    if origin is None:
        return None
    host = headers.get("host", "")
    own = _origin(f"http://{host}")
    if own is None or _origin(origin) != own:
        return f"cross-site request refused: Origin {origin[:200]!r} is not this server's (http://{host[:200]})"
    return None


def content_disposition(filename: str) -> str:
    """The Content-Disposition value of a download named ``filename``: the one rule by which a name (the
    photo's, chosen by whoever named the file) enters a header this server builds (RFC 6266).

    ``filename="..."`` carries a plain-ASCII stand-in (anything but letters, digits, space and ``._-()+,=@``
    becomes ``_``, so no quote, backslash, semicolon or control character can end the parameter) and
    ``filename*=UTF-8''...`` the name itself, control characters made ``_`` and every other byte outside
    RFC 3986's unreserved set percent-encoded. The value is printable ASCII whatever the name holds (a CR/LF
    in it made the server drop the connection without an answer: issue 50 bugs 3, 4)."""
    name = "".join("_" if unicodedata.category(c) in ("Cc", "Cf", "Zl", "Zp", "Cs") else c for c in filename)
    plain = "".join(c if c.isascii() and (c.isalnum() or c in " ._-()+,=@") else "_" for c in name)
    return f"attachment; filename=\"{plain}\"; filename*=UTF-8''{urllib.parse.quote(name, safe='')}"


def _require_type(request: Request, expected: str, name: str) -> None:
    """Refuse (415) a body whose Content-Type is not ``expected``: a page on another site can send text/plain
    (a CORS "simple" request, no preflight) but not JSON or octet-stream without the browser asking first."""
    given = request.headers.get("content-type", "")
    if given.split(";", 1)[0].strip().lower() != expected:
        raise HTTPRefusal(415, f"{name}: expected Content-Type {expected}, got {given[:100] or 'none'}")


class Budget:
    """What request bodies may hold, over all requests: at most ``total`` bytes read and not yet let go, and
    at most ``uploads`` uploads at once. Past either, a request is refused with 503 (try again), so that many
    slow or concurrent uploads cannot make the server grow (issue 35). Each body must arrive within
    ``seconds``, its bytes never pausing longer than ``idle`` (408), so that slow uploads cannot hold the slots
    either (issue 50 bug 5). Used from the server's one event loop only (no await between a check and its
    update)."""

    def __init__(self, total: int = MAX_BUFFERED_BYTES, uploads: int = MAX_UPLOADS,
                 seconds: float = BODY_SECONDS, idle: float = BODY_IDLE_SECONDS) -> None:  # fmt: skip
        self.total, self.uploads, self.seconds, self.idle = total, uploads, seconds, idle
        self.held = 0  # bytes
        self.running = 0  # uploads

    @contextlib.asynccontextmanager
    async def upload(self, name: str):
        """One upload slot for the block."""
        if self.running >= self.uploads:
            raise HTTPRefusal(503, f"{name}: the server is busy with {self.running} uploads (the most at once); "
                                   "try again when they are done")  # fmt: skip
        self.running += 1
        try:
            yield
        finally:
            self.running -= 1

    @contextlib.asynccontextmanager
    async def body(self, request: Request, name: str, limit: int):
        """The request body for the block, refused as soon as it passes ``limit`` bytes (never read whole
        first) or the budget; its bytes count against the budget until the block ends."""
        reserved = 0

        def reserve(n: int) -> None:
            nonlocal reserved
            if self.held + n > self.total:
                held = f"{self.held / 2**20:.1f} MiB of uploads (the most is {self.total >> 20} MiB)"
                raise HTTPRefusal(503, f"{name}: the server already holds {held}; try again when they are done")
            self.held += n
            reserved += n

        try:
            declared = request.headers.get("content-length")
            if declared is not None and declared.isdigit():
                if int(declared) > limit:
                    raise RelightError(f"{name}: the upload is {int(declared) / 2**20:.1f} MiB, the limit is "
                                       f"{limit / 2**20:g} MiB")  # fmt: skip
                reserve(int(declared))
            chunks, size = [], 0
            loop = asyncio.get_running_loop()
            end = loop.time() + self.seconds
            stream = request.stream().__aiter__()
            try:
                while True:
                    left = end - loop.time()  # the body's deadline, and no pause longer than idle before it
                    try:
                        chunk = await asyncio.wait_for(stream.__anext__(), max(0.0, min(left, self.idle)))
                    except StopAsyncIteration:
                        break
                    except asyncio.TimeoutError:
                        why = f"did not arrive within {self.seconds:g} s" if left <= self.idle else \
                            f"paused for more than {self.idle:g} s"
                        raise HTTPRefusal(408, f"{name}: the upload {why} ({size} bytes came); send it at "
                                               "once") from None  # fmt: skip
                    size += len(chunk)
                    if size > limit:
                        raise RelightError(f"{name}: the upload is larger than the limit of {limit / 2**20:g} MiB")
                    if size > reserved:
                        reserve(size - reserved)
                    chunks.append(chunk)
            except ClientDisconnect:  # the client went away mid-upload: an answer no one reads, not a traceback
                raise RelightError(f"{name}: the upload was interrupted after {size} bytes") from None
            data = b"".join(chunks)
            del chunks
            yield data
        finally:
            self.held -= reserved


def create_app(studio: Studio, allowed_hosts: list[str] | None = None, budget: Budget | None = None) -> FastAPI:
    """The FastAPI app serving ``studio``. ``allowed_hosts``: Host headers accepted (DNS-rebinding guard);
    default: 127.0.0.1, localhost and ::1 with any port. ``budget``: bytes and uploads held at once (default:
    ``Budget()``). A request with an Origin other than the server's own is refused (403), a JSON route
    takes only application/json and an upload only application/octet-stream (415)."""
    app = FastAPI(title="relight-rt studio", docs_url=None, redoc_url=None, openapi_url=None)
    hosts = allowed_hosts or list(LOCAL_HOSTS)
    budget = budget or Budget()
    app.add_middleware(TrustedHostMiddleware, allowed_hosts=hosts)

    @app.middleware("http")
    async def _same_origin_and_headers(request: Request, call_next):
        refusal = foreign_origin(request.headers)
        response = JSONResponse({"error": refusal}, status_code=403) if refusal else await call_next(request)
        for key, value in _HEADERS.items():
            response.headers.setdefault(key, value)
        return response

    @app.exception_handler(RelightError)
    async def _bad_input(request: Request, exc: RelightError):
        return JSONResponse({"error": str(exc)}, status_code=400)

    @app.exception_handler(RequestValidationError)
    async def _bad_parameter(request: Request, exc: RequestValidationError):
        """A query parameter FastAPI could not read (``?download=abc``): 400 with one line, as every bad input,
        not FastAPI's 422 with a list of details."""
        first = next(iter(exc.errors()), {})
        where = ".".join(str(k) for k in first.get("loc", ())[1:]) or "request"
        text = " ".join(str(first.get("msg", "not readable")).split())
        return JSONResponse({"error": f"{where}: {text}"}, status_code=400)

    @app.exception_handler(HTTPRefusal)
    async def _refused(request: Request, exc: HTTPRefusal):
        headers = {"Retry-After": "5"} if exc.status == 503 else None
        return JSONResponse({"error": str(exc)}, status_code=exc.status, headers=headers)

    app.mount("/static", StaticFiles(directory=STATIC), name="static")

    @app.get("/", include_in_schema=False)
    def index():
        return FileResponse(STATIC / "index.html", headers={"Cache-Control": "no-store"})

    @app.get("/api/info")
    def info():
        return studio.info()

    @app.get("/api/layers")
    def layers():
        return Response(studio.layers_bytes(), media_type="application/octet-stream")

    @app.get("/api/photo.png")
    def photo():
        return Response(studio.photo_png(), media_type="image/png")

    async def _json_object(request: Request, name: str, shape: str) -> dict:
        """The request's JSON body as an object, within JSON_LIMIT bytes; ``shape`` says what is expected."""
        _require_type(request, JSON, name)
        async with budget.body(request, name, JSON_LIMIT) as raw:
            try:
                body = json.loads(raw)
            except ValueError:
                raise RelightError(f"{name}: expected a JSON body {shape}") from None
            except RecursionError:  # "[" x 60000
                raise RelightError(f"{name}: the JSON body is nested too deeply") from None
        if not isinstance(body, dict):
            raise RelightError(f"{name}: expected a JSON object")
        return body

    @app.post("/api/render")
    async def render(request: Request):
        from starlette.concurrency import run_in_threadpool

        body = await _json_object(request, "render", '{"light": [27 numbers], "exposure": ...}')
        rid, rec = await run_in_threadpool(studio.render, body.get("light"), body.get("exposure", "auto"),
                                           body.get("grade_background", False))
        return {
            "id": rid,
            "seconds": rec.seconds,
            "diffuse_only": bool(studio.relighter.diffuse_only),
            "exposure": rec.exposure,
            "command": studio.command(rec, f"{studio.photo.stem}_light.npy"),
            "light": np.asarray(rec.light).tolist(),
        }

    @app.post("/api/shadow")
    async def shadow(request: Request):
        from starlette.concurrency import run_in_threadpool

        body = await _json_object(request, "shadow", '{"light": [27 numbers]}')
        out = await run_in_threadpool(studio.shadow, body.get("light"))
        return {"box": out["box"], "meter": out["meter"], "depth": base64.b64encode(out["depth"]).decode("ascii"),
                "head_box": out["head_box"], "head": base64.b64encode(out["head"]).decode("ascii")}

    @app.post("/api/panorama-view")
    async def panorama_view(request: Request):
        from starlette.concurrency import run_in_threadpool

        body = await _json_object(request, "panorama view", '{"panorama": N, "view": [az, el, fov]}')
        pid, out = await run_in_threadpool(studio.panorama_view, body.get("panorama"), body.get("view"))
        return {"id": pid, **out}

    @app.get("/api/panorama/{pid}.png")
    def panorama_plate(pid: str):
        png = studio.plates.get(pid)
        if png is None:
            raise RelightError(f"plate {pid}: unknown or expired; choose the view again")
        return Response(png, media_type="image/png")

    def _render(rid: str):
        rec = studio.renders.get(rid)
        if rec is None:
            raise RelightError(f"result {rid}: unknown or expired; relight again")
        return rec

    def _attachment(download: bool, filename: str) -> dict:
        return {"Content-Disposition": content_disposition(filename)} if download else {}

    @app.get("/api/result/{rid}.png")
    def result_png(rid: str, download: bool = False):
        rec = _render(rid)
        headers = _attachment(download, f"{studio.photo.stem}_relit.png")
        return Response(rec.png, media_type="image/png", headers=headers)

    @app.get("/api/result/{rid}/light.npy")
    def result_npy(rid: str, download: bool = False):
        headers = _attachment(download, f"{studio.photo.stem}_light.npy")
        return Response(light_npy(_render(rid).light), media_type="application/octet-stream", headers=headers)

    @app.get("/api/result/{rid}/light.json")
    def result_json(rid: str, download: bool = False):
        headers = _attachment(download, f"{studio.photo.stem}_light.json")
        return Response(light_json(_render(rid).light), media_type="application/json", headers=headers)

    async def _upload(request: Request, name: str, work) -> dict:
        """An upload: its content type, a slot, its bytes within the budget, then ``work(bytes)`` in a thread
        (the decode happens there, after the size in the header was checked: uploads.check_upload), one at a time
        for large ones (uploads.one_large_at_a_time)."""
        from starlette.concurrency import run_in_threadpool

        _require_type(request, UPLOAD, name)
        async with budget.upload(name), budget.body(request, name, MAX_UPLOAD_BYTES) as data:
            light = await run_in_threadpool(one_large_at_a_time, work, data, name)
        return {"light": light.tolist()}

    @app.post("/api/envmap")
    async def envmap(request: Request):
        return await _upload(request, "environment map", studio.envmap_light)

    @app.post("/api/photo-light")
    async def photo_light(request: Request):
        return await _upload(request, "photo", studio.photo_light)

    @app.post("/api/background-light")
    async def background_light(request: Request):
        key = request.query_params.get("key")  # "AZ,EL" degrees: where the scene's key light comes from
        return await _upload(request, "background", lambda data: studio.background_light(data, key))

    return app
