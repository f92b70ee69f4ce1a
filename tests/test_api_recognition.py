"""The recognition routes over the job service on the simulated bench: a finished scan into the
gallery, identified, refused where it should be, with the API-key rules of scans."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from fastapi.testclient import TestClient

from rig.config import load_config
from rig.service.job_service import JobService
from tests.conftest import default_config_data, wait_done, write_config
from tests.test_api import AUTH, _client


@pytest.fixture(scope="module")
def rest(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[TestClient, list[str]]]:
    """Two ring scans of the default bench (the quarter-resolution rig's rings leave a hole of
    50 mm about their centre: too little surface for a descriptor)."""
    folder = tmp_path_factory.mktemp("recognition")
    data = default_config_data()
    data["output"] = {"data_dir": str(folder / "data")}
    config = load_config(write_config(folder, data, "serve.yaml"))
    service = JobService(config, config.service.max_queue)
    service.start()
    with _client(service) as client:
        ids = [client.post("/v1/scans", json={"codec": "rings"}, headers=AUTH).json()["id"] for _ in range(2)]
        for job_id in ids:
            assert wait_done(client, job_id)["state"] == "done"
        yield client, ids
    service.shutdown(5.0)


def test_a_scan_added_to_the_gallery_identifies_another_scan_of_the_object(rest: tuple[TestClient, list[str]]) -> None:
    client, (first, second) = rest
    assert client.post(f"/v1/scans/{second}/identify", json={}, headers=AUTH).status_code == 422  # empty gallery
    assert client.post("/v1/gallery", json={"scan_id": first, "label": "sphere"}).status_code == 401
    request = {"scan_id": first, "label": "sphere", "rings": 6, "outer_mm": 40}
    added = client.post("/v1/gallery", json=request, headers=AUTH)
    assert added.status_code == 201, added.text
    entry = added.json()
    assert entry["scan_id"] == first and entry["settings"]["rings"] == 6
    assert added.headers["location"] == f"/v1/gallery/{entry['id']}"
    listed = client.get("/v1/gallery").json()
    assert [e["label"] for e in listed["entries"]] == ["sphere"] and listed["settings"]["rings"] == 6
    again = client.post("/v1/gallery", json={"scan_id": first, "label": "other"}, headers=AUTH)
    assert again.status_code == 409 and "already" in again.json()["detail"]
    other = client.post("/v1/gallery", json={"scan_id": second, "label": "b", "rings": 7}, headers=AUTH)
    assert other.status_code == 409 and "rings 7 (gallery: 6)" in other.json()["detail"]
    found = client.post(f"/v1/scans/{second}/identify", json={"top": 3}, headers=AUTH)
    assert found.status_code == 200, found.text
    assert found.json()["label"] == "sphere" and found.json()["matches"][0]["score"] > 0.99
    assert client.delete(f"/v1/gallery/{entry['id']}", headers=AUTH).status_code == 204
    assert client.delete(f"/v1/gallery/{entry['id']}", headers=AUTH).status_code == 404
    assert client.get("/v1/gallery").json()["entries"] == []


def test_bad_gallery_requests_name_the_field(rest: tuple[TestClient, list[str]]) -> None:
    client, (first, _) = rest
    bad_label = client.post("/v1/gallery", json={"scan_id": first, "label": "../x"}, headers=AUTH)
    assert bad_label.status_code == 422 and bad_label.json()["detail"][0]["loc"][-1] == "label"
    odd = client.post("/v1/gallery", json={"scan_id": first, "label": "a", "samples": 9}, headers=AUTH)
    assert odd.status_code == 422 and "samples" in odd.text
    unknown = client.post("/v1/gallery", json={"scan_id": "20260101-000000-abcdef", "label": "a"}, headers=AUTH)
    assert unknown.status_code == 404
    extra = client.post(f"/v1/scans/{first}/identify", json={"top": 0, "colour": 1}, headers=AUTH)
    assert extra.status_code == 422 and {e["loc"][-1] for e in extra.json()["detail"]} == {"top", "colour"}


def test_a_gallery_file_that_is_not_a_gallery_is_refused_and_kept(rest: tuple[TestClient, list[str]]) -> None:
    client, (first, _) = rest
    service = client.app.state.service  # type: ignore[attr-defined]
    path = service.data_dir / "gallery.db"
    saved = path.read_bytes() if path.exists() else None
    path.write_bytes(b"not a database, but someone's file")
    try:
        answer = client.post("/v1/gallery", json={"scan_id": first, "label": "a"}, headers=AUTH)
        assert answer.status_code == 503 and "not a gallery" in answer.json()["detail"]
        assert path.read_bytes() == b"not a database, but someone's file"
    finally:
        if saved is None:
            path.unlink()
        else:
            path.write_bytes(saved)
