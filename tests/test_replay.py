"""The replay camera in a rig: a scan of the simulated bench, its frames kept, played back through
a real projector's driver (HDMI, offscreen) and the replay camera, decodes to the same cloud; a
source whose frames are another size is refused when the camera opens."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from drivers.errors import DeviceError
from rig.assembly import open_rig
from rig.config import config_from_dict
from rig.pipeline.scan import run_scan
from rig.service.tasks import scan_to_directory
from tests.conftest import small_config_data


def _replaying(data: dict[str, Any], frames: Path, **replay: Any) -> dict[str, Any]:
    """The same rig's geometry, its projector an HDMI output (offscreen) and its camera the replay
    of `frames`."""
    played = copy.deepcopy(data)
    played.pop("simulation", None)
    played["projectors"][0] |= {"driver": "hdmi", "hdmi": {"video_driver": "offscreen"}}
    played["projectors"][0].pop("sim", None)
    played["cameras"][0] |= {"driver": "replay", "replay": {"source": str(frames), "rate_hz": 500.0, **replay}}
    played["cameras"][0].pop("sim", None)
    return played


def test_a_scans_kept_frames_replayed_through_the_rig_give_its_cloud(tmp_path: Path) -> None:
    data = small_config_data()
    with open_rig(config_from_dict(data, "recorded")) as rig:
        path, recorded = scan_to_directory(rig, tmp_path / "scan", "20261129-120000-000000", "gray", keep_frames=True)
    frames = path / "frames" / "projector0_camera0"
    with open_rig(config_from_dict(_replaying(data, frames), "replayed")) as rig:
        replayed = run_scan(rig, "gray")
    assert replayed.frames_projected == recorded.frames_projected
    first, again = recorded.pairs[0], replayed.pairs[0]
    assert first.correspondence.counts["decoded"] == again.correspondence.counts["decoded"] > 10000
    np.testing.assert_allclose(np.nan_to_num(again.grid), np.nan_to_num(first.grid), atol=1e-6)


def test_frames_of_another_size_are_refused_at_open(tmp_path: Path) -> None:
    import cv2

    (tmp_path / "frames").mkdir()
    cv2.imwrite(str(tmp_path / "frames" / "000.png"), np.zeros((10, 12), np.uint8))
    config = config_from_dict(_replaying(small_config_data(), tmp_path / "frames"), "wrong size")
    with pytest.raises(DeviceError, match=r"frames are 12x10, the camera is configured 320x256"), open_rig(config):
        pass


def test_the_doctor_names_a_missing_source_folder(tmp_path: Path) -> None:
    from rig.doctor.checks import check

    config = config_from_dict(_replaying(small_config_data(), tmp_path / "gone"), "replay")
    problems = [p["problem"] for p in check(config) if p["device"] == "camera0"]
    assert problems == [f"replay.source {tmp_path / 'gone'}: no such folder"]
    (tmp_path / "empty").mkdir()
    config = config_from_dict(_replaying(small_config_data(), tmp_path / "empty", files="*.png"), "replay")
    assert [p["problem"] for p in check(config) if p["device"] == "camera0"] == [
        f"replay.source {tmp_path / 'empty'}: no file matches '*.png'"
    ]
