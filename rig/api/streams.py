"""Server-sent event streams: a bounded number open at once, each giving its slot back however it
ends."""

from __future__ import annotations

from collections.abc import AsyncIterator, Callable

from fastapi import Request
from fastapi.responses import StreamingResponse

from rig.api.head import head_only
from rig.api.slots import CountedStream, Slots, client_address
from rig.service import ServiceStoppingError, TooManyOpenError

SSE_PING_S = 15.0  # a comment line this often keeps proxies from closing a quiet stream
MAX_EVENT_STREAMS = 64  # each holds a connection and polls
MAX_EVENT_STREAMS_PER_CLIENT = 16  # so one address cannot hold them all
SSE_HEADERS = {"Cache-Control": "no-cache", "X-Accel-Buffering": "no"}


def event_slots() -> Slots:
    return Slots("event streams", MAX_EVENT_STREAMS, MAX_EVENT_STREAMS_PER_CLIENT)


def event_stream(request: Request, content: Callable[[], AsyncIterator[bytes]]) -> StreamingResponse:
    """An event-stream response of `content()`, if a slot is free (else ServiceStoppingError: 503);
    to HEAD, the headers alone."""
    if head_only(request.scope):
        return StreamingResponse(iter(()), media_type="text/event-stream", headers=SSE_HEADERS)
    slots: Slots = request.app.state.event_streams
    try:
        release = slots.take(client_address(request.client))
    except TooManyOpenError as exc:
        raise ServiceStoppingError(f"{exc}; poll instead") from None
    return CountedStream(release, content(), media_type="text/event-stream", headers=SSE_HEADERS)


def sse(event: str, data: str, event_id: int | None = None) -> bytes:
    """One event; `data` is a JSON text (one line)."""
    head = "" if event_id is None else f"id: {event_id}\n"
    return f"{head}event: {event}\ndata: {data}\n\n".encode()
