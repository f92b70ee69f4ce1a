"""Live mode in the daemon: started and stopped over REST, run by the job worker (the one owner of
the rig) whenever no job is waiting, watched by any number of clients.

The worker writes the newest frame into one slot; readers take whatever is newest when they are
ready for it, so a slow reader skips sequences and never holds the rig back. A queued job pauses
live mode (a triggered scan waits for no preview, only for the sequence being triangulated as it
stops, a few milliseconds); it resumes once the queue is empty.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

from rig.config import RigConfig
from rig.errors import ConfigError
from rig.opened_rig import Rig
from rig.pipeline import LiveFrame, LiveStats, run_live
from rig.service.errors import JobConflictError
from rig.service.modes import WorkerMode

MAX_LIVE_S = 86400.0


class LiveMode(WorkerMode):
    """Whether live mode is wanted (the config it runs with), its state, its figures and its newest
    frame (thread-safe)."""

    def __init__(self, config: RigConfig, worker: threading.Condition) -> None:
        super().__init__(worker)
        self.config = config
        self._stats = LiveStats()
        self._latest: LiveFrame | None = None
        self._session = 0

    # --- requests (HTTP handlers) ---------------------------------------------------------------
    def start(self, codec: str | None, seconds: float | None, hdr: str | list[float] | None = None) -> dict[str, Any]:
        """Want live mode with `codec` (default scan.live's) for `seconds` (default: until stopped),
        at `hdr`'s exposures where given; JobConflictError for a codec or exposures that do not fit
        the rig. Starting again replaces the request (and its time limit) without interrupting what
        runs."""
        try:
            config = self.config.with_live(codec, hdr) if codec or hdr is not None else self.config
        except ConfigError as exc:
            raise JobConflictError(f"live mode does not fit this rig: {'; '.join(exc.problems)}") from None
        with self._lock:
            if self._wanted is None or self._wanted.scan.live != config.scan.live:
                self._session += 1
                self._stats, self._latest = LiveStats(), None
            self._want(config, seconds)
        self._wake_worker()
        return self.view()

    # --- the worker -----------------------------------------------------------------------------
    def run(self, rig: Rig, jobs_waiting: Callable[[], bool], beat: Callable[[], None]) -> None:
        """Run live mode on `rig` until it is no longer wanted or a job waits (then paused)."""
        with self._lock:
            config, session = self._wanted, self._session
            if config is None:
                return
            self._state = "running"
            stats = self._stats

        def keep_going() -> bool:
            beat()
            return self.wanted() and self._session == session and not jobs_waiting()

        try:
            run_live(rig, lambda frame: self._publish(frame, session), keep_going, stats, config.scan)
        except BaseException as exc:
            with self._lock:
                self._wanted, self._state = None, "failed"
                self._reason = str(exc) or type(exc).__name__
            raise
        with self._lock:
            if self._state == "running":
                if self._wanted is not None and self._session == session:
                    self._state, self._reason = "paused", "a job is running"
                else:
                    self._state = "off" if self._wanted is None else "starting"
                    self._reason = self._reason or "stopped"

    def _publish(self, frame: LiveFrame, session: int) -> None:
        with self._lock:
            if session == self._session:
                self._latest = frame

    # --- readers --------------------------------------------------------------------------------
    @property
    def latest(self) -> tuple[int, LiveFrame | None]:
        """The session and its newest frame (None before its first)."""
        with self._lock:
            return self._session, self._latest

    def state(self) -> tuple[str, str | None, int]:
        """State, reason and session: what a watcher is told when it changes."""
        with self._lock:
            return self._state, self._reason, self._session

    def dropped(self) -> int:
        """Sequences this session dropped whole so far (the machine fell behind)."""
        with self._lock:
            return self._stats.dropped

    def view(self) -> dict[str, Any]:
        with self._lock:
            config = self._wanted or self.config
            params = config.scan.live_params()
            left = None if self._deadline is None or self._wanted is None else self._deadline - time.monotonic()
            return {
                "state": self._state,
                "reason": self._reason,
                "session": self._session,
                "codec": config.scan.live.codec,
                "params": params.model_dump(mode="json") if params is not None else {},
                "hdr": config.scan.live.hdr,
                "seconds_left": None if left is None else round(max(0.0, left), 3),
                **self._stats.as_dict(),
            }
