"""Device calls asked for over REST (camera settings, projector power) are made by the job worker,
the rig's one owner (decision 0003): a request hands its call over and waits a bounded time for
the answer. Calls run between jobs, and between aim or live frames; while a job runs they are
refused at once rather than queued behind it.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from drivers.errors import DeviceError
from rig.opened_rig import Rig
from rig.service.errors import JobConflictError, SetupRefusedError

CALL_TIMEOUT_S = 15.0  # opening a rig takes seconds (cameras, the simulator's first ray cast)


@dataclass
class _Call:
    action: Callable[[Rig], Any]
    done: threading.Event = field(default_factory=threading.Event)
    answer: Any = None
    error: str | None = None


class WorkerCalls:
    def __init__(self, worker: threading.Condition) -> None:
        """`worker`: the job worker's condition, notified when a call waits."""
        self._worker = worker
        self._lock = threading.Lock()
        self._pending: list[_Call] = []

    def call(self, action: Callable[[Rig], Any], busy: str | None, what: str) -> Any:
        """`action(rig)` on the worker, its answer returned here. JobConflictError while job `busy`
        runs or waits (jobs come first) or when the worker does not get to it in time;
        SetupRefusedError with the driver's or the action's refusal (ValueError, a device error,
        SetupRefusedError); nothing changed then."""
        if busy is not None:
            raise JobConflictError(f"job {busy} is running or queued; {what} waits until the queue is empty")
        call = _Call(action)
        with self._lock:
            self._pending.append(call)
        with self._worker:
            self._worker.notify_all()
        if not call.done.wait(CALL_TIMEOUT_S):
            with self._lock:
                if call in self._pending:
                    self._pending.remove(call)
            raise JobConflictError(f"the rig did not get to {what} within {CALL_TIMEOUT_S:g} s (busy)")
        if call.error is not None:
            raise SetupRefusedError(call.error)
        return call.answer

    def pending(self) -> bool:
        with self._lock:
            return bool(self._pending)

    def run_pending(self, rig: Rig) -> None:
        """The worker: make the waiting calls on `rig`, then answer them."""
        with self._lock:
            waiting, self._pending = self._pending, []
        for call in waiting:
            try:
                call.answer = call.action(rig)
            except (ValueError, DeviceError, SetupRefusedError) as exc:
                call.error = str(exc)
            call.done.set()

    def fail_pending(self, reason: str) -> None:
        """The worker could not reach the devices: every waiting call is answered `reason`."""
        with self._lock:
            waiting, self._pending = self._pending, []
        for call in waiting:
            call.error = reason
            call.done.set()
