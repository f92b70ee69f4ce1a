"""Exposure and HDR over REST: a scan request's `exposure` and `hdr`, as `slrig scan --exposure --hdr`
takes them, and what the schema or the rig refuses, named."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from tests.conftest import wait_done
from tests.test_api import AUTH, _client, _service


@pytest.fixture
def client(tmp_path: Path) -> Iterator[TestClient]:
    service = _service(tmp_path)
    with _client(service) as c:
        yield c
    service.shutdown(5.0)


def test_a_scan_over_rest_at_the_exposures_it_asks_for(client: TestClient) -> None:
    created = client.post("/v1/scans", json={"codec": "gray", "exposure": "auto", "hdr": 2}, headers=AUTH)
    assert created.status_code == 202
    done = wait_done(client, created.json()["id"])
    assert done["state"] == "done", done["error"]
    manifest = client.get(f"/v1/scans/{done['id']}/files/manifest.json").json()
    assert manifest["exposure"]["mode"] == "hdr" and len(manifest["exposure"]["exposures_us"]["camera0"]) == 2
    assert manifest["pairs"][0]["counts"]["hdr_exposures"] == 2
    for body, status, named in (
        ({"hdr": [1000.0]}, 409, "hdr"),
        ({"hdr": 1}, 422, "hdr"),
        ({"exposure": "fast"}, 422, "exposure"),
    ):
        answer = client.post("/v1/scans", json=body, headers=AUTH)
        assert answer.status_code == status, (body, answer.json())
        assert named in json.dumps(answer.json()["detail"]), (body, answer.json())


def test_adaptive_projection_over_rest(client: TestClient) -> None:
    created = client.post("/v1/scans", json={"codec": "gray", "adaptive_projection": True}, headers=AUTH)
    assert created.status_code == 202
    done = wait_done(client, created.json()["id"])
    assert done["state"] == "done", done["error"]
    manifest = client.get(f"/v1/scans/{done['id']}/files/manifest.json").json()
    assert manifest["exposure"]["mode"] == "adaptive projection"
    assert {"response_exponent", "masks", "prescan_exposures_us"} <= set(manifest["exposure"]["adaptive_projection"])
    answer = client.post("/v1/scans", json={"adaptive_projection": "yes please"}, headers=AUTH)
    assert answer.status_code == 422 and "adaptive_projection" in json.dumps(answer.json()["detail"])
