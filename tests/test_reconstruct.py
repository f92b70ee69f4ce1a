"""`reconstruct`: captures in another system's convention, saved as files with another tool's
calibration, become a scan directory as accurate as slrig's own codec of the same family."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
import yaml

from rig.assembly import open_rig
from rig.calibrate.foreign import ForeignCalibrationOptions, write_opencv_stereo
from rig.cli import main
from rig.config import load_config
from rig.errors import FramesError
from rig.patterns.described import described_patterns
from rig.patterns.spec import opencv_graycode
from rig.pipeline.scan import run_scan
from rig.service.reconstruct import reconstruct_folder
from tests.conftest import shared_data, small_config_data, write_config


def _opencv_calibration(path: Path, camera: Any, projector: Any) -> Path:
    """The bench's true models as OpenCV's stereoCalibrate would give them (camera first)."""
    return write_opencv_stereo(path, camera, projector)


def _rms_against_truth(grid: np.ndarray, camera: Any, truth: Any, in_camera_frame: bool) -> tuple[float, int]:
    points = (grid - camera.t) @ camera.R if in_camera_frame else grid  # camera frame -> bench
    ok = np.isfinite(points).all(axis=2) & truth.hit
    return float(np.sqrt(np.mean(np.sum((points[ok] - truth.points[ok]) ** 2, axis=1)))), int(ok.sum())


def reconstructed_error(rendered: dict[str, Any], name: str) -> tuple[float, int]:
    """Rms against the truth and pixels of folder `name` (with `name`.yaml beside it) reconstructed
    with a rendered set's calibration (rendered: folder, calibration, config, camera, truth)."""
    folder: Path = rendered["folder"]
    _, result = reconstruct_folder(
        folder / name,
        folder / f"{name}.yaml",
        rendered["calibration"],
        folder / f"scan_{name}",
        f"20261125-120000-{name[:6]:a<6}",
        rendered["config"],
    )
    return _rms_against_truth(result.pairs[0].grid, rendered["camera"], rendered["truth"], in_camera_frame=True)


@pytest.fixture(scope="module")
def foreign(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    folder = tmp_path_factory.mktemp("foreign")
    config = load_config()
    with open_rig(config) as rig:
        width, height = config.projectors[0].resolution
        spec = opencv_graycode(width, height, "graycode_*.png")
        frames = folder / "frames"
        frames.mkdir()
        for i, pattern in enumerate(described_patterns(spec)):
            rig.projectors[0].show(pattern)
            cv2.imwrite(str(frames / f"graycode_{i:02d}.png"), rig.cameras[0].capture().image)
        own = run_scan(rig, "gray")
        assert rig.truth is not None
        truth = rig.truth.ground_truth(0, 0)
        camera, projector = rig.camera_models[0], rig.projector_models[0]
    (folder / "patterns.yaml").write_text(yaml.safe_dump(spec.model_dump(mode="json")))
    calibration = _opencv_calibration(folder / "calibration_result.xml", camera, projector)
    return {
        "folder": folder,
        "config": config,
        "own": own,
        "truth": truth,
        "camera": camera,
        "calibration": calibration,
    }


def test_foreign_gray_captures_reconstruct_as_accurately_as_slrigs_own_gray(foreign: dict[str, Any]) -> None:
    folder, camera, truth = foreign["folder"], foreign["camera"], foreign["truth"]
    target = folder / "scan"
    path, result = reconstruct_folder(
        folder / "frames",
        folder / "patterns.yaml",
        foreign["calibration"],
        target,
        "20261125-120000-abcdef",
        foreign["config"],
    )
    theirs, covered = _rms_against_truth(result.pairs[0].grid, camera, truth, in_camera_frame=True)
    ours, own_covered = _rms_against_truth(foreign["own"].pairs[0].grid, camera, truth, in_camera_frame=False)
    assert theirs <= 1.1 * ours, (theirs, ours)  # 0.850 and 0.849 mm measured
    assert covered >= 0.95 * own_covered
    manifest = json.loads((path / "manifest.json").read_text())
    assert manifest["codec"]["name"] == "described" and manifest["economy"]["frames_projected"] == 42
    inputs = manifest["origin"]["reconstructed"]
    assert len(inputs["frames_sha256"]) == 42 and len(inputs["patterns_sha256"]) == 64
    assert {"cloud.ply", "preview.png", "manifest.json"} <= {p.name for p in path.iterdir()}


def test_a_folder_with_a_frame_missing_writes_nothing(foreign: dict[str, Any], tmp_path: Path) -> None:
    frames = tmp_path / "frames"
    frames.mkdir()
    for source in sorted((foreign["folder"] / "frames").glob("*.png"))[:-1]:
        (frames / source.name).write_bytes(source.read_bytes())
    counted = r"the pattern description has 42 frames \(columns: 20 Gray; rows: 20 Gray; white and black 2\), 41 files"
    with pytest.raises(FramesError, match=counted):
        reconstruct_folder(
            frames,
            foreign["folder"] / "patterns.yaml",
            foreign["calibration"],
            tmp_path / "out",
            "x",
            foreign["config"],
        )
    assert not (tmp_path / "out").exists()


def test_the_command_line_writes_the_scan_and_refuses_what_does_not_fit(
    foreign: dict[str, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = foreign["folder"]
    common = [
        str(folder / "frames"),
        "--patterns",
        str(folder / "patterns.yaml"),
        "--calibration",
        str(foreign["calibration"]),
    ]
    assert main(["reconstruct", *common, "--out", str(tmp_path / "scan"), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["frames"] == 42 and summary["points"] > 0.9 * summary["lit"]
    assert main(["reconstruct", *common, "--out", str(tmp_path / "scan")]) == 2  # exists: kept
    assert "already exists" in capsys.readouterr().err
    assert main(["reconstruct", *common, "--out", str(tmp_path / "b"), "--camera-resolution", "640x512"]) == 2
    assert "img_shape: 1280x1024 in the file, 640x512 in the options" in capsys.readouterr().err
    assert main(["reconstruct", *common, "--out", str(tmp_path / "c"), "--translation-scale", "-1"]) == 2
    assert "--translation-scale: Input should be greater than 0" in capsys.readouterr().err
    assert not (tmp_path / "b").exists() and not (tmp_path / "c").exists()


def test_a_calibration_split_over_two_files_reconstructs_as_the_one_file(
    foreign: dict[str, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """OpenCV's stereo sample writes intrinsics.yml (M1 D1 M2 D2) and extrinsics.yml (R T): read
    together they are the calibration the one file holds."""
    from rig.calibrate.foreign import read_foreign_calibration

    found = read_foreign_calibration(foreign["calibration"])
    camera, projector = found.camera, found.projector
    split = {"intrinsics.yml": {"M1": camera.K, "D1": camera.dist, "M2": projector.K, "D2": projector.dist}}
    split["extrinsics.yml"] = {"R": projector.R @ camera.R.T, "T": projector.t - projector.R @ camera.R.T @ camera.t}
    for name, fields in split.items():
        storage = cv2.FileStorage(str(tmp_path / name), cv2.FILE_STORAGE_WRITE)
        for key, value in fields.items():
            storage.write(key, np.asarray(value, float))
        storage.release()
    folder = foreign["folder"]
    common = [str(folder / "frames"), "--patterns", str(folder / "patterns.yaml"), "--json"]
    assert (
        main(["reconstruct", *common, "--calibration", str(foreign["calibration"]), "--out", str(tmp_path / "a")]) == 0
    )
    one = json.loads(capsys.readouterr().out)
    sizes = ["--camera-resolution", f"{camera.width}x{camera.height}"]
    sizes += ["--projector-resolution", f"{projector.width}x{projector.height}"]
    files = [str(tmp_path / "intrinsics.yml"), str(tmp_path / "extrinsics.yml")]
    assert main(["reconstruct", *common, "--calibration", *files, *sizes, "--out", str(tmp_path / "b")]) == 0
    two = json.loads(capsys.readouterr().out)
    assert two["points"] == one["points"]
    manifest = json.loads((tmp_path / "b" / "manifest.json").read_text())
    assert manifest["origin"]["reconstructed"]["calibration"] == " + ".join(files)


def test_the_depth_jump_limit_follows_the_depth_a_code_step_makes(tmp_path: Path) -> None:
    """At 3.2-3.6 m with a 645-unit baseline a code step moves depth by about 8 units: the bench's
    2 mm limit would drop every point, so the limit rises to three steps; the scan keeps the board."""
    sample = shared_data("procam-calibration", "sample_data")
    description = tmp_path / "graycode.yaml"
    spec = {"projector": {"resolution": [2048, 1536], "code_step_px": 2}, "gray": {"axes": ["columns", "rows"]}}
    description.write_text(
        yaml.safe_dump({**spec, "frames": {"files": "graycode_*.png"}, "gray": {**spec["gray"], "white_black": "last"}})
    )
    options = ForeignCalibrationOptions(projector_resolution=(2048, 1536))
    path, result = reconstruct_folder(
        sample / "capture_1",
        description,
        sample / "calibration_result.xml",
        tmp_path / "scan",
        "x",
        load_config(),
        options,
    )
    limit = json.loads((path / "manifest.json").read_text())["config"]["scan"]["max_depth_jump_mm"]
    assert 20.0 < limit < 35.0  # 27.0 measured
    assert len(result.cloud) > 0.9 * result.pairs[0].correspondence.counts["decoded"]


@pytest.mark.parametrize("codec", ["gray", "phase"])
def test_a_scans_kept_frames_reconstruct_from_the_description_written_beside_them(tmp_path: Path, codec: str) -> None:
    """slrig's own codecs describe their frames: a scan's kept frames are read by `slrig reconstruct`
    as anyone's, and give the scan's own points."""
    from rig.service.tasks import scan_to_directory

    config = load_config(write_config(tmp_path, small_config_data()))
    with open_rig(config) as rig:
        path, scanned = scan_to_directory(rig, tmp_path / "scan", "20261125-120000-aaaaaa", codec, keep_frames=True)
        camera = rig.camera_models[0]
        calibration = _opencv_calibration(tmp_path / "calibration.xml", camera, rig.projector_models[0])
    frames = path / "frames" / "projector0_camera0"
    _, again = reconstruct_folder(
        frames, frames / "patterns.yaml", calibration, tmp_path / "again", "20261125-120000-bbbbbb", config
    )
    ours, theirs = scanned.pairs[0].points, again.pairs[0].points
    # the same pixels, the same points: the calibration file's world is the camera's, the scan's the bench's
    common, i_ours, i_theirs = np.intersect1d(ours.pixel, theirs.pixel, return_indices=True)
    assert len(common) >= 0.99 * len(ours.pixel)  # reconstruct's depth-jump limit keeps a few more
    in_bench = (theirs.points[i_theirs] - camera.t) @ camera.R
    assert np.abs(in_bench - ours.points[i_ours]).max() < 1e-3
