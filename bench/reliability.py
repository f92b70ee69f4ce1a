"""Reliability of `slrig serve` under faults and hostile clients, measured against a real daemon on
the simulated bench; prints one JSON object (and with --readme rewrites the README's table).

- 200 idle connections and a burst of 200 event streams: streams accepted against the cap, and
  the latency of /v1/health meanwhile (20 requests);
- a connection that sends nothing and one whose body stalls: seconds until the daemon closes the
  first and answers the second 408 (with header_timeout_s and body_stall_s of 2 s);
- SIGKILL at a random moment of a DELETE, then a restart: folders or records left behind;
- a full disk (a tmpfs, where this runs as root): the answer to a new scan, the health report,
  and the state a scan ends in when the disk fills while it is written.

    python bench/reliability.py [--kills 8] [--readme]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import platform
import random
import shutil
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import httpx
import yaml

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(REPO))

from _readme import markdown_table, replace_block  # noqa: E402

from rig.service.space import RESERVE_BYTES  # noqa: E402

KEY = "r" * 32
AUTH = {"X-API-Key": KEY}


def _config(folder: Path, data_dir: Path, stall: bool = False, **service: Any) -> Path:
    data = _small()
    data["output"] = {"data_dir": str(data_dir)}
    data["service"] = service
    if stall:
        data["cameras"][0]["sim"]["faults"] = {"stall_after_frames": 3}
        data.setdefault("scan", {})["capture_timeout_s"] = 60.0
    path = folder / f"serve-{len(list(folder.glob('serve-*.yaml')))}.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def _small() -> dict[str, Any]:
    from tests.conftest import small_config_data  # the suite's small bench: quick scans

    return small_config_data()


class Daemon:
    def __init__(self, config: Path, log: Path) -> None:
        with socket.socket() as probe:
            probe.bind(("127.0.0.1", 0))
            self.port = probe.getsockname()[1]
        self.url = f"http://127.0.0.1:{self.port}"
        with log.open("ab") as err:
            self.process = subprocess.Popen(
                [sys.executable, "-m", "rig.cli", "serve", "--config", str(config), "--port", str(self.port)],
                cwd=REPO,
                env={**os.environ, "SLRIG_API_KEY": KEY, "PYTHONPATH": str(REPO)},
                stdout=subprocess.DEVNULL,
                stderr=err,
            )
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            try:
                if httpx.get(f"{self.url}/v1/health", timeout=1).status_code == 200:
                    return
            except httpx.TransportError:
                time.sleep(0.1)
        raise RuntimeError(f"the daemon did not come up: {log.read_text()[-2000:]}")

    def kill(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait(10)


def _wait_done(url: str, job_id: str, timeout_s: float = 120.0) -> dict[str, Any]:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        job = httpx.get(f"{url}/v1/scans/{job_id}").json()
        if job["state"] not in ("queued", "running"):
            return job
        time.sleep(0.05)
    raise RuntimeError(f"{job_id} did not finish")


def _status(sock: socket.socket) -> int:
    head = b""
    while b"\r\n" not in head:
        chunk = sock.recv(256)
        if not chunk:
            return 0
        head += chunk
    return int(head.split(b" ", 2)[1])


def connections(folder: Path) -> dict[str, Any]:
    daemon = Daemon(_config(folder, folder / "conn", stall=True, header_timeout_s=2, body_stall_s=2), folder / "c.log")
    try:
        job_id = httpx.post(f"{daemon.url}/v1/scans", json={}, headers=AUTH).json()["id"]
        idle = [socket.create_connection(("127.0.0.1", daemon.port), timeout=30) for _ in range(200)]
        streams = [socket.create_connection(("127.0.0.1", daemon.port), timeout=30) for _ in range(200)]
        request = f"GET /v1/scans/{job_id}/events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n".encode()
        for sock in streams:
            sock.sendall(request)
        codes = [_status(sock) for sock in streams]
        latencies = []
        for _ in range(20):
            started = time.perf_counter()
            httpx.get(f"{daemon.url}/v1/health", timeout=10).raise_for_status()
            latencies.append((time.perf_counter() - started) * 1000)
        silent = socket.create_connection(("127.0.0.1", daemon.port), timeout=30)
        stalled = socket.create_connection(("127.0.0.1", daemon.port), timeout=30)
        stalled.sendall(
            f"POST /v1/scans HTTP/1.1\r\nHost: 127.0.0.1\r\nX-API-Key: {KEY}\r\nContent-Length: 50\r\n\r\n{{".encode()
        )
        started = time.monotonic()
        stalled_code = _status(stalled)
        stalled_s = time.monotonic() - started
        silent.recv(1)
        silent_s = time.monotonic() - started
        for sock in (*idle, *streams, silent, stalled):
            sock.close()
        return {
            "streams_accepted": codes.count(200),
            "streams_refused_503": codes.count(503),
            "health_ms_median": round(statistics.median(latencies), 1),
            "health_ms_max": round(max(latencies), 1),
            "silent_connection_closed_s": round(silent_s, 2),
            "stalled_body_status": stalled_code,
            "stalled_body_answered_s": round(stalled_s, 2),
        }
    finally:
        daemon.kill()


def kills_during_delete(folder: Path, tries: int, seed: int = 3) -> dict[str, Any]:
    rng = random.Random(seed)
    data_dir = folder / "kills"
    config = _config(folder, data_dir)
    left = 0
    for attempt in range(tries):
        daemon = Daemon(config, folder / "k.log")
        job_id = httpx.post(f"{daemon.url}/v1/scans", json={"keep_frames": True}, headers=AUTH).json()["id"]
        _wait_done(daemon.url, job_id)
        delay = rng.uniform(0.0, 0.03)
        with httpx.Client(base_url=daemon.url) as client, contextlib.suppress(httpx.TimeoutException):
            client.delete(f"/v1/scans/{job_id}", headers=AUTH, timeout=delay or 0.001)
        os.kill(daemon.process.pid, signal.SIGKILL)
        daemon.process.wait(10)
        restarted = Daemon(config, folder / "k.log")
        record = httpx.get(f"{restarted.url}/v1/scans/{job_id}").status_code
        folders = [p.name for p in (data_dir / "scans").iterdir()]
        if (record == 404) != (not folders) or any(name.endswith(".deleting") for name in folders):
            left += 1  # a record without its folder, a folder without its record, a hidden leftover
        elif record == 200:
            httpx.delete(f"{restarted.url}/v1/scans/{job_id}", headers=AUTH)
        restarted.kill()
        print(f"kill {attempt + 1}/{tries}: record {record}, folders {folders}", file=sys.stderr)
    return {"tries": tries, "left_behind": left}


def full_disk(folder: Path) -> dict[str, Any]:
    disk = folder / "disk"
    disk.mkdir()
    size_mb = RESERVE_BYTES // 1_000_000 + 40
    if (
        os.geteuid() != 0
        or subprocess.run(
            ["mount", "-t", "tmpfs", "-o", f"size={size_mb}m", "tmpfs", str(disk)], check=False
        ).returncode
    ):
        return {"skipped": "a tmpfs needs root"}
    daemon = Daemon(_config(folder, disk / "data"), folder / "d.log")
    try:
        ballast = disk / "ballast"
        with ballast.open("wb") as f:
            while shutil.disk_usage(disk).free > RESERVE_BYTES // 2 + (1 << 20):
                f.write(b"\0" * (1 << 20))
        refused = httpx.post(f"{daemon.url}/v1/scans", json={}, headers=AUTH)
        health = httpx.get(f"{daemon.url}/v1/health").json()
        ballast.unlink()
        after = httpx.post(f"{daemon.url}/v1/scans", json={}, headers=AUTH)
        done = _wait_done(daemon.url, after.json()["id"])["state"] if after.status_code == 202 else None
        return {
            "new_scan_status": refused.status_code,
            "health": health["status"],
            "health_problem": (health.get("problems") or [""])[0][:80],
            "after_freeing_space": done,
        }
    finally:
        daemon.kill()
        subprocess.run(["umount", "-l", str(disk)], check=False)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--kills", type=int, default=8)
    parser.add_argument("--readme", action="store_true")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        result = {
            "machine": f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}",
            "connections": connections(folder),
            "delete_killed": kills_during_delete(folder, args.kills),
            "full_disk": full_disk(folder),
        }
    print(json.dumps(result, indent=2))
    if args.readme:
        replace_block("reliability-table", _table(result))


def _table(result: dict[str, Any]) -> str:
    c, k, d = result["connections"], result["delete_killed"], result["full_disk"]
    rows = [
        [
            "200 idle connections + a burst of 200 event streams",
            "streams capped, health answered",
            f"{c['streams_accepted']} accepted, {c['streams_refused_503']} refused 503; health median "
            f"{c['health_ms_median']} ms, max {c['health_ms_max']} ms",
        ],
        [
            "a connection that sends nothing (header_timeout_s 2)",
            "closed",
            f"after {c['silent_connection_closed_s']} s",
        ],
        [
            "a body that stalls (body_stall_s 2)",
            "408",
            f"{c['stalled_body_status']} after {c['stalled_body_answered_s']} s",
        ],
        ["SIGKILL during DELETE, then restart", "nothing left behind", f"{k['left_behind']} of {k['tries']} left data"],
    ]
    if "skipped" not in d:
        rows.append(
            [
                "a full disk (tmpfs)",
                "507, degraded, scans again once freed",
                f"{d['new_scan_status']}, {d['health']}; next scan {d['after_freeing_space']}",
            ]
        )
    table = markdown_table(["fault", "promise", "measured"], rows)
    return f"{table}\n\nMeasured by `python bench/reliability.py --readme` ({result['machine']})."


if __name__ == "__main__":
    main()
