"""`slrig batch reprocess` on a local Dask cluster of two processes (rig.batch): an archive of small
scans reprocessed as `slrig reconstruct` reprocesses each, a corrupt input reported while the rest
finish, a rerun that skips what is done, a worker killed mid-scan that loses no scan, outputs made
from another input never overwritten, and scans too large for any worker refused up front."""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("distributed", reason="Dask is not installed (pip install -e '.[dask]')")

from distributed.diagnostics.plugin import WorkerPlugin

from rig.batch import Cluster, connect, find_inputs, reprocess_archive
from rig.cli import main
from rig.errors import UsageError
from tests.conftest import small_config_data, write_config

CODECS = ("gray", "phase", "gray")


@pytest.fixture(scope="module")
def archive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Three scans that kept their frames, and a copy of the first with a frame cut short."""
    from rig.assembly import open_rig
    from rig.config import load_config
    from rig.service.tasks import scan_to_directory

    root = tmp_path_factory.mktemp("archive")
    config = load_config(write_config(root, small_config_data()))
    scans = root / "scans"
    with open_rig(config) as rig:
        for number, codec in enumerate(CODECS):
            scan_to_directory(rig, scans / f"scan-{number}", f"20261129-120000-00000{number}", codec, keep_frames=True)
    corrupt = scans / "scan-corrupt"
    shutil.copytree(scans / "scan-0", corrupt)
    frame = next((corrupt / "frames").rglob("005.png"))
    frame.write_bytes(frame.read_bytes()[:200])
    return scans


@pytest.fixture(scope="module")
def cluster() -> Iterator[Cluster]:
    with connect("local", workers=2) as running:
        yield running


def _body(ply: Path) -> bytes:
    """The cloud without its header's comment, which names each scan's own id."""
    data = ply.read_bytes()
    head, body = data.split(b"end_header\n", 1)
    return b"\n".join(line for line in head.split(b"\n") if not line.startswith(b"comment")) + body


def test_an_archive_is_reprocessed_as_one_by_one_and_a_rerun_skips_it(
    archive: Path, cluster: Cluster, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from rig.service.tasks import reprocess_to_directory

    out = tmp_path / "out"
    address = cluster.client.scheduler.address  # the command joins the running cluster, as on many machines
    assert main(["batch", "reprocess", str(archive), "--out", str(out), "--scheduler", address, "--json"]) == 1
    lines = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    summary = lines[-1]
    assert (summary["event"], summary["done"], summary["skipped"], summary["failed"]) == ("summary", 3, 0, 1)
    failed = summary["failed_inputs"][0]
    assert failed["name"] == "scan-corrupt" and "cannot be read" in failed["error"]
    assert {e["name"] for e in lines[:-1] if e["event"] == "done"} == {f"scan-{n}" for n in range(3)}
    assert not (out / "scan-corrupt").exists() and not list(out.glob("*.partial"))
    for number in range(3):
        alone, _ = reprocess_to_directory(archive / f"scan-{number}", tmp_path / f"alone-{number}", "alone")
        assert _body(out / f"scan-{number}" / "cloud.ply") == _body(alone / "cloud.ply")
    written = {p: p.stat().st_mtime_ns for p in out.rglob("*")}
    again = reprocess_archive(cluster, find_inputs([archive]), out, [])
    assert sorted(s["name"] for s in again.skipped) == [f"scan-{n}" for n in range(3)]
    assert not again.done and [f["name"] for f in again.failed] == ["scan-corrupt"]
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*")} == written  # nothing rewritten


def test_another_systems_frames_folder_is_reconstructed_with_the_calibration_given(
    archive: Path, cluster: Cluster, tmp_path: Path
) -> None:
    from rig.assembly import open_rig
    from rig.calibrate.foreign import ForeignCalibrationOptions, write_opencv_stereo
    from rig.config import load_config
    from rig.service.reconstruct import reconstruct_folder

    folder = tmp_path / "captures" / "theirs"
    shutil.copytree(archive / "scan-0" / "frames" / "projector0_camera0", folder)  # frames and patterns.yaml
    config = load_config(write_config(tmp_path, small_config_data()))
    with open_rig(config, with_devices=False) as rig:
        calibration = write_opencv_stereo(tmp_path / "stereo.yml", rig.camera_models[0], rig.projector_models[0])
    summary = reprocess_archive(cluster, find_inputs([folder]), tmp_path / "out", [calibration])
    assert [d["name"] for d in summary.done] == ["theirs"], summary.failed
    options = ForeignCalibrationOptions()
    alone, _ = reconstruct_folder(
        folder, folder / "patterns.yaml", calibration, tmp_path / "alone", "a", config, options
    )
    assert _body(tmp_path / "out" / "theirs" / "cloud.ply") == _body(alone / "cloud.ply")
    without = reprocess_archive(cluster, find_inputs([folder]), tmp_path / "out2", [])
    assert "needs --calibration" in without.failed[0]["error"]


class _KillOnce(WorkerPlugin):
    """Kills its worker's process the first time a scan starts executing on any worker (a marker
    file says it has), as the kernel's OOM killer or a crash would."""

    def __init__(self, marker: str) -> None:
        self.marker = marker

    def transition(self, key: object, start: str, finish: str, **kwargs: object) -> None:
        if finish == "executing" and "reprocess-" in str(key) and not os.path.exists(self.marker):
            with open(self.marker, "w") as stream:
                stream.write(str(key))
            os._exit(1)


def test_a_worker_killed_mid_scan_loses_no_scan(archive: Path, cluster: Cluster, tmp_path: Path) -> None:
    marker = tmp_path / "killed"
    inputs = [i for i in find_inputs([archive]) if i.name != "scan-corrupt"]
    cluster.client.register_plugin(_KillOnce(str(marker)), name="kill-once")
    try:
        summary = reprocess_archive(cluster, inputs, tmp_path / "out", [])
    finally:
        cluster.client.unregister_worker_plugin("kill-once")
    assert marker.exists()  # a worker died holding a scan ...
    assert sorted(s["name"] for s in summary.done) == [f"scan-{n}" for n in range(3)]  # ... and every scan is done
    assert not summary.failed


def test_an_output_made_from_another_input_is_not_overwritten(archive: Path, cluster: Cluster, tmp_path: Path) -> None:
    out = tmp_path / "out"
    (out / "scan-1").mkdir(parents=True)
    (out / "scan-1" / "mine.txt").write_text("someone's work")
    summary = reprocess_archive(cluster, find_inputs([archive / "scan-1"]), out, [])
    assert "not overwritten" in summary.failed[0]["error"]
    assert (out / "scan-1" / "mine.txt").read_text() == "someone's work"


def test_a_scan_larger_than_any_worker_is_refused_before_it_runs(
    archive: Path, cluster: Cluster, tmp_path: Path
) -> None:
    small = dataclasses.replace(cluster, worker_memory=[1_000_000])
    summary = reprocess_archive(small, find_inputs([archive / "scan-0"]), tmp_path / "out", [])
    assert "the largest worker offers 0.0 GB" in summary.failed[0]["error"]
    assert not (tmp_path / "out").exists()


def test_inputs_that_are_not_scans_are_refused_naming_them(archive: Path, tmp_path: Path) -> None:
    with pytest.raises(UsageError, match="neither a scan directory"):
        find_inputs([tmp_path])
    twin = tmp_path / "elsewhere" / "scan-0"
    shutil.copytree(archive / "scan-0", twin)
    with pytest.raises(UsageError, match="both would be written to scan-0"):
        find_inputs([archive / "scan-0", twin])
    with pytest.raises(UsageError, match="--workers 0: at least one worker"), connect("local", workers=0):
        pass
    with pytest.raises(UsageError, match="--scheduler http://x:1: 'local', or a scheduler"), connect("http://x:1"):
        pass


def test_without_dask_batch_says_how_to_get_it(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "distributed" else real(name, *a))
    assert main(["batch", "reprocess", "anything", "--out", "out"]) == 2
    assert "pip install -e '.[dask]'" in capsys.readouterr().err


def test_eval_measures_each_scan_again_as_its_scan_measured_it(archive: Path, cluster: Cluster) -> None:
    from rig.batch.recognise import accuracy_summary, evaluate_archive

    summary = evaluate_archive(cluster, find_inputs([archive]), [])
    assert [f["name"] for f in summary.failed] == ["scan-corrupt"]
    for result in summary.done:
        stored = json.loads((archive / result["name"] / "manifest.json").read_text())["metrics"]
        pair = next(iter(stored))
        assert result["metrics"][pair]["rms_mm"] == pytest.approx(stored[pair]["rms_mm"], rel=1e-9)
        assert result["metrics"][pair]["completeness"] == stored[pair]["completeness"]
    accuracy = accuracy_summary(summary.done)
    assert len(accuracy["scans"]) == 3 and accuracy["worst_rms_mm"] >= accuracy["median_rms_mm"] > 0


def test_describe_fills_a_gallery_that_identifies_its_scans_and_a_rerun_skips_them(
    archive: Path, cluster: Cluster, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from rig.recognition.gallery import Gallery
    from rig.service.recognition import identify_scan

    gallery_file = tmp_path / "gallery.db"
    scans = [str(archive / f"scan-{n}") for n in range(3)]
    address = cluster.client.scheduler.address
    command = ["batch", "describe", *scans, "--gallery", str(gallery_file), "--label-from", "name"]
    assert main([*command, "--scheduler", address, "--json"]) == 0
    summary = json.loads(capsys.readouterr().out.splitlines()[-1])
    assert (summary["done"], summary["skipped"], summary["failed"]) == (3, 0, 0)
    with Gallery(gallery_file) as gallery:
        assert sorted(e.label for e in gallery.entries()) == ["scan-0", "scan-1", "scan-2"]
        _, found = identify_scan(gallery, archive / "scan-1", 3, None)
        assert found.matches[0].label == "scan-1" and found.matches[0].score == pytest.approx(1.0)
    assert main([*command, "--scheduler", address, "--json"]) == 0
    again = json.loads(capsys.readouterr().out.splitlines()[-1])
    assert (again["done"], again["skipped"]) == (0, 3)
    from rig.batch.recognise import describe_archive, labeller

    with Gallery(tmp_path / "other.db") as gallery:  # a label the gallery would refuse: refused before describing
        refused = describe_archive(cluster, find_inputs([archive / "scan-0"]), gallery, labeller("two words", None))
    assert refused.failed[0]["name"] == "scan-0" and "not a plain name" in refused.failed[0]["error"]
    assert main(["batch", "describe", scans[0], "--gallery", str(gallery_file)]) == 2
    assert "--label NAME (one label for every scan) or --label-from" in capsys.readouterr().err


class _HoldReprocessing(WorkerPlugin):
    """Holds every reprocessing task at its start until a file appears (at most 30 s), and notes
    each one's key: the test sees what ran on the cluster, and what the daemon did meanwhile."""

    def __init__(self, release: str, ran: str) -> None:
        self.release, self.ran = release, ran

    def transition(self, key: object, start: str, finish: str, **kwargs: object) -> None:
        if finish == "executing" and str(key).startswith("reprocess-"):
            with open(self.ran, "a") as stream:
                stream.write(f"{key}\n")
            deadline = time.monotonic() + 30
            while not os.path.exists(self.release) and time.monotonic() < deadline:
                time.sleep(0.05)


def _ended(service: Any, job_id: str, timeout_s: float = 120) -> Any:
    from rig.service.jobs import JobState

    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        job = service.job(job_id)
        if job.state not in (JobState.QUEUED, JobState.RUNNING):
            return job
        time.sleep(0.05)
    raise AssertionError(f"job {job_id} still {service.job(job_id).state} after {timeout_s} s")


def test_the_daemon_hands_reprocessing_to_the_cluster_and_keeps_its_worker_for_the_rig(
    cluster: Cluster, tmp_path: Path
) -> None:
    from rig.config import load_config
    from rig.service.errors import JobConflictError
    from rig.service.job_service import JobService
    from rig.service.jobs import JobState
    from rig.service.tasks import reprocess_to_directory

    data = small_config_data()
    data["output"] = {"data_dir": str(tmp_path / "data")}
    data["compute"] = {"scheduler": cluster.client.scheduler.address}
    service = JobService(load_config(write_config(tmp_path, data)))
    service.start()
    release, ran = tmp_path / "release", tmp_path / "ran"
    cluster.client.register_plugin(_HoldReprocessing(str(release), str(ran)), name="hold")
    try:
        source = _ended(service, service.submit_scan({"keep_frames": True}).id)
        assert source.state is JobState.DONE
        job = service.submit_reprocess(source.id, {})
        while not ran.exists():  # the cluster has it, held
            time.sleep(0.05)
        assert ran.read_text().split() == [f"reprocess-{job.id}"]
        with pytest.raises(JobConflictError, match="running task cannot be stopped"):
            service.cancel(job.id, "scan")
        scan = _ended(service, service.submit_scan({}).id)  # the rig's worker is free meanwhile
        assert scan.state is JobState.DONE and service.job(job.id).state is JobState.RUNNING
        release.touch()
        done = _ended(service, job.id)
        assert done.state is JobState.DONE, done.error
        alone, _ = reprocess_to_directory(tmp_path / "data" / "scans" / source.id, tmp_path / "alone", "alone")
        assert _body(tmp_path / "data" / "scans" / job.id / "cloud.ply") == _body(alone / "cloud.ply")
    finally:
        release.touch()
        cluster.client.unregister_worker_plugin("hold")
        service.shutdown()


def test_a_scheduler_that_does_not_answer_fails_the_job_naming_it(archive: Path, tmp_path: Path) -> None:
    from rig.config import load_config
    from rig.service.job_service import JobService
    from rig.service.jobs import JobState
    from tests.ports import free_port

    data = small_config_data()
    data["output"] = {"data_dir": str(tmp_path / "data")}
    data["compute"] = {"scheduler": f"tcp://127.0.0.1:{free_port()}"}
    service = JobService(load_config(write_config(tmp_path, data)))
    service.start()
    try:
        source = _ended(service, service.submit_scan({"keep_frames": True}).id)
        failed = _ended(service, service.submit_reprocess(source.id, {}).id)
        assert failed.state is JobState.FAILED
        assert "compute.scheduler: no Dask scheduler answered at tcp://127.0.0.1" in (failed.error or "")
        assert _ended(service, service.submit_scan({}).id).state is JobState.DONE  # the rig goes on
    finally:
        service.shutdown()
