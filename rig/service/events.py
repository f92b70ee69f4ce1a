"""Progress and state events per job, kept in a bounded buffer so a client that reconnects with
Last-Event-ID resumes where it left off."""

from __future__ import annotations

import threading
import time
from collections import OrderedDict, deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

from rig.progress import ProgressCallback, ProgressEvent

EVENTS_PER_JOB = 256
JOBS_KEPT = 256
STORING = 0.95  # from this fraction on a job is writing its results: too late to cancel
PROGRESS_EVERY_S = 0.2  # at most this often per job, plus every stage change


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


class ProgressRecord(Protocol):
    def progress(self, job_id: str, stage: str, fraction: float) -> None: ...


def progress_reporter(
    job_id: str, record: ProgressRecord, events: EventHub, checkpoint: Callable[[], None]
) -> ProgressCallback:
    """A job's progress callback: a cancellation checkpoint before storing begins, and the stage
    recorded and published at most every PROGRESS_EVERY_S, plus every stage change and the end."""
    last = {"t": 0.0, "stage": ""}

    def on_progress(event: ProgressEvent) -> None:
        if event.fraction < STORING:  # storing is never cut short: the folder is complete or absent
            checkpoint()
        now = time.monotonic()
        if event.stage != last["stage"] or now - last["t"] >= PROGRESS_EVERY_S or event.fraction >= 1.0:
            last["t"], last["stage"] = now, event.stage
            record.progress(job_id, event.stage, event.fraction)
            events.publish(job_id, "progress", event.as_dict())

    return on_progress
