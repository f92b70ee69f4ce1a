"""Responses that hold a connection for long (event streams, file downloads), counted: a bounded
number open at once, overall and per client address, each slot given back however its response
ends (also before its first byte)."""

from __future__ import annotations

import threading
from collections import Counter
from collections.abc import Callable
from typing import Any

from fastapi.responses import FileResponse, StreamingResponse

from rig.api.head import head_only
from rig.service import TooManyOpenError


class Slots:
    """At most `total` taken at once, at most `per_client` by one address."""

    def __init__(self, what: str, total: int, per_client: int | None = None) -> None:
        self.what = what
        self.total = total
        self.per_client = per_client
        self._taken: Counter[str] = Counter()
        self._lock = threading.Lock()  # taken in worker threads (sync routes), given back on the event loop

    @property
    def taken(self) -> int:
        return sum(self._taken.values())

    def take(self, client: str) -> Callable[[], None]:
        """A slot for `client`, and the call that gives it back (once); TooManyOpenError when none
        is free. Taken with the check under one lock: a burst cannot overshoot."""
        with self._lock:
            if self.taken >= self.total:
                raise TooManyOpenError(f"{self.total} {self.what} are open; try again shortly")
            if self.per_client is not None and self._taken[client] >= self.per_client:
                raise TooManyOpenError(f"{self.per_client} {self.what} are open from {client}; finish one first")
            self._taken[client] += 1
        given_back = False

        def release() -> None:
            nonlocal given_back
            with self._lock:
                if not given_back:
                    given_back = True
                    self._taken[client] -= 1
                    if self._taken[client] <= 0:
                        del self._taken[client]

        return release


class _Released:
    """Calls `release` when the response has been sent, failed or was cut."""

    _release: Callable[[], None]

    async def __call__(self, scope: Any, receive: Any, send: Any) -> None:
        try:
            await super().__call__(scope, receive, send)  # type: ignore[misc]
        finally:
            self._release()


class CountedStream(_Released, StreamingResponse):
    def __init__(self, release: Callable[[], None], *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._release = release


class CountedFile(_Released, FileResponse):
    def __init__(self, release: Callable[[], None], *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._release = release

    async def __call__(self, scope: Any, receive: Any, send: Any) -> None:
        if head_only(scope):  # FileResponse sends no body to a HEAD: it need not read the file
            scope = {**scope, "method": "HEAD"}
        await super().__call__(scope, receive, send)


def client_address(scope_client: Any) -> str:
    """The address a request came from ('unknown' for a test client without one)."""
    return str(scope_client.host) if scope_client is not None else "unknown"
