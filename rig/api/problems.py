"""Error responses a client can always read.

Validation errors rendered whatever the client sent: FastAPI echoes each bad input back, and an
input of NaN, Infinity, 1e999 or a lone surrogate cannot be written as JSON (the default handler
then fails with a 500); such inputs are shown by their repr, escaped. And a 405 whose Allow header
lists every method the path serves (Starlette's lists one route's)."""

from __future__ import annotations

import json
import re
from typing import Any

from fastapi import Request, Response
from fastapi.encoders import jsonable_encoder
from fastapi.exception_handlers import http_exception_handler
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException


def _renderable(value: Any) -> Any:
    """`value` where JSON can carry it, else its escaped repr (a string that always can)."""
    try:
        encoded = jsonable_encoder(value)
        json.dumps(encoded, allow_nan=False, ensure_ascii=False).encode("utf-8")  # as Starlette writes it
        return encoded
    except (ValueError, TypeError, UnicodeEncodeError):
        return repr(value).encode("ascii", "backslashreplace").decode("ascii")


async def validation_problem(request: Request, exc: Exception) -> JSONResponse:
    """422 with FastAPI's own shape (loc, msg, type, input, ctx), every value renderable."""
    assert isinstance(exc, RequestValidationError)
    detail = []
    for error in exc.errors():
        entry = {key: _renderable(error[key]) for key in ("type", "loc", "msg") if key in error}
        for key in ("input", "ctx"):
            if key in error:
                entry[key] = _renderable(error[key])
        detail.append(entry)
    return JSONResponse({"detail": detail}, status_code=422)


def allowed_methods(app: Any, path: str) -> list[str]:
    """Every method the API serves at `path`, from its OpenAPI paths (routers nest, the schema does
    not): what a 405's Allow header must list."""
    methods: set[str] = set()
    for template, operations in app.openapi().get("paths", {}).items():
        parts = re.split(r"(\{[^/}]+\})", template)
        pattern = "".join("[^/]+" if part.startswith("{") else re.escape(part) for part in parts)
        if re.fullmatch(pattern, path):
            methods |= {method.upper() for method in operations}
    if "GET" in methods:
        methods.add("HEAD")  # served wherever GET is (rig.api.app), not listed in the schema
    return sorted(methods)


async def method_not_allowed(request: Request, exc: Exception) -> Response:
    """Starlette's 405 with an Allow header that lists all the path's methods, not one route's."""
    assert isinstance(exc, StarletteHTTPException)
    if exc.status_code != 405:
        return await http_exception_handler(request, exc)
    allowed = allowed_methods(request.app, request.url.path)
    return JSONResponse({"detail": exc.detail}, status_code=405, headers={"Allow": ", ".join(allowed)})
