"""The REST API in process (FastAPI's TestClient) over the job service on the simulated bench:
lifecycle, paging, downloads, auth, input errors, queue bound, cancel, delete, reprocess,
calibration, events and restart recovery."""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from rig.api.app import create_app
from rig.api.security import ApiSettings
from rig.config import load_config
from rig.service.errors import JobConflictError
from rig.service.job_service import DB_NAME, JobService
from rig.service.jobs import JobStore
from tests.conftest import default_config_data, ply_xyz, small_config_data, wait_done, write_config

KEY = "k" * 32
AUTH = {"X-API-Key": KEY}


def _service(tmp_path: Path, start: bool = True, **service: Any) -> JobService:
    tmp_path.mkdir(parents=True, exist_ok=True)
    data = small_config_data()
    data["output"] = {"data_dir": str(tmp_path / "data")}
    data["service"] = service
    config = load_config(write_config(tmp_path, data, "serve.yaml"))
    s = JobService(config, config.service.max_queue)
    if start:
        s.start()
    return s


def _client(service: JobService, **settings: Any) -> TestClient:
    return TestClient(create_app(service, ApiSettings(api_key=KEY, **settings)), base_url="http://localhost")


@pytest.fixture
def service(tmp_path: Path) -> Iterator[JobService]:
    s = _service(tmp_path)
    yield s
    s.shutdown(5.0)


@pytest.fixture
def client(service: JobService) -> Iterator[TestClient]:
    with _client(service) as c:
        yield c


def test_a_scan_from_request_to_download(client: TestClient) -> None:
    created = client.post("/v1/scans", json={"codec": "gray", "label": "first"}, headers=AUTH)
    assert created.status_code == 202
    job = created.json()
    assert created.headers["location"] == f"/v1/scans/{job['id']}" and job["state"] == "queued"
    done = wait_done(client, job["id"])
    assert done["state"] == "done" and done["fraction"] == 1.0 and done["error"] is None
    assert done["result"]["points"] > 10_000 and done["request"]["label"] == "first"
    cloud = client.get(done["links"]["cloud.ply"])
    assert cloud.status_code == 200 and cloud.content.startswith(b"ply\n")
    assert len(ply_xyz(cloud.content)) == done["result"]["points"]
    manifest = client.get(f"/v1/scans/{job['id']}/files/manifest.json").json()
    assert manifest["scan_id"] == job["id"] and manifest["codec"]["name"] == "gray"
    assert client.get(f"/v1/scans/{job['id']}/files/preview.png").headers["content-type"] == "image/png"
    rig = client.get("/v1/rig").json()
    assert rig["state"] == "idle" and rig["devices"][0]["kind"] == "projector"
    assert all(d["open"] for d in rig["devices"])  # kept open between scans
    assert {c["name"] for c in client.get("/v1/codecs").json()} >= {"gray", "phase", "rings"}


def test_listing_pages_newest_first(client: TestClient) -> None:
    ids = [client.post("/v1/scans", json={}, headers=AUTH).json()["id"] for _ in range(3)]
    for job_id in ids:
        wait_done(client, job_id)
    first = client.get("/v1/scans", params={"limit": 2}).json()
    second = client.get("/v1/scans", params={"limit": 2, "offset": 2}).json()
    assert first["total"] == 3 and [j["id"] for j in first["items"]] == ids[::-1][:2]
    assert [j["id"] for j in second["items"]] == ids[:1]
    assert client.get("/v1/scans", params={"state": "failed"}).json()["total"] == 0
    assert client.get("/v1/scans", params={"limit": 0}).status_code == 422


def test_mutations_need_the_key_and_reads_do_not_on_loopback(client: TestClient) -> None:
    missing = client.post("/v1/scans", json={})
    assert missing.status_code == 401 and missing.headers["www-authenticate"] == "Bearer"
    assert client.post("/v1/scans", json={}, headers={"X-API-Key": "x" * 32}).status_code == 403
    assert client.post("/v1/scans", json={}, headers={"Authorization": f"Bearer {KEY}"}).status_code == 202
    assert client.get("/v1/scans").status_code == 200
    assert client.get("/v1/health").json()["status"] == "ok"


def test_beyond_loopback_every_request_needs_the_key(service: JobService) -> None:
    with _client(service, protect_reads=True) as c:
        reads = ["/v1/health", "/v1/rig", "/v1/codecs", "/v1/scans", "/v1/calibrations", "/openapi.json"]
        reads += ["/v1/scans/20261121-000000-abcdef", "/v1/scans/20261121-000000-abcdef/events"]
        assert {path: c.get(path).status_code for path in reads} == dict.fromkeys(reads, 401)
        assert c.get("/docs").status_code == 404  # no unauthenticated docs page
        assert c.get("/v1/scans", headers=AUTH).status_code == 200
        assert "/v1/scans" in c.get("/openapi.json", headers=AUTH).json()["paths"]


def test_bad_input_gets_a_4xx_that_names_the_field(client: TestClient) -> None:
    unknown = client.post("/v1/scans", json={"codex": "gray"}, headers=AUTH)
    assert unknown.status_code == 422 and unknown.json()["detail"][0]["loc"] == ["body", "codex"]
    codec = client.post("/v1/scans", json={"codec": "nope"}, headers=AUTH)
    assert codec.status_code == 422 and codec.json()["detail"][0]["loc"] == ["body", "codec"]
    assert "'gray'" in codec.json()["detail"][0]["msg"]  # the known codecs are named
    assert client.post("/v1/scans", content=b"{not json", headers=AUTH).status_code == 422
    assert client.get("/v1/scans/..%2F..%2Fetc").status_code in (404, 422)
    assert client.get("/v1/scans/20261121-000000-abcdef").status_code == 404
    assert client.get("/v1/scans/not-an-id").status_code == 422
    views = client.post("/v1/calibrations", json={"what": "rig", "views": 1}, headers=AUTH)
    assert views.status_code == 422 and views.json()["detail"][0]["loc"] == ["body", "views"]


# a pilot scan, a plan and the planned scan: 5 s alone, 126 s in a suite on two busy cores (a bound
# for a hang, not a timing)
_ADAPTIVE_WAIT_S = 600.0


def test_an_adaptive_scan_over_rest_and_a_scan_of_its_plan(client: TestClient) -> None:
    created = client.post("/v1/scans", json={"adaptive": True, "tolerance_mm": 0.5}, headers=AUTH)
    assert created.status_code == 202
    done = wait_done(client, created.json()["id"], timeout_s=_ADAPTIVE_WAIT_S)
    assert done["state"] == "done", done["error"]
    manifest = client.get(f"/v1/scans/{done['id']}/files/manifest.json").json()
    adaptive = manifest["adaptive"]
    assert adaptive["pilot_scanned"] and adaptive["tolerance_mm"] == 0.5 and manifest["codec"]["name"] == "rings"
    assert manifest["config"]["scan"]["rings"]["radii_px"] == pytest.approx(adaptive["plan"]["radii_px"], abs=0.01)
    again = client.post("/v1/scans", json={"plan": adaptive["plan"]}, headers=AUTH)
    assert again.status_code == 202
    reused = wait_done(client, again.json()["id"], timeout_s=_ADAPTIVE_WAIT_S)
    assert reused["state"] == "done", reused["error"]
    second = client.get(f"/v1/scans/{reused['id']}/files/manifest.json").json()
    assert not second["adaptive"]["pilot_scanned"] and second["adaptive"]["rings"] == adaptive["rings"]


def test_adaptive_and_plan_requests_that_contradict_themselves_or_the_rig_are_refused(client: TestClient) -> None:
    plan = {"format": "slrig-ring-plan/1", "tolerance_mm": 0.2, "center_px": [100.0, 80.0], "radii_px": [20.0, 40.0]}
    cases = [
        ({"adaptive": True, "plan": plan}, "not both"),
        ({"tolerance_mm": 0.2}, "tolerance_mm"),
        ({"adaptive": True, "codec": "phase"}, "codec"),
        ({"plan": {**plan, "radii_px": [20.0, 21.0]}}, "radii_px"),
        ({"plan": {"radii_px": [20.0, 40.0]}}, "not a ring plan"),
        ({"adaptive": True, "tolerance_mm": 0}, "greater than 0"),
    ]
    cases.append(({"plan": {**plan, "center_px": [5000.0, 80.0]}}, "center_px"))
    for body, named in cases:
        answer = client.post("/v1/scans", json=body, headers=AUTH)
        # what the schema says is 422; what only the request as a whole, or this rig, rules out is 409
        assert answer.status_code == (422 if "tolerance_mm" in body and body["tolerance_mm"] == 0 else 409), body
        assert named in json.dumps(answer.json()["detail"]), (body, answer.json())
    assert client.get("/v1/scans").json()["total"] == 0  # none of them was queued


def test_files_are_served_only_by_the_names_a_result_lists(client: TestClient, service: JobService) -> None:
    job_id = client.post("/v1/scans", json={}, headers=AUTH).json()["id"]
    wait_done(client, job_id)
    (service.scans_dir / job_id / "secret.txt").write_text("not listed")
    assert client.get(f"/v1/scans/{job_id}/files/secret.txt").status_code == 404
    assert client.get(f"/v1/scans/{job_id}/files/..%2Fslrig.db").status_code in (404, 422)
    assert client.get(f"/v1/scans/{job_id}/files/.manifest.json").status_code == 422


def test_large_bodies_and_foreign_hosts_are_refused(client: TestClient) -> None:
    big = client.post(
        "/v1/scans", content=b"{" + b" " * 70_000 + b"}", headers={**AUTH, "content-type": "application/json"}
    )
    assert big.status_code == 413

    def chunks() -> Iterator[bytes]:  # no Content-Length: the body streams in, chunked
        yield b'{"label": "'
        for _ in range(100):
            yield b"x" * 1000
        yield b'"}'

    chunked = client.post("/v1/scans", content=chunks(), headers={**AUTH, "content-type": "application/json"})
    assert chunked.status_code == 413
    assert client.get("/v1/health", headers={"host": "evil.example"}).status_code == 400


def test_the_queue_is_bounded(tmp_path: Path) -> None:
    idle = _service(tmp_path, start=False, max_queue=2)  # no worker: nothing leaves the queue
    with _client(idle) as c:
        assert [c.post("/v1/scans", json={}, headers=AUTH).status_code for _ in range(3)] == [202, 202, 429]
        full = c.post("/v1/scans", json={}, headers=AUTH)
        assert full.headers["retry-after"] == "5" and "queue" in full.json()["detail"]
        assert c.get("/v1/rig").json()["queue"] == {"queued": 2, "max": 2}
    idle.store.close()


def test_cancel_and_delete(tmp_path: Path) -> None:
    idle = _service(tmp_path, start=False)
    with _client(idle) as c:
        job_id = c.post("/v1/scans", json={}, headers=AUTH).json()["id"]
        cancelled = c.post(f"/v1/scans/{job_id}/cancel", headers=AUTH).json()
        assert cancelled["state"] == "cancelled" and cancelled["finished"] is not None
        assert c.post(f"/v1/scans/{job_id}/cancel", headers=AUTH).json()["state"] == "cancelled"  # idempotent
    idle.store.close()
    running = _service(tmp_path / "b")
    try:
        with _client(running) as c:
            job_id = c.post("/v1/scans", json={}, headers=AUTH).json()["id"]
            done = wait_done(c, job_id)
            folder = running.scans_dir / job_id
            assert folder.is_dir()
            assert c.delete(f"/v1/scans/{job_id}", headers=AUTH).status_code == 204
            assert not folder.exists() and c.get(f"/v1/scans/{job_id}").status_code == 404
            assert c.get(done["links"]["cloud.ply"]).status_code == 404
    finally:
        running.shutdown(5.0)


def test_a_running_scan_can_be_cancelled_and_the_projector_goes_dark(tmp_path: Path) -> None:
    data = default_config_data()  # full size: seconds of capture, so the cancel lands mid-scan
    data["output"] = {"data_dir": str(tmp_path / "data")}
    config = load_config(write_config(tmp_path, data, "full.yaml"))
    s = JobService(config)
    s.start()
    try:
        with _client(s) as c:
            job_id = c.post("/v1/scans", json={}, headers=AUTH).json()["id"]
            deadline = time.monotonic() + 60
            while c.get(f"/v1/scans/{job_id}").json()["fraction"] < 0.05 and time.monotonic() < deadline:
                time.sleep(0.01)
            assert c.delete(f"/v1/scans/{job_id}", headers=AUTH).status_code == 409  # running
            answer = c.post(f"/v1/scans/{job_id}/cancel", headers=AUTH)
            assert answer.status_code == 202 and answer.json()["state"] == "running"  # it stops at its next step
            job = wait_done(c, job_id)
            assert job["state"] == "cancelled" and job["error"] == "cancelled while running"
            assert all(p.is_dark for p in s.open_rig.projectors)  # type: ignore[union-attr, attr-defined]
            assert not (s.scans_dir / job_id).exists() and not list(s.scans_dir.glob("*.partial"))
            assert c.delete(f"/v1/scans/{job_id}", headers=AUTH).status_code == 204
    finally:
        s.shutdown(5.0)


def test_deleting_a_job_the_worker_is_starting_leaves_the_worker_alive(service: JobService) -> None:
    transition = service.store.transition

    def slow_start(job_id: str, state: str, **fields: Any) -> Any:
        if state == "running":
            time.sleep(0.3)  # widen the window between taking a job and recording it running
        return transition(job_id, state, **fields)

    service.store.transition = slow_start  # type: ignore[method-assign]
    job = service.submit_scan({})
    deadline = time.monotonic() + 10
    while service._current != job.id and time.monotonic() < deadline:
        time.sleep(0.005)
    with pytest.raises(JobConflictError):
        service.delete(job.id, "scan")  # the worker has it: refused, not half-done
    service.store.transition = transition  # type: ignore[method-assign]
    with _client(service) as c:
        assert wait_done(c, job.id)["state"] == "done"
        again = wait_done(c, c.post("/v1/scans", json={}, headers=AUTH).json()["id"])
    assert again["state"] == "done" and service.healthy()


def test_events_stream_to_the_end_and_resume(client: TestClient) -> None:
    job_id = client.post("/v1/scans", json={}, headers=AUTH).json()["id"]
    events = _read_events(client, f"/v1/scans/{job_id}/events")
    states = [e["data"]["state"] for e in events if e["event"] == "state"]
    assert states == ["queued", "running", "done"]
    assert any(e["event"] == "progress" and e["data"]["stage"] == "capture" for e in events)
    ids = [e["id"] for e in events]
    assert ids == sorted(ids) and len(set(ids)) == len(ids)
    resumed = _read_events(client, f"/v1/scans/{job_id}/events", {"Last-Event-ID": str(ids[-2])})
    assert [e["id"] for e in resumed] == ids[-1:]


def _read_events(client: TestClient, url: str, headers: dict[str, str] | None = None) -> list[dict[str, Any]]:
    events: list[dict[str, Any]] = []
    current: dict[str, Any] = {}
    with client.stream("GET", url, headers=headers, timeout=30) as response:
        assert response.headers["content-type"].startswith("text/event-stream")
        for line in response.iter_lines():
            if line.startswith("id: "):
                current["id"] = int(line[4:])
            elif line.startswith("event: "):
                current["event"] = line[7:]
            elif line.startswith("data: "):
                current["data"] = json.loads(line[6:])
            elif line == "" and current:
                events.append(current)
                current = {}
    return events


def test_reprocessing_a_stored_scan(client: TestClient) -> None:
    kept = wait_done(client, client.post("/v1/scans", json={"keep_frames": True}, headers=AUTH).json()["id"])
    again = client.post(f"/v1/scans/{kept['id']}/reprocess", json={}, headers=AUTH)
    assert again.status_code == 202
    same = wait_done(client, again.json()["id"])
    assert same["state"] == "done", same["error"]
    original = ply_xyz(client.get(kept["links"]["cloud.ply"]).content)
    assert np.array_equal(ply_xyz(client.get(same["links"]["cloud.ply"]).content), original)
    manifest = client.get(f"/v1/scans/{same['id']}/files/manifest.json").json()
    assert manifest["origin"]["reprocessed_from"] == kept["id"]
    looser = wait_done(
        client,
        client.post(f"/v1/scans/{kept['id']}/reprocess", json={"max_depth_jump_mm": 50.0}, headers=AUTH).json()["id"],
    )
    assert looser["result"]["points"] > same["result"]["points"]  # the filter kept more
    plain = wait_done(client, client.post("/v1/scans", json={}, headers=AUTH).json()["id"])
    refused = client.post(f"/v1/scans/{plain['id']}/reprocess", json={}, headers=AUTH)
    assert refused.status_code == 409 and "keep_frames" in refused.json()["detail"]


def test_a_calibration_session_and_a_scan_reprocessed_with_it(client: TestClient) -> None:
    scan = wait_done(client, client.post("/v1/scans", json={"keep_frames": True}, headers=AUTH).json()["id"])
    created = client.post("/v1/calibrations", json={"what": "rig", "views": 6}, headers=AUTH)
    assert created.status_code == 202
    calibration = wait_done(client, created.json()["id"], "calibrations", timeout_s=120)
    assert calibration["state"] == "done", calibration["error"]
    assert {"calibration.json", "calibration.yaml"} <= set(calibration["result"]["files"])
    assert calibration["result"]["report"]["devices"]["camera0"]["rms_px"] < 0.5
    document = client.get(f"/v1/calibrations/{calibration['id']}/files/calibration.json").json()
    assert document["sha256"] == calibration["result"]["sha256"]
    redone = client.post(f"/v1/scans/{scan['id']}/reprocess", json={"calibration": calibration["id"]}, headers=AUTH)
    result = wait_done(client, redone.json()["id"])
    assert result["state"] == "done", result["error"]
    manifest = client.get(f"/v1/scans/{result['id']}/files/manifest.json").json()
    assert set(manifest["calibration_sha256"].values()) == {calibration["result"]["sha256"]}
    assert abs(result["result"]["points"] - scan["result"]["points"]) < 0.05 * scan["result"]["points"]


def test_a_restart_marks_unfinished_jobs_interrupted_and_never_reruns_them(tmp_path: Path) -> None:
    first = _service(tmp_path, start=False)
    queued = first.submit_scan({})
    running = first.submit_scan({})
    first.store.transition(running.id, "running")
    partial = first.scans_dir / f"{running.id}.partial"
    partial.mkdir(parents=True)
    (partial / "cloud.ply").write_bytes(b"ply\nhalf")
    first.store.close()

    second = _service(tmp_path)
    try:
        with _client(second) as c:
            for job_id in (queued.id, running.id):
                job = c.get(f"/v1/scans/{job_id}").json()
                assert job["state"] == "interrupted" and "not re-run" in job["error"]
            assert not partial.exists()
            assert [j["id"] for j in c.get("/v1/scans").json()["items"]] == [running.id, queued.id]
            fresh = wait_done(c, c.post("/v1/scans", json={}, headers=AUTH).json()["id"])
            assert fresh["state"] == "done"
        assert JobStore(tmp_path / "data" / DB_NAME).integrity_ok()
    finally:
        second.shutdown(5.0)


def test_a_device_fault_fails_the_scan_and_the_daemon_goes_on(tmp_path: Path) -> None:
    data = small_config_data()
    data["output"] = {"data_dir": str(tmp_path / "data")}
    data["cameras"][0]["sim"]["faults"] = {"disconnect_after_frames": 5}
    config = load_config(write_config(tmp_path, data, "faulty.yaml"))
    s = JobService(config)
    s.start()
    try:
        with _client(s) as c:
            failed = wait_done(c, c.post("/v1/scans", json={}, headers=AUTH).json()["id"])
            assert failed["state"] == "failed" and "disconnected" in failed["error"]
            rig = c.get("/v1/rig").json()
            assert rig["state"] == "fault" and "disconnected" in rig["last_error"]
            assert s.open_rig is None  # closed (dark) after the fault, reopened by the next job
            again = wait_done(c, c.post("/v1/scans", json={}, headers=AUTH).json()["id"])
            assert again["state"] == "failed"  # the simulated camera fails the same way: still answered
            assert c.get("/v1/health").json()["status"] == "ok"
    finally:
        s.shutdown(5.0)


def test_health_turns_degraded_when_a_running_job_goes_silent(service: JobService) -> None:
    assert service.healthy()
    service._current = "20261121-000000-abcdef"
    service._heartbeat = time.monotonic() - service.health_stale_s - 1
    assert not service.healthy()
    service._current = None


def test_one_daemon_per_data_directory(tmp_path: Path, service: JobService) -> None:
    from rig.errors import ConfigError

    second = JobService(service.config)
    with pytest.raises(ConfigError, match="another slrig daemon is using"):
        second.start()
    second.store.close()
