"""Device faults and degenerate scans: each fails cleanly (projector dark, exit 1) or succeeds
with nothing, never with a traceback."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from drivers.errors import DeviceError
from rig.assembly import open_rig
from rig.cli import main
from rig.config import load_config
from rig.errors import ScanError
from rig.pipeline.scan import run_scan
from tests.conftest import small_config_data, write_config


def _two_projectors() -> dict[str, Any]:
    data = small_config_data()
    second = json.loads(json.dumps(data["projectors"][0]))
    second["name"] = "projector1"
    second["geometry"]["pose"]["position_mm"] = [-200.0, 0.0, 620.0]
    data["projectors"].append(second)
    data["scan"]["codec"] = "gray"
    return data


def test_two_projectors_scan_one_after_the_other(tmp_path: Path) -> None:
    with open_rig(load_config(write_config(tmp_path, _two_projectors()))) as the_rig:
        result = run_scan(the_rig)
        assert [(p.projector, p.camera) for p in result.pairs] == [(0, 0), (1, 0)]
        assert all(len(p.points) > 20_000 for p in result.pairs)
        assert all(p.is_dark for p in the_rig.projectors)  # type: ignore[attr-defined]


@pytest.mark.parametrize("repeat_at", [5, 19])  # inside the first projector's run, and at the switch
def test_a_stale_frame_fails_the_scan_even_at_a_projector_switch(tmp_path: Path, repeat_at: int) -> None:
    data = _two_projectors()
    frames_per_projector = 2 + 2 * 8  # gray, 256 columns
    assert repeat_at in (5, frames_per_projector + 1)
    data["cameras"][0]["sim"]["faults"] = {"repeat_frame_at": repeat_at}
    with open_rig(load_config(write_config(tmp_path, data))) as the_rig:
        with pytest.raises(ScanError, match="stale frame"):
            run_scan(the_rig)
        assert all(p.is_dark for p in the_rig.projectors)  # type: ignore[attr-defined]


def test_cli_exits_1_on_a_camera_timeout_and_leaves_the_projector_dark(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = small_config_data()
    data["cameras"][0]["sim"]["faults"] = {"stall_after_frames": 3}
    data["scan"]["capture_timeout_s"] = 0.2
    assert main(["scan", "--config", str(write_config(tmp_path, data)), "--out", str(tmp_path / "x")]) == 1
    err = capsys.readouterr().err
    assert "scan failed" in err and "deadline" in err
    assert not (tmp_path / "x").exists() and not (tmp_path / "x.partial").exists()


def test_a_projector_fault_during_show_fails_the_scan_and_darkens(tmp_path: Path) -> None:
    with open_rig(load_config(write_config(tmp_path, small_config_data()))) as the_rig:
        projector = the_rig.projectors[0]
        shown = 0
        original = projector._do_show

        def failing_show(pattern: np.ndarray) -> None:
            nonlocal shown
            shown += 1
            if shown == 4:
                raise DeviceError("lamp failure")
            original(pattern)

        projector._do_show = failing_show  # type: ignore[method-assign]
        with pytest.raises(ScanError, match="lamp failure"):
            run_scan(the_rig)
        assert projector.is_dark  # type: ignore[attr-defined]


@pytest.mark.parametrize("codec", ["gray", "rings"])
def test_a_scan_that_sees_nothing_succeeds_with_no_points(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], codec: str
) -> None:
    data = small_config_data()
    data["projectors"][0]["sim"]["brightness"] = 0.001  # far too dim to decode anything
    data["projectors"][0]["geometry"]["distortion"] = [0.05]  # and the distorted-projector paths
    path = write_config(tmp_path, data)
    assert main(["eval", "--config", str(path), "--codec", codec, "--json"]) == 0
    report = json.loads(capsys.readouterr().out)  # strict JSON: no NaN
    assert report["points"] == 0 and report["rms_mm"] is None
    out = tmp_path / "empty"
    assert main(["scan", "--config", str(path), "--codec", codec, "--out", str(out)]) == 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["economy"]["points"] == 0


def test_oak_worker_killed_mid_scan_fails_the_scan_not_the_process(tmp_path: Path) -> None:
    import os
    import signal

    from drivers.oak.camera import OakCamera

    with open_rig(load_config(write_config(tmp_path, small_config_data()))) as the_rig:
        oak = OakCamera("camera0", (320, 256), backend="fake")
        oak.open()
        the_rig.cameras[0] = oak
        original = oak.capture
        taken = 0

        def capture_then_die(timeout_s: float = 2.0):  # type: ignore[no-untyped-def]
            nonlocal taken
            taken += 1
            if taken == 5 and oak.worker_pid is not None:
                os.kill(oak.worker_pid, signal.SIGKILL)  # what a native abort or OOM kill looks like
            return original(timeout_s)

        oak.capture = capture_then_die  # type: ignore[method-assign]
        with pytest.raises(ScanError, match=r"exited|not running|gone"):
            run_scan(the_rig)
        assert all(p.is_dark for p in the_rig.projectors)  # type: ignore[attr-defined]
        oak.close()
    assert taken == 5  # the scan stopped at the fault; this process goes on
