"""The operator's console: static pages served from inside the package (`/` and `/console/...`)
and the API's docs (`/docs`) with Swagger UI's files from the swagger-ui-bundle-v2 wheel, so that
nothing is loaded from another host: the console works on a lab network without internet.

Every page answers with a Content-Security-Policy that allows only this origin's scripts,
styles, images and connections (no inline script), and may not be framed by another site.
"""

from __future__ import annotations

from pathlib import Path

from fastapi import FastAPI
from fastapi.responses import FileResponse, HTMLResponse
from fastapi.staticfiles import StaticFiles
from starlette.types import ASGIApp, Message, Receive, Scope, Send

STATIC = Path(__file__).parent / "console_static"
CSP = (
    "default-src 'self'; script-src 'self'; style-src 'self'; img-src 'self' blob: data:; "
    "connect-src 'self'; object-src 'none'; base-uri 'none'; form-action 'self'; frame-ancestors 'none'"
)
DOCS_CSP = CSP.replace("style-src 'self'", "style-src 'self' 'unsafe-inline'")  # Swagger UI styles its widgets
DOCS_PAGE = """<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>slrig API</title><link rel="icon" href="data:,">
<link rel="stylesheet" href="/console/vendor/swagger/swagger-ui.css"></head>
<body><div id="swagger-ui"></div>
<script src="/console/vendor/swagger/swagger-ui-bundle.js"></script>
<script src="/console/docs.js"></script></body></html>
"""


def swagger_dir() -> Path | None:
    """Swagger UI's files as the swagger-ui-bundle-v2 wheel ships them, or None without it."""
    try:
        import swagger_ui_bundle
    except ImportError:
        return None
    return Path(swagger_ui_bundle.swagger_ui_path)


def add_console(app: FastAPI, docs: bool) -> None:
    """`/` and its files; `/docs` too when `docs` (the schema is readable without a key)."""

    @app.get("/", include_in_schema=False)
    def console() -> FileResponse:
        return FileResponse(STATIC / "index.html", headers={"Cache-Control": "no-cache"})

    swagger = swagger_dir()
    if swagger is not None:
        app.mount("/console/vendor/swagger", StaticFiles(directory=swagger), name="swagger")
    app.mount("/console", StaticFiles(directory=STATIC), name="console")
    if docs:

        @app.get("/docs", include_in_schema=False)
        def api_docs() -> HTMLResponse:
            return HTMLResponse(DOCS_PAGE)

    app.add_middleware(SecurityHeaders)


class SecurityHeaders:
    """CSP, nosniff and no referrer on every answer (the API's JSON too: harmless, and uniform)."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        policy = (DOCS_CSP if scope["path"] == "/docs" else CSP).encode()

        async def with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                headers = list(message.get("headers", []))
                headers += [
                    (b"content-security-policy", policy),
                    (b"x-content-type-options", b"nosniff"),
                    (b"referrer-policy", b"no-referrer"),
                    (b"x-frame-options", b"DENY"),
                ]
                message = {**message, "headers": headers}
            await send(message)

        await self.app(scope, receive, with_headers)
