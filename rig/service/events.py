"""Progress and state events per job, kept in a bounded buffer so a client that reconnects with
Last-Event-ID resumes where it left off."""

from __future__ import annotations

import threading
from collections import OrderedDict, deque
from dataclasses import dataclass
from typing import Any

EVENTS_PER_JOB = 256
JOBS_KEPT = 256


@dataclass(frozen=True)
class Event:
    id: int  # increasing over all jobs, so never repeated within one
    type: str  # state, progress
    data: dict[str, Any]


class EventHub:
    """Thread-safe: the job worker publishes, API streams poll."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._events: OrderedDict[str, deque[Event]] = OrderedDict()
        self._last_id = 0

    def publish(self, job_id: str, kind: str, data: dict[str, Any]) -> None:
        with self._lock:
            if job_id not in self._events:
                self._events[job_id] = deque(maxlen=EVENTS_PER_JOB)
                while len(self._events) > JOBS_KEPT:
                    self._events.popitem(last=False)
            self._last_id += 1
            self._events[job_id].append(Event(self._last_id, kind, data))

    def since(self, job_id: str, last_id: int) -> list[Event]:
        with self._lock:
            return [e for e in self._events.get(job_id, ()) if e.id > last_id]
