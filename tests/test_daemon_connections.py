"""`slrig serve` against clients that hold connections: idle sockets, slow headers, stalled
bodies, bursts of event streams; and a port that another program holds. Each test asserts the
README's promise for it (docs: Reliability)."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.conftest import small_config_data
from tests.loopback import daemon_http
from tests.ports import free_port
from tests.test_daemon import AUTH, KEY, REPO, Daemon, _config, status_code

STREAMS_CAP = 64  # rig.api.streams.MAX_EVENT_STREAMS, as the README states it
PER_CLIENT_CAP = 16  # rig.api.streams.MAX_EVENT_STREAMS_PER_CLIENT


@pytest.fixture
def busy(tmp_path: Path) -> Iterator[tuple[Daemon, str]]:
    """A daemon whose scan runs for 30 s (its camera stalls), with short connection bounds."""
    data = small_config_data()
    data["cameras"][0]["sim"]["faults"] = {"stall_after_frames": 3}
    data["scan"] = {"capture_timeout_s": 30.0}
    config = _config(tmp_path, data, header_timeout_s=1.0, body_stall_s=1.0)
    daemon = Daemon(config, tmp_path / "daemon.log")
    job_id = daemon_http.post(f"{daemon.url}/v1/scans", json={}, headers=AUTH).json()["id"]
    yield daemon, job_id
    daemon.stop()


def _connect(port: int, source: str = "127.0.0.1") -> socket.socket:
    return socket.create_connection(("127.0.0.1", port), timeout=10, source_address=(source, 0))


def test_idle_connections_and_a_burst_of_event_streams_leave_health_answerable(busy: tuple[Daemon, str]) -> None:
    daemon, job_id = busy
    idle = [_connect(daemon.port) for _ in range(200)]  # never send a byte (uvicorn's old cap was 128)
    streams = [_connect(daemon.port, f"127.0.0.{1 + k % 20}") for k in range(200)]  # 10 from each of 20 addresses
    request = f"GET /v1/scans/{job_id}/events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n".encode()
    for sock in streams:
        sock.sendall(request)  # all at once: the cap must hold for a burst
    codes = [status_code(sock) for sock in streams]
    assert codes.count(200) == STREAMS_CAP and codes.count(503) == len(streams) - STREAMS_CAP
    health = daemon_http.get(f"{daemon.url}/v1/health", timeout=5)
    assert health.status_code == 200
    for sock in streams[:10]:
        sock.close()  # their slots come back
    time.sleep(0.5)
    again = _connect(daemon.port)
    again.sendall(request)
    assert status_code(again) == 200
    for sock in (*idle, *streams, again):
        sock.close()


def test_one_address_cannot_hold_every_event_stream(busy: tuple[Daemon, str]) -> None:
    daemon, job_id = busy
    request = f"GET /v1/scans/{job_id}/events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n".encode()
    mine = [_connect(daemon.port, "127.0.0.2") for _ in range(PER_CLIENT_CAP + 4)]
    for sock in mine:
        sock.sendall(request)
    codes = [status_code(sock) for sock in mine]
    assert codes.count(200) == PER_CLIENT_CAP and codes.count(503) == 4
    other = _connect(daemon.port, "127.0.0.3")
    other.sendall(request)
    assert status_code(other) == 200  # another address still finds a slot
    for sock in (*mine, other):
        sock.close()


def test_silent_connections_are_closed_and_a_stalled_body_gets_408(busy: tuple[Daemon, str]) -> None:
    daemon, _ = busy
    silent = _connect(daemon.port)
    slow = _connect(daemon.port)
    slow.sendall(b"GET /v1/health HTTP/1.1\r\nHost: 127.0.0.1\r\n")  # headers never finished
    stalled = _connect(daemon.port)
    head = f"POST /v1/scans HTTP/1.1\r\nHost: 127.0.0.1\r\nX-API-Key: {KEY}\r\nContent-Type: application/json\r\n"
    stalled.sendall(f'{head}Content-Length: 100\r\n\r\n{{"label":'.encode())
    started = time.monotonic()
    assert silent.recv(1) == b"" and slow.recv(1) == b""  # closed by the daemon, not by the 10 s timeout
    assert status_code(stalled) == 408
    assert time.monotonic() - started < 5.0
    for sock in (silent, slow, stalled):
        sock.close()


def test_a_port_in_use_is_refused_naming_it(small_config_path: Path) -> None:
    with socket.socket() as holder:
        port = free_port()
        holder.bind(("127.0.0.1", port))
        holder.listen()
        run = subprocess.run(
            [sys.executable, "-m", "rig.cli", "serve", "--config", str(small_config_path), "--port", str(port)],
            cwd=REPO,
            env={**os.environ, "SLRIG_API_KEY": KEY},
            capture_output=True,
            text=True,
            timeout=60,
        )
    assert run.returncode == 2 and f"--port {port}" in run.stderr and "in use" in run.stderr
    assert "Traceback" not in run.stderr
