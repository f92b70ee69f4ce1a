"""HTTP connections that cannot exhaust the daemon.

uvicorn keeps a connection that never sends a request, or never reads its response, for as long as
the client likes, and with a concurrency limit answers every later request 503 once enough such
connections are open (health checks included). Here:

- a connection must deliver its request headers within `service.header_timeout_s` of opening (or
  of its previous response) or it is closed;
- a response the client holds back (the send buffer full) must drain at `service.min_send_rate`
  bytes/s, judged every `service.send_timeout_s`, or its connection is cut (a slow reader);
- past `service.max_connections` one connection is closed to make room: idle ones before those
  with a request in progress, unauthenticated before authenticated (a request that presented a
  valid key), slow readers first among the busy, oldest first; the new one only when every other
  is an authenticated request in progress. So a request that arrives, a health check among them,
  is served.

Body stalls are bounded in BodyLimitMiddleware (rig.api.security), long responses counted in
rig.api.slots.
"""

from __future__ import annotations

import asyncio
import hmac
import logging
import time
from typing import Any

from uvicorn.protocols.http.h11_impl import H11Protocol

from rig.api import header_key

log = logging.getLogger(__name__)


def guarded_protocol(
    header_timeout_s: float,
    max_connections: int,
    send_timeout_s: float = 15.0,
    min_send_rate: int = 1024,
    keys: tuple[str, ...] = (),
) -> type[H11Protocol]:
    """The protocol class for uvicorn's `http` setting, with these bounds; `keys` are those that
    make a request authenticated (for the eviction order)."""
    settings = {
        "header_timeout_s": header_timeout_s,
        "max_connections": max_connections,
        "send_timeout_s": send_timeout_s,
        "min_send_rate": min_send_rate,
        "keys": tuple(k.encode() for k in keys),
    }
    return type("ConfiguredGuardedH11Protocol", (GuardedH11Protocol,), settings)


class GuardedH11Protocol(H11Protocol):
    """uvicorn's h11 protocol with a deadline for request headers and idle connections evicted."""

    header_timeout_s = 10.0
    max_connections = 1000
    send_timeout_s = 15.0
    min_send_rate = 1024
    keys: tuple[bytes, ...] = ()

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._header_deadline: asyncio.TimerHandle | None = None
        self._send_check: asyncio.TimerHandle | None = None
        self._send_mark = 0  # bytes waiting to be sent when the last check began
        self._opened = time.monotonic()
        self._authenticated = False  # its latest request presented a valid key

    def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
        super().connection_made(transport)
        self._arm()
        if len(self.connections) > self.max_connections:
            self._evict_idle()

    def connection_lost(self, exc: Exception | None) -> None:
        self._disarm()
        self._stop_send_check()
        super().connection_lost(exc)

    def data_received(self, data: bytes) -> None:
        super().data_received(data)
        if self._in_request():
            self._disarm()  # the headers are in; the body has its own bound
            self._authenticated = self._presents_key()
        elif self._header_deadline is None:
            self._arm()  # bytes of the next request's headers: they get the same deadline

    # --- a client that does not read its response ---------------------------------------------
    def pause_writing(self) -> None:
        super().pause_writing()
        self._start_send_check()

    def resume_writing(self) -> None:
        super().resume_writing()
        self._stop_send_check()

    def _start_send_check(self) -> None:
        self._stop_send_check()
        self._send_mark = self.transport.get_write_buffer_size()
        self._send_check = self.loop.call_later(self.send_timeout_s, self._check_send_rate)

    def _stop_send_check(self) -> None:
        if self._send_check is not None:
            self._send_check.cancel()
            self._send_check = None

    def _check_send_rate(self) -> None:
        """While the response is held back, nothing more is written to the buffer: what left it
        is what the client took. Also once the connection is closing: close() waits for the
        buffer to drain, which a client that never reads would make for ever."""
        self._send_check = None
        if self.transport.get_write_buffer_size() == 0:
            return
        taken = self._send_mark - self.transport.get_write_buffer_size()
        if taken < self.min_send_rate * self.send_timeout_s or taken <= 0:
            log.info(
                "cutting a connection that took %d bytes of its response in %g s (at least %d bytes/s)",
                max(taken, 0),
                self.send_timeout_s,
                self.min_send_rate,
            )
            self.transport.abort()  # close() would wait for the buffer to drain
            return
        self._start_send_check()

    def _slow_reader(self) -> bool:
        return self.flow.write_paused

    def _presents_key(self) -> bool:
        if not self.keys or self.cycle is None:
            return False
        presented = (header_key(self.cycle.scope["headers"]) or "").encode()
        return any(hmac.compare_digest(presented, key) for key in self.keys)

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
            self._close()

    def on_response_complete(self) -> None:
        super().on_response_complete()
        if self.transport.get_write_buffer_size() and self._send_check is None:
            self._start_send_check()  # its last bytes, too, must leave at min_send_rate

    def _close(self) -> None:
        """Close, or abort when bytes still wait for a client that may never read them."""
        if self.transport.get_write_buffer_size():
            self.transport.abort()
        else:
            self.transport.close()

    def _lingering(self) -> bool:
        """Closing, but holding bytes the client has not taken (its socket and buffer stay)."""
        return self.transport.is_closing() and self.transport.get_write_buffer_size() > 0

    def _eviction_rank(self) -> tuple[int, float]:
        """Lower goes first: closing ones still holding unread bytes, idle unauthenticated, idle
        authenticated, busy unauthenticated slow readers, other busy unauthenticated; oldest
        first within each."""
        if self._lingering():
            return (-1, self._opened)
        if not self._in_request():
            return (0 if not self._authenticated else 1, self._opened)
        if not self._authenticated:
            return (2 if self._slow_reader() else 3, self._opened)
        return (4, self._opened)  # an authenticated request in progress: never evicted

    def _evict_idle(self) -> None:
        """Close the connection that matters least (see the module's docstring); with only
        authenticated requests in progress besides, this new one (so file descriptors never run
        out, and a request that arrives later finds room once one ends)."""
        open_ = [
            c
            for c in self.connections
            if isinstance(c, GuardedH11Protocol) and (not c.transport.is_closing() or c._lingering())
        ]
        if len(open_) <= self.max_connections:
            return  # others closing in this pass already made room
        others = [c for c in open_ if c is not self and c._eviction_rank()[0] < 4]
        victim = min(others, key=lambda c: c._eviction_rank()) if others else self
        reasons = {-1: "one closing", 0: "an idle one", 1: "an idle one", 2: "a slow reader", 3: "a request"}
        label = "the new one" if victim is self else reasons[victim._eviction_rank()[0]]
        log.warning("%d connections open: closing %s", len(open_), label)
        if victim._in_request() or victim._lingering():
            victim.transport.abort()  # its response would otherwise be waited out
        else:
            victim._close()
