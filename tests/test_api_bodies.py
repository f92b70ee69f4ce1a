"""Error responses a client can read: request bodies JSON cannot echo back (non-finite numbers,
lone surrogates) are 422 naming the field, never a 500; a 405 lists every method of its path."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from tests.test_api import AUTH, _client, _service


@pytest.fixture
def client(tmp_path: Path) -> Iterator[TestClient]:
    service = _service(tmp_path, start=False)
    with _client(service) as c:
        yield c
    service.store.close()


@pytest.mark.parametrize(
    ("body", "field"),
    [
        ('{"label": NaN}', "label"),
        ('{"label": Infinity}', "label"),
        ('{"keep_frames": 1e999}', "keep_frames"),
        ('{"label": "\\ud800"}', "label"),
        ('{"codec": "gray\\udfff"}', "codec"),
        ("[NaN, -Infinity]", "body"),
    ],
)
def test_non_finite_numbers_and_lone_surrogates_are_422_naming_the_field(
    client: TestClient, body: str, field: str
) -> None:
    """The error echoes the bad input; where JSON cannot carry it (NaN, 1e999, a lone surrogate) it
    is shown by its repr instead of failing with a 500."""
    answer = client.post("/v1/scans", content=body, headers={**AUTH, "Content-Type": "application/json"})
    assert answer.status_code == 422, answer.text
    assert answer.json()["detail"][0]["loc"][-1] == field


@pytest.mark.parametrize(
    ("method", "path", "allowed"),
    [
        ("DELETE", "/v1/scans", "GET, HEAD, POST"),  # HEAD wherever GET is
        ("PATCH", "/v1/gallery", "GET, HEAD, POST"),
        ("PATCH", "/v1/scans/20261121-105227-a1b2c3", "DELETE, GET, HEAD"),
        ("POST", "/v1/imports/board/frame.png", "PUT"),
    ],
)
def test_a_405_lists_every_method_the_path_serves(client: TestClient, method: str, path: str, allowed: str) -> None:
    answer = client.request(method, path, headers=AUTH)
    assert answer.status_code == 405 and answer.headers["allow"] == allowed


def test_one_calibration_request_cannot_hold_the_rig_for_long(client: TestClient) -> None:
    """200 views would hold the rig for about ten minutes; over REST a request asks for 40 at most."""
    answer = client.post("/v1/calibrations", json={"what": "rig", "views": 200}, headers=AUTH)
    assert answer.status_code == 422 and answer.json()["detail"][0]["loc"][-1] == "views"
    assert "40" in answer.json()["detail"][0]["msg"]
    assert client.post("/v1/calibrations", json={"what": "rig", "views": 40}, headers=AUTH).status_code == 202
