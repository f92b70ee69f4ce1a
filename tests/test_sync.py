"""Projector-camera sync on the simulated bench's timing model: a projector that lights the scene
some time after show(), and a camera driver that hands out buffered (older) frames."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from rig.assembly import open_rig
from rig.cli import main
from rig.config import load_config
from tests.conftest import small_config_data, write_config

LATENCY_S = 0.05  # a frame and a half at 30 frames per second
BUFFERED = 2


def _timed(configured_latency_s: float) -> dict[str, Any]:
    data = small_config_data()
    data["projectors"][0]["sim"]["latency_s"] = LATENCY_S
    data["projectors"][0]["latency_s"] = configured_latency_s
    data["cameras"][0]["sim"]["buffered_frames"] = BUFFERED
    return data


def test_a_naive_capture_loop_records_the_previous_pattern(tmp_path: Path) -> None:
    with open_rig(load_config(write_config(tmp_path, _timed(LATENCY_S)))) as the_rig:
        projector, camera = the_rig.projectors[0], the_rig.cameras[0]
        width, height = projector.resolution
        lit = camera.capture().image.mean()
        projector.show(np.full((height, width), 255, np.uint8))
        naive = camera.capture().image.mean()  # show, then capture at once: a frame from before
        the_rig.wait(LATENCY_S)
        camera.flush()
        synced = camera.capture().image.mean()  # slrig's order: show, wait the latency, flush, capture
    assert naive < lit + 2  # still dark
    assert synced > 5 * max(naive, 1.0)


def _eval(tmp_path: Path, data: dict[str, Any], capsys: pytest.CaptureFixture[str], name: str) -> dict[str, Any]:
    assert main(["eval", "--config", str(write_config(tmp_path, data, name)), "--codec", "gray", "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_software_sync_gives_the_cloud_of_an_ideal_bench(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    ideal = _eval(tmp_path, small_config_data(), capsys, "ideal.yaml")
    synced = _eval(tmp_path, _timed(LATENCY_S), capsys, "synced.yaml")
    unsynced = _eval(tmp_path, _timed(0.0), capsys, "unsynced.yaml")  # latency not measured
    assert synced["points"] == ideal["points"]
    assert synced["rms_mm"] == pytest.approx(ideal["rms_mm"], rel=1e-9)  # the same frames, so the same cloud
    assert unsynced["completeness"] < 0.5 * ideal["completeness"]  # every frame one pattern behind


def test_a_frame_exposed_before_the_light_is_dropped_by_its_stamp(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A driver that keeps one frame more than the flush drops: the stamps show that frame was
    exposed before the pattern was lit, and the next one is taken instead."""
    ideal = _eval(tmp_path, _timed(LATENCY_S), capsys, "ideal.yaml")
    data = _timed(LATENCY_S)
    data["cameras"][0]["sim"]["faults"] = {"early_frame_at": 5}
    gated = _eval(tmp_path, data, capsys, "early.yaml")
    # the same patterns; the sensor noise differs (the dropped frame drew its own)
    assert gated["points"] == pytest.approx(ideal["points"], rel=0.002)
    assert gated["rms_mm"] == pytest.approx(ideal["rms_mm"], rel=0.01)
    from rig.evaluate.pairs import evaluate_on_bench
    from rig.pipeline.scan import run_scan

    with open_rig(load_config(write_config(tmp_path, data, "early.yaml"))) as the_rig:
        projector = the_rig.projectors[0]
        show = projector.show

        def show_unstamped(pattern: np.ndarray) -> None:  # a driver that cannot tell when it presented
            show(pattern)
            projector.last_present_s = None

        projector.show = show_unstamped  # type: ignore[method-assign]
        ungated = evaluate_on_bench(the_rig, run_scan(the_rig).pairs[0])
    # taking the early frame would have given another cloud (one bit plane of the previous pattern)
    assert abs(ungated["points"] - ideal["points"]) > 0.05 * ideal["points"]


def test_hardware_trigger_path_gives_the_same_cloud(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    software = _eval(tmp_path, small_config_data(), capsys, "software.yaml")
    data = small_config_data()
    data["projectors"][0]["sync"] = "hardware"
    data["projectors"][0]["sim"]["latency_s"] = LATENCY_S  # the sequence starts late; triggers follow the light
    data["cameras"][0]["sim"]["buffered_frames"] = BUFFERED  # nothing buffered in triggered mode
    hardware = _eval(tmp_path, data, capsys, "hardware.yaml")
    assert hardware["points"] == software["points"]
    assert hardware["rms_mm"] == pytest.approx(software["rms_mm"], rel=1e-9)


def test_a_missed_trigger_fails_the_scan(tmp_path: Path) -> None:
    from drivers.sequences import TriggerMode
    from rig.errors import ScanError
    from rig.pipeline.scan import run_scan

    data = small_config_data()
    data["projectors"][0]["sync"] = "hardware"
    with open_rig(load_config(write_config(tmp_path, data))) as the_rig:
        camera = the_rig.cameras[0]
        original = camera.capture

        def skip_one(timeout_s: float = 2.0):  # type: ignore[no-untyped-def]
            if camera.trigger is TriggerMode.EXTERNAL and original.__self__._captures == 4:  # type: ignore[attr-defined]
                original(timeout_s)  # this pulse's frame is lost
            return original(timeout_s)

        camera.capture = skip_one  # type: ignore[method-assign]
        with pytest.raises(ScanError, match=r"trigger was missed|dropped"):
            run_scan(the_rig)
        assert all(p.is_dark for p in the_rig.projectors)  # type: ignore[attr-defined]


def test_doctor_measures_the_latency_and_scans_use_it(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data = _timed("measured")
    data["output"] = {"data_dir": str(tmp_path / "data")}
    path = write_config(tmp_path, data, "measured.yaml")
    assert main(["scan", "--config", str(path), "--out", str(tmp_path / "early")]) == 2  # nothing measured yet
    assert "slrig doctor --latency" in capsys.readouterr().err
    assert main(["doctor", "--config", str(path), "--latency", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    measured = report["latency_s"]["projector0"]
    frame_period = 1 / 30
    assert LATENCY_S <= measured < LATENCY_S + frame_period + 0.011  # one frame's resolution, plus exposure
    assert json.loads(Path(report["latency_file"]).read_text()) == {"projector0": measured}
    synced = _eval(tmp_path, data, capsys, "measured-eval.yaml")
    ideal = _eval(tmp_path, small_config_data(), capsys, "ideal2.yaml")
    assert synced["rms_mm"] == pytest.approx(ideal["rms_mm"], rel=1e-9)


def test_doctor_names_what_a_real_bench_lacks(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from rig.config import REPO_CONFIG_DIR

    assert main(["doctor", "--config", str(REPO_CONFIG_DIR / "bench-hdmi-uvc.yaml"), "--json"]) == 1
    problems = {p["device"]: p["problem"] for p in json.loads(capsys.readouterr().out)["problems"]}
    assert "/dev/slrig-cam0 does not exist" in problems["camera0"]
    assert "calibration" in problems["rig"]


def test_doctor_looks_for_the_lightcrafter_on_usb(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    from drivers.dlp import hdmi_patterns as lightcrafter
    from rig.config import REPO_CONFIG_DIR

    config = str(REPO_CONFIG_DIR / "bench-lightcrafter-uvc.yaml")
    hub = {"devices": [{"vid": 0x1D6B, "pid": 0x0002, "bus": 1, "address": 1}]}
    monkeypatch.setattr(lightcrafter, "attached_usb", lambda: hub)
    assert main(["doctor", "--config", config, "--json"]) == 1
    problems = " | ".join(p["problem"] for p in json.loads(capsys.readouterr().out)["problems"])
    assert "no LightCrafter 4500 (USB 0451:6401) attached" in problems
    attached = {"devices": [{"vid": 0x0451, "pid": 0x6401, "bus": None, "address": None}]}
    monkeypatch.setattr(lightcrafter, "attached_usb", lambda: attached)
    assert main(["doctor", "--config", config, "--json"]) == 1
    problems = " | ".join(p["problem"] for p in json.loads(capsys.readouterr().out)["problems"])
    assert "0451:6401" not in problems
