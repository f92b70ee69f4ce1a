"""Validation errors rendered whatever the client sent: FastAPI echoes each bad input back, and an
input of NaN, Infinity, 1e999 or a lone surrogate cannot be written as JSON (the default handler
then fails with a 500). Inputs that cannot be are shown by their repr, escaped."""

from __future__ import annotations

import json
from typing import Any

from fastapi import Request
from fastapi.encoders import jsonable_encoder
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse


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
