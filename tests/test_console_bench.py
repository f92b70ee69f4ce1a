"""The bench over REST beyond scans, as the console's Rig page uses it: `doctor`'s checks and a
projector's power control, its calls made by the job worker."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
import yaml
from fastapi.testclient import TestClient

from rig.api.app import create_app
from rig.api.security import ApiSettings
from rig.config import load_config
from rig.service.job_service import JobService
from tests.conftest import small_config_data, write_config
from tests.test_hardware_rigs import REPO_CONFIG_DIR

KEY = "0123456789abcdef" * 2
AUTH = {"X-API-Key": KEY}


def _client(tmp_path: Path, data: dict) -> Iterator[tuple[TestClient, JobService]]:
    data["output"] = {"data_dir": str(tmp_path / "data")}
    service = JobService(load_config(write_config(tmp_path, data)))
    service.start()
    try:
        yield TestClient(create_app(service, ApiSettings(api_key=KEY)), base_url="http://127.0.0.1"), service
    finally:
        service.shutdown()


@pytest.fixture
def powered(tmp_path: Path) -> Iterator[tuple[TestClient, JobService]]:
    """An HDMI projector (offscreen) with a BenQ RS-232 power control on the serial fake, and a
    fake OAK camera: real drivers over protocol fakes."""
    data = yaml.safe_load((REPO_CONFIG_DIR / "bench-hdmi-oak.yaml").read_text())
    projector = data["projectors"][0]
    projector.update(resolution=[256, 192], latency_s=0.0, hdmi={"video_driver": "offscreen"})
    projector["geometry"]["intrinsics"] = {"fx": 320.0, "fy": 320.0, "cx": 127.5, "cy": 95.5}
    projector["power"] = {"protocol": "benq", "url": "simprojector://benq?power=off"}
    camera = data["cameras"][0]
    camera.update(resolution=[320, 256], oak={"backend": "fake"})
    camera["geometry"]["intrinsics"] = {"fx": 450.0, "fy": 450.0, "cx": 159.5, "cy": 127.5}
    yield from _client(tmp_path, data)


def test_power_and_input_go_to_the_projector_through_the_worker(powered: tuple[TestClient, JobService]) -> None:
    client, service = powered
    name = service.config.projectors[0].name
    closed = client.get(f"/v1/projectors/{name}/power")
    assert closed.status_code == 409 and "not open" in closed.json()["detail"]  # a read opens nothing
    on = client.put(f"/v1/projectors/{name}/power", json={"on": True}, headers=AUTH)
    assert on.status_code == 200 and on.json()["state"] in ("warming", "on")
    first = client.get(f"/v1/projectors/{name}/power").json()
    assert first["state"] in ("warming", "on")
    switched = client.put(f"/v1/projectors/{name}/power", json={"on": False}, headers=AUTH)
    assert switched.status_code == 200 and switched.json()["state"] in ("cooling", "off")
    assert client.put(f"/v1/projectors/{name}/input", json={"input": "hdmi"}, headers=AUTH).status_code == 200
    refused = client.put(f"/v1/projectors/{name}/input", json={"input": "betamax"}, headers=AUTH)
    assert refused.status_code == 409 and "betamax" in refused.json()["detail"]
    unknown = client.put("/v1/projectors/nosuch/power", json={"on": True}, headers=AUTH)
    assert unknown.status_code == 409 and "nosuch" in unknown.json()["detail"]
    assert client.put(f"/v1/projectors/{name}/power", json={"on": True}).status_code == 401
    assert client.put(f"/v1/projectors/{name}/power", json={"on": 1}, headers=AUTH).status_code == 422


def test_doctor_reports_what_the_machine_lacks_and_power_needs_a_power_control(tmp_path: Path) -> None:
    for client, service in _client(tmp_path, small_config_data()):
        assert client.get("/v1/doctor").json() == {"problems": []}  # the simulated bench needs nothing
        name = service.config.projectors[0].name
        missing = client.put(f"/v1/projectors/{name}/power", json={"on": True}, headers=AUTH)
        assert missing.status_code == 409 and "no power control" in missing.json()["detail"]


def test_doctor_names_the_device_and_the_fix(powered: tuple[TestClient, JobService]) -> None:
    client, _ = powered
    problems = client.get("/v1/doctor").json()["problems"]
    assert any(p["device"] == "rig" and "calibration" in p["problem"] for p in problems)  # nominal geometry
