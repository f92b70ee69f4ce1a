"""Reliability of `slrig serve` under faults and hostile clients, measured against a real daemon on
the simulated bench; prints one JSON object (and with --docs rewrites the manual's table).

- 200 idle connections and a burst of 200 event streams: streams accepted against the cap, and
  the latency of /v1/health meanwhile (20 requests);
- a connection that sends nothing and one whose body stalls: seconds until the daemon closes the
  first and answers the second 408 (with header_timeout_s and body_stall_s of 2 s);
- SIGKILL at a random moment of a scan (capture, decode or store) and of a DELETE, then a restart:
  whether the stored scan changed, a folder lost its record or a record its files (lost);
- a full disk (a tmpfs, where this runs as root): the answer to a new scan, the health report,
  and the state a scan ends in when the disk fills while it is written;
- poisoned bodies (values JSON cannot carry back, in fields and free-form objects): 5xx, bodies
  accepted, listings that then fail; and the schema test's generated requests, randomised;
- every typed body field sent with a value of another type: how many were accepted;
- 1000 unauthenticated connections that ask for a 256 MB file and never read: downloads served,
  health checks answered meanwhile, held downloads cut;
- uploads: an empty body, a folder past its limit, and (as root, on a tmpfs) a disk filled by
  uploads: the statuses, and whether the job records' reserve stayed free;
- a 20000x20000 PNG bomb uploaded, and placed as every frame of a reconstruction: the statuses and
  the daemon's peak memory before and after;
- broken key files (BOM, non-ASCII, inner newline, empty, over 4 KiB, a directory, /dev/zero, a
  FIFO): exit code and time of `slrig serve`; the key sent in every part of a URL: times logged;
- SIGTERM in each state a daemon can be in (bench/stop_time.py): seconds until the process is
  gone, and whether the projector was dark.

    python bench/reliability.py [--kills 8] [--schema-examples 200] [--docs]
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
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

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(REPO))

import _attacks as attacks  # noqa: E402
from _daemon import daemon_config  # noqa: E402
from _readme import markdown_table, replace_block  # noqa: E402
from _reliability_rows import attack_rows  # noqa: E402
from stop_time import stop_times  # noqa: E402

from rig.service.space import RESERVE_BYTES  # noqa: E402
from tests.conftest import wait_done  # noqa: E402
from tests.test_daemon import AUTH, KEY, Daemon, status_code  # noqa: E402  # the suite's daemon in a process


def _done(url: str, job_id: str) -> dict[str, Any]:
    with httpx.Client(base_url=url) as client:
        return wait_done(client, job_id)


def connections(folder: Path) -> dict[str, Any]:
    daemon = Daemon(
        daemon_config(folder, folder / "conn", stall=True, header_timeout_s=2, body_stall_s=2), folder / "c.log"
    )
    try:
        job_id = httpx.post(f"{daemon.url}/v1/scans", json={}, headers=AUTH).json()["id"]
        idle = [socket.create_connection(("127.0.0.1", daemon.port), timeout=30) for _ in range(200)]
        streams = [  # from 20 addresses: the overall cap, not the 16 one address may hold
            socket.create_connection(
                ("127.0.0.1", daemon.port), timeout=30, source_address=(f"127.0.0.{1 + k % 20}", 0)
            )
            for k in range(200)
        ]
        request = f"GET /v1/scans/{job_id}/events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n".encode()
        for sock in streams:
            sock.sendall(request)
        codes = [status_code(sock) for sock in streams]
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
        stalled_code = status_code(stalled)
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
        daemon.stop()


def _digest(folder: Path) -> dict[str, str]:
    files = sorted(p for p in folder.rglob("*") if p.is_file())
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest() for p in files}


def _store_whole(url: str, scans: Path, keeper: str, before: dict[str, str]) -> list[str]:
    """What a restart found wrong: the stored scan changed, a folder without a record or a record
    of a finished scan without its folder, a half-written or half-deleted folder left."""
    wrong = [] if _digest(scans / keeper) == before else [f"{keeper} changed"]
    listed = {job["id"]: job for job in httpx.get(f"{url}/v1/scans", params={"limit": 100}).json()["items"]}
    for path in scans.iterdir():
        if path.name not in listed:
            wrong.append(f"{path.name}: no record")
    for job_id, job in listed.items():
        if job["state"] == "done" and not all((scans / job_id / name).is_file() for name in job["result"]["files"]):
            wrong.append(f"{job_id}: files missing")
        if job["state"] != "done" and (scans / job_id).exists():
            wrong.append(f"{job_id}: a folder for a job that is {job['state']}")
    return wrong


def kill_cycles(folder: Path, operation: str, tries: int, seed: int = 3) -> dict[str, Any]:
    """SIGKILL during a scan (while it captures or stores) or during a DELETE, then a restart."""
    rng = random.Random(seed)
    data_dir = folder / f"kill-{operation}"
    config = daemon_config(folder, data_dir)
    daemon = Daemon(config, folder / "k.log")
    keeper = _done(daemon.url, httpx.post(f"{daemon.url}/v1/scans", json={}, headers=AUTH).json()["id"])["id"]
    daemon.stop()
    before = _digest(data_dir / "scans" / keeper)
    lost = 0
    for attempt in range(tries):
        daemon = Daemon(config, folder / "k.log")
        job_id = httpx.post(f"{daemon.url}/v1/scans", json={"keep_frames": True}, headers=AUTH).json()["id"]
        if operation == "scan":
            time.sleep(rng.uniform(0.05, 1.5))  # capture, decode or store
        else:
            _done(daemon.url, job_id)
            with httpx.Client(base_url=daemon.url) as client, contextlib.suppress(httpx.TimeoutException):
                client.delete(f"/v1/scans/{job_id}", headers=AUTH, timeout=rng.uniform(0.001, 0.03))
        os.kill(daemon.process.pid, signal.SIGKILL)
        daemon.process.wait(10)
        restarted = Daemon(config, folder / "k.log")
        wrong = _store_whole(restarted.url, data_dir / "scans", keeper, before)
        lost += bool(wrong)
        state = httpx.get(f"{restarted.url}/v1/scans/{job_id}").json().get("state", "deleted")
        print(f"{operation} kill {attempt + 1}/{tries}: job {state}; {wrong or 'whole'}", file=sys.stderr)
        if state != "deleted":
            httpx.delete(f"{restarted.url}/v1/scans/{job_id}", headers=AUTH)
        restarted.stop()
    return {"tries": tries, "lost": lost}


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
    daemon = Daemon(daemon_config(folder, disk / "data"), folder / "d.log")
    scans = disk / "data" / "scans"
    try:
        keeper = _done(daemon.url, httpx.post(f"{daemon.url}/v1/scans", json={}, headers=AUTH).json()["id"])["id"]
        before = _digest(scans / keeper)
        ballast = disk / "ballast"
        with ballast.open("wb") as f:
            while shutil.disk_usage(disk).free > RESERVE_BYTES // 2 + (1 << 20):
                f.write(b"\0" * (1 << 20))
        refused = httpx.post(f"{daemon.url}/v1/scans", json={}, headers=AUTH)
        health = httpx.get(f"{daemon.url}/v1/health").json()
        ballast.unlink()
        after = httpx.post(f"{daemon.url}/v1/scans", json={}, headers=AUTH)
        done = _done(daemon.url, after.json()["id"])["state"] if after.status_code == 202 else None
        return {
            "lost": len(_store_whole(daemon.url, scans, keeper, before)),
            "new_scan_status": refused.status_code,
            "health": health["status"],
            "health_problem": (health.get("problems") or [""])[0][:80],
            "after_freeing_space": done,
        }
    finally:
        daemon.stop()
        subprocess.run(["umount", "-l", str(disk)], check=False)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--kills", type=int, default=8)
    parser.add_argument("--schema-examples", type=int, default=200, help="generated requests per operation")
    parser.add_argument("--docs", "--readme", dest="readme", action="store_true")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        result = {
            "machine": f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}",
            "connections": connections(folder),
            "scan_killed": kill_cycles(folder, "scan", args.kills),
            "delete_killed": kill_cycles(folder, "delete", args.kills),
            "full_disk": full_disk(folder),
            "poison": attacks.poisoned_bodies(folder, 500),
            "schema": attacks.randomised_schema(args.schema_examples, args.schema_examples // 2),
            "strict_types": attacks.strict_types(folder),
            "slow_readers": attacks.slow_readers(folder),
            "uploads": attacks.uploads(folder, RESERVE_BYTES),
            "bombs": attacks.bombs(folder),
            "key_files": attacks.key_files(folder),
            "stop": stop_times(folder, 5),
        }
    print(json.dumps(result, indent=2))
    if args.readme:
        replace_block("reliability-table", _table(result))


def _table(result: dict[str, Any]) -> str:
    c, d = result["connections"], result["full_disk"]
    rows = [
        [
            "200 idle connections + a burst of 200 event streams from 20 addresses",
            "1 burst, 20 health checks",
            0,
            f"{c['streams_accepted']} streams accepted, {c['streams_refused_503']} refused 503; health answered "
            f"in {c['health_ms_median']} ms median, {c['health_ms_max']} ms at most",
        ],
        ["a connection that sends nothing", 1, 0, f"closed after {c['silent_connection_closed_s']} s (timeout 2 s)"],
        [
            "a request body that stalls",
            1,
            0,
            f"{c['stalled_body_status']} after {c['stalled_body_answered_s']} s (body_stall_s 2)",
        ],
    ]
    for key, what in (("scan_killed", "SIGKILL during a scan"), ("delete_killed", "SIGKILL during a DELETE")):
        k = result[key]
        rows.append([f"{what}, then a restart", k["tries"], k["lost"], "stored scan byte-identical, no orphan"])
    if "skipped" not in d:
        rows.append(
            [
                "a full disk (tmpfs)",
                1,
                d["lost"],
                f"new scan {d['new_scan_status']}, health {d['health']}; "
                f"once freed, the next scan {d['after_freeing_space']}",
            ]
        )
    rows += attack_rows(result)
    table = markdown_table(["fault", "tries", "failed", "what held"], rows)
    return f"{table}\n\nMeasured by `python bench/reliability.py --docs` ({result['machine']})."


if __name__ == "__main__":
    main()
