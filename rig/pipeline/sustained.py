"""Keeping pace with the camera: a sequence's frames are decoded as they arrive, on the thread that
captures them (rig.patterns.stream), and what is left once its last frame is in (finishing the
decode, triangulating, publishing) runs on a worker thread while the next sequence is captured.

At most one finished sequence waits beside the one the worker is on. When the machine cannot keep
up, a newer sequence replaces the waiting one, and the one replaced is dropped whole and counted:
a sequence is never mixed with another's frames, and what is published is the newest there is.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Generic, TypeVar

from rig.errors import ScanError

Captured = TypeVar("Captured")
Finished = TypeVar("Finished")

_POLL_S = 0.5  # the worker's wait for work, renewed until it is closed


class SequenceWorker(Generic[Captured, Finished]):
    """Finishes captured sequences (`finish`) on its own thread and hands each result to `publish`
    (on that thread: it must not block). An exception in either stops the worker; the next
    `submit` or `close` raises it in the caller's thread."""

    def __init__(
        self,
        finish: Callable[[Captured], Finished],
        publish: Callable[[Finished], None],
        name: str = "slrig-sequences",
    ) -> None:
        self._finish, self._publish = finish, publish
        self._ready = threading.Condition()
        self._waiting: Captured | None = None
        self._closing = False
        self._error: BaseException | None = None
        self.dropped = 0  # sequences replaced while they waited
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def submit(self, captured: Captured) -> None:
        """Hand on a captured sequence; one still waiting is dropped for it."""
        with self._ready:
            self._raise_failure()
            if self._waiting is not None:
                self.dropped += 1
            self._waiting = captured
            self._ready.notify()

    def close(self, timeout_s: float) -> None:
        """Finish what waits, then stop; ScanError if that takes over `timeout_s`, and the worker's
        own exception if it failed."""
        with self._ready:
            self._closing = True
            self._ready.notify()
        self._thread.join(timeout_s)
        if self._thread.is_alive():
            raise ScanError(f"the last sequence was not finished within {timeout_s:g} s")
        with self._ready:
            self._raise_failure()

    def _raise_failure(self) -> None:
        if self._error is not None:
            raise self._error

    def _run(self) -> None:
        while True:
            with self._ready:
                while self._waiting is None and not self._closing:
                    self._ready.wait(_POLL_S)
                if self._waiting is None:
                    return
                captured, self._waiting = self._waiting, None
            try:
                self._publish(self._finish(captured))
            except BaseException as exc:  # handed to the caller's thread, which decides
                with self._ready:
                    self._error, self._waiting = exc, None
                return
