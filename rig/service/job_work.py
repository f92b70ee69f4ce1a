"""What each kind of job does on the job service's worker (rig.service.tasks does the work): a mixin
of rig.service.job_service.JobService, which picks the handler and records how the job ended."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from rig.config import RigConfig
from rig.progress import ProgressCallback, ProgressEvent
from rig.service import tasks
from rig.service.calibrating import calibration_to_directory
from rig.service.errors import JobConflictError
from rig.service.jobs import Job, JobState, JobType
from rig.service.remote import RemoteJobs
from rig.service.space import check_free_space, expected_scan_bytes
from rig.service.stopping import WorkerRig


class JobWork:
    """The handlers; JobService provides what they read."""

    config: RigConfig
    data_dir: Path
    scans_dir: Path
    calibrations_dir: Path
    _rigs: WorkerRig
    _remote: RemoteJobs | None
    job: Callable[..., Job]
    job_folder: Callable[[Job], Path]
    _finish: Callable[..., None]

    def _scan(self, job: Job, progress: ProgressCallback) -> dict[str, Any]:
        check_free_space(self.data_dir, expected_scan_bytes(self.config, job.request), "this scan")
        target = self.scans_dir / job.id
        path, result = tasks.scan_job_to_directory(self._rigs.open(), target, job.id, job.request, progress)
        return tasks.scan_summary(path, result)

    def _reprocess(self, job: Job, progress: ProgressCallback) -> dict[str, Any] | None:
        """A reprocessing, here or handed to the cluster (compute.scheduler: None, the worker goes on
        to the next job, and the cluster's end is recorded by _remote_ended)."""
        if self._remote is None:
            return tasks.reprocess_job(*self._reprocessing(job), progress=progress)
        self._remote.submit(job.id, tasks.reprocess_job, *self._reprocessing(job))
        progress(ProgressEvent("on the cluster", 0.0, 0.0, None, self._remote.address))
        return None

    def _reprocessing(self, job: Job) -> tuple[Path, Path, str, Path | None, dict[str, Any], dict[str, Any]]:
        """What tasks.reprocess_job takes for a reprocessing job: source, target, id, calibration
        folder, overrides and origin."""
        request = job.request
        source = self.job(request["source"], JobType.SCAN)  # JobNotFoundError if deleted since
        calibration = self.job(request["calibration"], JobType.CALIBRATION) if request.get("calibration") else None
        overrides = {"max_depth_jump_mm": request["max_depth_jump_mm"]} if "max_depth_jump_mm" in request else {}
        folder = None if calibration is None else self.job_folder(calibration)
        origin = {"reprocessed_from": source.id, "calibration": request.get("calibration")}
        return self.scans_dir / source.id, self.scans_dir / job.id, job.id, folder, overrides, origin

    def _remote_ended(self, job_id: str, result: dict[str, Any] | None, error: str | None) -> None:
        if error is not None:
            self._finish(job_id, JobState.FAILED, error=error)
        else:
            self._finish(job_id, JobState.DONE, result=result, stage="done", fraction=1.0)

    def _reconstruct(self, job: Job, progress: ProgressCallback) -> dict[str, Any]:
        inputs = (self.data_dir, self._calibration_folder, job.request["reconstruct"], self.scans_dir / job.id)
        return tasks.reconstruction_to_directory(*inputs, job.id, self.config, progress)

    def _calibration_folder(self, calibration_id: str) -> Path:
        calibration = self.job(calibration_id, JobType.CALIBRATION)
        if calibration.state is not JobState.DONE or calibration.request.get("what") == "response":
            raise JobConflictError(f"calibration {calibration_id} is not a finished geometric calibration")
        return self.job_folder(calibration)

    def _calibration(self, job: Job, progress: ProgressCallback) -> dict[str, Any]:
        out = self.calibrations_dir / job.id
        try:
            return calibration_to_directory(self._rigs.open, self.config, self.data_dir, job.request, out, progress)
        finally:
            if "images" not in job.request:
                self._rigs.drop()  # the simulated bench showed boards: a fresh rig for the next job
