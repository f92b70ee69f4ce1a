"""Calibration on the simulated bench: accuracy against the simulator's geometry, the quality
report, the files, and bad inputs."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from rig.assembly import geometry_model, open_rig
from rig.calibrate.files import load_calibration
from rig.calibrate.session import CalibrationOutcome, calibrate
from rig.cli import main
from rig.config import load_config
from tests.conftest import default_config_data, small_config_data, write_config


def _pose_error(estimated: Any, truth: Any) -> tuple[float, float]:
    """Rotation (degrees) and position (mm) of an estimated device pose against the truth."""
    relative = estimated.R @ truth.R.T
    angle = np.degrees(np.arccos(np.clip((np.trace(relative) - 1) / 2, -1, 1)))
    return float(angle), float(np.linalg.norm(estimated.center - truth.center))


@pytest.fixture(scope="module")
def full_calibration(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[CalibrationOutcome, Path]]:
    folder = tmp_path_factory.mktemp("cal")
    with open_rig(load_config()) as the_rig:
        outcome = calibrate(the_rig, "rig", folder, views=10)
    yield outcome, folder


def test_intrinsics_and_extrinsics_match_the_simulator(full_calibration: tuple[CalibrationOutcome, Path]) -> None:
    outcome, folder = full_calibration
    models, digest = load_calibration(folder)
    assert digest == outcome.sha256
    config = load_config()
    truth = {d.name: geometry_model(d.geometry, d.resolution) for d in (*config.cameras, *config.projectors)}
    for name, model in models.items():
        true = truth[name]
        assert model.K[0, 0] == pytest.approx(true.K[0, 0], rel=0.005)
        assert model.K[1, 1] == pytest.approx(true.K[1, 1], rel=0.005)
        assert abs(model.K[0, 2] - true.K[0, 2]) <= 2.0 and abs(model.K[1, 2] - true.K[1, 2]) <= 2.0
        angle, shift = _pose_error(model, true)
        assert angle <= 0.1 and shift <= 0.5, name
    # the rig's own extrinsics: camera -> projector
    cam, proj = models["camera0"], models["projector0"]
    true_cam, true_proj = truth["camera0"], truth["projector0"]
    relative = proj.R @ cam.R.T
    true_relative = true_proj.R @ true_cam.R.T
    angle = np.degrees(np.arccos(np.clip((np.trace(relative @ true_relative.T) - 1) / 2, -1, 1)))
    baseline = proj.t - relative @ cam.t
    true_baseline = true_proj.t - true_relative @ true_cam.t
    assert angle <= 0.1 and np.linalg.norm(baseline - true_baseline) <= 0.5
    report = outcome.report["devices"]
    assert report["camera0"]["rms_px"] <= 0.3 and report["projector0"]["rms_px"] <= 0.5


def test_a_scan_with_the_estimated_calibration(
    full_calibration: tuple[CalibrationOutcome, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _, folder = full_calibration
    assert main(["eval", "--json"]) == 0
    truth = json.loads(capsys.readouterr().out)
    data = default_config_data()
    data["calibration"] = {"file": str(folder)}
    config_path = write_config(tmp_path, data)
    assert main(["eval", "--config", str(config_path), "--json"]) == 0
    estimated = json.loads(capsys.readouterr().out)
    assert estimated["rms_mm"] <= 1.5 * truth["rms_mm"]
    assert main(["scan", "--config", str(config_path), "--out", str(tmp_path / "scan")]) == 0
    manifest = json.loads((tmp_path / "scan" / "manifest.json").read_text())
    assert set(manifest["calibration_sha256"].values()) == {load_calibration(folder)[1]}


def test_files_and_report(full_calibration: tuple[CalibrationOutcome, Path]) -> None:
    outcome, folder = full_calibration
    storage = cv2.FileStorage(str(folder / "calibration.yaml"), cv2.FILE_STORAGE_READ)
    camera_matrix = storage.getNode("camera0").getNode("camera_matrix").mat()
    np.testing.assert_allclose(camera_matrix, outcome.devices[0].K, rtol=1e-9)
    assert storage.getNode("sha256").string() == outcome.sha256
    for name in ("camera0", "projector0"):
        picture = cv2.imread(str(folder / f"coverage_{name}.png"))
        assert picture is not None and picture.std() > 5
        device = outcome.report["devices"][name]
        assert len(device["per_view_rms_px"]) >= 8 and 0.2 < device["coverage"] <= 1.0


def _small(tmp_path: Path, **calibration: Any) -> Path:
    data = small_config_data()
    data["calibration"] = calibration
    return write_config(tmp_path, data)


def _calibrate(what: str, config: Path | str, out: Path, *options: str) -> int:
    """`slrig calibrate <what>` on a config, writing to `out`; the CLI's exit code."""
    return main(["calibrate", what, "--config", str(config), "--out", str(out), *options])


def test_charuco_and_a_folder_of_views_give_the_same_calibration(tmp_path: Path) -> None:
    path = _small(
        tmp_path, board={"kind": "charuco", "squares": [8, 6], "square_mm": 25.0, "marker_mm": 18.0}, views=12
    )
    assert _calibrate("camera", path, tmp_path / "a", "--save-views", str(tmp_path / "views")) == 0
    assert _calibrate("camera", path, tmp_path / "b", "--images", str(tmp_path / "views")) == 0
    a, _ = load_calibration(tmp_path / "a")
    b, _ = load_calibration(tmp_path / "b")
    np.testing.assert_allclose(a["camera0"].K, b["camera0"].K, rtol=1e-6)
    truth = geometry_model(load_config(path).cameras[0].geometry, (320, 256))
    assert a["camera0"].K[0, 0] == pytest.approx(truth.K[0, 0], rel=0.02)  # a quarter-resolution camera


def test_few_views_are_reported(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert _calibrate("camera", _small(tmp_path), tmp_path / "cal", "--views", "4", "--json") == 0
    report = json.loads(capsys.readouterr().out)
    assert any("only 4 views" in w for w in report["warnings"])


def _save_views(tmp_path: Path, views: Path) -> None:
    """Three views of the small bench's 10x7 board, written as a folder of images."""
    assert _calibrate("camera", _small(tmp_path, views=3), tmp_path / "first", "--save-views", str(views)) == 0


def _existing_calibration(folder: Path) -> bytes:
    folder.mkdir(parents=True)
    (folder / "calibration.json").write_text('{"kept": true}')
    return (folder / "calibration.json").read_bytes()


@pytest.mark.parametrize(
    ("case", "message"),
    [
        ("no board", "no view shows"),
        ("wrong board", "no view shows the 9x6"),
        ("two views", "at least 3"),
    ],
)
def test_bad_calibration_inputs_exit_2_and_keep_the_old_calibration(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], case: str, message: str
) -> None:
    out = tmp_path / "cal"
    before = _existing_calibration(out)
    views = tmp_path / "views"
    args = ["calibrate", "camera", "--out", str(out)]
    if case == "no board":
        for k in range(4):
            (views / f"view_{k:02d}").mkdir(parents=True)
            cv2.imwrite(str(views / f"view_{k:02d}" / "camera0.png"), np.full((256, 320), 40, np.uint8))
        args += ["--config", str(_small(tmp_path)), "--images", str(views)]
    elif case == "wrong board":  # the views show a 10x7 board; the config says 9x6
        _save_views(tmp_path, views)
        args += ["--config", str(_small(tmp_path, board={"squares": [9, 6]})), "--images", str(views)]
    else:
        _save_views(tmp_path, views)
        for extra in sorted(views.iterdir())[2:]:
            for f in extra.iterdir():
                f.unlink()
            extra.rmdir()
        args += ["--config", str(_small(tmp_path)), "--images", str(views)]
    capsys.readouterr()
    assert main(args) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert (out / "calibration.json").read_bytes() == before
    assert _calibrate("camera", _small(tmp_path), out, "--views", "2") == 2
    assert "--views" in capsys.readouterr().err


def test_operator_supplied_poses(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    poses = [{"center_mm": [0.0, 0.0, 0.0]}] + [
        {"center_mm": [x, y, 30.0], "rotation_deg": [rx, ry, 5.0]}
        for x, y, rx, ry in [(-40, -30, 20, 0), (40, -30, 0, 20), (40, 30, -20, 0), (-40, 30, 0, -20), (0, 0, 15, 15)]
    ]
    path = _small(tmp_path, poses=poses)
    assert _calibrate("camera", path, tmp_path / "cal", "--json") == 0
    report = json.loads(capsys.readouterr().out)
    assert report["views"] == 6
    assert report["devices"]["camera0"]["views_used"] == [0, 1, 2, 3, 4, 5]


def test_calibration_captures_in_sync_on_a_bench_with_latency(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = small_config_data()
    data["projectors"][0]["sim"]["latency_s"] = 0.05
    data["projectors"][0]["latency_s"] = 0.05
    data["cameras"][0]["sim"]["buffered_frames"] = 2
    data["calibration"] = {"views": 6}
    path = write_config(tmp_path, data)
    assert _calibrate("rig", path, tmp_path / "cal", "--json") == 0
    report = json.loads(capsys.readouterr().out)["devices"]
    assert report["camera0"]["rms_px"] < 0.3 and report["projector0"]["rms_px"] < 0.5


def test_a_lens_model_per_device(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A camera with its centre fixed beside a projector whose centre (a DLP's lens shift) is free."""
    path = _small(tmp_path, views=8)
    models = ["--camera-model", "k1+fixed_centre", "--projector-model", "k1k2"]
    assert _calibrate("rig", path, tmp_path / "cal", *models, "--json") == 0
    report = json.loads(capsys.readouterr().out)
    chosen = {name: device["model"] for name, device in report["devices"].items()}
    assert chosen == {"camera0": "k1+fixed_centre", "projector0": "k1k2"}
    assert _calibrate("rig", path, tmp_path / "bad", "--projector-model", "k9") == 2
    assert "--projector-model 'k9'" in capsys.readouterr().err


def test_the_world_frame_is_the_first_boards_or_the_first_cameras(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The same views written in either frame: the camera at the origin in its own, the pair's relative
    pose unchanged, and the first view's board, triangulated by the pair, where each frame puts it."""
    path = _small(tmp_path, views=8)
    assert _calibrate("rig", path, tmp_path / "board", "--save-views", str(tmp_path / "views"), "--json") == 0
    on_board = json.loads(capsys.readouterr().out)["world"]
    in_camera_frame = ["--images", str(tmp_path / "views"), "--world", "camera"]
    assert _calibrate("rig", path, tmp_path / "camera", *in_camera_frame) == 0
    capsys.readouterr()
    board, _ = load_calibration(tmp_path / "board")
    camera, _ = load_calibration(tmp_path / "camera")
    np.testing.assert_allclose(camera["camera0"].R, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(camera["camera0"].t, 0.0, atol=1e-9)
    relative = board["projector0"].R @ board["camera0"].R.T
    np.testing.assert_allclose(camera["projector0"].R, relative, atol=1e-9)
    truth = geometry_model(load_config(path).cameras[0].geometry, (320, 256))
    assert _pose_error(board["camera0"], truth)[1] < 5.0  # the board frame is the bench's: the camera sits there
    document = json.loads((tmp_path / "camera" / "calibration.json").read_text())
    in_camera = document["report"]["world"]
    assert on_board["frame"] == "board" and in_camera["frame"] == "camera" and document["world"] == "camera"
    for placed in (on_board["first_view_board"], in_camera["first_view_board"]):
        assert placed["corners"] >= 20 and placed["rms_mm"] < 1.0  # a 320 x 256 camera, 20 mm squares
    assert in_camera["first_view_board"]["rms_mm"] == pytest.approx(on_board["first_view_board"]["rms_mm"], abs=1e-3)
    assert main(["calibration", "show", str(tmp_path / "camera" / "calibration.json"), "--json"]) == 0
    shown = json.loads(capsys.readouterr().out)
    assert shown["world"] == "camera" and shown["devices"]["camera0"]["center_mm"] == [0.0, 0.0, 0.0]
    for name in ("on-board", "on-camera"):
        (tmp_path / name).mkdir()
    scanning = _small(tmp_path / "on-board", views=8, file=str(tmp_path / "board"))
    before = (tmp_path / "board" / "calibration.json").read_bytes()
    assert _calibrate("rig", scanning, tmp_path / "board", *in_camera_frame) == 2
    assert "is the calibration the simulated bench scans with" in capsys.readouterr().err
    assert (tmp_path / "board" / "calibration.json").read_bytes() == before  # nothing replaced
    scanned = _small(tmp_path / "on-camera", views=8, file=str(tmp_path / "camera"))
    assert main(["scan", "--config", str(scanned), "--out", str(tmp_path / "scan")]) == 2
    assert "written in the first camera's frame (--world camera)" in capsys.readouterr().err
