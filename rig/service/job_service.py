"""The job service: one worker thread runs queued jobs on the rig one at a time.

Scans, reprocessing of stored scans and calibrations share the queue, because they share the rig.
The rig stays open between jobs (opening cameras takes seconds) and is closed after a job that
failed or replaced the simulated scene, so the next job starts from a known state. Every job
ends in a terminal state that names what happened; none is re-run by itself.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import Any, TextIO

from drivers.errors import DeviceError
from rig.config import RigConfig
from rig.errors import CaptureFaultError, ConfigError, PlanError, SlrigError
from rig.opened_rig import Rig
from rig.progress import ProgressCallback
from rig.service.adaptive import check_scan_request
from rig.service.aim import AimMode
from rig.service.calibrating import calibration_settings, captured_views
from rig.service.camera_settings import CameraSettings
from rig.service.errors import (
    JobCancelledError,
    JobConflictError,
    JobNotFoundError,
    QueueFullError,
    ServiceStoppingError,
)
from rig.service.events import EventHub, progress_reporter
from rig.service.frames import FrameTap
from rig.service.idle import IdleWork
from rig.service.imports import reconstruction_inputs, remove_leftovers
from rig.service.job_work import JobWork
from rig.service.jobs import DB_NAME, Job, JobState, JobStore, JobType
from rig.service.live import LiveMode
from rig.service.recovery import clear_leftovers, discard, hide_folder, lock_data_dir
from rig.service.remote import RemoteJobs
from rig.service.space import check_free_space, expected_scan_bytes, storage_problems
from rig.service.status import device_views, result_file
from rig.service.stopping import WorkerRig
from rig.service.worker_calls import WorkerCalls
from rig.store import new_scan_id, publishing_through
from rig.workers import release_free_memory

log = logging.getLogger(__name__)


class JobService(JobWork):
    """Owns the job store, the queue, the worker thread and the open rig."""

    def __init__(self, config: RigConfig, max_queue: int = 8, health_stale_s: float = 120.0) -> None:
        self.config = config
        self.data_dir = config.output.data_dir
        self.scans_dir = self.data_dir / "scans"
        self.calibrations_dir = self.data_dir / "calibrations"
        self.max_queue = max_queue
        self.health_stale_s = health_stale_s
        self.store = JobStore(self.data_dir / DB_NAME)
        self.events = EventHub()
        self._cond = threading.Condition()
        self.live = LiveMode(config, self._cond)
        self.aim = AimMode(config, self._cond)
        self.frames = FrameTap()
        self.calls = WorkerCalls(self._cond)
        self.camera_settings = CameraSettings(config, self.calls)
        self._queue: deque[str] = deque()
        self._current: str | None = None
        self._stopping = False
        self._rigs = WorkerRig(config, self._cond, lambda: self._stopping, self._checkpoint)
        self._cancel = self._rigs.cancel
        scheduler = config.compute.scheduler
        self._remote = RemoteJobs(scheduler, self._remote_ended) if scheduler else None
        waiting = lambda: bool(self._queue) or self._stopping  # noqa: E731 - a job waits: live and aim mode pause
        pieces = (self._rigs, self.live, self.aim, self.camera_settings, self.calls)
        self._idle = IdleWork(*pieces, self._checkpoint, waiting, self._fault)
        self._rigs.on_open = lambda rig: self._idle.prepare(rig, self.frames.publish)
        self._shutdown_lock = threading.Lock()
        self._shut_down = False
        self._rig_error: str | None = None
        self._heartbeat = time.monotonic()
        self._worker: threading.Thread | None = None
        self._lock_file: TextIO | None = None

    # --- lifecycle -------------------------------------------------------------------------
    def start(self) -> None:
        """Take the data directory, recover from a previous run, then start the worker."""
        self._lock_file = lock_data_dir(self.data_dir)
        clear_leftovers(self.store, (self.scans_dir, self.calibrations_dir))  # first: frees what a crash filled
        remove_leftovers(self.data_dir)
        for job_id in self.store.interrupt_unfinished("the daemon stopped before this job finished; not re-run"):
            self._publish_state(job_id)
        self._worker = threading.Thread(target=self._work, name="slrig-jobs", daemon=True)
        self._worker.start()

    @property
    def stopping(self) -> bool:
        return self._stopping

    def begin_stop(self) -> None:
        """Accept no more jobs and cancel the running one (its projectors go dark)."""
        with self._cond:
            self._stopping = True
            self.live.interrupted("the daemon is stopping")
            self.aim.interrupted("the daemon is stopping")
            self._cancel.set()
            self._cond.notify_all()

    def shutdown(self, timeout_s: float = 8.0, wait_for_worker: bool = True) -> None:
        """Stop: the running job is cancelled and recorded interrupted, queued ones too; projectors
        dark first. A worker still busy after a grace is in a step that cannot be interrupted: its
        projectors are darkened and closed from here. Then it is waited for up to `timeout_s` in all;
        without `wait_for_worker` (the process exits next) only to record a job whose folder it has
        just published (rig.service.stopping). Idempotent."""
        with self._shutdown_lock:
            if self._shut_down:
                return
            self._shut_down = True
            self.begin_stop()
            stopped = self._rigs.let_go(self._worker, timeout_s, wait_for_worker)  # dark first, before bookkeeping
            if self._remote is not None:
                self._remote.close()  # its running jobs: interrupted with the rest
            self.store.interrupt_unfinished("the daemon stopped before this job finished")
            if self.store.unsaved:  # the next start marks them interrupted
                log.error("job states not written at shutdown: %s", self.store.unsaved)
            if self._lock_file is not None and (stopped or wait_for_worker):  # else released at exit
                self._lock_file.close()  # and with it the lock on the data directory
                self._lock_file = None

    def healthy(self) -> bool:
        """The worker is alive and, when running a job, has reported progress recently."""
        if self._worker is None or not self._worker.is_alive():
            return False
        return self._current is None or time.monotonic() - self._heartbeat < self.health_stale_s

    def problems(self) -> list[str]:
        """What makes the service degraded: a stalled worker, job states the disk will not take."""
        found = [] if self.healthy() else ["the job worker is not running or has stalled"]
        return found + storage_problems(self.data_dir, self.store)

    # --- requests --------------------------------------------------------------------------
    def submit(self, kind: JobType, request: dict[str, Any]) -> Job:
        """Queue a job; QueueFullError past max_queue, ServiceStoppingError while stopping."""
        with self._cond:
            if self._stopping:
                raise ServiceStoppingError("the daemon is shutting down")
            if len(self._queue) >= self.max_queue:
                raise QueueFullError(f"the queue holds {self.max_queue} jobs already; try again later")
            job = self.store.add(new_scan_id(), kind, request)
            self._queue.append(job.id)
            self._cond.notify_all()
        self._publish_state(job.id)
        return job

    def submit_scan(self, request: dict[str, Any]) -> Job:
        try:
            check_scan_request(self.config, request)
        except PlanError as exc:
            raise JobConflictError(str(exc)) from None
        if request.get("codec"):
            try:
                self.config.with_codec(request["codec"])
            except ConfigError as exc:  # a known codec whose parameters do not fit this rig
                raise JobConflictError(
                    f"codec {request['codec']} does not fit this rig: {'; '.join(exc.problems)}"
                ) from None
        check_free_space(self.data_dir, expected_scan_bytes(self.config, request), "a scan of this rig")
        return self.submit(JobType.SCAN, request)

    def submit_reprocess(self, source_id: str, request: dict[str, Any]) -> Job:
        source = self.job(source_id, JobType.SCAN)
        if source.state is not JobState.DONE:
            raise JobConflictError(f"scan {source_id} is {source.state}; only a finished scan can be reprocessed")
        if not (self.scans_dir / source_id / "frames").is_dir():
            raise JobConflictError(f"scan {source_id} kept no frames; scan with keep_frames: true to reprocess")
        if request.get("calibration"):
            self._calibration_folder(request["calibration"])
        return self.submit(JobType.SCAN, {**request, "source": source_id})

    def submit_reconstruction(self, request: dict[str, Any]) -> Job:
        """Queue a reconstruction of uploaded frames; refused inputs are answered now, never queued."""
        reconstruction_inputs(self.data_dir, self._calibration_folder, request)
        return self.submit(JobType.SCAN, {"reconstruct": request})

    def submit_calibration(self, request: dict[str, Any]) -> Job:
        """Queue a calibration; a board, model or captures that are refused are answered now."""
        calibration_settings(self.config, request)
        if "images" in request:
            captured_views(self.data_dir, request)
        return self.submit(JobType.CALIBRATION, request)

    def job(self, job_id: str, kind: JobType | None = None) -> Job:
        job = self.store.get(job_id)
        if kind is not None and job.kind != kind:
            raise JobNotFoundError(f"no {kind} {job_id}")
        return job

    def cancel(self, job_id: str, kind: JobType) -> Job:
        self.job(job_id, kind)  # it exists and is of this kind
        if self._remote is not None:
            self._remote.refuse_cancel(job_id)
        with self._cond:
            if job_id in self._queue:
                self._queue.remove(job_id)
                self.store.transition(job_id, JobState.CANCELLED, error="cancelled before it ran")
                self._publish_state(job_id)
            elif self._current == job_id:
                self._cancel.set()  # the worker records it when the job stops
        return self.store.get(job_id)

    def delete(self, job_id: str, kind: JobType) -> None:
        """Delete a job not running: folder hidden and record gone under the lock, contents after."""
        self.job(job_id, kind)
        with self._cond:
            if self._current == job_id or (self._remote is not None and self._remote.running(job_id)):
                raise JobConflictError(f"{kind} {job_id} is running; cancel it first")
            doomed = hide_folder(self.job_folder(Job.placeholder(job_id, kind)), lambda: self.store.delete(job_id))
            if job_id in self._queue:  # only once the record is gone (StorageFullError: still queued)
                self._queue.remove(job_id)
        discard(doomed)

    def job_folder(self, job: Job) -> Path:
        return (self.calibrations_dir if job.kind is JobType.CALIBRATION else self.scans_dir) / job.id

    def file_path(self, job_id: str, kind: JobType, name: str) -> Path:
        """A result file of a finished job, by a name its result lists (never a path)."""
        job = self.job(job_id, kind)
        return result_file(job, self.job_folder(job), name)

    def rig_status(self) -> dict[str, Any]:
        with self._cond:
            queued, current = len(self._queue), self._current
        live, aim = self.live.view()["state"] == "running", self.aim.view()["state"] == "running"
        state = "busy" if current else "live" if live else "aim" if aim else ("fault" if self._rig_error else "idle")
        return {
            "name": self.config.name,
            "simulated": self.config.simulated,
            "state": state,
            "running": current,
            "last_error": self._rig_error,
            "queue": {"queued": queued, "max": self.max_queue},
            "devices": device_views(self.config, self.open_rig),
        }

    # --- the worker ------------------------------------------------------------------------
    def _work(self) -> None:
        while True:
            with self._cond:
                self._cond.wait_for(lambda: self._stopping or bool(self._queue) or self._idle.wanted(), timeout=1.0)
                self._heartbeat = time.monotonic()
                if self._stopping:
                    return
                job_id = self._queue.popleft() if self._queue else None
                self._current, self._rigs.published = job_id, False
                self._cancel.clear()
            if job_id is None:  # no job waits: settings, live or aim mode if wanted; what the disk refused
                if self.store.unsaved:
                    self.store.flush()
                self._idle.run()
                continue
            try:
                self._run(job_id)
            except Exception:  # the worker must outlive any job
                log.exception("job %s: unexpected error in the worker", job_id)
            finally:
                with self._cond:
                    self._current = None
            release_free_memory()  # an idle daemon holds no job's freed arrays (after: the rig reads idle)

    def _run(self, job_id: str) -> None:
        try:
            job = self.store.transition(job_id, JobState.RUNNING, stage="start", fraction=0.0)
        except SlrigError as exc:  # deleted or cancelled between the queue and here
            log.info("job %s not started: %s", job_id, exc)
            return
        self._publish_state(job_id)
        reprocess = any(k in job.request for k in ("source", "reconstruct", "images"))  # files only: no devices
        handler: Callable[[Job, ProgressCallback], dict[str, Any] | None]
        if job.kind is JobType.CALIBRATION:
            handler = self._calibration
        elif "reconstruct" in job.request:
            handler = self._reconstruct
        elif reprocess:
            handler = self._reprocess
        else:
            handler = self._scan
        try:
            with publishing_through(self._rigs.publish):  # no folder appears once stopping
                result = handler(job, progress_reporter(job_id, self.store, self.events, self._checkpoint))
        except JobCancelledError:
            self._rigs.darken()
            state = JobState.INTERRUPTED if self._stopping else JobState.CANCELLED
            reason = "the daemon stopped during the job" if self._stopping else "cancelled while running"
            self._finish(job_id, state, error=reason)
        except (SlrigError, DeviceError) as exc:
            if self._stopping:  # its projectors were taken from it (shutdown): the stop, not a fault
                self._rigs.darken()
                self._finish(job_id, JobState.INTERRUPTED, error=f"the daemon stopped during the job ({exc})")
                return
            if isinstance(exc, (DeviceError, CaptureFaultError)) or isinstance(exc.__cause__, DeviceError):
                self._rig_error = str(exc)  # reported by /v1/rig until a job succeeds
            if not reprocess:
                self._rigs.drop()
            self._finish(job_id, JobState.FAILED, error=str(exc))
        except Exception as exc:
            log.exception("%s %s: internal error", job.kind, job_id)
            if not reprocess:
                self._rigs.drop()
            self._finish(job_id, JobState.FAILED, error=f"internal error: {type(exc).__name__}: {exc}")
        else:
            if not reprocess:
                self._rig_error = None
            if result is not None:  # None: handed to the cluster, which records it (_remote_ended)
                self._finish(job_id, JobState.DONE, result=result, stage="done", fraction=1.0)

    def _finish(self, job_id: str, state: JobState, **fields: Any) -> None:
        with self._cond:  # the rig reads idle (or its fault) by the time anyone sees the job ended
            if self._current == job_id:
                self._current = None
        try:
            self.store.transition(job_id, state, **fields)
        except SlrigError as exc:  # shutdown() recorded it interrupted meanwhile
            log.warning("%s", exc)
        except Exception:  # a database that cannot even be read: the worker goes on regardless
            log.exception("job %s: its end (%s) could not be recorded", job_id, state)
        self._publish_state(job_id)

    def _checkpoint(self) -> None:
        """Between steps of a job: alive, and stop here if cancelled."""
        self._heartbeat = time.monotonic()
        if self._cancel.is_set():
            raise JobCancelledError("cancelled")

    def _publish_state(self, job_id: str) -> None:
        try:
            job = self.store.get(job_id)
        except JobNotFoundError:
            self.events.publish(job_id, "state", {"id": job_id, "state": "deleted", "error": None})
            return
        except Exception:  # unreadable: streams find the state by polling once it can be read
            log.exception("job %s: its state could not be read to publish", job_id)
            return
        self.events.publish(job_id, "state", {"id": job.id, "state": job.state, "error": job.error})

    def _fault(self, reason: str) -> None:
        self._rig_error = reason

    @property
    def open_rig(self) -> Rig | None:  # read-only use: only the worker drives it
        return self._rigs.rig

    @property
    def busy_with(self) -> str | None:  # the job running, or the next queued: device calls wait for neither
        with self._cond:
            return self._current or (self._queue[0] if self._queue else None)
