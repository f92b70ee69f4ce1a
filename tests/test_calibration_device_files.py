"""Calibration files of one device each (ROS camera_info, 3DUNDERWORLD, OpenCV's camera
calibration sample) read as a camera-projector pair, and MATLAB's stereoParameters struct: each file
written here as its tool's documentation describes it, read back to the geometry it was made from."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from rig.calibrate.foreign import ForeignCalibrationOptions, read_foreign_calibration
from rig.errors import CalibrationError
from tests import calibration_writers as write
from tests.test_foreign_calibration import CAMERA_DIST, CAMERA_K, PROJECTOR_K, ROTATION, TRANSLATION

CAMERA_SIZE, PROJECTOR_SIZE = (1280, 1024), (912, 1140)
PAIR = write.Pair(CAMERA_K, CAMERA_DIST, CAMERA_SIZE, PROJECTOR_K, np.zeros(5), PROJECTOR_SIZE, ROTATION, TRANSLATION)


def _ros_pair(folder: Path) -> tuple[Path, Path]:
    left, right = write.ros_pair(folder, PAIR)
    return left, right


def test_two_ros_camera_infos_are_a_pair_posed_by_their_rectification(tmp_path: Path) -> None:
    left, right = _ros_pair(tmp_path)
    found = read_foreign_calibration([left, right])
    assert found.format == "ROS camera_info" and found.unit == "m"
    assert found.projector is not None
    assert np.allclose(found.camera.K, CAMERA_K) and np.allclose(found.camera.dist, CAMERA_DIST)
    assert (found.camera.width, found.camera.height) == CAMERA_SIZE
    assert (found.projector.width, found.projector.height) == PROJECTOR_SIZE
    assert np.allclose(found.projector.R, ROTATION, atol=1e-9)
    assert np.allclose(found.projector.t, TRANSLATION, atol=1e-6)  # metres read as millimetres
    assert found.found["camera_matrix"] == "left.yaml: camera_matrix"
    with pytest.raises(CalibrationError, match=r"left\.yaml: holds a camera alone .*give its file as well"):
        read_foreign_calibration([left])
    alone = read_foreign_calibration([left], single_device=True)
    assert alone.projector is None and np.allclose(alone.camera.K, CAMERA_K)
    fisheye = tmp_path / "fisheye.yaml"
    fisheye.write_text(left.read_text().replace("plumb_bob", "equidistant"))
    with pytest.raises(CalibrationError, match=r"fisheye\.yaml: distortion_model: equidistant"):
        read_foreign_calibration([fisheye, right])


def test_3dunderworld_cameras_posed_from_one_board_are_a_pair(tmp_path: Path) -> None:
    camera, projector = write.underworld_pair(tmp_path, PAIR)
    options = ForeignCalibrationOptions(camera_resolution=CAMERA_SIZE)  # the text files hold no size
    found = read_foreign_calibration([camera, projector], options)
    assert found.format == "3DUNDERWORLD" and found.projector is not None
    assert np.allclose(found.camera.K, CAMERA_K) and np.allclose(found.camera.dist, CAMERA_DIST)
    assert (found.projector.width, found.projector.height) == PROJECTOR_SIZE
    assert np.allclose(found.projector.R, ROTATION) and np.allclose(found.projector.t, TRANSLATION)
    with pytest.raises(CalibrationError, match=r"camera_size: missing .* give camera_resolution"):
        read_foreign_calibration([camera, projector])
    (camera / "cam_trans_vectror.txt").unlink()
    with pytest.raises(CalibrationError, match=r"camera: not 3DUNDERWORLD's four text files \(missing cam_trans"):
        read_foreign_calibration([camera, projector], options)


def test_opencv_camera_samples_are_a_pair_with_a_third_file_for_their_pose(tmp_path: Path) -> None:
    camera, projector, pose = write.opencv_samples(tmp_path, PAIR)
    found = read_foreign_calibration([camera, projector, pose])
    assert found.format == "OpenCV camera calibration" and found.projector is not None
    assert found.found["rotation"] == "R" and found.rms_px is None  # one device's error is not the pair's
    assert np.allclose(found.projector.R, ROTATION) and np.allclose(found.projector.t, TRANSLATION)
    assert (found.projector.width, found.projector.height) == PROJECTOR_SIZE
    with pytest.raises(CalibrationError, match=r"rotation: missing \(looked for R, rotation"):
        read_foreign_calibration([camera, projector])
    alone = read_foreign_calibration([camera], single_device=True)
    assert alone.rms_px == pytest.approx(0.31)


def test_matlab_stereo_parameters_read_from_a_mat_file_and_from_json(tmp_path: Path) -> None:
    write.matlab_mat(tmp_path, PAIR)
    document = json.loads(write.matlab_json(tmp_path, PAIR)[0].read_text())
    (tmp_path / "stereo.yaml").write_text(yaml.safe_dump(document))  # a YAML export of the same struct
    for name in ("stereo.mat", "stereo.json", "stereo.yaml"):
        found = read_foreign_calibration(tmp_path / name)
        assert found.format == "MATLAB stereoParameters" and found.unit == "millimeters" and found.projector
        assert np.allclose(found.camera.K, CAMERA_K) and np.allclose(found.camera.dist, CAMERA_DIST)
        assert (found.camera.width, found.camera.height) == CAMERA_SIZE
        assert np.allclose(found.projector.R, ROTATION) and np.allclose(found.projector.t, TRANSLATION)
    document["CameraParameters1"]["WorldUnits"] = "cm"
    (tmp_path / "cm.json").write_text(json.dumps(document))
    assert np.allclose(read_foreign_calibration(tmp_path / "cm.json").projector.t, TRANSLATION * 10)
    document["CameraParameters1"]["WorldUnits"] = "furlongs"
    (tmp_path / "odd.json").write_text(json.dumps(document))
    with pytest.raises(CalibrationError, match=r"CameraParameters1\.WorldUnits: 'furlongs' is not a unit"):
        read_foreign_calibration(tmp_path / "odd.json")
    document["CameraParameters1"]["K"][0][1] = 3.0
    (tmp_path / "skew.json").write_text(json.dumps(document))
    with pytest.raises(CalibrationError, match=r"CameraParameters1\.K: a skew of 3"):
        read_foreign_calibration(tmp_path / "skew.json", ForeignCalibrationOptions(translation_scale=1.0))


def test_calibration_show_prints_a_camera_alone_and_a_pair(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from rig.cli import main

    left, right = _ros_pair(tmp_path)
    assert main(["calibration", "show", str(left)]) == 0
    out = capsys.readouterr().out
    assert "ROS camera_info; its lengths in m" in out and "a camera alone: no projector, no baseline" in out
    assert main(["calibration", "show", str(left), str(right), "--json"]) == 0
    shown = json.loads(capsys.readouterr().out)
    assert shown["baseline_mm"] == pytest.approx(float(np.linalg.norm(TRANSLATION)), abs=1e-4)
    assert [d["kind"] for d in shown["devices"].values()] == ["camera", "projector"]
    patterns = tmp_path / "patterns.yaml"
    patterns.write_text("projector: {resolution: [912, 1140]}\ngray: {axes: [columns, rows]}\n")
    command = ["reconstruct", str(tmp_path), "--patterns", str(patterns), "--calibration", str(left)]
    assert main([*command, "--out", str(tmp_path / "o")]) == 2
    assert "holds a camera alone" in capsys.readouterr().err
