"""Stopping: SIGTERM to `slrig serve` while a scan captures or stores, or while a camera has stalled,
ends the process with the projectors dark and the job recorded interrupted, and no folder appears for
it; the service in process: a cancel cuts a stalled camera's wait, a worker in a step that cannot be
interrupted is not waited for, and a projector shut from another thread stays dark. Asserted by
mechanism, never by a tight clock (the suite runs on loaded machines): the stop waits out neither the
camera's capture timeout nor the shutdown timeout. bench/stop_time.py measures the seconds."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from drivers.base import Projector
from drivers.errors import DeviceCancelledError, DeviceStateError
from rig.assembly import open_rig
from rig.config import load_config
from rig.evaluate.merged import measure_on_bench
from rig.service import tasks
from rig.service.job_service import DB_NAME, JobService
from rig.service.jobs import JobState, JobStore, JobType
from tests.conftest import default_config_data, small_config_data, write_config
from tests.loopback import daemon_http
from tests.ports import free_port
from tests.test_daemon import AUTH, KEY, REPO, Daemon, _config

STUCK_S = 60.0  # the stalled camera's capture timeout: a stop must not wait it out
SHUTDOWN_S = 10.0  # service.shutdown_timeout_s (its largest): nor this


def _stalled_data() -> dict[str, Any]:
    data = small_config_data()
    data["cameras"][0]["sim"]["faults"] = {"stall_after_frames": 2}
    data["scan"]["capture_timeout_s"] = STUCK_S
    return data


def _reach(url: str, job_id: str, stages: tuple[str, ...]) -> None:
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        job = daemon_http.get(f"{url}/v1/scans/{job_id}").json()
        assert job["state"] in ("queued", "running"), job
        if job["state"] == "running" and job["stage"] in stages and job["fraction"] > 0:
            return
        time.sleep(0.005)
    raise AssertionError(f"the scan never reached {stages}")


def _sigterm(daemon: Daemon) -> tuple[int, float, str]:
    """Exit code, seconds to exit, and what the daemon logged from the signal on."""
    offset = daemon.log.stat().st_size
    start = time.monotonic()
    daemon.process.send_signal(signal.SIGTERM)
    code = daemon.process.wait(STUCK_S)
    elapsed = time.monotonic() - start
    with daemon.log.open("rb") as f:
        f.seek(offset)
        return code, elapsed, f.read().decode(errors="replace")


def _assert_stopped_dark(tmp_path: Path, job_id: str, code: int, elapsed: float, log: str) -> None:
    assert code == 0
    assert elapsed < SHUTDOWN_S  # nothing was waited out (a stop takes well under a second when idle)
    assert "projectors dark" in log and "still lit" not in log
    assert JobStore(tmp_path / "data" / DB_NAME).get(job_id).state == JobState.INTERRUPTED
    assert not (tmp_path / "data" / "scans" / job_id).exists()  # never a finished-looking folder


def test_sigterm_cuts_a_stalled_cameras_wait(tmp_path: Path) -> None:
    config = _config(tmp_path, _stalled_data(), shutdown_timeout_s=SHUTDOWN_S)
    daemon = Daemon(config, tmp_path / "daemon.log")
    try:
        job_id = daemon_http.post(f"{daemon.url}/v1/scans", json={}, headers=AUTH).json()["id"]
        _reach(daemon.url, job_id, ("capture",))
        time.sleep(1.0)  # past its second frame: the worker waits in the camera's driver
        code, elapsed, log = _sigterm(daemon)
    finally:
        daemon.stop()
    _assert_stopped_dark(tmp_path, job_id, code, elapsed, log)
    assert "the daemon stopped" in (JobStore(tmp_path / "data" / DB_NAME).get(job_id).error or "")


@pytest.mark.parametrize("stages", [("capture",), ("store",)], ids=["capturing", "storing"])
def test_sigterm_during_a_scan_ends_dark_and_interrupted(tmp_path: Path, stages: tuple[str, ...]) -> None:
    config = _config(tmp_path, default_config_data(), shutdown_timeout_s=SHUTDOWN_S)  # seconds of capture
    daemon = Daemon(config, tmp_path / "daemon.log")
    try:
        job_id = daemon_http.post(f"{daemon.url}/v1/scans", json={}, headers=AUTH).json()["id"]
        _reach(daemon.url, job_id, stages)
        code, elapsed, log = _sigterm(daemon)
    finally:
        daemon.stop()
    _assert_stopped_dark(tmp_path, job_id, code, elapsed, log)


def test_a_cancel_cuts_a_stalled_cameras_wait(tmp_path: Path) -> None:
    config = load_config(write_config(tmp_path, {**_stalled_data(), "output": {"data_dir": str(tmp_path)}}))
    with open_rig(config) as rig:
        camera, cancel = rig.cameras[0], threading.Event()
        for _ in range(2):
            camera.capture(timeout_s=5.0)
        raised: list[BaseException] = []

        def capture() -> None:
            try:
                camera.capture(timeout_s=STUCK_S, cancel=cancel)
            except BaseException as exc:
                raised.append(exc)

        waiting = threading.Thread(target=capture)
        waiting.start()
        cancel.set()
        waiting.join(STUCK_S / 2)
        assert not waiting.is_alive() and isinstance(raised[0], DeviceCancelledError)
        with pytest.raises(DeviceCancelledError):  # already set: the capture does not begin
            camera.capture(timeout_s=STUCK_S, cancel=cancel)


def test_a_stalled_scan_is_cancelled_before_its_capture_timeout(tmp_path: Path) -> None:
    data = {**_stalled_data(), "output": {"data_dir": str(tmp_path / "data")}}
    service = JobService(load_config(write_config(tmp_path, data)))
    service.start()
    try:
        job_id = service.submit_scan({}).id
        deadline = time.monotonic() + STUCK_S / 2
        while service.job(job_id).fraction == 0 and time.monotonic() < deadline:
            time.sleep(0.01)
        service.cancel(job_id, JobType.SCAN)
        while service.job(job_id).state is JobState.RUNNING and time.monotonic() < deadline:
            time.sleep(0.01)
        assert service.job(job_id).state is JobState.CANCELLED  # the wait was cut, not timed out
        assert all(p.is_dark for p in service.open_rig.projectors)  # type: ignore[union-attr, attr-defined]
    finally:
        service.shutdown(5.0)


def test_a_worker_that_cannot_be_interrupted_is_not_waited_for(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A step with no checkpoint (here: the accuracy measured before a scan is stored) holds the
    worker: shutdown darkens and closes the projectors itself, records the job interrupted and
    returns; when the step ends, its folder is refused and removed."""
    computing, release = threading.Event(), threading.Event()

    def long_step(*args: Any) -> tuple[dict[str, object], Any]:
        computing.set()
        release.wait(STUCK_S)
        return measure_on_bench(*args)

    monkeypatch.setattr(tasks, "measure_on_bench", long_step)
    data = {**small_config_data(), "output": {"data_dir": str(tmp_path / "data")}}
    service = JobService(load_config(write_config(tmp_path, data)))
    service.start()
    job_id = service.submit_scan({}).id
    assert computing.wait(STUCK_S)
    rig = service.open_rig
    assert rig is not None
    service.shutdown(SHUTDOWN_S, wait_for_worker=False)
    try:
        assert not release.is_set()  # returned with the worker still inside the step
        assert all(not p.is_open and p.is_dark for p in rig.projectors)  # type: ignore[attr-defined]
        assert service.job(job_id).state is JobState.INTERRUPTED
    finally:
        release.set()
        assert service._worker is not None
        service._worker.join(STUCK_S)
    assert not service._worker.is_alive()
    scans = tmp_path / "data" / "scans"
    assert not (scans / job_id).exists() and not (scans / f"{job_id}.partial").exists()
    assert service.job(job_id).state is JobState.INTERRUPTED
    rig.close()
    assert service._lock_file is not None  # kept (a process exits next): released here by hand
    service._lock_file.close()


class _Wedged(Projector):
    """A projector whose show() hangs until released, as a driver whose transport stopped answering."""

    def __init__(self) -> None:
        super().__init__("wedged")
        self.showing, self.release, self.lit = threading.Event(), threading.Event(), False

    @property
    def resolution(self) -> tuple[int, int]:
        return 4, 2

    def _do_open(self) -> None:
        self.lit = False

    def _do_show(self, pattern: np.ndarray) -> None:
        self.showing.set()
        self.release.wait(STUCK_S)
        self.lit = True

    def _do_dark(self) -> None:
        self.lit = False


def test_a_projector_shut_from_another_thread_stays_dark() -> None:
    projector = _Wedged()
    projector.open()
    assert projector.shut(SHUTDOWN_S)  # nothing in flight: taken at once
    with pytest.raises(DeviceStateError):  # closed: no pattern lights it again
        projector.show(np.zeros((2, 4), np.uint8))

    projector = _Wedged()
    projector.open()
    hung = threading.Thread(target=projector.show, args=(np.full((2, 4), 255, np.uint8),))
    hung.start()
    assert projector.showing.wait(STUCK_S)
    assert not projector.shut(0.05)  # the call in flight never ends: darkened and closed regardless
    assert not projector.lit and not projector.is_open
    projector.release.set()
    hung.join(STUCK_S)
    assert not hung.is_alive() and not projector.lit  # the late pattern was darkened by its own call


def test_a_stop_in_the_moment_the_daemon_starts_listening_is_a_stop_not_a_failure(tmp_path: Path) -> None:
    """SIGTERM as soon as the port takes connections (uvicorn still starting, or just started):
    exit 0 and no traceback, as for any stop (it was exit 1, "could not serve", or an IndexError)."""
    config = _config(tmp_path, small_config_data())
    for attempt, delay in enumerate((0.0, 0.005, 0.01, 0.02, 0.04)):
        port = free_port()
        log = tmp_path / f"early-{attempt}.log"
        with log.open("wb") as err:
            process = subprocess.Popen(
                [sys.executable, "-m", "rig.cli", "serve", "--config", str(config), "--port", str(port)],
                cwd=REPO,
                env={**os.environ, "SLRIG_API_KEY": KEY},
                stdout=subprocess.DEVNULL,
                stderr=err,
            )
        deadline = time.monotonic() + 60
        while process.poll() is None and time.monotonic() < deadline:
            try:
                socket.create_connection(("127.0.0.1", port), timeout=1).close()
                break
            except OSError:
                time.sleep(0.002)
        time.sleep(delay)
        process.send_signal(signal.SIGTERM)
        assert process.wait(30) == 0, log.read_text()
        assert "Traceback" not in log.read_text() and "could not serve" not in log.read_text()
