"""Read access as a choice (service.read_access): open on loopback and protected beyond by
default, or either way by the config; and a read-only key that lets a dashboard watch and change
nothing."""

from __future__ import annotations

from pathlib import Path

import pytest

from rig.config import load_config
from rig.daemon.server import api_settings
from tests.conftest import small_config_data, write_config
from tests.test_api import AUTH, KEY, _client, _service

READ_KEY = "r" * 32


@pytest.mark.parametrize(
    ("access", "host", "protected"),
    [
        ("auto", "127.0.0.1", False),
        ("auto", "::1", False),
        ("auto", "192.0.2.7", True),
        ("key", "127.0.0.1", True),
        ("open", "192.0.2.7", False),
    ],
)
def test_read_access_follows_the_config(tmp_path: Path, access: str, host: str, protected: bool) -> None:
    data = small_config_data()
    data["service"] = {"read_access": access}
    config = load_config(write_config(tmp_path, data))
    assert api_settings(config, host, KEY).protect_reads is protected


def test_an_unknown_read_access_is_refused_naming_the_field(tmp_path: Path) -> None:
    from rig.errors import ConfigError

    data = small_config_data()
    data["service"] = {"read_access": "sometimes"}
    with pytest.raises(ConfigError, match=r"service\.read_access"):
        load_config(write_config(tmp_path, data))


def test_a_read_only_key_reads_and_changes_nothing(tmp_path: Path) -> None:
    service = _service(tmp_path, start=False)
    try:
        with _client(service, protect_reads=True, read_key=READ_KEY) as client:
            reader = {"X-API-Key": READ_KEY}
            assert client.get("/v1/scans").status_code == 401  # reads are protected: a key is needed
            assert client.get("/v1/scans", headers={"X-API-Key": "x" * 32}).status_code == 403
            assert client.get("/v1/scans", headers=reader).status_code == 200
            assert client.get("/v1/health", headers={"Authorization": f"Bearer {READ_KEY}"}).status_code == 200
            refused = client.post("/v1/scans", json={}, headers=reader)
            assert refused.status_code == 403 and "read-only" in refused.json()["detail"]
            assert client.get("/v1/scans", headers=reader).json()["total"] == 0  # nothing was queued
            assert client.post("/v1/scans", json={}, headers=AUTH).status_code == 202
            assert client.get("/v1/scans", headers=AUTH).json()["total"] == 1
    finally:
        service.store.close()


def test_without_a_read_key_only_the_api_key_opens_protected_reads(tmp_path: Path) -> None:
    service = _service(tmp_path, start=False)
    try:
        with _client(service, protect_reads=True) as client:
            assert client.get("/v1/scans", headers={"X-API-Key": READ_KEY}).status_code == 403
            assert client.get("/v1/scans", headers=AUTH).status_code == 200
    finally:
        service.store.close()
