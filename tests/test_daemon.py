"""`slrig serve` as a real process on loopback (uvicorn, the simulated bench): a scan over HTTP equal
to the CLI's, bounded load, SIGKILL and restart, SIGTERM mid-scan, systemd notification, the
API key kept out of the logs, and the unit file."""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import random
import shutil
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest

from rig.cli import main
from rig.service.job_service import DB_NAME
from rig.service.jobs import JobStore
from tests.conftest import default_config_data, ply_xyz, small_config_data, wait_done, write_config
from tests.loopback import daemon_http
from tests.ports import free_port

REPO = Path(__file__).resolve().parents[1]
KEY = "0123456789abcdef" * 2
AUTH = {"X-API-Key": KEY}


def status_code(sock: socket.socket) -> int:
    """The HTTP status of the response arriving on a raw socket (0: closed without one)."""
    head = b""
    while b"\r\n" not in head:
        chunk = sock.recv(256)
        if not chunk:
            return 0
        head += chunk
    return int(head.split(b" ", 2)[1])


class Daemon:
    """`python -m rig.cli serve` in its own process; its stderr goes to `log`."""

    def __init__(self, config: Path, log: Path, env: dict[str, str] | None = None) -> None:
        self.log = log
        for _ in range(5):  # another program may take the port between our check and the child's bind
            if self._start(config, {**os.environ, "SLRIG_API_KEY": KEY, **(env or {})}):
                return
        raise AssertionError(f"no port was free for the daemon: {log.read_text()}")

    def _start(self, config: Path, environment: dict[str, str]) -> bool:
        """Starts the daemon on a fresh port: True when it answers, False when the port was taken."""
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        already = self.log.stat().st_size if self.log.exists() else 0
        with self.log.open("ab") as err:
            self.process = subprocess.Popen(
                [sys.executable, "-m", "rig.cli", "serve", "--config", str(config), "--port", str(self.port)],
                cwd=REPO,
                env=environment,
                stdout=subprocess.DEVNULL,
                stderr=err,
            )
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            if self.process.poll() is not None:
                said = self.log.read_bytes()[already:].decode(errors="replace")
                if f"--port {self.port}:" in said and "is in use" in said:
                    return False
                raise AssertionError(f"the daemon exited: {self.log.read_text()}")
            try:
                if daemon_http.get(f"{self.url}/v1/health", timeout=1).status_code == 200:
                    return True
            except httpx.TransportError:
                time.sleep(0.1)
        raise AssertionError("the daemon did not come up")

    def stop(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait(10)


def _config(tmp_path: Path, data: dict[str, Any], name: str = "serve.yaml", **service: Any) -> Path:
    data["output"] = {"data_dir": str(tmp_path / "data")}
    data["service"] = service
    return write_config(tmp_path, data, name)


@pytest.fixture
def small(tmp_path: Path) -> Path:
    return _config(tmp_path, small_config_data(), max_queue=4)


@pytest.fixture
def daemon(small: Path, tmp_path: Path) -> Iterator[Daemon]:
    d = Daemon(small, tmp_path / "daemon.log")
    yield d
    d.stop()


def test_a_scan_over_http_gives_the_clis_cloud(daemon: Daemon, small: Path, tmp_path: Path) -> None:
    created = daemon_http.post(f"{daemon.url}/v1/scans", json={"codec": "phase"}, headers=AUTH)
    assert created.status_code == 202
    job_id = created.json()["id"]
    states = []
    with daemon_http.stream("GET", f"{daemon.url}/v1/scans/{job_id}/events", timeout=60) as events:
        for line in events.iter_lines():
            if line.startswith("data: ") and '"state"' in line:
                states.append(json.loads(line[6:])["state"])
    assert states[-1] == "done" and "running" in states
    served = daemon_http.get(f"{daemon.url}/v1/scans/{job_id}/files/cloud.ply")
    assert served.status_code == 200

    assert main(["scan", "--config", str(small), "--codec", "phase", "--out", str(tmp_path / "cli")]) == 0
    by_cli = (tmp_path / "cli" / "cloud.ply").read_bytes()
    assert np.array_equal(ply_xyz(served.content), ply_xyz(by_cli))

    assert daemon_http.post(f"{daemon.url}/v1/scans", json={}, headers={"X-API-Key": "wrong" * 8}).status_code == 403
    assert daemon_http.post(f"{daemon.url}/v1/scans", json={}).status_code == 401
    assert daemon_http.get(f"{daemon.url}/v1/scans?limit=1&api_key={KEY}").status_code == 200  # a key in the query
    log = daemon.log.read_text()
    assert "GET /v1/scans?limit=REDACTED&api_key=REDACTED" in log  # the access line, values never written
    assert f"scan {job_id}: running -> done" in log  # one journal line per state change, with the id
    assert KEY not in log and "wrong" * 8 not in log


def test_bounded_load_every_request_answered(daemon: Daemon) -> None:
    """20 clients, 500 requests mixed: no 5xx, the queue bound shows as 429, and every accepted
    scan is listed once and ends."""
    rng = random.Random(7)
    plan = rng.choices(["create", "status", "list", "download"], weights=[3, 3, 3, 1], k=500)
    accepted: list[str] = []
    codes: list[int] = []

    async def client(jobs: list[str]) -> None:
        async with httpx.AsyncClient(base_url=daemon.url, timeout=30) as http:
            for action in jobs:
                known = accepted[-1] if accepted else "20261121-000000-000000"
                if action == "create":
                    response = await http.post("/v1/scans", json={}, headers=AUTH)
                    if response.status_code == 202:
                        accepted.append(response.json()["id"])
                elif action == "status":
                    response = await http.get(f"/v1/scans/{known}")
                elif action == "list":
                    response = await http.get("/v1/scans", params={"limit": 10})
                else:
                    response = await http.get(f"/v1/scans/{known}/files/cloud.ply")
                codes.append(response.status_code)

    async def run() -> None:
        await asyncio.gather(*(client(plan[i::20]) for i in range(20)))

    asyncio.run(run())
    assert len(codes) == 500
    assert not [c for c in codes if c >= 500]
    assert 429 in codes  # the queue bound was reached and enforced
    assert set(codes) <= {200, 202, 404, 409, 429}  # 404/409: a download before a scan was done
    with httpx.Client(base_url=daemon.url) as http:
        assert all(wait_done(http, job_id)["state"] == "done" for job_id in accepted)
    listed: list[str] = []
    page = daemon_http.get(f"{daemon.url}/v1/scans", params={"limit": 100}).json()
    while True:
        listed += [j["id"] for j in page["items"]]
        if len(listed) >= page["total"]:
            break
        page = daemon_http.get(f"{daemon.url}/v1/scans", params={"limit": 100, "offset": len(listed)}).json()
    assert sorted(listed) == sorted(accepted) and len(set(listed)) == len(listed)


def _running(url: str, job_id: str) -> None:
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        job = daemon_http.get(f"{url}/v1/scans/{job_id}").json()
        if job["state"] == "running" and job["fraction"] > 0.05:
            return
        time.sleep(0.02)
    raise AssertionError("the scan never ran")


def test_sigkill_mid_scan_then_restart(tmp_path: Path) -> None:
    config = _config(tmp_path, default_config_data())  # a full-size scan: seconds of capture
    first = Daemon(config, tmp_path / "first.log")
    try:
        job_id = daemon_http.post(f"{first.url}/v1/scans", json={}, headers=AUTH).json()["id"]
        _running(first.url, job_id)
        first.process.send_signal(signal.SIGKILL)
        first.process.wait(10)
    finally:
        first.stop()
    scans = tmp_path / "data" / "scans"
    assert not (scans / job_id).exists()  # never a finished-looking directory

    second = Daemon(config, tmp_path / "second.log")
    try:
        assert JobStore(tmp_path / "data" / DB_NAME).integrity_ok()
        job = daemon_http.get(f"{second.url}/v1/scans/{job_id}").json()
        assert job["state"] == "interrupted" and "not re-run" in job["error"]
        assert not list(scans.glob("*.partial"))
        assert [j["id"] for j in daemon_http.get(f"{second.url}/v1/scans").json()["items"]] == [job_id]
        nxt = daemon_http.post(f"{second.url}/v1/scans", json={"codec": "gray"}, headers=AUTH).json()["id"]
        with httpx.Client(base_url=second.url) as http:
            assert wait_done(http, nxt)["state"] == "done"
        assert job["state"] == daemon_http.get(f"{second.url}/v1/scans/{job_id}").json()["state"]  # not re-run
    finally:
        second.stop()


def test_sigterm_mid_scan_exits_within_10_s_dark(tmp_path: Path) -> None:
    config = _config(tmp_path, default_config_data())
    d = Daemon(config, tmp_path / "daemon.log")
    try:
        job_id = daemon_http.post(f"{d.url}/v1/scans", json={}, headers=AUTH).json()["id"]
        _running(d.url, job_id)
        start = time.monotonic()
        d.process.send_signal(signal.SIGTERM)
        code = d.process.wait(10)
        elapsed = time.monotonic() - start
    finally:
        d.stop()
    assert code == 0 and elapsed < 10
    log = d.log.read_text()
    assert "projectors dark" in log
    assert JobStore(tmp_path / "data" / DB_NAME).get(job_id).state == "interrupted"


@contextlib.contextmanager
def _systemd(config: Path, tmp_path: Path) -> Iterator[tuple[socket.socket, Daemon]]:
    """A daemon told to notify a datagram socket (as systemd's), with a 0.4 s watchdog."""
    path = tmp_path / "notify.sock"
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as sock:
        sock.bind(str(path))
        sock.settimeout(10)
        d = Daemon(config, tmp_path / "daemon.log", {"NOTIFY_SOCKET": str(path), "WATCHDOG_USEC": "400000"})
        try:
            yield sock, d
        finally:
            d.stop()


def test_systemd_hears_ready_watchdog_and_stopping(small: Path, tmp_path: Path) -> None:
    with _systemd(small, tmp_path) as (sock, d):
        received: list[str] = []
        pings: list[float] = []
        while len(pings) < 4:
            message = sock.recv(4096).decode()
            received.append(message)
            if message == "WATCHDOG=1":
                pings.append(time.monotonic())
        assert received[0].startswith("READY=1\nSTATUS=serving on 127.0.0.1:")
        assert np.diff(pings).max() < 0.4  # at least every half interval (0.2 s), with slack for scheduling
        d.process.send_signal(signal.SIGTERM)
        while "STOPPING=1" not in received:
            received.append(sock.recv(4096).decode())
        assert d.process.wait(10) == 0


def _serve_once(config: Path, env: dict[str, str], *extra: str) -> subprocess.CompletedProcess[str]:
    command = [sys.executable, "-m", "rig.cli", "serve", "--config", str(config), "--port", "0", *extra]
    return subprocess.run(command, cwd=REPO, env=env, capture_output=True, text=True, timeout=60)


def test_a_key_that_guards_nothing_is_refused(small: Path) -> None:
    env = {**os.environ, "SLRIG_API_KEY": "changeme"}
    run = _serve_once(small, env)
    assert run.returncode == 2 and "SLRIG_API_KEY: the API key is a placeholder" in run.stderr
    env["SLRIG_API_KEY"] = KEY
    run = _serve_once(small, env, "--host", "0.0.0.0")
    assert run.returncode == 2 and "service.allowed_hosts: listening on all addresses" in run.stderr


def test_without_a_key_one_is_generated_and_mutations_still_need_it(small: Path, tmp_path: Path) -> None:
    d = Daemon(small, tmp_path / "daemon.log", env={"SLRIG_API_KEY": ""})  # no key given
    try:
        path = tmp_path / "data" / "api-key"
        key = path.read_text().strip()
        assert path.stat().st_mode & 0o777 == 0o600 and len(key) == 64
        assert daemon_http.post(f"{d.url}/v1/scans", json={}).status_code == 401
        assert daemon_http.post(f"{d.url}/v1/scans", json={}, headers={"X-API-Key": key}).status_code == 202
        assert key not in d.log.read_text() and str(path) in d.log.read_text()
    finally:
        d.stop()


def test_the_watchdog_stops_while_a_driver_is_stuck(tmp_path: Path) -> None:
    """A camera that never delivers (a wedged driver) and a job that reports nothing for longer
    than health_stale_s: the pings stop and systemd would restart the service. Asserted by what
    the daemon sends, not by the clock (a loaded machine delays every step): never unhealthy before
    health_stale_s, unhealthy while the camera is still stuck (long before its capture timeout ends
    the job), and from then on no ping at all for many watchdog intervals."""
    stale_s, stuck_s = 5.0, 60.0
    data = small_config_data()
    data["cameras"][0]["sim"]["faults"] = {"stall_after_frames": 2}
    data["scan"]["capture_timeout_s"] = stuck_s
    config = _config(tmp_path, data, "stuck.yaml", health_stale_s=stale_s)
    with _systemd(config, tmp_path) as (sock, d):
        sock.settimeout(stuck_s / 2)  # a message comes every interval (0.2 s): this only bounds a hang
        assert sock.recv(4096).startswith(b"READY=1")
        assert sock.recv(4096) == b"WATCHDOG=1"
        start = time.monotonic()  # before the job exists: its heartbeat is no older than this
        daemon_http.post(f"{d.url}/v1/scans", json={}, headers=AUTH)
        while (message := sock.recv(4096)) != b"STATUS=job worker unhealthy":
            assert message == b"WATCHDOG=1"
        unhealthy_after = time.monotonic() - start
        assert stale_s <= unhealthy_after < stuck_s / 2  # the stall, not the capture timeout's end
        after = [sock.recv(4096) for _ in range(20)]  # twenty more intervals: still stuck, still silent
        assert b"WATCHDOG=1" not in after and set(after) == {b"STATUS=job worker unhealthy"}


def test_the_unit_file_verifies(tmp_path: Path) -> None:
    analyze = shutil.which("systemd-analyze")
    if analyze is None:
        pytest.skip("systemd-analyze is not installed here (no systemd)")
    slrig = Path(sys.executable).with_name("slrig")
    unit = (REPO / "systemd" / "slrig.service").read_text().replace("/opt/slrig/venv/bin/slrig", str(slrig))
    (tmp_path / "slrig.service").write_text(unit)
    result = subprocess.run([analyze, "verify", str(tmp_path / "slrig.service")], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert "Type=notify" in unit and "WatchdogSec=" in unit and "PrivateDevices=no" in unit


def test_the_access_log_writes_query_names_not_values() -> None:
    import logging

    from rig.daemon.logs import RedactQueryValues

    record = logging.LogRecord(
        "uvicorn.access",
        logging.INFO,
        __file__,
        1,
        '%s - "%s %s HTTP/%s" %d',
        ("127.0.0.1:5000", "GET", "/v1/scans?token=s3cret&x=&api_key=k%20k", "1.1", 200),
        None,
    )
    assert RedactQueryValues().filter(record)
    line = record.getMessage()
    assert "s3cret" not in line and "k%20k" not in line
    assert '"GET /v1/scans?token=REDACTED&x=REDACTED&api_key=REDACTED HTTP/1.1" 200' in line
