"""Rig configs with real drivers: the example benches validate, a rig of real drivers runs end to
end without hardware (HDMI worker offscreen, OAK worker on its fake backend), and a missing device
fails cleanly with nothing left running."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import pytest
import yaml

from drivers.errors import DeviceNotFoundError
from rig.assembly import open_rig
from rig.cli import main
from rig.config import REPO_CONFIG_DIR, load_config
from rig.errors import ConfigError
from tests.conftest import write_config


def _children() -> list[int]:
    """Live processes whose parent is this one."""
    me, found = os.getpid(), []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                fields = Path(f"/proc/{entry}/stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == me and fields[0] != "Z":
                found.append(int(entry))
    return found


@pytest.mark.parametrize(
    "name", ["bench-hdmi-uvc.yaml", "bench-hdmi-oak.yaml", "bench-lightcrafter-uvc.yaml", "bench-lightcrafter-oak.yaml"]
)
def test_example_benches_validate(name: str) -> None:
    config = load_config(REPO_CONFIG_DIR / name)
    assert config.simulation is None
    assert config.projectors[0].driver == name.split("-")[1]


def _offscreen_oak_rig() -> dict[str, Any]:
    data = yaml.safe_load((REPO_CONFIG_DIR / "bench-hdmi-oak.yaml").read_text())
    projector = data["projectors"][0]
    projector.update(resolution=[256, 192], latency_s=0.0, hdmi={"video_driver": "offscreen"})
    projector["geometry"]["intrinsics"] = {"fx": 320.0, "fy": 320.0, "cx": 127.5, "cy": 95.5}
    del projector["power"]
    camera = data["cameras"][0]
    camera.update(resolution=[320, 256], oak={"backend": "fake"})
    camera["geometry"]["intrinsics"] = {"fx": 450.0, "fy": 450.0, "cx": 159.5, "cy": 127.5}
    data["scan"]["codec"] = "gray"
    return data


def test_a_rig_of_real_drivers_scans_end_to_end(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write_config(tmp_path, _offscreen_oak_rig())
    out = tmp_path / "scan"
    before = set(_children())  # what earlier tests left (multiprocessing's resource tracker, say)
    assert main(["scan", "--config", str(path), "--out", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["devices"]["projectors"][0]["driver"] == "hdmi"
    assert manifest["devices"]["cameras"][0]["driver"] == "oak"
    assert manifest["economy"]["frames_projected"] == summary["frames"] == 2 + 2 * 8
    assert manifest["metrics"] == {}  # no ground truth for a real rig
    assert set(_children()) <= before  # both worker processes are gone


def test_a_missing_camera_fails_cleanly(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data = yaml.safe_load((REPO_CONFIG_DIR / "bench-hdmi-uvc.yaml").read_text())
    data["projectors"][0]["hdmi"] = {"video_driver": "offscreen"}
    data["cameras"][0]["v4l2"]["device"] = "/dev/video-not-attached"
    path = write_config(tmp_path, data)
    before = set(_children())
    with pytest.raises(DeviceNotFoundError, match="does not exist"):
        open_rig(load_config(path))
    assert set(_children()) <= before  # the display worker that did start was stopped
    assert main(["scan", "--config", str(path), "--out", str(tmp_path / "x")]) == 1
    assert "does not exist" in capsys.readouterr().err


def test_real_and_simulated_devices_do_not_mix(tmp_path: Path) -> None:
    data = yaml.safe_load((REPO_CONFIG_DIR / "sim.yaml").read_text())
    data["cameras"][0]["driver"] = "v4l2"
    data["cameras"][0]["v4l2"] = {"device": "/dev/video0"}
    with pytest.raises(ConfigError, match="cannot share a rig"):
        load_config(write_config(tmp_path, data))
    data["cameras"][0]["driver"] = "sim"
    data["projectors"][0].update(driver="hdmi", sync="hardware")
    with pytest.raises(ConfigError, match="software sync"):
        load_config(write_config(tmp_path, data))
