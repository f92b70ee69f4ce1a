"""What live mode and aim mode share: each is wanted or not (requests set it, the job worker reads
it), has a state with its reason, an optional time limit, and wakes the worker when it is wanted.
The worker runs one whenever no job waits; a queued job pauses it."""

from __future__ import annotations

import abc
import threading
import time
from typing import Any


class WorkerMode(abc.ABC):
    """States: off, starting (wanted, not yet run), running, paused (a job runs), failed."""

    def __init__(self, worker: threading.Condition) -> None:
        """`worker`: the job worker's condition, notified when the mode is wanted."""
        self._worker = worker
        self._lock = threading.Lock()
        self._wanted: Any = None  # what the mode runs with, while wanted
        self._deadline: float | None = None
        self._state = "off"
        self._reason: str | None = None

    def _want(self, wanted: Any, seconds: float | None) -> None:
        """Under self._lock: want the mode with `wanted` for `seconds` (None: until stopped)."""
        self._wanted = wanted
        self._deadline = None if seconds is None else time.monotonic() + seconds
        if self._state in ("off", "failed"):
            self._state, self._reason = "starting", None

    def _wake_worker(self) -> None:
        with self._worker:
            self._worker.notify_all()

    def stop(self, reason: str = "stopped by request") -> dict[str, Any]:
        with self._lock:
            self._wanted = None
            if self._state in ("starting", "paused"):
                self._state, self._reason = "off", reason
            elif self._state == "running":
                self._reason = reason  # the worker turns it off (dark) after the step it is in
        return self.view()

    def wanted(self) -> bool:
        with self._lock:
            if self._wanted is not None and self._deadline is not None and time.monotonic() >= self._deadline:
                self._wanted, self._state, self._reason = None, "off", "its time limit passed"
            return self._wanted is not None

    def interrupted(self, reason: str) -> None:
        """The daemon is stopping: the mode is off."""
        with self._lock:
            self._wanted, self._state, self._reason = None, "off", reason

    @abc.abstractmethod
    def view(self) -> dict[str, Any]: ...
