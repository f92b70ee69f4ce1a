"""The daemon on loopback: request rate and latency of reads under concurrent clients, and what a
scan costs over REST compared with the same scan in process. Prints one JSON object.

    python bench/service.py            # JSON
    python bench/service.py --docs   # also rewrite the service table in the manual (docs/)
"""

from __future__ import annotations

import asyncio
import os
import platform
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx
import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _readme import markdown_table, run

from rig.assembly import open_rig
from rig.config import REPO_CONFIG_DIR, load_config
from rig.service.tasks import scan_to_directory

REPO = Path(__file__).resolve().parent.parent
KEY = "bench-key-0123456789abcdef"
CLIENTS, SECONDS = 16, 5.0


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


async def _hammer(url: str, path: str) -> list[float]:
    """Latencies (s) of GETs by CLIENTS clients, each sending one after another for SECONDS."""
    latencies: list[float] = []
    stop = time.monotonic() + SECONDS

    async def client() -> None:
        async with httpx.AsyncClient(base_url=url, timeout=10) as http:
            while time.monotonic() < stop:
                start = time.perf_counter()
                response = await http.get(path)
                latencies.append(time.perf_counter() - start)
                if response.status_code != 200:
                    raise SystemExit(f"{path}: {response.status_code}")

    await asyncio.gather(*(client() for _ in range(CLIENTS)))
    return latencies


def measure() -> dict[str, object]:
    with tempfile.TemporaryDirectory() as tmp:
        data = yaml.safe_load((REPO_CONFIG_DIR / "sim.yaml").read_text())
        data["output"] = {"data_dir": str(Path(tmp) / "data")}
        config_path = Path(tmp) / "rig.yaml"
        config_path.write_text(yaml.safe_dump(data))
        with open_rig(load_config(config_path)) as rig:  # the same job in process, rig already open
            scan_to_directory(rig, Path(tmp) / "warm", "warm")  # caches per-pixel terms, as the daemon's rig does
            start = time.perf_counter()
            scan_to_directory(rig, Path(tmp) / "timed", "timed")  # scan, metrics, files: what a job does
            in_process = time.perf_counter() - start
        port = _port()
        url = f"http://127.0.0.1:{port}"
        env = {**os.environ, "SLRIG_API_KEY": KEY}
        command = [sys.executable, "-m", "rig.cli", "serve", "--config", str(config_path), "--port", str(port)]
        daemon = subprocess.Popen(command, cwd=REPO, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            for _ in range(300):
                try:
                    if httpx.get(f"{url}/v1/health", timeout=1).status_code == 200:
                        break
                except httpx.TransportError:
                    time.sleep(0.1)
            scans = []
            for _ in range(3):  # the first opens the rig; the later ones show the steady cost
                start = time.perf_counter()
                job = httpx.post(f"{url}/v1/scans", json={}, headers={"X-API-Key": KEY}).json()["id"]
                with httpx.stream("GET", f"{url}/v1/scans/{job}/events", timeout=120) as events:
                    for line in events.iter_lines():
                        if line.startswith("data: ") and '"done"' in line:
                            break
                scans.append(time.perf_counter() - start)
            reads = {path: asyncio.run(_hammer(url, path)) for path in ("/v1/health", "/v1/scans?limit=20")}
        finally:
            daemon.terminate()
            daemon.wait(20)
    out: dict[str, object] = {
        "config": "config/sim.yaml (phase, 1280x1024 camera)",
        "scan_in_process_s": round(in_process, 2),
        "scan_over_rest_s": [round(s, 2) for s in scans],
        "clients": CLIENTS,
        "machine": f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}",
    }
    for path, latencies in reads.items():
        ms = np.array(latencies) * 1e3
        out[path] = {
            "requests_per_s": round(len(ms) / SECONDS, 1),
            "p50_ms": round(float(np.percentile(ms, 50)), 2),
            "p99_ms": round(float(np.percentile(ms, 99)), 2),
        }
    return out


def table(m: dict[str, object]) -> str:
    rows = [
        [f"`GET {path}`", r["requests_per_s"], r["p50_ms"], r["p99_ms"]]  # type: ignore[index]
        for path, r in m.items()
        if path.startswith("/v1")
    ]
    scans = m["scan_over_rest_s"]
    return (
        markdown_table([f"{m['clients']} clients, 5 s", "requests/s", "p50 ms", "p99 ms"], rows)
        + f"\n\nA phase scan of the default bench over REST (POST, then its events to `done`): "
        f"{', '.join(str(s) for s in scans)} s for three in a row (the first opens the devices), against "  # type: ignore[attr-defined]
        f"{m['scan_in_process_s']} s for the same job (scan, accuracy against the simulator, files) in process "
        "with the rig open. "
        f"Clients and daemon share the machine. Measured by `python bench/service.py --docs` ({m['machine']})."
    )


def main() -> None:
    run(__doc__ or "", "service-table", measure, table)


if __name__ == "__main__":
    main()
