"""What the console stands on, over HTTP without a browser: sessions and CSRF, aim mode and the
camera views, camera settings reaching the driver, binary clouds, and pages from this origin only."""

from __future__ import annotations

import io
import json
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from drivers.sim.projector import SimProjector
from rig.api.app import create_app
from rig.api.security import ApiSettings
from rig.config import load_config
from rig.patterns import codec_class
from rig.service.job_service import JobService
from tests.conftest import ply_vertex, small_config_data, wait_done, write_config

KEY = "0123456789abcdef" * 2
READ_KEY = "fedcba9876543210" * 2
AUTH = {"X-API-Key": KEY}


@pytest.fixture
def service(tmp_path: Path) -> Iterator[JobService]:
    data = small_config_data()
    data["output"] = {"data_dir": str(tmp_path / "data")}
    svc = JobService(load_config(write_config(tmp_path, data)))
    svc.start()
    yield svc
    svc.shutdown()


def _client(service: JobService, protect_reads: bool = False) -> TestClient:
    settings = ApiSettings(api_key=KEY, read_key=READ_KEY, protect_reads=protect_reads)
    return TestClient(create_app(service, settings), base_url="http://127.0.0.1")


def _frame(client: TestClient, after: int, **query: Any) -> Any:
    """The next frame after `after` (the daemon waits for one), within 30 s."""
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        response = client.get("/v1/cameras/0/frame.jpg", params={"after": after, **query})
        if response.status_code == 200:
            return response
        assert response.status_code == 204
    raise AssertionError("no frame within 30 s")


# --- sessions ---------------------------------------------------------------------------------
def test_a_login_sets_an_httponly_strict_cookie_and_changes_need_its_csrf_token(service: JobService) -> None:
    client = _client(service, protect_reads=True)
    assert client.get("/v1/rig").status_code == 401
    assert client.get("/v1/session").json() == {"role": None, "csrf": None}
    login = client.post("/v1/session", json={"key": KEY})
    assert login.status_code == 200
    cookie = login.headers["set-cookie"].lower()
    assert "httponly" in cookie and "samesite=strict" in cookie and "path=/" in cookie
    assert KEY not in login.text and KEY not in login.headers["set-cookie"]
    csrf = login.json()["csrf"]
    assert client.get("/v1/rig").status_code == 200  # the cookie reads
    refused = client.post("/v1/aim", json={"pattern": "white", "seconds": 5})
    assert refused.status_code == 403 and "CSRF" in refused.json()["detail"]
    wrong = client.post("/v1/aim", json={"pattern": "white", "seconds": 5}, headers={"X-CSRF-Token": "x" * 43})
    assert wrong.status_code == 403
    started = client.post("/v1/aim", json={"pattern": "white", "seconds": 5}, headers={"X-CSRF-Token": csrf})
    assert started.status_code == 202
    assert client.delete("/v1/aim", headers={"X-CSRF-Token": csrf}).status_code == 200
    assert client.delete("/v1/session", headers={"X-CSRF-Token": csrf}).status_code == 204
    assert client.get("/v1/rig").status_code == 401  # logged out: the cookie is gone, and the session with it
    assert client.get("/v1/session").json()["role"] is None


def test_a_wrong_key_gets_no_session_and_a_read_only_session_changes_nothing(service: JobService) -> None:
    client = _client(service, protect_reads=True)
    wrong = client.post("/v1/session", json={"key": "not the key at all"})
    assert wrong.status_code == 403 and "set-cookie" not in wrong.headers
    assert client.post("/v1/session", json={}).status_code == 422
    view = client.post("/v1/session", json={"key": READ_KEY}).json()
    assert view["role"] == "read"
    assert client.get("/v1/scans").status_code == 200
    changed = client.post("/v1/scans", json={}, headers={"X-CSRF-Token": view["csrf"]})
    assert changed.status_code == 403 and "read-only" in changed.json()["detail"]


def test_a_stolen_csrf_token_is_no_use_without_the_cookie(service: JobService) -> None:
    client = _client(service)
    csrf = client.post("/v1/session", json={"key": KEY}).json()["csrf"]
    other = _client(service)  # another browser: no cookie
    assert other.post("/v1/aim", json={"pattern": "white"}, headers={"X-CSRF-Token": csrf}).status_code == 401


# --- the pages --------------------------------------------------------------------------------
def test_the_console_and_the_api_docs_load_nothing_from_another_host(service: JobService) -> None:
    client = _client(service)
    page = client.get("/")
    assert page.status_code == 200 and 'src="/console/app.js"' in page.text
    assert "default-src 'self'" in page.headers["content-security-policy"]
    assert "script-src 'self';" in page.headers["content-security-policy"]  # no inline script
    docs = client.get("/docs")
    assert docs.status_code == 200
    for asset in ("/console/vendor/swagger/swagger-ui-bundle.js", "/console/vendor/swagger/swagger-ui.css"):
        assert asset in docs.text
        assert client.get(asset).status_code == 200
    static = Path(__file__).parent.parent / "rig" / "api" / "console_static"
    for path in [*static.rglob("*.js"), *static.rglob("*.html"), *static.rglob("*.css")]:
        text = path.read_text()
        assert "http://" not in text.replace("http://www.w3.org/2000/svg", "") and "https://" not in text, path
        assert client.get(f"/console/{path.relative_to(static)}").status_code == 200


# --- aim mode and the camera views ------------------------------------------------------------
def test_aim_mode_streams_changing_frames_and_an_exposure_change_reaches_the_camera(service: JobService) -> None:
    client = _client(service)
    idle = client.get("/v1/cameras/0/frame.jpg", params={"wait_s": 10})
    assert idle.status_code == 204 and "nothing captures" in idle.headers["x-reason"]  # no wait for nothing
    assert client.post("/v1/aim", json={"pattern": "crosshair", "seconds": 60}, headers=AUTH).status_code == 202
    first = _frame(client, 0, width=160, overlay="true")
    count = int(first.headers["x-frame"])
    second = _frame(client, count)
    assert int(second.headers["x-frame"]) > count
    assert first.headers["content-type"] == "image/jpeg" and first.content[:2] == b"\xff\xd8"
    assert sum(int(c) for c in first.headers["x-histogram"].split(",")) == 320 * 256  # the whole small camera
    dark = float(first.headers["x-dark-fraction"])
    assert 0.2 < dark < 1.0  # a crosshair lights a few lines: most of the view is dark

    set_to = client.put("/v1/cameras/0/settings", json={"exposure_us": 2500, "gain": 1.5}, headers=AUTH)
    assert set_to.status_code == 200 and set_to.json()["exposure_us"] == 2500
    device = service.open_rig.cameras[0]  # type: ignore[union-attr]
    assert device.exposure_us == 2500 and device.gain == 1.5
    after = _frame(client, int(set_to.json()["frame"] or 0))
    assert float(after.headers["x-exposure-us"]) == 2500 and float(after.headers["x-gain"]) == 1.5
    assert client.get("/v1/cameras").json()[0]["exposure_us"] == 2500

    refused = client.put("/v1/cameras/0/settings", json={"exposure_us": 0}, headers=AUTH)
    assert refused.status_code == 422 and "exposure_us" in json.dumps(refused.json())
    missing = client.put("/v1/cameras/3/settings", json={"exposure_us": 100}, headers=AUTH)
    assert missing.status_code == 409 and "camera" in missing.json()["detail"]  # this rig has one


def test_camera_settings_are_kept_for_the_next_rig(service: JobService) -> None:
    client = _client(service)
    assert client.put("/v1/cameras/0/settings", json={"exposure_us": 4000}, headers=AUTH).status_code == 200
    service._rigs.drop()  # a job that failed closes the rig; the next opens a new one
    job = client.post("/v1/scans", json={"codec": "gray"}, headers=AUTH).json()
    waits = client.put("/v1/cameras/0/settings", json={"exposure_us": 5000}, headers=AUTH)
    assert waits.status_code == 409 and job["id"] in waits.json()["detail"]  # jobs first, never a wait behind them
    done = wait_done(client, job["id"])
    manifest = client.get(f"/v1/scans/{done['id']}/files/manifest.json").json()
    assert manifest["devices"]["cameras"][0]["exposure_us"] == 4000  # the scan ran at what was set
    assert service.config.cameras[0].exposure_us != 4000


def test_aim_mode_shows_setup_patterns_on_a_hardware_synced_projector_and_scans_follow(tmp_path: Path) -> None:
    data = small_config_data()
    data["output"] = {"data_dir": str(tmp_path / "data")}
    data["projectors"][0].update(sync="hardware", pattern_period_us=8333)  # it plays preloaded sequences
    data["cameras"][0]["exposure_us"] = 8000.0
    svc = JobService(load_config(write_config(tmp_path, data)))
    svc.start()
    try:
        client = _client(svc)
        assert client.post("/v1/aim", json={"pattern": "white", "seconds": 30}, headers=AUTH).status_code == 202
        first = _frame(client, 0)
        assert client.get("/v1/aim").json()["state"] == "running"
        assert float(first.headers["x-dark-fraction"]) < 0.5  # the white pattern lights the scene
        client.delete("/v1/aim", headers=AUTH)
        job = client.post("/v1/scans", json={"codec": "gray"}, headers=AUTH).json()
        done = wait_done(client, job["id"])
        assert done["state"] == "done" and done["result"]["points"] > 10_000  # the sequence plays again
    finally:
        svc.shutdown()


def test_aim_mode_goes_dark_when_its_time_limit_passes(service: JobService) -> None:
    client = _client(service)
    client.post("/v1/aim", json={"pattern": "white", "seconds": 1.5}, headers=AUTH)
    _frame(client, 0)
    rig = service.open_rig
    assert rig is not None and not all(p.is_dark for p in rig.projectors)  # type: ignore[attr-defined]
    deadline = time.monotonic() + 20
    while client.get("/v1/aim").json()["state"] != "off" and time.monotonic() < deadline:
        time.sleep(0.1)
    assert client.get("/v1/aim").json() == {**client.get("/v1/aim").json(), "state": "off"}
    assert all(p.is_dark for p in rig.projectors)  # type: ignore[attr-defined]


def test_a_codec_pattern_is_shown_as_the_scan_would_show_it(
    service: JobService, monkeypatch: pytest.MonkeyPatch
) -> None:
    shown: list[np.ndarray] = []
    original = SimProjector._do_show
    monkeypatch.setattr(
        SimProjector, "_do_show", lambda self, pattern: (shown.append(pattern), original(self, pattern))
    )
    client = _client(service)
    answer = client.post("/v1/aim", json={"pattern": "codec", "codec": "gray", "index": 9999}, headers=AUTH)
    assert answer.status_code == 409 and "index: gray has patterns 0 to 17" in answer.json()["detail"]
    board = client.post("/v1/aim", json={"pattern": "checkerboard", "square_px": 500}, headers=AUTH)
    assert board.status_code == 409 and "square_px" in board.json()["detail"]
    assert (
        client.post("/v1/aim", json={"pattern": "codec", "codec": "gray", "index": 3}, headers=AUTH).status_code == 202
    )
    _frame(client, 0)
    resolution = tuple(service.config.projectors[0].resolution)
    expected = codec_class("gray")(resolution, service.config.with_codec("gray").scan.gray).patterns()[3]
    assert shown and np.array_equal(shown[-1], expected)
    client.delete("/v1/aim", headers=AUTH)


def test_aim_mode_waits_while_live_mode_runs(service: JobService) -> None:
    client = _client(service)
    assert client.post("/v1/live", json={}, headers=AUTH).status_code == 202
    refused = client.post("/v1/aim", json={"pattern": "white"}, headers=AUTH)
    assert refused.status_code == 409 and "live mode" in refused.json()["detail"]
    client.delete("/v1/live", headers=AUTH)


# --- clouds -----------------------------------------------------------------------------------
def _body(data: bytes) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    length = int.from_bytes(data[:4], "little")
    header = json.loads(data[4 : 4 + length])
    arrays = {}
    for a in header["arrays"]:
        start = 4 + length + a["offset"]
        arrays[a["name"]] = np.frombuffer(data, a["type"], a["count"] * a["components"], start).reshape(a["count"], -1)
    return header, arrays


def test_a_cloud_reaches_the_viewer_as_compact_binary_decimated_to_a_budget(service: JobService) -> None:
    client = _client(service)
    job = wait_done(client, client.post("/v1/scans", json={"codec": "gray"}, headers=AUTH).json()["id"])
    ply = client.get(f"/v1/scans/{job['id']}/files/cloud.ply").content
    vertex = ply_vertex(ply)
    full_points = np.column_stack([vertex[a] for a in "xyz"])
    total = len(full_points)
    budget = total // 3
    header, arrays = _body(client.get(f"/v1/scans/{job['id']}/cloud.bin", params={"budget": budget}).content)
    assert header["points"] == budget and header["total"] == total
    assert arrays["position"].dtype == np.float32 and arrays["color"].dtype == np.uint8
    rows = {tuple(p) for p in full_points.tolist()}
    assert all(tuple(p) in rows for p in arrays["position"].tolist())  # a subset of the scan's own points
    whole = client.get(f"/v1/scans/{job['id']}/cloud.bin", params={"budget": 0})
    header, arrays = _body(whole.content)
    assert header["points"] == total
    assert np.array_equal(arrays["position"], full_points.astype(np.float32))
    colours = np.column_stack([vertex[c] for c in ("red", "green", "blue")])
    assert np.array_equal(arrays["color"], colours)
    normals = np.column_stack([vertex[f"n{a}"] for a in "xyz"])
    assert np.abs(arrays["normal"] / 127.0 - normals).max() < 0.01
    per_point = 12 + 3 + 3 + 1 + 4  # position, colour, normal, quality, error: no more than that
    assert len(whole.content) <= 4 + 4096 + total * per_point + 5 * 3 and len(whole.content) < 0.65 * len(ply)
    truth = np.load(io.BytesIO(client.get(f"/v1/scans/{job['id']}/files/truth_error_mm.npy").content))
    assert np.array_equal(arrays["error"][:, 0], truth)  # each point's distance to the true surface
    manifest = client.get(f"/v1/scans/{job['id']}/files/manifest.json").json()
    rms = float(np.sqrt(np.mean(truth.astype(np.float64) ** 2)))
    assert rms == pytest.approx(next(iter(manifest["metrics"].values()))["rms_mm"], rel=1e-3)
    assert client.get(f"/v1/scans/{job['id']}/mesh.bin").status_code == 404  # a gray scan has no ring mesh


def test_a_calibration_report_has_every_corners_error_and_its_plot(service: JobService) -> None:
    client = _client(service)
    job = client.post("/v1/calibrations", json={"what": "rig", "views": 6}, headers=AUTH).json()
    done = wait_done(client, job["id"], "calibrations")
    for name, device in done["result"]["report"]["devices"].items():
        corners = device["corner_residual_px"]
        # the corners' own errors add up to the fit's rms: residuals from the model that was kept
        assert corners["rms"] == pytest.approx(device["rms_px"], rel=0.02, abs=2e-4)
        assert corners["p50"] <= corners["p95"] <= corners["max"]
        plot = client.get(f"/v1/calibrations/{job['id']}/files/residuals_{name}.png")
        assert plot.status_code == 200 and plot.content[:8] == b"\x89PNG\r\n\x1a\n"
    views = [f for f in done["result"]["files"] if f.startswith("view_")]
    assert len(views) == 6  # each view of the one camera, with its corners drawn
    first = client.get(f"/v1/calibrations/{job['id']}/files/{views[0]}")
    assert first.status_code == 200 and first.content[:2] == b"\xff\xd8"
