"""The studio's web application (Starlette/FastAPI) and its server (uvicorn): routes over a ``Studio``.

Needs the ``studio`` extra (``pip install "relight-rt[studio]"``); this module imports FastAPI at import
time, so import it only through ``relight_rt.studio.create_app`` / ``serve``, which say what to install.

Routes (no route takes a filesystem path; ids are random tokens of the server's own store):
    GET  /                         the page; /static/... its script and style (files of this package)
    GET  /api/info                 sizes, layer format, own light, presets, features (JSON)
    GET  /api/layers               display-resolution layers (binary, see Studio.layers_bytes)
    GET  /api/photo.png            the photo as the pipeline reads it, full resolution (the page's "before")
    POST /api/render               {"light": 27 numbers, "exposure": ...} -> {"id", "seconds", "command", ...}
    GET  /api/result/ID.png        a render's PNG at full resolution (?download=1: as an attachment)
    GET  /api/result/ID/light.npy  its light (9, 3) float32 RGB; light.json likewise
    POST /api/envmap               raw body: an .hdr / PNG / JPEG equirectangular map -> {"light"}
    POST /api/photo-light          raw body: a PNG/WebP photo of a person with alpha -> {"light"}
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np
from fastapi import FastAPI, Request
from fastapi.responses import FileResponse, JSONResponse, Response
from fastapi.staticfiles import StaticFiles
from starlette.middleware.trustedhost import TrustedHostMiddleware

from .._errors import RelightError
from .core import MAX_UPLOAD_BYTES, Studio, light_json, light_npy

log = logging.getLogger(__name__)

LOCAL_HOSTS = ("127.0.0.1", "localhost", "::1")
STATIC = Path(__file__).resolve().parent / "static"
_HEADERS = {
    "X-Content-Type-Options": "nosniff",
    "Content-Security-Policy": "default-src 'self'; img-src 'self' blob: data:; style-src 'self'; "
    "script-src 'self'; connect-src 'self'; frame-ancestors 'none'",
    "Referrer-Policy": "no-referrer",
}


async def _read_body(request: Request, name: str, limit: int = MAX_UPLOAD_BYTES) -> bytes:
    """The request body, refused as soon as it passes ``limit`` bytes (never read whole first)."""
    declared = request.headers.get("content-length")
    if declared is not None and declared.isdigit() and int(declared) > limit:
        raise RelightError(f"{name}: the upload is {int(declared) / 2**20:.1f} MiB, the limit is {limit >> 20} MiB")
    chunks, total = [], 0
    async for chunk in request.stream():
        total += len(chunk)
        if total > limit:
            raise RelightError(f"{name}: the upload is larger than the limit of {limit >> 20} MiB")
        chunks.append(chunk)
    return b"".join(chunks)


def create_app(studio: Studio, allowed_hosts: list[str] | None = None) -> FastAPI:
    """The FastAPI app serving ``studio``. ``allowed_hosts``: Host headers accepted (DNS-rebinding guard);
    default: 127.0.0.1, localhost and ::1 with any port."""
    app = FastAPI(title="relight-rt studio", docs_url=None, redoc_url=None, openapi_url=None)
    hosts = allowed_hosts or list(LOCAL_HOSTS)
    app.add_middleware(TrustedHostMiddleware, allowed_hosts=hosts)

    @app.middleware("http")
    async def _security_headers(request: Request, call_next):
        response = await call_next(request)
        for key, value in _HEADERS.items():
            response.headers.setdefault(key, value)
        return response

    @app.exception_handler(RelightError)
    async def _bad_input(request: Request, exc: RelightError):
        return JSONResponse({"error": str(exc)}, status_code=400)

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

    @app.post("/api/render")
    async def render(request: Request):
        raw = await _read_body(request, "render", limit=1 << 16)
        try:
            body = json.loads(raw)
        except ValueError:
            raise RelightError('render: expected a JSON body {"light": [27 numbers], "exposure": ...}') from None
        if not isinstance(body, dict):
            raise RelightError("render: expected a JSON object")
        from starlette.concurrency import run_in_threadpool

        rid, rec = await run_in_threadpool(studio.render, body.get("light"), body.get("exposure", "auto"))
        return {
            "id": rid,
            "seconds": rec.seconds,
            "diffuse_only": bool(studio.relighter.diffuse_only),
            "exposure": rec.exposure,
            "command": studio.command(rec, f"{studio.photo.stem}_light.npy"),
            "light": np.asarray(rec.light).tolist(),
        }

    def _render(rid: str):
        rec = studio.renders.get(rid)
        if rec is None:
            raise RelightError(f"result {rid}: unknown or expired; relight again")
        return rec

    def _attachment(download: int, filename: str) -> dict:
        return {"Content-Disposition": f'attachment; filename="{filename}"'} if download else {}

    @app.get("/api/result/{rid}.png")
    def result_png(rid: str, download: int = 0):
        rec = _render(rid)
        headers = _attachment(download, f"{studio.photo.stem}_relit.png")
        return Response(rec.png, media_type="image/png", headers=headers)

    @app.get("/api/result/{rid}/light.npy")
    def result_npy(rid: str, download: int = 0):
        headers = _attachment(download, f"{studio.photo.stem}_light.npy")
        return Response(light_npy(_render(rid).light), media_type="application/octet-stream", headers=headers)

    @app.get("/api/result/{rid}/light.json")
    def result_json(rid: str, download: int = 0):
        headers = _attachment(download, f"{studio.photo.stem}_light.json")
        return Response(light_json(_render(rid).light), media_type="application/json", headers=headers)

    @app.post("/api/envmap")
    async def envmap(request: Request):
        from starlette.concurrency import run_in_threadpool

        data = await _read_body(request, "environment map")
        light = await run_in_threadpool(studio.envmap_light, data)
        return {"light": light.tolist()}

    @app.post("/api/photo-light")
    async def photo_light(request: Request):
        from starlette.concurrency import run_in_threadpool

        data = await _read_body(request, "photo")
        light = await run_in_threadpool(studio.photo_light, data)
        return {"light": light.tolist()}

    @app.post("/api/background-light")
    async def background_light(request: Request):
        from starlette.concurrency import run_in_threadpool

        data = await _read_body(request, "background")
        key = request.query_params.get("key")  # "AZ,EL" degrees: where the scene's key light comes from
        light = await run_in_threadpool(studio.background_light, data, key)
        return {"light": light.tolist()}

    return app
