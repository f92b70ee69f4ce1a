"""Clients that ask for a large file and never read it cannot lock others out: downloads are capped
(overall and per address), a response the client holds back is cut once it drains slower than
service.min_send_rate, and past service.max_connections unauthenticated slow readers are closed
before any authenticated request. Files are served with Range and HEAD."""

from __future__ import annotations

import os
import socket
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from rig.service.jobs import DB_NAME, JobStore, JobType
from tests.conftest import default_config_data, small_config_data, wait_done
from tests.loopback import daemon_http
from tests.test_daemon import AUTH, KEY, Daemon, _config, status_code

LARGE = 256 * 1024 * 1024  # far more than the kernel's socket buffers hold


def _daemon(tmp_path: Path, **service: Any) -> tuple[Daemon, str]:
    """A daemon with one finished scan whose cloud.ply is made LARGE (zeros, sparse on disk)."""
    daemon = Daemon(_config(tmp_path, small_config_data(), header_timeout_s=2.0, **service), tmp_path / "d.log")
    with httpx.Client(base_url=daemon.url) as client:
        job_id = client.post("/v1/scans", json={}, headers=AUTH).json()["id"]
        assert wait_done(client, job_id)["state"] == "done"
    os.truncate(tmp_path / "data" / "scans" / job_id / "cloud.ply", LARGE)
    return daemon, job_id


def _slow_reader(daemon: Daemon, job_id: str, key: str | None = None) -> socket.socket:
    """A connection that asks for the large file and reads nothing (a small receive buffer)."""
    sock = socket.socket()
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    sock.settimeout(30)
    sock.connect(("127.0.0.1", daemon.port))
    auth = f"X-API-Key: {key}\r\n" if key else ""
    sock.sendall(f"GET /v1/scans/{job_id}/files/cloud.ply HTTP/1.1\r\nHost: 127.0.0.1\r\n{auth}\r\n".encode())
    return sock


def _received_until_closed(sock: socket.socket) -> int:
    total = 0
    try:
        while chunk := sock.recv(1 << 20):
            total += len(chunk)
    except (ConnectionResetError, TimeoutError):
        pass
    return total


@pytest.fixture
def capped(tmp_path: Path) -> Iterator[tuple[Daemon, str]]:
    daemon, job_id = _daemon(tmp_path, max_connections=16, send_timeout_s=1.0, min_send_rate=65536)
    yield daemon, job_id
    daemon.stop()


def test_slow_readers_get_a_few_slots_and_are_cut(capped: tuple[Daemon, str]) -> None:
    daemon, job_id = capped
    readers, codes = [], []
    for _ in range(60):  # one address: 4 downloads at most; the others' connections go idle
        readers.append(_slow_reader(daemon, job_id))
        codes.append(status_code(readers[-1]))
    assert codes.count(200) == 4 and codes.count(429) == 56
    for _ in range(5):  # every slot of connections was offered meanwhile: health still answers
        assert daemon_http.get(f"{daemon.url}/v1/health", timeout=10).status_code == 200
    deadline = time.monotonic() + 120  # each is judged every send_timeout_s once its buffers are full
    while daemon.log.read_text().count("cutting a connection that took") < 4 and time.monotonic() < deadline:
        time.sleep(0.2)
    holding = [sock for sock, code in zip(readers, codes, strict=True) if code == 200]
    for sock in holding:  # cut, not waited out: each took far less than the file
        assert _received_until_closed(sock) < LARGE // 4
    for sock in readers:
        sock.close()


def test_past_the_connection_cap_slow_readers_go_before_an_authenticated_download(tmp_path: Path) -> None:
    daemon, job_id = _daemon(
        tmp_path, max_connections=16, send_timeout_s=600.0, max_downloads=100, max_downloads_per_client=100
    )
    try:
        mine = _slow_reader(daemon, job_id, key=KEY)  # the oldest: an age-only rule would close it first
        assert status_code(mine) == 200
        attackers = []
        for _ in range(30):  # each one's response begun before the next comes: busy, not idle, at the cap
            attackers.append(_slow_reader(daemon, job_id))
            status_code(attackers[-1])
        for _ in range(5):
            assert daemon_http.get(f"{daemon.url}/v1/health", timeout=10).status_code == 200
        mine.settimeout(5)
        assert len(mine.recv(65536)) > 0  # still being served
        log = daemon.log.read_text()
        assert "closing a slow reader" in log or "closing a request" in log
        for sock in attackers:
            sock.close()
        mine.close()
    finally:
        daemon.stop()


def test_files_are_served_with_range_and_head(tmp_path: Path) -> None:
    daemon = Daemon(_config(tmp_path, small_config_data()), tmp_path / "d.log")
    try:
        with httpx.Client(base_url=daemon.url, timeout=30) as client:
            job_id = client.post("/v1/scans", json={}, headers=AUTH).json()["id"]
            wait_done(client, job_id)
            url = f"/v1/scans/{job_id}/files/cloud.ply"
            whole = client.get(url).content
            head = client.head(url)
            assert head.status_code == 200 and head.content == b""
            assert int(head.headers["content-length"]) == len(whole) and head.headers["accept-ranges"] == "bytes"
            part = client.get(url, headers={"Range": "bytes=10-109"})
            assert part.status_code == 206 and part.content == whole[10:110]
            assert part.headers["content-range"] == f"bytes 10-109/{len(whole)}"
            assert client.get(url, headers={"Range": f"bytes={len(whole) + 5}-"}).status_code == 416
            for path in ("/v1/health", "/v1/scans", f"/v1/scans/{job_id}", "/v1/rig", f"/v1/scans/{job_id}/events"):
                answer = client.head(path)
                assert answer.status_code == 200 and answer.content == b"", path
            assert "HEAD" in client.put("/v1/health").headers["allow"]
    finally:
        daemon.stop()


def _eventually_served(client: httpx.Client, url: str, within_s: float = 30.0) -> bool:
    deadline = time.monotonic() + within_s
    while (answer := client.get(url)).status_code == 429 and time.monotonic() < deadline:
        time.sleep(0.05)
    return answer.status_code == 200


def test_a_download_cap_frees_its_slot_when_the_download_ends(tmp_path: Path) -> None:
    # the default bench: its 39 MB cloud cannot fit in the sockets' buffers, so the download held
    # stays in flight (the small bench's 2 MB could, and then it would end while held)
    daemon = Daemon(_config(tmp_path, default_config_data(), max_downloads=1), tmp_path / "d.log")
    try:
        with httpx.Client(base_url=daemon.url, timeout=30) as client:
            job_id = client.post("/v1/scans", json={}, headers=AUTH).json()["id"]
            wait_done(client, job_id)
            url = f"/v1/scans/{job_id}/files/manifest.json"
            for _ in range(5):  # one at a time: each ends (its slot given back a moment after its last byte)
                assert _eventually_served(client, url)
            with (
                httpx.Client(base_url=daemon.url, timeout=30) as other,
                other.stream("GET", f"/v1/scans/{job_id}/files/cloud.ply") as held,
            ):
                assert held.status_code == 200
                refused = client.get(url)
                assert refused.status_code == 429 and "retry-after" in refused.headers
            assert _eventually_served(client, url)  # the held download ends as its client goes away
    finally:
        daemon.stop()


def _held_by_the_daemon(port: int) -> int:
    """Connections the daemon still holds open (established, on its side) with bytes unsent."""
    held = 0
    for line in Path("/proc/net/tcp").read_text().splitlines()[1:]:
        fields = line.split()
        local, state, queues = fields[1], fields[3], fields[4]
        if int(local.split(":")[1], 16) == port and state == "01" and int(queues.split(":")[0], 16) > 0:
            held += 1
    return held


@pytest.mark.skipif(not Path("/proc/net/tcp").exists(), reason="reads the daemon's sockets from /proc/net/tcp")
def test_a_finished_response_the_client_never_reads_is_not_kept_for_ever(tmp_path: Path) -> None:
    """A listing of large records is written in one piece: the response is complete and the
    connection closing (keep-alive ends), but megabytes sit in its buffer, and close() alone would
    wait for a reader that never comes."""
    # judged after uvicorn's keep-alive (5 s) has closed it: a closing connection is judged too
    config = _config(tmp_path, small_config_data(), send_timeout_s=8.0, min_send_rate=65536)
    store = JobStore(tmp_path / "data" / DB_NAME)
    for k in range(90):  # records as a daemon keeps them, each with a large free-form plan
        store.add(f"20261127-1200{k // 60:02d}-{k % 60:06x}", JobType.SCAN, {"plan": {"notes": ["x" * 9_000] * 5}})
    store.close()
    daemon = Daemon(config, tmp_path / "d.log")
    try:
        sockets = []
        for _ in range(3):
            sock = socket.socket()
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
            sock.connect(("127.0.0.1", daemon.port))
            sock.sendall(b"GET /v1/scans?limit=100 HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
            sockets.append(sock)
        deadline = time.monotonic() + 120
        time.sleep(1.0)
        while _held_by_the_daemon(daemon.port) and time.monotonic() < deadline:
            time.sleep(0.5)
        assert _held_by_the_daemon(daemon.port) == 0
        for sock in sockets:
            sock.close()
    finally:
        daemon.stop()
