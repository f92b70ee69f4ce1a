"""What bench/reliability.py tries against a real daemon as a hostile or careless client would:
poisoned bodies, wrongly typed fields, slow readers, uploads past the limits, decompression bombs
and broken key files. Each function returns the figures of one row of the manual's table."""

from __future__ import annotations

import json
import os
import random
import resource
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import httpx

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from _daemon import daemon_config  # noqa: E402

from rig.assembly import open_rig  # noqa: E402
from rig.calibrate.foreign import write_opencv_stereo  # noqa: E402
from rig.config import load_config  # noqa: E402
from rig.patterns.spec import opencv_graycode  # noqa: E402
from tests.bombs import write_png_bomb  # noqa: E402
from tests.conftest import wait_done  # noqa: E402
from tests.test_daemon import AUTH, KEY, Daemon, status_code  # noqa: E402

POISON = ["NaN", "Infinity", "-Infinity", "1e999", '"\\ud800"', '"x\\udfff"', '{"\\udbff": 1}']
FAKE_ID = "20260101-000000-abcdef"


def _named_config(folder: Path, name: str, **service: Any) -> Path:
    """A daemon config keeping its data in <folder>/<name>-data."""
    return daemon_config(folder, folder / f"{name}-data", **service)


def _rss_peak_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def _random_json(rng: random.Random, depth: int = 0) -> str:
    """JSON text with, somewhere inside, at least one value JSON cannot carry back."""
    roll = rng.random()
    if depth < 4 and roll < 0.3:
        items = [f"{json.dumps(f'k{i}')}: {_random_json(rng, depth + 1)}" for i in range(rng.randint(1, 4))]
        return "{" + ", ".join(items) + "}"
    if depth < 4 and roll < 0.45:
        return "[" + ", ".join(_random_json(rng, depth + 1) for _ in range(rng.randint(1, 4))) + "]"
    if roll < 0.75:
        return rng.choice(POISON)
    return json.dumps(rng.choice([1, 2.5, "text", True, None, -3]))


def poisoned_bodies(folder: Path, count: int, seed: int = 7) -> dict[str, Any]:
    """`count` bodies, each with a poisoned value in a free-form object or a field, to every
    operation that takes a JSON body; then every listing, page and filter."""
    rng = random.Random(seed)
    daemon = Daemon(_named_config(folder, "poison"), folder / "poison.log")
    bodies = [
        ("/v1/scans", lambda v: f'{{"plan": {{"criteria": {v}, "rings": [1, 2]}}}}'),
        ("/v1/scans", lambda v: f'{{"label": {v}}}'),
        ("/v1/scans", lambda v: f'{{"adaptive": true, "tolerance_mm": {v}}}'),
        ("/v1/reconstructions", lambda v: f'{{"frames": "f", "calibration": "c.yaml", "patterns": {v}}}'),
        (
            "/v1/reconstructions",
            lambda v: (
                f'{{"frames": "f", "calibration": "c", "patterns": "p.yaml", "calibration_options": {{"x": {v}}}}}'
            ),
        ),
        ("/v1/calibrations", lambda v: f'{{"views": {v}}}'),
        ("/v1/live", lambda v: f'{{"seconds": {v}}}'),
        ("/v1/gallery", lambda v: f'{{"scan_id": "{FAKE_ID}", "label": "a", "inner_mm": {v}}}'),
    ]
    server_errors = accepted = 0
    try:
        with httpx.Client(base_url=daemon.url, timeout=30) as client:
            for _ in range(count):
                path, make = rng.choice(bodies)
                value = _random_json(rng)
                if not any(token in value for token in POISON):
                    value = rng.choice(POISON)
                answer = client.post(
                    path,
                    content=make(value).encode("utf-8", "surrogatepass"),
                    headers={**AUTH, "Content-Type": "application/json"},
                )
                server_errors += answer.status_code >= 500
                accepted += answer.status_code < 300
            listings = [f"/v1/scans?limit=100&offset={k}" for k in (0, 1, 100)]
            listings += [f"/v1/scans?state={s}" for s in ("queued", "running", "done", "failed")]
            listings += ["/v1/calibrations", "/v1/health", "/v1/rig"]
            broken = sum(client.get(p).status_code != 200 for p in listings)
            stored = client.get("/v1/scans").json()["total"] + client.get("/v1/calibrations").json()["total"]
    finally:
        daemon.stop()
    return {"requests": count, "5xx": server_errors, "accepted": accepted, "listings_broken": broken, "stored": stored}


def _wrong_values(kind: str) -> list[Any]:
    return {
        "number": [True, "1", [1], {"v": 1}],
        "integer": [True, "1", 1.5, [1]],
        "boolean": [1, 0, "true", None],
        "string": [1, True, ["a"]],
    }.get(kind, [])


def strict_types(folder: Path) -> dict[str, Any]:
    """Every typed field of every JSON body, sent with values of another type (true for a number,
    "1" for an integer, 1.5 for an integer, 1 for a boolean, ...): each must be refused."""
    daemon = Daemon(_named_config(folder, "types"), folder / "types.log")
    tried = accepted = server_errors = 0
    try:
        with httpx.Client(base_url=daemon.url, timeout=30) as client:
            schema = client.get("/openapi.json").json()
            models = schema["components"]["schemas"]
            for path, operations in schema["paths"].items():
                for method, operation in operations.items():
                    ref = (
                        operation.get("requestBody", {})
                        .get("content", {})
                        .get("application/json", {})
                        .get("schema", {})
                        .get("$ref")
                    )
                    if method != "post" or not ref:
                        continue
                    url = path.replace("{job_id}", FAKE_ID).replace("{label}", "a")
                    for field, spec in models[ref.rsplit("/", 1)[1]]["properties"].items():
                        kinds = {s.get("type") for s in spec.get("anyOf", [spec])} - {"null", None}
                        for kind in kinds:
                            for value in _wrong_values(kind):
                                answer = client.post(url, json={field: value}, headers=AUTH)
                                tried += 1
                                accepted += answer.status_code < 300
                                server_errors += answer.status_code >= 500
    finally:
        daemon.stop()
    return {"requests": tried, "accepted": accepted, "5xx": server_errors}


def slow_readers(folder: Path, count: int = 1000, large_mb: int = 256) -> dict[str, Any]:
    """`count` unauthenticated connections that each ask for a large file and never read it, on
    the default connection settings; health checked throughout."""
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    resource.setrlimit(resource.RLIMIT_NOFILE, (min(hard, max(soft, count + 512)), hard))
    daemon = Daemon(_named_config(folder, "slow"), folder / "slow.log")
    try:
        with httpx.Client(base_url=daemon.url, timeout=60) as client:
            job_id = client.post("/v1/scans", json={}, headers=AUTH).json()["id"]
            wait_done(client, job_id)
        os.truncate(folder / "slow-data" / "scans" / job_id / "cloud.ply", large_mb << 20)
        request = f"GET /v1/scans/{job_id}/files/cloud.ply HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n".encode()
        sockets, codes, health, health_ms = [], [], [], []
        for k in range(count):
            sock = socket.socket()
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
            sock.settimeout(30)
            try:
                sock.connect(("127.0.0.1", daemon.port))
                sock.sendall(request)
                codes.append(status_code(sock))
            except OSError:
                codes.append(0)
            sockets.append(sock)
            if k % 50 == 49:
                started = time.perf_counter()
                try:
                    health.append(httpx.get(f"{daemon.url}/v1/health", timeout=10).status_code)
                except httpx.HTTPError:
                    health.append(0)
                health_ms.append((time.perf_counter() - started) * 1000)
        deadline = time.monotonic() + 120  # the held downloads are cut within a few send_timeout_s
        while time.monotonic() < deadline and daemon.log.read_text().count("cutting a connection") < codes.count(200):
            time.sleep(0.5)
        cut = daemon.log.read_text().count("cutting a connection")
        after = httpx.get(f"{daemon.url}/v1/health", timeout=10).status_code
        for sock in sockets:
            sock.close()
    finally:
        daemon.stop()
    return {
        "connections": count,
        "downloads_served": codes.count(200),
        "refused_429": codes.count(429),
        "health_checks": len(health) + 1,
        "health_answered": health.count(200) + (after == 200),
        "health_ms_max": round(max(health_ms), 1),
        "held_downloads_cut": cut,
    }


def uploads(folder: Path, reserve_bytes: int) -> dict[str, Any]:
    """Empty bodies, a folder past its limit, and (as root, on a small tmpfs) uploads until the
    disk is nearly full: each refusal's status, and the free space left."""
    daemon = Daemon(_named_config(folder, "up", max_import_bytes=8 << 20), folder / "up.log")
    result: dict[str, Any] = {}
    try:
        with httpx.Client(base_url=daemon.url, timeout=60) as client:
            result["empty_body"] = client.put("/v1/imports/f/frame_00.png", content=b"", headers=AUTH).status_code
            codes = [
                client.put(f"/v1/imports/f/p{k}.yaml", content=b"x" * (3 << 20), headers=AUTH).status_code
                for k in range(4)
            ]
            result["folder_limit"] = codes[-1] if codes[:2] == [201, 201] else codes
    finally:
        daemon.stop()
    disk = folder / "updisk"
    disk.mkdir()
    size_mb = reserve_bytes // 1_000_000 + 60
    mounted = (
        os.geteuid() == 0
        and not subprocess.run(
            ["mount", "-t", "tmpfs", "-o", f"size={size_mb}m", "tmpfs", str(disk)], check=False
        ).returncode
    )
    if not mounted:
        return {**result, "full_disk": "skipped: a tmpfs needs root"}
    config = _named_config(disk, "full")
    daemon = Daemon(config, folder / "full.log")
    try:
        statuses = []
        with httpx.Client(base_url=daemon.url, timeout=60) as client:
            for k in range(40):
                statuses.append(
                    client.put(f"/v1/imports/g/p{k}.yaml", content=os.urandom(4 << 20), headers=AUTH).status_code
                )
                if statuses[-1] != 201:
                    break
            health = client.get("/v1/health").status_code
        free = shutil.disk_usage(disk).free
        result.update(
            full_disk_status=statuses[-1],
            stored=statuses.count(201),
            reserve_intact=free >= reserve_bytes,
            free_mb=round(free / 1e6, 1),
            health=health,
        )
    finally:
        daemon.stop()
        subprocess.run(["umount", "-l", str(disk)], check=False)
    return result


def bombs(folder: Path) -> dict[str, Any]:
    """A 20000x20000 16-bit PNG (0.78 MB) uploaded as a frame, and the same bomb as every frame of
    an imports folder put there behind the API's back (an OpenCV Gray code sequence of the small
    bench, with its true calibration), then reconstructed: the status, and the daemon's peak memory."""
    config = _named_config(folder, "bomb")
    daemon = Daemon(config, folder / "bomb.log")
    bomb = folder / "bomb.png"
    write_png_bomb(bomb, 20000, 20000)
    placed = folder / "bomb-data" / "imports" / "placed"
    placed.mkdir(parents=True)
    with open_rig(load_config(config)) as rig:
        width, height = rig.config.projectors[0].resolution
        spec = opencv_graycode(width, height, "frame_*.png")
        write_opencv_stereo(placed / "calibration.xml", rig.camera_models[0], rig.projector_models[0])
    frames = len(spec.roles())
    for k in range(frames):
        os.link(bomb, placed / f"frame_{k:02d}.png")
    try:
        before = _rss_peak_mb(daemon.process.pid)
        with httpx.Client(base_url=daemon.url, timeout=60) as client:
            upload = client.put("/v1/imports/bombs/frame_00.png", content=bomb.read_bytes(), headers=AUTH).status_code
            body = {"frames": "placed", "calibration": "calibration.xml", "patterns": spec.model_dump(mode="json")}
            created = client.post("/v1/reconstructions", headers=AUTH, json=body)
            state = None
            if created.status_code == 202:
                job = wait_done(client, created.json()["id"])
                state = f"{job['state']}: ...{(job['error'] or '')[-60:]}"
        after = _rss_peak_mb(daemon.process.pid)
    finally:
        daemon.stop()
    return {
        "bomb_bytes": bomb.stat().st_size,
        "frames": frames,
        "upload_status": upload,
        "reconstruction_status": created.status_code,
        "reconstruction": state or created.text[:90],
        "peak_rss_before_mb": round(before, 1),
        "peak_rss_after_mb": round(after, 1),
    }


def key_files(folder: Path) -> dict[str, Any]:
    """`slrig serve --api-key-file F` for each kind of broken key file: its exit code and how long
    it took; and a daemon whose log is searched for a key sent in every part of a URL."""
    good = "a1B2c3D4e5F6g7H8i9J0k1L2m3N4o5P6"
    cases: dict[str, Path] = {}
    for name, data in {
        "bom": b"\xef\xbb\xbf" + good.encode(),
        "non_ascii": (good + "\u00e9").encode(),
        "inner_newline": (good[:16] + "\n" + good[16:]).encode(),
        "empty": b"",
        "over_4_kib": b"k" * 5000,
    }.items():
        cases[name] = folder / f"key-{name}"
        cases[name].write_bytes(data)
    cases["directory"] = folder
    cases["dev_zero"] = Path("/dev/zero")
    cases["fifo"] = folder / "key-fifo"
    os.mkfifo(cases["fifo"])
    config = _named_config(folder, "keys")
    outcomes = {name: _serve_with_key_file(config, path) for name, path in cases.items()}
    daemon = Daemon(config, folder / "keys.log")
    try:
        for query in (
            f"?{KEY}",
            f"?a=1&{KEY}",
            f"?{KEY}=1",
            f"?key={KEY}",
            f"/{KEY}",
            f"?k={KEY[:8]}%{ord(KEY[8]):02X}{KEY[9:]}",
        ):
            httpx.get(f"{daemon.url}/v1/scans{query}")
    finally:
        daemon.stop()
    leaked = daemon.log.read_text().count(KEY)
    return {
        "cases": outcomes,
        "refused_with_2": sum(o["exit"] == 2 for o in outcomes.values()),
        "slowest_s": max(o["s"] for o in outcomes.values()),
        "key_in_log": leaked,
    }


def _serve_with_key_file(config: Path, key_file: Path) -> dict[str, Any]:
    command = [sys.executable, "-m", "rig.cli", "serve", "--config", str(config), "--port", "0"]
    environment = {k: v for k, v in os.environ.items() if k != "SLRIG_API_KEY"}
    started = time.monotonic()
    try:
        run = subprocess.run(
            [*command, "--api-key-file", str(key_file)],
            cwd=REPO,
            capture_output=True,
            text=True,
            timeout=30,
            env=environment,
        )
    except subprocess.TimeoutExpired:
        return {"exit": "hung", "s": 30.0}
    return {"exit": run.returncode, "s": round(time.monotonic() - started, 2)}


def randomised_schema(examples: int, poisoned: int) -> dict[str, Any]:
    """The suite's schema test with random (not derandomised) cases, more of them."""
    from tests.test_api_schema import schema_failures

    with tempfile.TemporaryDirectory() as tmp:
        operations, failures = schema_failures(Path(tmp), examples, poisoned, {"database": None})
    return {"operations": operations, "examples_per_operation": examples, "failures": failures}
