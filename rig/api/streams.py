"""Server-sent event streams: a bounded number open at once, each giving its slot back however it
ends."""

from __future__ import annotations

from collections.abc import AsyncIterator, Callable
from typing import Any

from fastapi import Request
from fastapi.responses import StreamingResponse

from rig.service.errors import ServiceStoppingError

SSE_PING_S = 15.0  # a comment line this often keeps proxies from closing a quiet stream
MAX_EVENT_STREAMS = 64  # each holds a connection and polls


def event_stream(request: Request, content: Callable[[], AsyncIterator[bytes]]) -> StreamingResponse:
    """An event-stream response of `content()`, if a slot is free (else ServiceStoppingError: 503)."""
    state = request.app.state
    if state.event_streams >= MAX_EVENT_STREAMS:
        raise ServiceStoppingError(f"{MAX_EVENT_STREAMS} event streams are open; poll instead")
    state.event_streams += 1  # taken with the check (no await between): a burst cannot overshoot

    def release() -> None:
        state.event_streams -= 1

    return _CountedStream(
        content(),
        release,
        media_type="text/event-stream",
        headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"},
    )


def sse(kind: str, data: str, event_id: int | None = None) -> bytes:
    """One event; `data` is a JSON text (one line)."""
    head = "" if event_id is None else f"id: {event_id}\n"
    return f"{head}event: {kind}\ndata: {data}\n\n".encode()


class _CountedStream(StreamingResponse):
    """Gives its event-stream slot back however the response ends (also before its first byte)."""

    def __init__(self, content: AsyncIterator[bytes], release: Callable[[], None], **kwargs: Any) -> None:
        super().__init__(content, **kwargs)
        self._release = release

    async def __call__(self, scope: Any, receive: Any, send: Any) -> None:
        try:
            await super().__call__(scope, receive, send)
        finally:
            self._release()
