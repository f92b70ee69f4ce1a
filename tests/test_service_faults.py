"""The job service when the disk or the rig fails it: every job ends in a recorded state, the
service says why it is degraded, refuses new work with 507, and nothing stored is lost. A full
disk is a real one (a small tmpfs) where the suite runs as root; a database that cannot be
written is injected (SQLite's query_only), since a full tmpfs need not fail a WAL write."""

from __future__ import annotations

import errno
import hashlib
import os
import shutil
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from rig.config import load_config
from rig.service.errors import StorageFullError
from rig.service.job_service import DB_NAME, JobService
from rig.service.jobs import JobState, JobStore, JobType
from rig.service.space import RESERVE_BYTES
from tests.conftest import small_config_data, wait_done, write_config
from tests.test_api import AUTH, _client


def _service(tmp_path: Path, data_dir: Path | None = None, **camera_faults: Any) -> JobService:
    data = small_config_data()
    data["output"] = {"data_dir": str(data_dir or tmp_path / "data")}
    if camera_faults:
        data["cameras"][0]["sim"]["faults"] = camera_faults
    config = load_config(write_config(tmp_path, data, "serve.yaml"))
    service = JobService(config)
    service.start()
    return service


def _folder_digest(folder: Path) -> dict[str, str]:
    files = sorted(p for p in folder.rglob("*") if p.is_file())
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest() for p in files}


def _refuse_writes(store: JobStore, refuse: bool) -> None:
    store._db.execute(f"PRAGMA query_only = {'ON' if refuse else 'OFF'}")


def test_a_store_that_cannot_write_keeps_states_in_memory_and_writes_them_later(tmp_path: Path) -> None:
    store = JobStore(tmp_path / DB_NAME)
    job = store.add("20261125-000000-aaaaaa", JobType.SCAN, {})
    store.transition(job.id, JobState.RUNNING)
    _refuse_writes(store, True)
    failed = store.transition(job.id, JobState.FAILED, error="cannot write scan: disk full")
    assert failed.state is JobState.FAILED and store.get(job.id).error == "cannot write scan: disk full"
    assert store.list(JobType.SCAN, None, 10, 0)[0][0].state is JobState.FAILED
    assert "cannot be written" in (store.unsaved or "")
    with pytest.raises(StorageFullError, match="cannot be written"):
        store.add("20261125-000000-bbbbbb", JobType.SCAN, {})
    with pytest.raises(StorageFullError):
        store.delete(job.id)
    assert not store.flush()
    _refuse_writes(store, False)
    assert store.flush() and store.unsaved is None
    store.close()
    again = JobStore(tmp_path / DB_NAME)  # what a restart reads: the state held in memory, written
    assert again.get(job.id).state is JobState.FAILED and again.get(job.id).error == "cannot write scan: disk full"
    again.close()


def test_held_states_decide_what_is_listed_and_what_a_stop_interrupts(tmp_path: Path) -> None:
    store = JobStore(tmp_path / DB_NAME)
    ended = store.add("20261125-000000-aaaaaa", JobType.SCAN, {}).id
    waiting = store.add("20261125-000001-bbbbbb", JobType.SCAN, {}).id
    store.transition(ended, JobState.RUNNING)
    _refuse_writes(store, True)
    store.transition(ended, JobState.DONE, result={"files": []})
    store.transition(waiting, JobState.RUNNING)  # the table still says queued
    assert [j.id for j in store.list(JobType.SCAN, JobState.DONE, 10, 0)[0]] == [ended]
    assert store.list(JobType.SCAN, JobState.QUEUED, 10, 0) == ([], 0)
    assert store.interrupt_unfinished("the daemon stopped") == [waiting]  # not the one that ended
    assert store.get(ended).state is JobState.DONE and store.get(ended).error is None
    _refuse_writes(store, False)
    assert store.flush()
    store.close()
    again = JobStore(tmp_path / DB_NAME)
    assert again.get(ended).state is JobState.DONE and again.get(waiting).state is JobState.INTERRUPTED
    again.close()


def test_a_refused_delete_leaves_a_queued_job_queued(tmp_path: Path) -> None:
    data = small_config_data()
    data["output"] = {"data_dir": str(tmp_path / "data")}
    service = JobService(load_config(write_config(tmp_path, data, "idle.yaml")))  # not started: jobs wait
    job = service.submit_scan({})
    _refuse_writes(service.store, True)
    with pytest.raises(StorageFullError):
        service.delete(job.id, JobType.SCAN)
    assert service.job(job.id).state is JobState.QUEUED and job.id in service._queue  # it will still run
    _refuse_writes(service.store, False)
    service.store.close()


def test_a_job_whose_database_write_fails_still_ends_and_the_service_says_so(tmp_path: Path) -> None:
    service = _service(tmp_path)
    try:
        with _client(service) as client:
            kept = wait_done(client, client.post("/v1/scans", json={}, headers=AUTH).json()["id"])
            ran = {"n": 0}
            progress = service.store.progress

            def refuse_mid_job(job_id: str, stage: str, fraction: float) -> None:
                ran["n"] += 1
                if ran["n"] == 3:  # the job is running: from here on the disk takes nothing
                    _refuse_writes(service.store, True)
                progress(job_id, stage, fraction)

            service.store.progress = refuse_mid_job  # type: ignore[method-assign]
            job_id = client.post("/v1/scans", json={}, headers=AUTH).json()["id"]
            job = wait_done(client, job_id, timeout_s=60)
            assert job["state"] == "done"  # its folder was written; only the record is held in memory
            events = client.get(f"/v1/scans/{job_id}/events").text  # it ends: the job did
            assert "event: state" in events and '"state": "done"' in events
            health = client.get("/v1/health").json()
            assert health["status"] == "degraded" and any("cannot be written" in p for p in health["problems"])
            refused = client.post("/v1/scans", json={}, headers=AUTH)
            assert refused.status_code == 507 and "cannot be written" in refused.json()["detail"]
            assert client.delete(f"/v1/scans/{kept['id']}", headers=AUTH).status_code == 507
            assert (service.scans_dir / kept["id"] / "cloud.ply").is_file()  # nothing deleted
            assert client.post(f"/v1/scans/{job_id}/cancel", headers=AUTH).json()["state"] == "done"
            _refuse_writes(service.store, False)
            deadline = time.monotonic() + 10  # the idle worker writes the held states
            while client.get("/v1/health").json()["status"] != "ok" and time.monotonic() < deadline:
                time.sleep(0.1)
            assert client.get("/v1/health").json() == {**health, "status": "ok", "problems": []}
    finally:
        service.shutdown(5.0)
    reread = JobStore(service.data_dir / DB_NAME)
    assert reread.get(job_id).state is JobState.DONE
    reread.close()


class _Disk:
    """A disk that can be filled: a real tmpfs (root only) or, elsewhere, an injected one whose
    free space reads low and whose scan writes fail with ENOSPC."""

    def __init__(self, folder: Path, monkeypatch: pytest.MonkeyPatch, real: bool) -> None:
        self.folder, self.monkeypatch, self.real = folder, monkeypatch, real
        self.ballast = folder / "ballast"

    def fill(self, leave_bytes: int) -> None:
        if self.real:
            with self.ballast.open("wb") as f:
                while shutil.disk_usage(self.folder).free > leave_bytes + (1 << 20):
                    f.write(b"\0" * (1 << 20))
                f.write(b"\0" * max(0, shutil.disk_usage(self.folder).free - leave_bytes))
            return
        usage = shutil.disk_usage(self.folder)
        full = type(usage)(usage.total, usage.total - leave_bytes, leave_bytes)
        self.monkeypatch.setattr("rig.service.space.shutil.disk_usage", lambda path: full)

        def no_space(path: object, data: bytes) -> None:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))

        self.monkeypatch.setattr("rig.store.scandir.write_atomic", no_space)

    def free(self) -> None:
        if self.real:
            self.ballast.unlink()
        else:
            self.monkeypatch.undo()


@pytest.fixture(params=["tmpfs", "injected"])
def disk(request: pytest.FixtureRequest, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[_Disk]:
    folder = tmp_path / "disk"
    folder.mkdir()
    if request.param == "injected":
        yield _Disk(folder, monkeypatch, real=False)
        return
    if os.geteuid() != 0:
        pytest.skip("a real full disk needs a tmpfs, which only root can mount (the injected one runs anyway)")
    size = f"size={RESERVE_BYTES // 1_000_000 + 40}m"
    if subprocess.run(["mount", "-t", "tmpfs", "-o", size, "tmpfs", str(folder)], check=False).returncode:
        pytest.skip("this machine does not let root mount a tmpfs (a container without CAP_SYS_ADMIN)")
    try:
        yield _Disk(folder, monkeypatch, real=True)
    finally:
        subprocess.run(["umount", "-l", str(folder)], check=False)


def test_a_full_disk_refuses_scans_with_507_and_fails_the_one_that_fills_it(tmp_path: Path, disk: _Disk) -> None:
    service = _service(tmp_path, disk.folder / "data")
    try:
        with _client(service) as client:
            stored = wait_done(client, client.post("/v1/scans", json={}, headers=AUTH).json()["id"])["id"]
            before = _folder_digest(service.scans_dir / stored)
            disk.fill(RESERVE_BYTES // 2)
            refused = client.post("/v1/scans", json={}, headers=AUTH)
            assert refused.status_code == 507 and "MB free" in refused.json()["detail"]
            health = client.get("/v1/health").json()
            assert health["status"] == "degraded" and any("MB free" in p for p in health["problems"])
            disk.free()
            progress = service.store.progress
            filled: list[str] = []

            def fill_at_store(job_id: str, stage: str, fraction: float) -> None:
                if stage == "store" and not filled:  # the scan is about to be written: fill the disk
                    disk.fill(0)
                    filled.append(job_id)
                progress(job_id, stage, fraction)

            service.store.progress = fill_at_store  # type: ignore[method-assign]
            job = wait_done(client, client.post("/v1/scans", json={}, headers=AUTH).json()["id"], timeout_s=60)
            assert filled and job["state"] == "failed" and "No space left on device" in job["error"]
            assert [p.name for p in service.scans_dir.iterdir()] == [stored]  # the half-written one is gone
            disk.free()
            service.store.progress = progress  # type: ignore[method-assign]
            again = wait_done(client, client.post("/v1/scans", json={}, headers=AUTH).json()["id"], timeout_s=60)
            assert again["state"] == "done" and client.get("/v1/health").json()["status"] == "ok"
            assert _folder_digest(service.scans_dir / stored) == before  # nothing stored changed
    finally:
        service.shutdown(5.0)


def test_a_stale_frame_fails_the_job_and_the_rig_reports_the_fault(tmp_path: Path) -> None:
    service = _service(tmp_path, repeat_frame_at=4)
    try:
        with _client(service) as client:
            job = wait_done(client, client.post("/v1/scans", json={}, headers=AUTH).json()["id"])
            assert job["state"] == "failed" and "stale frame" in job["error"]
            rig = client.get("/v1/rig").json()
            assert rig["state"] == "fault" and "stale frame" in rig["last_error"]
    finally:
        service.shutdown(5.0)


KILLER = """
import os, signal, sys
import rig.service.recovery as recovery
from rig.config import load_config
from rig.service.job_service import JobService

service = JobService(load_config(sys.argv[1]))
service.start()
def die(*args, **kwargs):
    os.kill(os.getpid(), signal.SIGKILL)
if sys.argv[3] == "with_the_record":
    service.store.delete = die  # the folder is out of sight, the record still there
else:
    recovery.shutil.rmtree = die  # the record is gone, the folder not yet
service.delete(sys.argv[2], "scan")
"""


@pytest.mark.parametrize("killed", ["with_the_record", "with_the_folder"])
def test_a_delete_killed_midway_is_finished_by_the_next_start(tmp_path: Path, killed: str) -> None:
    service = _service(tmp_path)
    with _client(service) as client:
        job_id = wait_done(client, client.post("/v1/scans", json={}, headers=AUTH).json()["id"])["id"]
    service.shutdown(5.0)
    root = Path(__file__).resolve().parents[1]
    env = {**os.environ, "PYTHONPATH": str(root)}
    run = subprocess.run(
        ["python", "-c", KILLER, str(tmp_path / "serve.yaml"), job_id, killed], env=env, cwd=root, timeout=120
    )
    assert run.returncode == -9  # killed where asked, not failed before
    assert not (service.scans_dir / job_id).exists() and list(service.scans_dir.glob(".*.deleting"))
    restarted = _service(tmp_path)
    try:
        with _client(restarted) as client:
            assert client.get(f"/v1/scans/{job_id}").status_code == 404
        assert not list(restarted.scans_dir.iterdir())  # no hidden folder left to fill the disk
    finally:
        restarted.shutdown(5.0)


def test_start_removes_half_written_folders_and_keeps_scans_it_has_no_record_of(tmp_path: Path) -> None:
    service = _service(tmp_path)
    with _client(service) as client:
        kept = wait_done(client, client.post("/v1/scans", json={}, headers=AUTH).json()["id"])["id"]
    service.shutdown(5.0)
    by_cli = service.scans_dir / "20260101-000000-abcdef"  # `slrig scan` writes here with no record
    shutil.copytree(service.scans_dir / kept, by_cli)
    (service.scans_dir / "20260101-000001-abcdef.partial").mkdir()
    (service.calibrations_dir / "20260101-000002-abcdef.partial").mkdir(parents=True)
    restarted = _service(tmp_path)
    restarted.shutdown(5.0)
    assert sorted(p.name for p in restarted.scans_dir.iterdir()) == sorted([kept, by_cli.name])
    assert not list(restarted.calibrations_dir.iterdir())


STORE_KILLER = """
import json, os, signal, sys, time
import rig.store.atomic as atomic
from rig.config import load_config
from rig.service.jobs import JobType
from rig.service.job_service import JobService

original, calls = atomic.write_atomic, []
def dying(*args, **kwargs):
    calls.append(args[0])
    if len(calls) == 2:  # the first file is written, the second is being written
        os.kill(os.getpid(), signal.SIGKILL)
    return original(*args, **kwargs)
for module in list(sys.modules.values()):
    if getattr(module, "write_atomic", None) is original:
        module.write_atomic = dying
service = JobService(load_config(sys.argv[1]))
service.start()
operation, argument = sys.argv[2], sys.argv[3]
if operation == "scan":
    job = service.submit_scan({"keep_frames": True})
elif operation == "reprocess":
    job = service.submit_reprocess(argument, {})
else:
    job = service.submit(JobType.CALIBRATION, {"what": "camera", "views": 3})
print(job.id, flush=True)
time.sleep(120)  # killed long before
"""


@pytest.mark.parametrize("operation", ["scan", "reprocess", "calibration"])
def test_sigkill_while_a_job_stores_loses_nothing_and_leaves_nothing(tmp_path: Path, operation: str) -> None:
    service = _service(tmp_path)
    with _client(service) as client:
        kept = wait_done(client, client.post("/v1/scans", json={"keep_frames": True}, headers=AUTH).json()["id"])["id"]
    service.shutdown(5.0)
    before = _folder_digest(service.scans_dir / kept)
    root = Path(__file__).resolve().parents[1]
    run = subprocess.run(
        ["python", "-c", STORE_KILLER, str(tmp_path / "serve.yaml"), operation, kept],
        env={**os.environ, "PYTHONPATH": str(root)},
        cwd=root,
        capture_output=True,
        text=True,
        timeout=180,
    )
    assert run.returncode == -9, run.stderr[-2000:]  # killed while it wrote, not failed before
    job_id = run.stdout.split()[0]
    restarted = _service(tmp_path)
    try:
        kind = JobType.CALIBRATION if operation == "calibration" else JobType.SCAN
        job = restarted.job(job_id, kind)
        assert job.state is JobState.INTERRUPTED
        assert not (restarted.job_folder(job)).exists()  # nothing half-written under the job's name
        leftovers = [p.name for p in (*restarted.scans_dir.iterdir(), *restarted.calibrations_dir.glob("*"))]
        assert leftovers == [kept]
        assert _folder_digest(restarted.scans_dir / kept) == before  # the stored scan untouched
    finally:
        restarted.shutdown(5.0)


@pytest.mark.parametrize(
    ("own", "files", "room"),
    [
        (
            "0::/system.slice/slrig.service\n",
            {"system.slice/slrig.service/memory.max": "8000", "system.slice/slrig.service/memory.current": "3000"},
            5000,
        ),
        ("0::/\n", {"memory.max": "max", "memory.current": "3000"}, None),
        (
            "4:memory:/lab\n0::/\n",
            {"memory/lab/memory.limit_in_bytes": "9000", "memory/lab/memory.usage_in_bytes": "1000"},
            8000,
        ),
        (
            "4:memory:/\n",
            {"memory/memory.limit_in_bytes": "9223372036854771712", "memory/memory.usage_in_bytes": "1"},
            None,
        ),
    ],
)
def test_a_container_memory_limit_is_what_a_rig_must_fit(
    tmp_path: Path, own: str, files: dict[str, str], room: int | None
) -> None:
    from rig.assembly.memory import _cgroup_room

    for name, text in files.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text)
    (tmp_path / "own").write_text(own)
    assert _cgroup_room(str(tmp_path), str(tmp_path / "own")) == room
