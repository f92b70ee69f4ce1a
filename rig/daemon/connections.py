"""HTTP connections that cannot exhaust the daemon.

uvicorn keeps a connection that never sends a request for as long as the client likes, and with
a concurrency limit answers every later request 503 once enough such connections are open
(health checks included). Here a connection must deliver its request headers within
`service.header_timeout_s` of opening (or of its previous response) or it is closed; past
`service.max_connections` the oldest connection with no request in progress is closed to make room, so a request that
arrives is always served. Body stalls are bounded in BodyLimitMiddleware (rig.api.security).
"""

from __future__ import annotations

import asyncio
import logging
import time
from typing import Any

from uvicorn.protocols.http.h11_impl import H11Protocol

log = logging.getLogger(__name__)


def guarded_protocol(header_timeout_s: float, max_connections: int) -> type[H11Protocol]:
    """The protocol class for uvicorn's `http` setting, with these bounds."""
    return type(
        "ConfiguredGuardedH11Protocol",
        (GuardedH11Protocol,),
        {"header_timeout_s": header_timeout_s, "max_connections": max_connections},
    )


class GuardedH11Protocol(H11Protocol):
    """uvicorn's h11 protocol with a deadline for request headers and idle connections evicted."""

    header_timeout_s = 10.0
    max_connections = 1000

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._header_deadline: asyncio.TimerHandle | None = None
        self._opened = time.monotonic()

    def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
        super().connection_made(transport)
        self._arm()
        if len(self.connections) > self.max_connections:
            self._evict_idle()

    def connection_lost(self, exc: Exception | None) -> None:
        self._disarm()
        super().connection_lost(exc)

    def data_received(self, data: bytes) -> None:
        super().data_received(data)
        if self._in_request():
            self._disarm()  # the headers are in; the body has its own bound
        elif self._header_deadline is None:
            self._arm()  # bytes of the next request's headers: they get the same deadline

    def _in_request(self) -> bool:
        return self.cycle is not None and not self.cycle.response_complete

    def _arm(self) -> None:
        self._disarm()
        self._header_deadline = self.loop.call_later(self.header_timeout_s, self._headers_late)

    def _disarm(self) -> None:
        if self._header_deadline is not None:
            self._header_deadline.cancel()
            self._header_deadline = None

    def _headers_late(self) -> None:
        self._header_deadline = None
        if not self._in_request() and not self.transport.is_closing():
            log.info("closing a connection that sent no request within %g s", self.header_timeout_s)
            self.transport.close()

    def _evict_idle(self) -> None:
        """Close the oldest idle connection; with none idle, this new one (so file descriptors
        never run out, and a request that arrives later finds room once one ends)."""
        open_ = [c for c in self.connections if isinstance(c, GuardedH11Protocol) and not c.transport.is_closing()]
        if len(open_) <= self.max_connections:
            return  # others closing in this pass already made room
        idle = [c for c in open_ if c is not self and not c._in_request()]
        victim = min(idle, key=lambda c: c._opened) if idle else self
        log.warning("%d connections open: closing %s", len(open_), "the oldest idle one" if idle else "a new one")
        victim.transport.close()
