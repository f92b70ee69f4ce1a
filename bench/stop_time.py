"""How long `slrig serve` takes to stop on SIGTERM, in each state it can be in, measured from outside:
a real daemon process per run on the simulated bench, brought into the state, sent SIGTERM, and timed
until waitpid returns. Whether the projectors ended dark is read from the daemon's log (the job
service writes "projectors dark" once it has darkened and let go of them, and names any projector
that still reports light); the state the running job was recorded in is read from its database.

States: idle; a scan capturing, decoding/triangulating and storing (the default bench,
config/sim.yaml, and its first scan: the longest steps); live mode; a calibration; a camera that
stalls (its driver never delivers; scan.capture_timeout_s 60 s); 20 event streams open and two
downloads that read nothing while a scan runs.

    python bench/stop_time.py [--repeats 3]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import signal
import socket
import statistics
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _daemon import daemon_config  # noqa: E402

from rig.service.job_service import DB_NAME  # noqa: E402
from rig.service.jobs import JobStore  # noqa: E402
from tests.conftest import default_config_data  # noqa: E402
from tests.test_daemon import AUTH, Daemon  # noqa: E402  # the suite's daemon in a process

STATE_TIMEOUT_S = 120.0  # to reach a state (a cold daemon's first scan takes seconds)
POLL_S = 0.005
DARK = "projectors dark"
LIT = "still lit"


def _until(check: Callable[[], bool], what: str) -> None:
    deadline = time.monotonic() + STATE_TIMEOUT_S
    while time.monotonic() < deadline:
        if check():
            return
        time.sleep(POLL_S)
    raise RuntimeError(f"the daemon never reached {what}")


def _job(daemon: Daemon, collection: str, job_id: str) -> dict[str, Any]:
    job: dict[str, Any] = httpx.get(f"{daemon.url}/v1/{collection}/{job_id}", timeout=10).json()
    if job.get("state") not in ("queued", "running"):
        raise RuntimeError(f"{collection} {job_id} ended before the signal: {job.get('state')} {job.get('error')}")
    return job


def _scan_at(stages: tuple[str, ...], after: float = 0.0) -> Callable[[Daemon], str]:
    """A scan, up to the first progress report of one of `stages` past fraction `after`."""

    def reach(daemon: Daemon) -> str:
        job_id = str(httpx.post(f"{daemon.url}/v1/scans", json={}, headers=AUTH).json()["id"])

        def there() -> bool:
            job = _job(daemon, "scans", job_id)
            return job["state"] == "running" and job["stage"] in stages and job["fraction"] > after

        _until(there, f"a scan in {'/'.join(stages)}")
        return job_id

    return reach


def _idle(daemon: Daemon) -> None:
    return None


def _live(daemon: Daemon) -> None:
    httpx.post(f"{daemon.url}/v1/live", json={}, headers=AUTH).raise_for_status()
    _until(lambda: httpx.get(f"{daemon.url}/v1/live/status").json()["sequences"] >= 1, "live sequences")


def _calibrating(daemon: Daemon) -> str:
    created = httpx.post(f"{daemon.url}/v1/calibrations", json={"what": "camera", "views": 8}, headers=AUTH)
    job_id = str(created.json()["id"])
    _until(lambda: _job(daemon, "calibrations", job_id)["state"] == "running", "a calibration running")
    time.sleep(1.5)  # among its views (each about a second on the default bench)
    _job(daemon, "calibrations", job_id)
    return job_id


def _stalled(daemon: Daemon) -> str:
    job_id = _scan_at(("capture",))(daemon)
    time.sleep(1.0)  # the camera has stopped delivering: the worker waits in its driver
    return job_id


def _slow_reader(daemon: Daemon, path: str) -> socket.socket:
    """A download whose client reads nothing: the response waits for the client to drain it."""
    sock = socket.socket()
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    sock.connect(("127.0.0.1", daemon.port))
    sock.sendall(f"GET {path} HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n".encode())
    sock.recv(1024)  # the response has started
    return sock


def _streams_and_downloads(daemon: Daemon) -> tuple[str, list[socket.socket]]:
    """A finished scan to download, then one running and four queued, each watched by event streams."""
    first = str(httpx.post(f"{daemon.url}/v1/scans", json={}, headers=AUTH).json()["id"])
    _until(lambda: httpx.get(f"{daemon.url}/v1/scans/{first}").json()["state"] == "done", "a finished scan")
    jobs = [str(httpx.post(f"{daemon.url}/v1/scans", json={}, headers=AUTH).json()["id"]) for _ in range(5)]
    held = [_slow_reader(daemon, f"/v1/scans/{first}/files/cloud.ply") for _ in range(2)]
    for i in range(20):
        sock = socket.create_connection(("127.0.0.1", daemon.port), timeout=30)
        sock.sendall(f"GET /v1/scans/{jobs[i % len(jobs)]}/events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n".encode())
        sock.recv(256)  # its headers: the stream is open
        held.append(sock)
    _job(daemon, "scans", jobs[0])
    return jobs[0], held


# state -> (config: small bench, stalling camera; how to get there)
STATES: dict[str, tuple[bool, bool, Callable[[Daemon], Any]]] = {
    "idle": (False, False, _idle),
    "capturing": (False, False, _scan_at(("capture",), 0.05)),
    "decoding": (False, False, _scan_at(("decode", "triangulate"))),
    "storing": (False, False, _scan_at(("store",))),
    "live": (True, False, _live),
    "calibrating": (False, False, _calibrating),
    "stalled_camera": (True, True, _stalled),
    "streams_and_downloads": (False, False, _streams_and_downloads),
}


def stop_once(folder: Path, state: str) -> dict[str, Any]:
    """One daemon brought into `state` and sent SIGTERM: seconds to exit, dark, the job's end."""
    small, stall, reach = STATES[state]
    data_dir = folder / f"data-{state}-{time.monotonic_ns()}"
    log = folder / f"{data_dir.name}.log"
    data = None if small else default_config_data()
    daemon = Daemon(daemon_config(folder, data_dir, data, stall, max_queue=8), log)
    held: list[socket.socket] = []
    try:
        reached = reach(daemon)
        if isinstance(reached, tuple):
            reached, held = reached
        offset = log.stat().st_size
        hung = threading.Timer(STATE_TIMEOUT_S, daemon.process.kill)  # a daemon that never exits: -9
        started = time.monotonic()
        os.kill(daemon.process.pid, signal.SIGTERM)
        hung.start()
        code = daemon.process.wait()  # a blocking waitpid: the moment the process is gone
        seconds = time.monotonic() - started
        hung.cancel()
    finally:
        for sock in held:
            sock.close()
        daemon.stop()
    with log.open("rb") as f:
        f.seek(offset)
        after = f.read().decode(errors="replace")
    job_state = None if reached is None else str(JobStore(data_dir / DB_NAME).get(reached).state)
    ran = reached is not None or state == "live"  # a rig was opened: its projectors must end dark
    return {
        "seconds": seconds,
        "exit_code": code,
        "dark": (DARK in after or not ran) and LIT not in after,
        "job_state": job_state,
    }


def stop_times(folder: Path, repeats: int) -> dict[str, dict[str, Any]]:
    """Per state: median and max seconds from SIGTERM to the process gone, whether the projectors
    ended dark in every run, and the number of runs ({"state": {"median_s", "max_s", "dark", "runs",
    "interrupted"}}; interrupted: every run recorded its job interrupted, None where no job ran)."""
    out: dict[str, dict[str, Any]] = {}
    for state in STATES:
        runs = [stop_once(folder, state) for _ in range(repeats)]
        for run in runs:
            print(f"{state}: {run}", file=sys.stderr)
        seconds = [run["seconds"] for run in runs]
        states = {run["job_state"] for run in runs}
        out[state] = {
            "median_s": round(statistics.median(seconds), 3),
            "max_s": round(max(seconds), 3),
            "dark": all(run["dark"] and run["exit_code"] == 0 for run in runs),
            "runs": len(runs),
            "interrupted": None if states == {None} else states == {"interrupted"},
        }
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        result = stop_times(Path(tmp), args.repeats)
    machine = f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}"
    print(json.dumps({"machine": machine, "states": result}, indent=2))


if __name__ == "__main__":
    main()
