"""Live mode: depth images per repeated sequence, from the CLI, the service and over HTTP with a
client too slow to take every frame."""

from __future__ import annotations

import contextlib
import io
import itertools
import json
import socket
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from fastapi.testclient import TestClient

from rig.api.app import create_app
from rig.api.security import ApiSettings
from rig.assembly import open_rig
from rig.cli import main
from rig.config import RigConfig, config_from_dict, load_config
from rig.errors import ConfigError
from rig.patterns import codec_names
from rig.patterns.stream import FrameStream
from rig.pipeline.live import LiveFrame, dark_frames, live_codecs, run_live, warm_up
from rig.service.job_service import JobService
from tests.conftest import small_config_data, wait_done, write_config
from tests.loopback import daemon_http
from tests.test_daemon import KEY, Daemon

AUTH = {"X-API-Key": KEY}


def _sequences(rig_config: RigConfig, count: int) -> list[LiveFrame]:
    """`count` sequences captured; those published (all but any dropped), then the truth."""
    frames: list[LiveFrame] = []
    asked = iter(range(count))
    with open_rig(rig_config) as rig:
        stats = run_live(rig, frames.append, lambda: next(asked, None) is not None)
        assert all(p.is_dark for p in rig.projectors)  # type: ignore[attr-defined]
        truth = rig.truth.ground_truth(0, 0)  # type: ignore[union-attr]
    numbers = [f.sequence for f in frames]
    assert numbers == sorted(set(numbers)) and numbers[-1] == count  # the newest is never dropped
    assert len(frames) + stats.dropped == count == stats.captured
    frames.append(LiveFrame(0, (truth.depth.astype(np.float32),), 0, 0.0, 0.0, 0.0))  # the truth, last
    return frames


def test_live_depth_images_follow_the_surface(small_config: RigConfig) -> None:
    *frames, truth = _sequences(small_config, 3)
    true_depth = truth.depths[0]
    for frame in frames:
        depth = frame.depths[0]
        found = np.isfinite(depth)
        assert frame.points == int(found.sum())
        assert found.mean() > 0.7  # the short sequence decodes most of the lit bench
        error = np.abs(depth[found] - true_depth[found])
        assert np.median(error) < 0.15 and np.percentile(error, 99) < 1.0  # mm (measured 0.08 and 0.66)
        assert 0 < frame.latency_ms < frame.sequence_ms


@pytest.mark.parametrize(
    ("codec", "sensor"),
    [*((codec, {}) for codec in codec_names()), ("phase", {"bit_depth": 12}), ("phase", {"color": True})],
    ids=[*codec_names(), "phase-12-bit", "phase-colour"],
)  # every codec; the sensor's kind (the dark frames' shape and type) with one
def test_the_warm_up_runs_dark_frames_like_the_cameras_through_every_codec_and_drives_no_device(
    codec: str, sensor: dict[str, Any]
) -> None:
    data = small_config_data()
    data["scan"]["live"] = {"codec": codec}
    data["cameras"][0].update(sensor)
    with open_rig(config_from_dict(data, "warm-up")) as rig:
        codecs = live_codecs(rig)
        assert warm_up(rig, codecs) == 1  # the pair decoded and triangulated its dark frames
        assert [p.shown for p in rig.projectors] == [0]  # type: ignore[attr-defined]
        frame = rig.cameras[0].capture(timeout_s=5.0)  # the cameras' first frame is still their first
        assert frame.sequence == 1
        dark = dark_frames(rig)[0]  # and the warm-up's frames are like theirs
        assert (dark.shape, dark.dtype) == (frame.image.shape, frame.image.dtype) and not dark.any()


def test_the_warm_up_holds_two_sequences_in_flight_before_it_finishes_either(monkeypatch: pytest.MonkeyPatch) -> None:
    # Live mode decodes one sequence while it triangulates the one before, so the warm-up grows the
    # heap by two sequences' arrays held at once (decision 0047), not by one sequence twice.
    events: list[tuple[str, int]] = []
    with open_rig(config_from_dict(small_config_data(), "warm-up")) as rig:
        codecs = live_codecs(rig)
        make = codecs[0].stream

        def stream(full_scale: int) -> FrameStream:
            made = make(full_scale)
            add, finish = made.add, made.finish
            monkeypatch.setattr(made, "add", lambda frame: (events.append(("add", id(made))), add(frame))[1])
            monkeypatch.setattr(made, "finish", lambda: (events.append(("finish", id(made))), finish())[1])
            return made

        monkeypatch.setattr(codecs[0], "stream", stream)
        assert warm_up(rig, codecs) == 1
    streams = list(dict.fromkeys(stream for _, stream in events))
    assert len(streams) == 2
    first_finish = events.index(("finish", streams[0]))
    assert all(("add", s) in events[:first_finish] for s in streams)  # both sequences' frames in first
    assert [e for e in events if e[0] == "add"].count(("add", streams[1])) == codecs[0].frame_count
    assert [e for e in events if e[0] == "finish"] == [("finish", s) for s in streams]


def test_live_hdr_reads_a_dark_and_white_object_that_one_exposure_cannot(tmp_path: Path) -> None:
    data = small_config_data()
    data["simulation"]["texture"] = {"kind": "checker", "size_mm": 25.0, "colours": [[0.03] * 3, [1.0] * 3]}
    single = load_config(write_config(tmp_path, data))
    bracketed = single.with_live(None, "auto")
    assert bracketed.scan.live.hdr == "auto"
    one = _sequences(single, 1)[0]
    *frames, truth = _sequences(bracketed, 2)
    for frame in frames:
        found = np.isfinite(frame.depths[0])
        assert found.sum() > 1.3 * np.isfinite(one.depths[0]).sum()  # the dark squares read too
        error = np.abs(frame.depths[0][found] - truth.depths[0][found])
        assert np.median(error) < 0.15
    with pytest.raises(ConfigError, match="hdr: 2 to 4 exposures"):
        single.with_live(None, "1000,2000,4000,8000,16000")


def test_live_config_is_checked_like_the_file(tmp_path: Path) -> None:
    data = small_config_data()
    data["scan"]["live"] = {"codec": "gray", "params": {"steps": 3}}
    with pytest.raises(ConfigError, match=r"scan\.live\.params \(for codec gray\): steps"):
        load_config(write_config(tmp_path, data))
    data["scan"]["live"] = {"codec": "gray"}  # without params: gray's own
    assert load_config(write_config(tmp_path, data)).scan.live_params().model_dump()["directions"] == "columns"  # type: ignore[union-attr]


def test_slrig_live_reports_rate_and_latency(small_config_path: Path, tmp_path: Path) -> None:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(
            [
                "live",
                "--config",
                str(small_config_path),
                "--seconds",
                "1.5",
                "--json",
                "--depth-png",
                str(tmp_path / "d.png"),
            ]
        )
    assert code == 0
    report = json.loads(out.getvalue())
    assert report["codec"] == "phase" and report["params"]["steps"] == 4
    assert report["sequences"] >= 2 and report["clouds_per_s"] > 0
    assert 0 < report["latency_ms"]["median"] < report["sequence_ms_median"]
    depth = cv2.imread(str(tmp_path / "d.png"), cv2.IMREAD_UNCHANGED)
    assert depth.dtype == np.uint16 and depth.shape == (256, 320)
    assert 450 < np.median(depth[depth > 0]) < 650  # mm: the bench lies about 600 mm below the camera


def _service(tmp_path: Path) -> JobService:
    data = small_config_data()
    data["output"] = {"data_dir": str(tmp_path / "data")}
    config = load_config(write_config(tmp_path, data, "serve.yaml"))
    service = JobService(config, config.service.max_queue)
    service.start()
    return service


@pytest.fixture
def client(tmp_path: Path) -> Iterator[tuple[TestClient, JobService]]:
    service = _service(tmp_path)
    with TestClient(create_app(service, ApiSettings(api_key=KEY)), base_url="http://localhost") as c:
        yield c, service
    service.shutdown(5.0)


def _wait_live(client: TestClient, check: Any, timeout_s: float = 60.0) -> dict[str, Any]:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        view = client.get("/v1/live/status").json()
        if check(view):
            return view
        time.sleep(0.05)
    raise AssertionError(f"live mode never got there: {view}")


def test_a_queued_scan_pauses_live_mode_which_then_resumes(client: tuple[TestClient, JobService]) -> None:
    c, service = client
    assert c.post("/v1/live", json={}).status_code == 401  # starting drives the projector: the key
    assert c.post("/v1/live", json={"codec": "nope"}, headers=AUTH).status_code == 422
    assert c.post("/v1/live", json={"seconds": 0}, headers=AUTH).status_code == 422
    assert c.get("/v1/live/depth.png").status_code == 404  # nothing yet
    ended = c.get("/v1/live").text  # live mode is off: its state, then the stream ends
    assert ended.startswith("event: state\n") and '"state": "off"' in ended and "retry: 2000" in ended
    started = c.post("/v1/live", json={}, headers=AUTH)
    assert started.status_code == 202 and started.json()["params"]["steps"] == 4
    _wait_live(c, lambda v: v["state"] == "running" and v["sequences"] >= 2)
    assert c.get("/v1/rig").json()["state"] == "live"
    depth = c.get("/v1/live/depth.png")
    assert depth.status_code == 200 and depth.headers["x-depth-unit-mm"] == "0.1"
    image = cv2.imdecode(np.frombuffer(depth.content, np.uint8), cv2.IMREAD_UNCHANGED)
    assert image.shape == (256, 320) and 4500 < np.median(image[image > 0]) < 6500  # tenths of a mm
    scan = c.post("/v1/scans", json={"codec": "gray"}, headers=AUTH).json()
    assert wait_done(c, scan["id"])["state"] == "done"  # a triggered scan never waits for live mode
    before = c.get("/v1/live/status").json()["sequences"]
    _wait_live(c, lambda v: v["state"] == "running" and v["sequences"] > before + 1)  # resumed
    stopped = c.delete("/v1/live", headers=AUTH).json()
    assert stopped["state"] in ("running", "off") and stopped["reason"] == "stopped by request"
    _wait_live(c, lambda v: v["state"] == "off")
    deadline = time.monotonic() + 10
    while c.get("/v1/rig").json()["state"] != "idle" and time.monotonic() < deadline:
        time.sleep(0.05)
    assert all(p.is_dark for p in service.open_rig.projectors)  # type: ignore[union-attr, attr-defined]


def test_live_mode_stops_at_its_time_limit(client: tuple[TestClient, JobService]) -> None:
    c, _ = client
    assert c.post("/v1/live", json={"seconds": 1.0}, headers=AUTH).status_code == 202
    view = _wait_live(c, lambda v: v["state"] == "off" and v["sequences"] > 0)
    assert view["reason"] == "its time limit passed"


def test_live_hdr_over_rest(client: tuple[TestClient, JobService]) -> None:
    c, _ = client
    # the time limit runs from the request: long enough that a busy machine's job worker, which
    # starts live mode, still captures a sequence within it (1 s did not, once, in a full suite run)
    started = c.post("/v1/live", json={"seconds": 5.0, "hdr": [2000.0, 8000.0]}, headers=AUTH)
    assert started.status_code == 202 and started.json()["hdr"] == [2000.0, 8000.0]
    view = _wait_live(c, lambda v: v["state"] == "off" and v["sequences"] > 0)
    assert view["reason"] == "its time limit passed"
    for body in ({"hdr": [2000.0]}, {"hdr": "sometimes"}):
        refused = c.post("/v1/live", json=body, headers=AUTH)
        assert refused.status_code in (409, 422) and "hdr" in json.dumps(refused.json()), refused.json()


def _depth_sequences(chunk: bytes) -> list[int]:
    """The sequence numbers of the depth events in a stretch of an event stream."""
    found = []
    for block in chunk.split(b"\n\n"):
        lines = block.split(b"\n")
        if b"event: depth" in lines:
            found.append(int(next(line for line in lines if line.startswith(b"id: "))[4:]))
    return found


def _status(url: str) -> dict[str, Any]:
    return daemon_http.get(f"{url}/v1/live/status", timeout=5).json()


def _rate(url: str, seconds: float) -> float:
    first = _status(url)["sequences"]
    t = time.monotonic()
    time.sleep(seconds)
    return (_status(url)["sequences"] - first) / (time.monotonic() - t)


def _sequences_beyond_buffers(url: str) -> int:
    """How many full-size depth events overflow every buffer a stalled client's stream passes."""
    png = daemon_http.get(f"{url}/v1/live/depth.png", timeout=5).content
    event_bytes = len(png) * 4 // 3  # the event carries the PNG in base64
    wmem = Path("/proc/sys/net/ipv4/tcp_wmem")  # Linux's most a send buffer grows to; else its default
    kernel_bytes = int(wmem.read_text().split()[2]) if wmem.exists() else 4 << 20
    server_bytes = 1 << 16  # the server's write buffer before it waits for the socket
    client_bytes = 1 << 16  # the client's receive window and its kernel's slack
    return (kernel_bytes + server_bytes + client_bytes) // event_bytes + 3


def test_a_slow_client_drops_frames_and_never_slows_the_rig(tmp_path: Path) -> None:
    data = small_config_data()
    data["output"] = {"data_dir": str(tmp_path / "data")}
    config = write_config(tmp_path, data, "serve.yaml")
    daemon = Daemon(config, tmp_path / "daemon.log")
    stack = contextlib.ExitStack()  # the slow client's socket, closed however the test ends
    try:
        assert daemon_http.post(f"{daemon.url}/v1/live", json={}, headers=AUTH, timeout=5).status_code == 202
        deadline = time.monotonic() + 60
        while _status(daemon.url)["sequences"] < 3:
            assert time.monotonic() < deadline, "live mode did not start"
            time.sleep(0.1)
        alone = _rate(daemon.url, 3.0)
        # A client with a tiny receive window asking for full-size depth images, then not reading.
        slow = stack.enter_context(socket.socket())
        slow.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        slow.connect(("127.0.0.1", daemon.port))
        slow.sendall(b"GET /v1/live?stride=1 HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
        slow.settimeout(10)
        first = slow.recv(4096)
        assert b" 200 " in first.split(b"\r\n", 1)[0]
        at_stall = _status(daemon.url)["sequences"]
        stalled = _rate(daemon.url, 3.0)  # the client reads nothing meanwhile
        # A rig that waited for the client would stop within a buffer's worth of frames; the
        # margin is for a machine whose other work (another test, another process) takes a core.
        assert stalled >= 0.25 * alone, f"the rig slowed from {alone:.1f} to {stalled:.1f} sequences/s"
        # More sequences than every buffer between the rig and the client holds (the kernel's send
        # buffer, which grows up to tcp_wmem's maximum, the server's write buffer and the client's
        # window): a rig that drops frames for this client must then have dropped some.
        wanted = _sequences_beyond_buffers(daemon.url)
        deadline = time.monotonic() + 180
        while _status(daemon.url)["sequences"] - at_stall < wanted:
            assert time.monotonic() < deadline, f"the rig made fewer than {wanted} sequences in 3 minutes"
            time.sleep(0.2)
        # It reads again: what it gets skips sequences and soon reaches the newest.
        received = b""
        slow.settimeout(5)
        end = time.monotonic() + 3
        while time.monotonic() < end:
            received += slow.recv(1 << 20)
        slow.close()
        newest = _status(daemon.url)["sequences"]
        sequences = _depth_sequences(received)
        assert len(sequences) >= 2
        assert max(b - a for a, b in itertools.pairwise(sequences)) > 1  # dropped
        assert newest - sequences[-1] <= 0.5 * newest  # not replaying a backlog
        assert (
            daemon_http.delete(f"{daemon.url}/v1/live", headers=AUTH, timeout=5).json()["reason"]
            == "stopped by request"
        )
    finally:
        stack.close()
        daemon.stop()


def test_a_failure_during_live_mode_is_the_one_raised_and_the_projector_ends_dark(small_config: RigConfig) -> None:
    """The worker still finishing a sequence when live mode fails must not hide why it failed."""
    asked = iter(range(3))

    def keep_going() -> bool:
        if next(asked, None) is None:
            raise RuntimeError("the operator pulled the plug")
        return True

    frames: list[LiveFrame] = []
    with open_rig(small_config) as rig:
        with pytest.raises(RuntimeError, match="pulled the plug"):
            run_live(rig, frames.append, keep_going)
        assert all(p.is_dark for p in rig.projectors)  # type: ignore[attr-defined]
    assert [f.sequence for f in frames][-1] == 3  # the last sequence was finished all the same
