"""The job worker's rig, and how it is let go of when the daemon stops (SIGTERM): dark first, in
about a second whatever the worker is doing.

The worker is cancelled at once, and its waits are cut: for light (Rig.wait's checkpoint) and for
frames (Rig.capture's cancel, also a stalled driver's wait). While it drives the devices it stops by
itself within STOP_GRACE_S: it darkens the projectors and records the job interrupted. Some steps
cannot be interrupted. On the default bench (config/sim.yaml), measured between checkpoints: the
simulator's ray casting for a rig's first frame 1.2-1.5 s, a ring scan's fit and surface (numba)
1.2-1.6 s, a calibration view about 1 s, a scan's accuracy and files when it is stored 0.6-1.5 s.
Those are not waited out, and no checkpoints are sown into them (there would always be another
kernel): the stopping thread darkens and closes the projectors itself, under each projector's
call lock (drivers.base.Projector.shut), so nothing the worker does later lights them; no rig is
taken on after that, and the worker's folders are published through a gate that refuses once
stopping (WorkerRig.publish), so none appears behind a job recorded interrupted.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections.abc import Callable

from rig.assembly import open_rig
from rig.config import RigConfig
from rig.opened_rig import Rig
from rig.service.errors import JobCancelledError

log = logging.getLogger(__name__)

# The worker's longest step between checkpoints while it drives devices is one frame (tens of ms on
# the default bench); a third of a second leaves room for a loaded machine.
STOP_GRACE_S = 0.3


class WorkerRig:
    """The rig the job worker keeps open between jobs. The worker takes it on, darkens it and drops
    it after a failure; the thread that stops the service lets go of it (let_go)."""

    def __init__(
        self, config: RigConfig, cond: threading.Condition, stopping: Callable[[], bool], checkpoint: Callable[[], None]
    ) -> None:
        """`cond`: the service's, under which `stopping` turns true; `checkpoint`: the worker's."""
        self.config = config
        self.rig: Rig | None = None
        self._cond, self._stopping, self._checkpoint = cond, stopping, checkpoint
        self.cancel = threading.Event()  # set to cut the worker's waits for frames
        self.published = False  # the running job's folder is in place (the worker resets it per job)
        self.on_open: Callable[[Rig], None] | None = None  # the service's settings for a rig just opened

    def open(self) -> Rig:
        """The open rig, opened if need be; JobCancelledError once stopping (then no rig is taken
        on: the stopping thread may have let go of the last one already)."""
        rig = self.rig
        if rig is None:
            rig = open_rig(self.config)
            rig.checkpoint, rig.cancel = self._checkpoint, self.cancel  # long waits check, and are cut
            if self.on_open is not None:
                try:
                    self.on_open(rig)
                except BaseException:
                    rig.close()  # dark and closed: nothing half set up stays open
                    raise
            with self._cond:
                refused = self._stopping()
                if not refused:
                    self.rig = rig
            if refused:
                rig.close()
                raise JobCancelledError("the daemon is stopping")
        return rig

    def publish(self, rename: Callable[[], None]) -> None:
        """The worker's folders appear through here (rig.store.atomic.publishing_through);
        JobCancelledError once stopping: the job is then recorded interrupted without waiting for
        the worker, and its folder is never published."""
        with self._cond:
            if self._stopping():
                raise JobCancelledError("the daemon is stopping: the folder is not published")
            rename()
            self.published = True

    def darken(self) -> None:
        if self.rig is not None:
            self.rig.all_dark()

    def drop(self) -> None:
        """Closed (dark first): the next job opens a fresh one."""
        rig, self.rig = self.rig, None
        if rig is not None:
            with contextlib.suppress(Exception):
                rig.close()

    def let_go(self, worker: threading.Thread | None, timeout_s: float, wait: bool) -> bool:
        """Once stopping (the worker cancelled): give the worker STOP_GRACE_S to stop; if it is
        still busy, darken and close the projectors from here. Then wait for it up to `timeout_s` in
        all if `wait`, or if it has just published a folder (it is recording that job). Close the
        rig once it has stopped or the wait is over; a worker still computing without `wait` keeps
        its cameras until the process exits. Returns whether the worker has stopped."""
        deadline, stopped = time.monotonic() + timeout_s, False
        try:
            stopped = _joined(worker, min(STOP_GRACE_S, timeout_s))
            if not stopped:
                log.warning("the running job is in a step that cannot be interrupted: darkening the projectors here")
                with self._cond:
                    rig = self.rig
                lit = [] if rig is None else rig.shut_projectors(deadline - time.monotonic())
                _report(lit, "projectors dark (darkened and closed by the stopping thread)")
                if wait or self.published:
                    stopped = _joined(worker, deadline - time.monotonic())
                    if not stopped:
                        log.error("the running job did not stop within %.1f s; recording it interrupted", timeout_s)
        finally:
            if stopped or wait:
                rig, self.rig = self.rig, None
                lit = [] if rig is None else _closed(rig)
                _report(lit, "rig closed, projectors dark" if rig is not None else "no rig open: projectors dark")
        return stopped


def _joined(worker: threading.Thread | None, timeout_s: float) -> bool:
    if worker is None:
        return True
    worker.join(max(0.0, timeout_s))
    return not worker.is_alive()


def _closed(rig: Rig) -> list[str]:
    rig.close()  # dark first, then every device
    return rig.lit()


def _report(lit: list[str], dark: str) -> None:
    if lit:
        log.error("%s still lit after being darkened and closed", ", ".join(lit))
    else:
        log.info("%s", dark)
