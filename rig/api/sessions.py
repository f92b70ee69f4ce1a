"""Console sessions: a browser logs in once with a key (POST /v1/session) and gets an HttpOnly,
SameSite=Strict cookie, so the key is never kept in the page, a URL or browser storage.

A request with the cookie has the key's role (admin or read). A state-changing one must also carry
the session's CSRF token in `X-CSRF-Token` (the page reads it from GET /v1/session, which another
site's page cannot read); SameSite=Strict already keeps the cookie off other sites' requests, the
token makes that hold for browsers that ignore it. Sessions live in memory: a restart logs out.
"""

from __future__ import annotations

import hmac
import secrets
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from fastapi import APIRouter, HTTPException, Request, Response, status
from pydantic import BaseModel, Field

from rig.api.models import _Request

COOKIE = "slrig_session"
CSRF_HEADER = "x-csrf-token"
IDLE_S = 12 * 3600.0  # a bench shift
MAX_SESSIONS = 256  # the oldest goes first past this


@dataclass
class Session:
    role: str
    csrf: str
    seen_s: float


class Sessions:
    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._by_token: dict[str, Session] = {}

    def new(self, role: str) -> tuple[str, Session]:
        token, session = secrets.token_urlsafe(32), Session(role, secrets.token_urlsafe(32), time.monotonic())
        with self._lock:
            if len(self._by_token) >= MAX_SESSIONS:
                oldest = min(self._by_token, key=lambda t: self._by_token[t].seen_s)
                del self._by_token[oldest]
            self._by_token[token] = session
        return token, session

    def get(self, token: str | None) -> Session | None:
        if not token:
            return None
        now = time.monotonic()
        with self._lock:
            session = self._by_token.get(token)
            if session is None:
                return None
            if now - session.seen_s > IDLE_S:
                del self._by_token[token]
                return None
            session.seen_s = now
            return session

    def end(self, token: str | None) -> None:
        with self._lock:
            self._by_token.pop(token or "", None)


def session_role(request: Request, changes: bool) -> str | None:
    """The role of the request's session cookie, or None without a live one; 403 for a change
    without the session's CSRF token."""
    session = request.app.state.sessions.get(request.cookies.get(COOKIE))
    if session is None:
        return None
    if changes and not hmac.compare_digest(request.headers.get(CSRF_HEADER, "").encode(), session.csrf.encode()):
        raise HTTPException(status.HTTP_403_FORBIDDEN, "the session's CSRF token (X-CSRF-Token) is missing or wrong")
    return session.role


class Login(_Request):
    key: str = Field(min_length=1, max_length=4096, description="the API key or the read-only key")


class SessionView(BaseModel):
    role: str | None = Field(description="admin (the API key), read (the read-only key), none: not logged in")
    csrf: str | None = Field(description="send it as X-CSRF-Token with every change made with the session cookie")


def session_router(errors: dict[int | str, Any], role_of: Callable[[str], str | None]) -> APIRouter:
    """`role_of(key)`: admin, read or None (rig.api.security.key_role)."""
    router = APIRouter(prefix="/session", tags=["session"], responses=errors)

    @router.post("", response_model=SessionView)
    def log_in(body: Login, request: Request, response: Response) -> SessionView:
        role = role_of(body.key)
        if role is None:
            raise HTTPException(status.HTTP_403_FORBIDDEN, "the key is not valid")
        token, session = request.app.state.sessions.new(role)
        secure = request.url.scheme == "https"
        response.set_cookie(COOKIE, token, httponly=True, samesite="strict", secure=secure, path="/")
        return SessionView(role=session.role, csrf=session.csrf)

    @router.get("", response_model=SessionView)
    def current(request: Request) -> SessionView:
        session = request.app.state.sessions.get(request.cookies.get(COOKIE))
        if session is None:  # an answer, not an error: a page asks before it knows
            return SessionView(role=None, csrf=None)
        return SessionView(role=session.role, csrf=session.csrf)

    @router.delete("", status_code=status.HTTP_204_NO_CONTENT)
    def log_out(request: Request) -> Response:
        token = request.cookies.get(COOKIE)
        if session_role(request, changes=True) is not None:
            request.app.state.sessions.end(token)
        response = Response(status_code=status.HTTP_204_NO_CONTENT)
        response.delete_cookie(COOKIE, path="/", httponly=True, samesite="strict")
        return response

    return router
