"""API key, Host header and request-size checks of the REST API.

A key comes in `X-API-Key` or `Authorization: Bearer`, never in a query string, and is compared
in constant time; the console's session cookie stands for the key it logged in with
(rig.api.sessions). The API key is needed for every mutating request; reads need a key (the API key
or the read-only key, for dashboards and automation that only watch) when `service.read_access`
says so, by default when the daemon listens beyond loopback. Missing: 401; wrong, or the read-only
key for a change: 403. No key is ever logged.
"""

from __future__ import annotations

import asyncio
import hmac
import ipaddress
import json
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

from fastapi import Depends, HTTPException, Request, status
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from rig.api.sessions import session_role

MIN_KEY_LENGTH = 16
MIN_BODY_RATE = 65536  # bytes/s a request body must average (besides one stall's allowance)
PLACEHOLDER_KEYS = frozenset({"changeme", "changethis", "secret", "password", "slrig"})


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def check_key_strength(key: str) -> str | None:
    """Why a key is unfit to guard the rig, or None."""
    if key.lower() in PLACEHOLDER_KEYS:
        return "is a placeholder; generate one, e.g. `openssl rand -hex 32`"
    if len(key) < MIN_KEY_LENGTH:
        return f"is shorter than {MIN_KEY_LENGTH} characters"
    return None


@dataclass(frozen=True)
class ApiSettings:
    api_key: str = field(repr=False)  # repr=False: never printed with the settings
    protect_reads: bool = False  # every read needs a key (service.read_access; by default beyond loopback)
    read_key: str | None = field(default=None, repr=False)  # reads only
    max_downloads: int = 16
    max_downloads_per_client: int = 4
    max_body_bytes: int = 65536
    cors_origins: tuple[str, ...] = ()
    allowed_hosts: tuple[str, ...] = ("127.0.0.1", "localhost", "::1", "[::1]")
    body_stall_s: float = 10.0  # a body that sends nothing for this long is answered 408, its connection freed


def _presented_key(request: Request) -> str | None:
    return _key_from(request.headers.get("x-api-key"), request.headers.get("authorization", ""))


def header_key(raw_headers: Iterable[tuple[bytes, bytes]]) -> str | None:
    """The key a raw request presents in its ASGI headers (before the application parses them)."""
    headers = {name.decode("latin-1").lower(): value.decode("latin-1") for name, value in raw_headers}
    return _key_from(headers.get("x-api-key"), headers.get("authorization", ""))


def _key_from(header: str | None, authorization: str) -> str | None:
    if header:
        return header
    scheme, _, token = authorization.partition(" ")
    return token.strip() if scheme.lower() == "bearer" and token.strip() else None


def key_role(settings: ApiSettings, presented: str | None) -> str | None:
    """The role of a presented key: admin (the API key), read (the read-only key), or None. Constant time."""
    if presented is None:
        return None
    given = presented.encode()
    if hmac.compare_digest(given, settings.api_key.encode()):
        return "admin"
    if settings.read_key is not None and hmac.compare_digest(given, settings.read_key.encode()):
        return "read"
    return None


def _check(request: Request, changes: bool) -> None:
    settings: ApiSettings = request.app.state.api_settings
    presented = _presented_key(request)
    if presented is None:
        session = session_role(request, changes)  # the console's cookie (rig.api.sessions)
        if session == "admin" or (session == "read" and not changes):
            return
        if session == "read":
            raise HTTPException(status.HTTP_403_FORBIDDEN, "a read-only key cannot change anything; use the API key")
        raise HTTPException(
            status.HTTP_401_UNAUTHORIZED,
            "an API key is required (header X-API-Key or Authorization: Bearer)",
            headers={"WWW-Authenticate": "Bearer"},
        )
    role = key_role(settings, presented)
    if role is None:
        raise HTTPException(status.HTTP_403_FORBIDDEN, "the API key is not valid")
    if changes and role != "admin":
        raise HTTPException(status.HTTP_403_FORBIDDEN, "a read-only key cannot change anything; use the API key")


def require_key(request: Request) -> None:
    """For mutating endpoints: the API key."""
    _check(request, changes=True)


def require_key_for_reads(request: Request) -> None:
    """For read endpoints: either key, when reads are protected (service.read_access)."""
    if request.app.state.api_settings.protect_reads:
        _check(request, changes=False)


MUTATING = [Depends(require_key)]
READING = [Depends(require_key_for_reads)]


@dataclass(frozen=True)
class UploadRule:
    """File uploads under `prefix`: bodies up to `limit` for the API key's holder, and
    `refusal(declared bytes)`, the (status, reason) to answer before the body is read, or None."""

    prefix: str
    limit: int
    refusal: Callable[[int], tuple[int, str] | None] = lambda declared: None


class BodyLimitMiddleware:
    """413 for a request body over `limit` bytes, declared or streamed (chunked): the body is read
    here, up to the limit, before the application sees the request."""

    def __init__(
        self, app: ASGIApp, limit: int, uploads: UploadRule | None = None, key: str = "", stall_s: float = 10.0
    ) -> None:
        self.app = app
        self.limit = limit
        self.stall_s = stall_s
        self.uploads = uploads  # file uploads, larger than any JSON body
        self.key = key

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        limit = self._limit(scope)
        declared = dict(scope["headers"]).get(b"content-length")
        if declared is not None and not declared.strip().isdigit():
            await _reply(send, 400, "Content-Length is not a number")
            return
        if declared is not None and int(declared) > limit:
            await _reply(send, 413, f"request body larger than {limit} bytes")
            return
        if declared is not None and self._is_upload(scope) and self._holds_key(scope):  # others: 401/403 first
            refused = self.uploads.refusal(int(declared))  # type: ignore[union-attr]
            if refused is not None:  # before a byte of it is read (a full disk: 507)
                await _reply(send, *refused)
                return
        body = bytearray()
        loop = asyncio.get_running_loop()
        deadline = loop.time() + self.stall_s + limit / MIN_BODY_RATE  # a trickle cannot hold it for ever
        while True:
            try:
                message = await asyncio.wait_for(receive(), min(self.stall_s, max(0.0, deadline - loop.time())))
            except TimeoutError:
                await _reply(send, 408, f"the request body stalled or came slower than {MIN_BODY_RATE} bytes/s")
                return
            if message["type"] == "http.disconnect":
                return  # the client went away
            body += message.get("body", b"")
            if len(body) > limit:
                await _reply(send, 413, f"request body larger than {limit} bytes")
                return
            if not message.get("more_body", False):
                break
        replayed = False

        async def replay() -> Message:
            nonlocal replayed
            if not replayed:
                replayed = True
                return {"type": "http.request", "body": bytes(body), "more_body": False}
            return await receive()  # then what the server says (a disconnect, for event streams)

        await self.app(scope, replay, send)

    def _limit(self, scope: Scope) -> int:
        """The body limit of this request: an upload's, for the key's holder only (no one else
        makes the daemon hold a large body), else the JSON bodies'."""
        if not self._is_upload(scope) or not self._holds_key(scope):
            return self.limit
        return self.uploads.limit  # type: ignore[union-attr]

    def _holds_key(self, scope: Scope) -> bool:
        presented = (header_key(scope["headers"]) or "").encode()
        return bool(self.key) and hmac.compare_digest(presented, self.key.encode())

    def _is_upload(self, scope: Scope) -> bool:
        return self.uploads is not None and scope["method"] == "PUT" and scope["path"].startswith(self.uploads.prefix)


async def _reply(send: Send, status_code: int, detail: str) -> None:
    """A refusal in the API's shapes: a 422 as FastAPI's own (a list naming the body), else text."""
    shaped: object = [{"loc": ["body"], "msg": detail, "type": "value_error"}] if status_code == 422 else detail
    body = json.dumps({"detail": shaped}).encode()
    await send(
        {
            "type": "http.response.start",
            "status": status_code,
            "headers": [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode())],
        }
    )
    await send({"type": "http.response.body", "body": body})
