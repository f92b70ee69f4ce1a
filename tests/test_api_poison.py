"""Bodies that could poison the store are refused before anything is queued (lone surrogates and
numbers JSON cannot carry, anywhere, free-form objects included; strict types), and a record that
cannot be served as stored never breaks a listing: it is shown with its problem and can be deleted."""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from rig.service.job_service import DB_NAME, JobService
from rig.service.jobs import JobType
from tests.test_api import AUTH, _client, _service


@pytest.fixture
def idle(tmp_path: Path) -> Iterator[tuple[JobService, TestClient]]:
    service = _service(tmp_path, start=False)  # no worker: what is queued stays queued
    with _client(service) as client:
        yield service, client
    service.store.close()


def _raw(client: TestClient, path: str, text: str) -> int:
    headers = {**AUTH, "Content-Type": "application/json"}
    return client.post(path, content=text.encode("utf-8", "surrogatepass"), headers=headers).status_code


POISON = [
    '{"plan": {"criteria": {"note": "\\ud800"}}}',
    '{"plan": {"rings": [1, 2, "\\udfff"]}}',
    '{"plan": {"\\ud800": 1}}',
    '{"label": "scan \\ud800"}',
    '{"adaptive": true, "tolerance_mm": NaN}',
    '{"adaptive": true, "tolerance_mm": Infinity}',
    '{"plan": {"criteria": {"tolerance_mm": 1e999}}}',
    '{"plan": {"pilot": {"x": -Infinity}}}',
    '{"plan": {"criteria": {"x": NaN}}}',
]


@pytest.mark.parametrize("body", POISON)
def test_a_poisoned_body_is_refused_and_nothing_is_queued(idle: tuple[JobService, TestClient], body: str) -> None:
    service, client = idle
    assert _raw(client, "/v1/scans", body) == 422
    listing = client.get("/v1/scans")
    assert listing.status_code == 200 and listing.json()["total"] == 0
    assert service.store.list(JobType.SCAN, None, 10, 0) == ([], 0)


def test_the_refusal_names_the_place_inside_a_free_form_object(idle: tuple[JobService, TestClient]) -> None:
    _, client = idle
    headers = {**AUTH, "Content-Type": "application/json"}
    answer = client.post("/v1/scans", content=POISON[0].encode("utf-8", "surrogatepass"), headers=headers)
    assert answer.status_code == 422
    assert "plan.criteria.note" in answer.text and "surrogate" in answer.text


def test_deep_and_large_free_form_objects_are_refused(idle: tuple[JobService, TestClient]) -> None:
    _, client = idle
    deep: object = 1
    for _ in range(40):
        deep = {"a": deep}
    assert client.post("/v1/scans", json={"plan": deep}, headers=AUTH).status_code == 422
    assert client.post("/v1/scans", json={"plan": {"rings": list(range(30_000))}}, headers=AUTH).status_code in (
        413,  # over the body limit
        422,
    )
    assert client.get("/v1/scans").json()["total"] == 0


@pytest.mark.parametrize(
    ("path", "body"),
    [
        ("/v1/live", {"seconds": True}),
        ("/v1/live", {"seconds": "2"}),
        ("/v1/scans", {"keep_frames": 1}),
        ("/v1/scans", {"keep_frames": "true"}),
        ("/v1/scans", {"adaptive": True, "tolerance_mm": "0.2"}),
        ("/v1/calibrations", {"views": "5"}),
        ("/v1/calibrations", {"views": 5.5}),
        ("/v1/calibrations", {"views": True}),
    ],
)
def test_types_the_schema_refuses_are_refused(
    idle: tuple[JobService, TestClient], path: str, body: dict[str, object]
) -> None:
    _, client = idle
    answer = client.post(path, json=body, headers=AUTH)
    assert answer.status_code == 422, answer.text
    field = list(body)[-1]  # the one of the wrong type
    assert field in json.dumps(answer.json()["detail"])


def test_numbers_of_the_right_type_are_still_accepted(idle: tuple[JobService, TestClient]) -> None:
    _, client = idle
    assert client.post("/v1/scans", json={"adaptive": True, "tolerance_mm": 1}, headers=AUTH).status_code == 202
    assert client.post("/v1/calibrations", json={"views": 5}, headers=AUTH).status_code == 202


def _poison_the_database(service: JobService) -> str:
    """A queued scan, then its stored request replaced by what an older version could store."""
    job = service.submit_scan({"label": "fine"})
    db = sqlite3.connect(service.data_dir / DB_NAME)
    with db:
        db.execute("UPDATE jobs SET request = ? WHERE id = ?", ('{"plan": {"criteria": "\\ud800"}}', job.id))
    db.close()
    return job.id


def test_a_damaged_record_never_breaks_a_listing_and_can_be_deleted(tmp_path: Path) -> None:
    service = _service(tmp_path, start=False)
    try:
        good = service.submit_scan({"label": "good"}).id
        bad = _poison_the_database(service)
        db = sqlite3.connect(service.data_dir / DB_NAME)
        with db:
            other = service.submit_scan({}).id
            db.execute("UPDATE jobs SET state = 'exploded', result = 'not json' WHERE id = ?", (other,))
        db.close()
        with _client(service) as client:
            for query in ("", "?state=queued", "?limit=1", "?limit=1&offset=1"):
                assert client.get(f"/v1/scans{query}").status_code == 200, query
            items = {item["id"]: item for item in client.get("/v1/scans").json()["items"]}
            assert set(items) == {good, bad, other}
            assert items[good]["problem"] is None and items[good]["request"] == {"label": "good"}
            assert "request.plan.criteria" in items[bad]["problem"] and items[bad]["request"] == {}
            assert items[other]["state"] is None and "state" in items[other]["problem"]
            assert "result" in items[other]["problem"]
            assert client.get(f"/v1/scans/{bad}").status_code == 200
            assert client.post(f"/v1/scans/{other}/cancel", headers=AUTH).status_code == 409
            for job_id in (bad, other):
                assert client.delete(f"/v1/scans/{job_id}", headers=AUTH).status_code == 204
            assert [item["id"] for item in client.get("/v1/scans").json()["items"]] == [good]
    finally:
        service.store.close()


def test_store_check_finds_and_quarantines_damaged_records(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from rig.cli import main

    service = _service(tmp_path, start=False)
    good = service.submit_scan({"label": "good"}).id
    bad = _poison_the_database(service)
    service.store.close()
    data_dir = str(service.data_dir)
    assert main(["store", "check", "--data-dir", data_dir, "--json"]) == 1
    report = json.loads(capsys.readouterr().out)
    assert report["records"] == 2 and [d["id"] for d in report["damaged"]] == [bad] and not report["clean"]
    assert main(["store", "check", "--data-dir", data_dir, "--repair", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["quarantined"] == 1
    db = sqlite3.connect(service.data_dir / DB_NAME)
    kept = [row[0] for row in db.execute("SELECT id FROM jobs")]
    quarantined = db.execute("SELECT id, request, problem FROM quarantine").fetchall()
    db.close()
    assert kept == [good] and quarantined[0][0] == bad and "\\ud800" in quarantined[0][1]
    assert "surrogate" in quarantined[0][2]
    assert main(["store", "check", "--data-dir", data_dir]) == 0
    assert "2 records" not in capsys.readouterr().out  # one is left


def test_store_repair_refuses_while_a_daemon_holds_the_data_directory(tmp_path: Path) -> None:
    from rig.cli import main

    service = _service(tmp_path)  # started: holds the lock
    try:
        assert main(["store", "check", "--data-dir", str(service.data_dir), "--repair"]) == 2
        assert main(["store", "check", "--data-dir", str(service.data_dir)]) == 0  # reading is fine
    finally:
        service.shutdown(5.0)


PLAN = {"format": "slrig-ring-plan/1", "tolerance_mm": 0.2, "center_px": [128, 96], "radii_px": [20, 40, 60]}


@pytest.mark.parametrize(
    ("plan", "status"),
    [
        ({**PLAN, "radii_px": [10**400]}, 409),  # a JSON number, but no float
        ({**PLAN, "tolerance_mm": 10**400}, 409),
        ({**PLAN, "profile": [1, 2]}, 409),
        ({**PLAN, "criteria": "abc"}, 409),
        ({**PLAN, "criteria": [[1]]}, 409),
        ({**PLAN, "radii_px": {"50": 1}}, 409),
        ({**PLAN, "center_px": "12"}, 409),
        ({**PLAN, "radii_px": ["20", 40]}, 409),
        ({**PLAN, "tolerance_mm": True}, 409),
    ],
)
def test_a_plan_of_the_wrong_shape_is_refused_naming_its_field(
    idle: tuple[JobService, TestClient], plan: dict[str, object], status: int
) -> None:
    _, client = idle
    answer = client.post("/v1/scans", json={"plan": plan}, headers=AUTH)
    assert answer.status_code == status, answer.text
    assert client.get("/v1/scans").json()["total"] == 0
    assert client.post("/v1/scans", json={"plan": PLAN}, headers=AUTH).status_code == 202  # the same, well formed


def _edit(service: JobService, sql: str, *args: object) -> None:
    db = sqlite3.connect(service.data_dir / DB_NAME)
    with db:
        db.execute(sql, args)
    db.close()


def test_records_damaged_in_every_column_are_listed_named_and_deletable(tmp_path: Path) -> None:
    service = _service(tmp_path, start=False)
    try:
        ids = [service.submit_scan({}).id for _ in range(4)]
        _edit(service, "UPDATE jobs SET request = CAST(X'7B2278223A2022FF227D' AS TEXT) WHERE id = ?", ids[0])
        _edit(service, "UPDATE jobs SET kind = 'hologram' WHERE id = ?", ids[1])
        _edit(service, "UPDATE jobs SET created = 1e300 WHERE id = ?", ids[2])
        _edit(service, "UPDATE jobs SET id = 'hand-edited' WHERE id = ?", ids[3])
        with _client(service) as client:
            listing = client.get("/v1/scans")
            assert listing.status_code == 200
            items = {item["id"]: item for item in listing.json()["items"]}
            assert set(items) == {*ids[:3], "hand-edited"}
            assert "request" in items[ids[0]]["problem"] and "surrogate" in items[ids[0]]["problem"]
            assert "kind" in items[ids[1]]["problem"] and "created" in items[ids[2]]["problem"]
            assert "store check --repair" in items["hand-edited"]["problem"]
            for job_id in ids[:3]:
                assert client.get(f"/v1/scans/{job_id}").status_code == 200
                assert client.delete(f"/v1/scans/{job_id}", headers=AUTH).status_code == 204
            assert [item["id"] for item in client.get("/v1/scans").json()["items"]] == ["hand-edited"]
    finally:
        service.store.close()


def test_the_event_stream_of_a_record_whose_state_is_unreadable_ends(tmp_path: Path) -> None:
    service = _service(tmp_path, start=False)
    try:
        job_id = service.submit_scan({}).id
        _edit(service, "UPDATE jobs SET state = 'exploded' WHERE id = ?", job_id)
        with _client(service) as client, client.stream("GET", f"/v1/scans/{job_id}/events") as events:
            text = "".join(events.iter_text())  # ends: no job will move it
        assert "event: state" in text and '"state": null' in text
    finally:
        service.store.close()


def test_store_check_refuses_a_file_that_is_not_a_database(tmp_path: Path) -> None:
    from rig.cli import main

    (tmp_path / DB_NAME).write_bytes(b"this is not SQLite" * 100)
    assert main(["store", "check", "--data-dir", str(tmp_path)]) == 2
